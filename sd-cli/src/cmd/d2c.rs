//! `sdctl d2c`.

use crate::commands::{finite_pos, model_json};
use crate::io::{emit, from_model, read_model, CliError};
use sd_model::d2c_with_aliases;

/// Arguments of `sdctl d2c`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Discrete model JSON file ("-" reads stdin).
    pub(crate) model: String,
    /// Highest candidate frequency listed per mode (Hz; default 3 × the sample rate).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) max_hz: Option<f64>,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            model,
            max_hz,
            output,
        } = self;
        let sys = read_model(&model)?;
        let ts = sys.ts().unwrap_or(1.0);
        let max_hz = finite_pos(max_hz.unwrap_or(3.0 / ts), "--max-hz")?;
        let (c, modes) = d2c_with_aliases(&sys, max_hz).map_err(|e| from_model(&model, e))?;
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
