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
            output,
        } = self;
        let exp = crate::io::load_experiments(&manifest, |n| n == experiment)?
            .pop()
            .ok_or_else(|| {
                CliError::input(format!("{manifest}: no experiment named `{experiment}`"))
            })?;
        let fs = exp.spec.sample_rate_hz;
        let frd = match exp.spec.period_samples {
            Some(p) => {
                let mut opt = sd_ident::PeriodicOptions::new(p, exp.spec.skip_periods);
                if let Some(f) = excited_fraction {
                    if !(f.is_finite() && f > 0.0 && f < 1.0) {
                        return Err(CliError::input(format!(
                            "--excited-fraction {f} must be in (0, 1)"
                        )));
                    }
                    opt.excited_fraction = f;
                }
                sd_ident::frf_periodic(fs, exp.r.as_deref(), &exp.u, &exp.y, &opt)
                    .map_err(|e| from_ident(&experiment, e))?
                    .frd
            }
            None => {
                let lo = sd_ident::LpmOptions::default();
                match &exp.r {
                    Some(r) => sd_ident::lpm_closed_loop(fs, r, &exp.u, &exp.y, &lo),
                    None => {
                        let n = exp.u.len();
                        let x = nalgebra::DMatrix::from_column_slice(n, 1, &exp.u);
                        let z = nalgebra::DMatrix::from_column_slice(n, 1, &exp.y);
                        sd_ident::lpm(fs, &x, &z, &lo).map(|e| e.frd)
                    }
                }
                .map_err(|e| from_ident(&experiment, e))?
            }
        };
        let json = sd_model::frd_to_json_string(&frd).map_err(|e| from_model("output", e))?;
        emit(&json, output.as_deref())
    }
}
