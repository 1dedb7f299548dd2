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
    /// Measured FRD JSON of the plant at the plant's sample time: the chordal distance between
    /// the shaped model and the shaped measurement (the ν-gap to the measured plant when the
    /// winding condition holds) against the design's stability margin ε = 1/achieved.
    #[arg(long)]
    pub(crate) measured: Option<String>,
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
            measured,
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
        let gap = measured
            .as_deref()
            .map(|m| measured_gap(&p, m, w1m.as_ref(), w2m.as_ref()))
            .transpose()?;
        let eps = 1.0 / d.achieved;
        if json {
            let parse = |m: &StateSpace| -> Result<serde_json::Value, CliError> {
                serde_json::from_str(&model_json(m)?)
                    .map_err(|e| CliError::numerical(format!("model JSON: {e}")))
            };
            let mut v = json!({
                "gamma_min": d.gamma_min,
                "gamma": d.gamma,
                "achieved": d.achieved,
                "closed_loop_stable": d.closed_loop_stable,
                "closed_loop_radius": d.closed_loop_radius,
                "controller": parse(&d.controller)?,
                "shaped_controller": parse(&d.shaped_controller)?,
                "riccati": d.riccati.iter().map(|r| json!({"equation": r.name, "residual": r.residual, "condition": r.condition})).collect::<Vec<_>>(),
            });
            if let (Some(g), Some(obj)) = (gap, v.as_object_mut()) {
                obj.insert("stability_margin".into(), json!(eps));
                obj.insert("nu_gap_measured".into(), json!(g));
            }
            emit(&v.to_string(), output.as_deref())
        } else {
            if let Some(g) = gap {
                eprintln!("{}", gap_text(eps, &g));
            }
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

/// The chordal distance between the (shaped) plant model and the measured FRF in `path`.
fn measured_gap(
    p: &StateSpace,
    path: &str,
    w1: Option<&StateSpace>,
    w2: Option<&StateSpace>,
) -> Result<sd_uncertainty::ChordalGap, CliError> {
    let frd = sd_model::frd_from_json_str(&crate::io::read_text(path)?)
        .map_err(|e| crate::io::from_model(path, e))?;
    let weight = match (w1, w2) {
        (Some(a), Some(b)) => {
            Some(sd_model::series(a, b).map_err(|e| crate::io::from_model("--w1/--w2", e))?)
        }
        (Some(a), None) | (None, Some(a)) => Some(a.clone()),
        (None, None) => None,
    };
    sd_uncertainty::chordal_gap(p, &frd, weight.as_ref())
        .map_err(|e| crate::cmd::uncertainty::from_unc(path, e))
}

/// The ν-gap comparison in words.
fn gap_text(eps: f64, g: &sd_uncertainty::ChordalGap) -> String {
    let verdict = if g.max < eps {
        "below ε: the controller stabilises the measured plant if the winding condition holds \
         (a measured FRF cannot show it: check the model's and the plant's unstable poles agree)"
    } else {
        "at or above ε: the design's margin does not cover what the data say"
    };
    format!(
        "stability margin ε = 1/achieved = {eps:.4}; chordal distance of the shaped model to the \
         measured FRF: {:.4} at {:.2} Hz over {} lines, {verdict}",
        g.max, g.at_hz, g.lines
    )
}
