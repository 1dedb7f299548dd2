//! `sdctl frf`.

use crate::io::{emit, from_ident, from_model, CliError};

/// Arguments of `sdctl frf`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Experiment manifest (TOML, docs/formats.md).
    pub(crate) manifest: String,
    /// Name of the experiment.
    #[arg(long)]
    pub(crate) experiment: String,
    /// Excited-line threshold relative to the strongest line (periodic data).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) excited_fraction: Option<f64>,
    /// Keep the lines whose input SNR |Ū|²/σ²_Ū is below 100 (biased ratio, no valid
    /// variance; left out by default, with a warning), and write an estimate of a record
    /// without excitation (refused by default) with a warning.
    #[arg(long)]
    pub(crate) keep_low_snr: bool,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            manifest,
            experiment,
            excited_fraction,
            keep_low_snr,
            output,
        } = self;
        let exp = sd_ident::load_experiment(std::path::Path::new(&manifest), &experiment)
            .map_err(|e| from_ident(&manifest, e))?;
        let req = sd_ident::FrfRequest {
            excited_fraction,
            keep_low_snr,
        };
        let (frd, warnings) =
            sd_ident::frf_of_experiment(&exp, &req).map_err(|e| from_ident(&experiment, e))?;
        for w in &warnings {
            eprintln!("sdctl: warning: {experiment}: {w}");
        }
        let mut json = sd_model::frd_to_json_string(&frd).map_err(|e| from_model("output", e))?;
        if !warnings.is_empty() {
            json = with_warnings(&json, &warnings)?;
        }
        emit(&json, output.as_deref())
    }
}

/// The FRD JSON text with a `"warnings"` array (each `{"kind", "message", …}`), which readers
/// accept and ignore.
fn with_warnings(json: &str, warnings: &[sd_ident::DataWarning]) -> Result<String, CliError> {
    let bad = |e: serde_json::Error| CliError::numerical(format!("FRD JSON: {e}"));
    let mut v: serde_json::Value = serde_json::from_str(json).map_err(bad)?;
    if let Some(m) = v.as_object_mut() {
        m.insert("warnings".into(), crate::io::warnings_json(warnings));
    }
    serde_json::to_string(&v).map_err(bad)
}
