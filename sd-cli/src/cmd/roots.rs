//! `sdctl poles` and `sdctl zeros`.

use crate::io::{emit, from_model, read_model, CliError};
use serde_json::json;

/// Arguments of `sdctl poles` and `sdctl zeros`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[arg(help = crate::commands::MODEL_HELP)]
    pub(crate) model: String,
    #[arg(help = crate::commands::JSON_HELP, long)]
    pub(crate) json: bool,
}

impl Args {
    /// Runs the command: the poles when `poles`, else the invariant zeros.
    pub(crate) fn run(self, poles: bool) -> Result<(), CliError> {
        roots(&self.model, self.json, poles)
    }
}

/// Prints the poles (or zeros) of a model with their frequency and damping.
fn roots(model: &str, json: bool, poles: bool) -> Result<(), CliError> {
    let sys = read_model(model)?;
    let r = if poles { sys.poles() } else { sys.zeros() }.map_err(|e| from_model(model, e))?;
    let ts = sys.ts();
    if json {
        let v: Vec<_> = r
            .iter()
            .map(|p| {
                let (f, z) = sd_model::poles::natural_frequency(*p, ts);
                json!({"re": p.re, "im": p.im, "freq_hz": f, "damping": z})
            })
            .collect();
        emit(&serde_json::Value::Array(v).to_string(), None)
    } else {
        let mut s = format!(
            "{:>24} {:>24} {:>14} {:>10}\n",
            "re", "im", "freq_hz", "damping"
        );
        for p in &r {
            let (f, z) = sd_model::poles::natural_frequency(*p, ts);
            s += &format!(
                "{:>24.16e} {:>24.16e} {:>14.6} {:>10.6}\n",
                p.re, p.im, f, z
            );
        }
        emit(s.trim_end(), None)
    }
}
