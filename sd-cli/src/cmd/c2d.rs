//! `sdctl c2d`.

use crate::commands::{finite_pos, model_json};
use crate::io::{emit, from_model, from_multirate, read_model, CliError};
use sd_model::{c2d, Discretization};

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub(crate) enum Method {
    Zoh,
    Foh,
    Tustin,
    /// Matched pole-zero (SISO; zeros at infinity but one to z = −1; low-frequency gain kept).
    Matched,
    /// Impulse-invariant (strictly proper models).
    Impulse,
}

/// Arguments of `sdctl c2d`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Model JSON file ("-" for stdin).
    pub(crate) model: String,
    /// Sampling period in seconds.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) ts: f64,
    /// Method: zoh (exact zero-order hold, default), foh (triangle hold), tustin (bilinear),
    /// matched (pole-zero mapping, SISO) or impulse (impulse-invariant, D = 0).
    #[arg(long, value_enum, default_value = "zoh")]
    pub(crate) method: Method,
    /// Tustin prewarp frequency in Hz.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) prewarp_hz: Option<f64>,
    /// ZOH that switches this fraction of the period late (0..1; adds nu states).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) hold_delay: Option<f64>,
    /// Sampler averaging over the last fraction of the period (0..1; adds ny states).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) averaging: Option<f64>,
    /// Output file (default stdout).
    #[arg(short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            model,
            ts,
            method,
            prewarp_hz,
            hold_delay,
            averaging,
            output,
        } = self;
        let sys = read_model(&model)?;
        finite_pos(ts, "--ts")?;
        if ts > 1.0 {
            // a period above a second is legal (slow processes) but mostly a rate typed as a
            // period: say so, and go on
            eprintln!(
                "sdctl: warning: --ts {ts} is a sample period of {ts} s ({:.3e} Hz); for a rate \
                 of {ts} Hz give --ts {:.6e}",
                1.0 / ts,
                1.0 / ts
            );
        }
        if prewarp_hz.is_some() && !matches!(method, Method::Tustin) {
            return Err(CliError::input(
                "--prewarp-hz only applies to --method tustin",
            ));
        }
        if hold_delay.is_some() || averaging.is_some() {
            if !matches!(method, Method::Zoh) {
                return Err(CliError::input(
                    "--hold-delay and --averaging apply to --method zoh (the default)",
                ));
            }
            let ni = sd_multirate::NonIdeal {
                hold_delay: hold_delay.unwrap_or(0.0),
                averaging: averaging.unwrap_or(0.0),
            };
            let d =
                sd_multirate::c2d_nonideal(&sys, ts, ni).map_err(|e| from_multirate(&model, e))?;
            return emit(&model_json(&d)?, output.as_deref());
        }
        let m = match method {
            Method::Zoh => Discretization::Zoh,
            Method::Foh => Discretization::Foh,
            Method::Tustin => Discretization::Tustin { prewarp_hz },
            Method::Matched => Discretization::Matched,
            Method::Impulse => Discretization::Impulse,
        };
        let d = c2d(&sys, ts, m).map_err(|e| from_model(&model, e))?;
        emit(&model_json(&d)?, output.as_deref())
    }
}
