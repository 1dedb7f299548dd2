//! `sdctl downsample`.

use crate::commands::{factor_arg, model_json};
use crate::io::{emit, from_multirate, read_model, CliError};

/// Arguments of `sdctl downsample`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Discrete model JSON file ("-" for stdin).
    pub(crate) model: String,
    /// Rate factor F = T/h (integer >= 1).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) factor: i64,
    /// Slow hold switching this fraction of the slow period late (a multiple of 1/F).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) hold_delay: Option<f64>,
    /// Slow sampler returning the mean of the last fraction of fast samples (a multiple of 1/F).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) averaging: Option<f64>,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            model,
            factor,
            hold_delay,
            averaging,
            output,
        } = self;
        let sys = read_model(&model)?;
        if sys.ts().is_none() {
            return Err(CliError {
                code: 2,
                message: format!(
                    "{model}: downsample takes a discrete model at the fast rate (Lemma 6), and \
                     this one is continuous-time (\"ts\": null); for the slow model use \
                     `sdctl c2d {model} --ts <slow period>` directly (exact ZOH; --hold-delay and \
                     --averaging are there too), or c2d to the fast rate first"
                ),
            });
        }
        let f = factor_arg(factor)?;
        let ni = sd_multirate::NonIdeal {
            hold_delay: hold_delay.unwrap_or(0.0),
            averaging: averaging.unwrap_or(0.0),
        };
        let d = sd_multirate::downsample_nonideal(&sys, f, ni)
            .map_err(|e| from_multirate(&model, e))?;
        emit(&model_json(&d)?, output.as_deref())
    }
}
