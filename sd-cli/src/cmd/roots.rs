//! `sdctl poles` and `sdctl zeros`.

use crate::io::{emit, from_model, read_model, CliError};
use serde_json::json;

/// Arguments of `sdctl poles` and `sdctl zeros`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Model JSON file (docs/formats.md; "-" reads stdin).
    pub(crate) model: String,
    /// Print JSON (keys in docs/formats.md) instead of text.
    #[arg(long)]
    pub(crate) json: bool,
}

impl Args {
    /// Runs the command: the poles when `poles`, else the invariant zeros.
    pub(crate) fn run(self, poles: bool) -> Result<(), CliError> {
        roots(&self.model, self.json, poles)
    }
}

fn pole_info(p: num_complex::Complex64, ts: Option<f64>) -> (f64, f64) {
    // (frequency Hz, damping) of the equivalent continuous pole
    let s = match ts {
        None => p,
        Some(h) => p.ln() / h,
    };
    let f = s.norm() / (2.0 * std::f64::consts::PI);
    let z = if s.norm() == 0.0 {
        1.0
    } else {
        -s.re / s.norm()
    };
    (f, z)
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
                let (f, z) = pole_info(*p, ts);
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
            let (f, z) = pole_info(*p, ts);
            s += &format!(
                "{:>24.16e} {:>24.16e} {:>14.6} {:>10.6}\n",
                p.re, p.im, f, z
            );
        }
        emit(s.trim_end(), None)
    }
}
