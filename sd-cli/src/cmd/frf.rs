//! `sdctl frf`.

use crate::io::{emit, from_ident, from_model, CliError};

/// Arguments of `sdctl frf`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Experiment manifest (TOML, docs/formats.md).
    pub(crate) manifest: String,
    /// Name of the experiment; repeat it for a MIMO set (experiments at one rate and period,
    /// at least one per input: one input excited each, or orthogonal multisines), whose FRF is
    /// ny × nu. A single experiment with several inputs or outputs (lists in the manifest)
    /// gives a MIMO FRF too (non-periodic: LPM over its inputs).
    #[arg(long, required = true)]
    pub(crate) experiment: Vec<String>,
    /// With a MIMO FRF: add `covariance` (per line the covariance of vec(G), columns stacked,
    /// as `re` and `im` arrays of (ny·nu)² entries) to the FRD JSON.
    #[arg(long)]
    pub(crate) covariance: bool,
    /// Excited-line threshold relative to the strongest line (periodic data).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) excited_fraction: Option<f64>,
    /// Keep the lines whose input SNR |Ū|²/σ²_Ū is below 100 (biased ratio, no valid
    /// variance; left out by default, with a warning), and write an estimate of a record
    /// without excitation (refused by default) with a warning.
    #[arg(long)]
    pub(crate) keep_low_snr: bool,
    /// Also write the FRF as CSV to this file: per entry and line the frequency (Hz),
    /// magnitude (dB), unwrapped phase (degrees), σ of the estimate and the SNR |G|/σ (dB).
    #[arg(long)]
    pub(crate) csv: Option<String>,
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
            covariance,
            csv,
            output,
        } = self;
        let req = sd_ident::FrfRequest {
            excited_fraction,
            keep_low_snr,
        };
        let path = std::path::Path::new(&manifest);
        // every experiment of the manifest: a SISO estimate may borrow its distortion level
        // from a sibling ([`sd_ident::estimate_in_set`])
        let single = experiment.len() == 1;
        let exps =
            sd_ident::load_experiments(path, |n| single || experiment.iter().any(|e| e == n))
                .map_err(|e| from_ident(&manifest, e))?;
        if let Some(missing) = experiment
            .iter()
            .find(|n| !exps.iter().any(|e| &e.spec.name == *n))
        {
            return Err(from_ident(
                &manifest,
                sd_ident::IdentError::InvalidArgument(format!("no experiment named `{missing}`")),
            ));
        }
        let chosen: Vec<sd_ident::Experiment> = exps
            .iter()
            .filter(|e| experiment.contains(&e.spec.name))
            .cloned()
            .collect();
        if chosen.len() > 1 || chosen.iter().any(|e| e.spec.is_mimo()) {
            return mimo(
                &chosen,
                &req,
                covariance,
                (output.as_deref(), csv.as_deref()),
            );
        }
        let Some(target) = exps.iter().position(|e| e.spec.name == experiment[0]) else {
            return Err(CliError::input("no experiment given"));
        };
        let name = experiment[0].clone();
        let est =
            sd_ident::estimate_in_set(&exps, target, &req).map_err(|e| from_ident(&name, e))?;
        for w in &est.warnings {
            eprintln!("sdctl: warning: {name}: {w}");
        }
        let mut json =
            sd_model::frd_to_json_string(&est.frd).map_err(|e| from_model("output", e))?;
        if !est.warnings.is_empty() {
            json = with_warnings(&json, &est.warnings)?;
        }
        if let Some(bla) = &est.bla {
            eprintln!("[frf] {name}: {}", bla.distortion);
            json = with_bla(&json, bla)?;
        }
        if let Some(path) = &csv {
            emit(crate::io::frd_csv(&est.frd).trim_end(), Some(path))?;
        }
        emit(&json, output.as_deref())
    }
}

/// The FRD JSON text with the BLA's parts: `var_noise` and `var_distortion` (the shape of
/// `var`, which is their sum) and `distortion` (how it was measured, `bands` with the noise and
/// distortion relative to |G|); readers accept and ignore them.
fn with_bla(json: &str, bla: &sd_ident::Bla) -> Result<String, CliError> {
    let bad = |e: serde_json::Error| CliError::numerical(format!("FRD JSON: {e}"));
    let mut v: serde_json::Value = serde_json::from_str(json).map_err(bad)?;
    let cube = |x: &[f64]| -> Vec<[[f64; 1]; 1]> { x.iter().map(|v| [[*v]]).collect() };
    let mut d = serde_json::to_value(&bla.distortion).map_err(bad)?;
    if let Some(m) = d.as_object_mut() {
        m.insert("measured".into(), bla.distortion.measured().into());
        m.insert("summary".into(), bla.distortion.to_string().into());
        m.insert(
            "bands".into(),
            serde_json::to_value(bla.bands()).map_err(bad)?,
        );
    }
    if let Some(m) = v.as_object_mut() {
        m.insert("var_noise".into(), serde_json::json!(cube(&bla.noise_var)));
        m.insert(
            "var_distortion".into(),
            serde_json::json!(cube(&bla.distortion_var)),
        );
        m.insert("distortion".into(), d);
    }
    serde_json::to_string(&v).map_err(bad)
}

/// The ny × nu FRF of several experiments, or of one with several channels
/// ([`sd_ident::frf_of_experiments`]).
fn mimo(
    exps: &[sd_ident::Experiment],
    req: &sd_ident::FrfRequest,
    covariance: bool,
    (output, csv): (Option<&str>, Option<&str>),
) -> Result<(), CliError> {
    let refs: Vec<&sd_ident::Experiment> = exps.iter().collect();
    let names: Vec<&str> = exps.iter().map(|e| e.spec.name.as_str()).collect();
    let est =
        sd_ident::frf_of_experiments(&refs, req).map_err(|e| from_ident(&names.join(", "), e))?;
    let (ny, nu) = est.frd.shape();
    eprintln!(
        "[frf] {ny}x{nu} from {}: {} lines{}",
        names.join(", "),
        est.frd.len(),
        if est.periods > 0 {
            format!(", {} steady periods", est.periods)
        } else {
            String::new()
        }
    );
    let json = sd_model::frd_to_json_string(&est.frd).map_err(|e| from_model("output", e))?;
    if let Some(path) = csv {
        emit(crate::io::frd_csv(&est.frd).trim_end(), Some(path))?;
    }
    if !covariance {
        return emit(&json, output);
    }
    if est.covariance.is_empty() {
        return Err(CliError::input(
            "no covariance: it needs periodic experiments with two steady periods or more",
        ));
    }
    let bad = |e: serde_json::Error| CliError::numerical(format!("FRD JSON: {e}"));
    let mut v: serde_json::Value = serde_json::from_str(&json).map_err(bad)?;
    let part = |f: fn(&num_complex::Complex64) -> f64| -> Vec<Vec<Vec<f64>>> {
        est.covariance
            .iter()
            .map(|c| {
                (0..c.nrows())
                    .map(|i| c.row(i).iter().map(f).collect())
                    .collect()
            })
            .collect()
    };
    if let Some(m) = v.as_object_mut() {
        m.insert(
            "covariance".into(),
            serde_json::json!({"re": part(|c| c.re), "im": part(|c| c.im)}),
        );
    }
    emit(&serde_json::to_string(&v).map_err(bad)?, output)
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
