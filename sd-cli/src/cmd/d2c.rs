//! `sdctl d2c`.

use crate::commands::{finite_pos, model_json};
use crate::io::{emit, from_model, read_model, CliError};
use sd_model::{d2c_near, d2c_with_aliases};

/// Arguments of `sdctl d2c`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Discrete model JSON file ("-" reads stdin).
    pub(crate) model: String,
    /// Highest candidate frequency listed per mode (Hz; default 3 × the sample rate).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) max_hz: Option<f64>,
    /// Use the alias branch nearest to this natural frequency (Hz) for the mode that has one
    /// there (e.g. `--near-hz 653` turns the 347 Hz principal branch of a 653 Hz mode sampled at
    /// 1 kHz back into 653 Hz). Repeat for several modes; other modes stay principal.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) near_hz: Vec<f64>,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            model,
            max_hz,
            near_hz,
            output,
        } = self;
        let sys = read_model(&model)?;
        let ts = sys.ts().unwrap_or(1.0);
        let max_hz = finite_pos(max_hz.unwrap_or(3.0 / ts), "--max-hz")?;
        let (principal, modes) =
            d2c_with_aliases(&sys, max_hz).map_err(|e| from_model(&model, e))?;
        let c = if near_hz.is_empty() {
            principal
        } else {
            let (c, picks) = d2c_near(&sys, &near_hz).map_err(|e| from_model(&model, e))?;
            for p in picks {
                eprintln!(
                    "--near-hz {}: mode z = {:.6}{:+.6}i on branch k = {} at {:.4} Hz ζ={:.5} \
                     (principal {:.4} Hz)",
                    p.requested_hz, p.z.re, p.z.im, p.branch, p.freq_hz, p.damping, p.principal_hz
                );
            }
            c
        };
        emit(&model_json(&c)?, output.as_deref())?;
        eprintln!(
            "mode alias candidates (natural frequency |s|/2π in Hz, as `sdctl poles`; damping) \
             up to {max_hz} Hz:"
        );
        for m in modes {
            let list: Vec<String> = m
                .candidates
                .iter()
                .map(|(f, z)| format!("{f:.4} (ζ={z:.4})"))
                .collect();
            eprintln!(
                "  z = {:.6}{:+.6}i  principal branch {:.4} Hz ζ={:.5}: {}",
                m.z.re,
                m.z.im,
                m.freq_hz,
                m.damping,
                list.join(", ")
            );
        }
        Ok(())
    }
}
