//! `sdctl loopshape`.

use crate::commands::model_json;
use crate::io::{emit, from_hinf, read_model, CliError};
use sd_model::StateSpace;
use serde_json::json;

/// Arguments of `sdctl loopshape`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Plant model JSON (discrete or continuous).
    pub(crate) plant: String,
    /// Input weight W1 (model JSON, nu×nu); identity if absent.
    #[arg(long)]
    w1: Option<String>,
    /// Output weight W2 (model JSON, ny×ny); identity if absent.
    #[arg(long)]
    w2: Option<String>,
    /// γ = factor·γ_min (> 1).
    #[arg(long, default_value_t = 1.1, allow_negative_numbers = true)]
    pub(crate) factor: f64,
    /// Strictly proper controller (no feedthrough; discrete plants).
    #[arg(long)]
    pub(crate) strictly_proper: bool,
    /// Print gamma_min, gamma, the controllers, stability and Riccati residuals as JSON.
    #[arg(long)]
    pub(crate) json: bool,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            plant,
            w1,
            w2,
            factor,
            strictly_proper,
            json,
            output,
        } = self;
        let p = read_model(&plant)?;
        let w1m = w1.as_deref().map(read_model).transpose()?;
        let w2m = w2.as_deref().map(read_model).transpose()?;
        let opt = sd_hinf::LoopshapeOptions {
            factor,
            strictly_proper,
        };
        let d = sd_hinf::loopshape(&p, w1m.as_ref(), w2m.as_ref(), &opt)
            .map_err(|e| from_hinf(&plant, e))?;
        if json {
            let parse = |m: &StateSpace| -> Result<serde_json::Value, CliError> {
                serde_json::from_str(&model_json(m)?)
                    .map_err(|e| CliError::numerical(format!("model JSON: {e}")))
            };
            let v = json!({
                "gamma_min": d.gamma_min,
                "gamma": d.gamma,
                "achieved": d.achieved,
                "closed_loop_stable": d.closed_loop_stable,
                "closed_loop_radius": d.closed_loop_radius,
                "controller": parse(&d.controller)?,
                "shaped_controller": parse(&d.shaped_controller)?,
                "riccati": d.riccati.iter().map(|r| json!({"equation": r.name, "residual": r.residual, "condition": r.condition})).collect::<Vec<_>>(),
            });
            emit(&v.to_string(), output.as_deref())
        } else {
            eprintln!(
                "γ_min {:.6}, γ {:.6}, achieved {:.6}, closed loop {}",
                d.gamma_min,
                d.gamma,
                d.achieved,
                if d.closed_loop_stable {
                    "stable"
                } else {
                    "UNSTABLE"
                }
            );
            emit(&model_json(&d.controller)?, output.as_deref())
        }
    }
}
