//! `sdctl norm`.

use crate::io::{emit, from_model, read_model, CliError};
use serde_json::json;

/// Arguments of `sdctl norm`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[arg(help = crate::commands::MODEL_HELP)]
    pub(crate) model: String,
    #[arg(help = crate::commands::JSON_HELP, long)]
    pub(crate) json: bool,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args { model, json } = self;
        let sys = read_model(&model)?;
        let hinf = sys.hinf_norm().map_err(|e| from_model(&model, e))?;
        let h2 = sys.h2_norm().ok();
        if json {
            emit(
            &json!({"hinf": if hinf.value.is_finite() { json!(hinf.value) } else { json!("inf") },
                    "hinf_db": if hinf.value.is_finite() { json!(20.0 * hinf.value.log10()) } else { json!("inf") },
                    "peak_hz": hinf.peak_hz, "stable": hinf.stable,
                    "h2": h2.map(|v| json!(v)).unwrap_or(json!("inf"))})
            .to_string(),
            None,
        )
        } else {
            emit(
                &format!(
                    "H-infinity norm {} ({:.3} dB) at {:.6} Hz{}\nH2 norm {}",
                    hinf.value,
                    20.0 * hinf.value.log10(),
                    hinf.peak_hz,
                    if hinf.stable {
                        ""
                    } else {
                        " (unstable model: L-infinity norm)"
                    },
                    h2.map(|v| v.to_string()).unwrap_or_else(|| "inf".into())
                ),
                None,
            )
        }
    }
}
