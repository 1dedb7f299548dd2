//! `sdctl hinfsyn`.

use crate::commands::{finite_pos, model_json};
use crate::io::{emit, from_hinf, read_model, CliError};
use serde_json::json;

/// Arguments of `sdctl hinfsyn`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Generalized plant model JSON (discrete or continuous): inputs [w; u], outputs [z; y].
    pub(crate) plant: String,
    /// Number of measurements: the plant's last NMEAS outputs.
    #[arg(long)]
    pub(crate) nmeas: usize,
    /// Number of controls: the plant's last NCON inputs.
    #[arg(long)]
    pub(crate) ncon: usize,
    /// Design at this γ (at least γ_min) instead of at γ_min.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) gamma: Option<f64>,
    /// Relative tolerance of the γ iteration.
    #[arg(long, default_value_t = sd_hinf::tol::GAMMA_TOL, allow_negative_numbers = true)]
    pub(crate) tol: f64,
    /// Print gamma, gamma_min, achieved_norm, the controller and the γ iteration as JSON
    /// (without it: the controller's model JSON, a summary on stderr).
    #[arg(long)]
    pub(crate) json: bool,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let p = read_model(&self.plant)?;
        let tol = finite_pos(self.tol, "--tol")?;
        if let Some(g) = self.gamma {
            finite_pos(g, "--gamma")?;
        }
        let opt = sd_hinf::HinfOptions {
            gamma: self.gamma,
            tolerance: tol,
            ..Default::default()
        };
        let part = sd_hinf::Partition {
            nmeas: self.nmeas,
            ncon: self.ncon,
        };
        let r = sd_hinf::hinfsyn(&p, part, &opt).map_err(|e| from_hinf(&self.plant, e))?;
        let controller = model_json(&r.controller)?;
        if self.json {
            let v = report_json(&r, &controller, vec![("convention", json!(LFT_CONVENTION))])?;
            emit(&v, self.output.as_deref())
        } else {
            eprintln!(
                "γ_min {:.6} (infeasible at {:.6}), γ {:.6}, achieved ‖F_l(P, K)‖∞ {:.6} at {:.4} \
                 Hz, closed loop {}, controller order {}, {} γ levels tried",
                r.gamma_min,
                r.gamma_infeasible,
                r.gamma,
                r.achieved_norm,
                r.peak_hz,
                if r.closed_loop_stable {
                    "stable"
                } else {
                    "UNSTABLE"
                },
                r.controller_order,
                r.steps.len()
            );
            emit(&controller, self.output.as_deref())
        }
    }
}

/// The controller convention of `hinfsyn` and `h2syn` (printed in their JSON).
pub(crate) const LFT_CONVENTION: &str =
    "u = K y (positive feedback, the last ncon inputs from the last nmeas outputs)";

/// A synthesis report as JSON text: the result's own fields, the controller's model JSON under
/// `controller`, and `extra` keys.
pub(crate) fn report_json(
    r: &impl serde::Serialize,
    controller: &str,
    extra: Vec<(&str, serde_json::Value)>,
) -> Result<String, CliError> {
    let mut v =
        serde_json::to_value(r).map_err(|e| CliError::numerical(format!("result JSON: {e}")))?;
    let k: serde_json::Value = serde_json::from_str(controller)
        .map_err(|e| CliError::numerical(format!("model JSON: {e}")))?;
    if let Some(obj) = v.as_object_mut() {
        obj.insert("controller".into(), k);
        for (key, val) in extra {
            obj.insert(key.into(), val);
        }
    }
    Ok(v.to_string())
}
