//! `sdctl mixsyn`.

use super::hinfsyn::report_json;
use crate::commands::{finite_pos, model_json};
use crate::io::{emit, from_hinf, read_model, CliError};
use sd_model::StateSpace;

/// Arguments of `sdctl mixsyn`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Plant model JSON (discrete or continuous).
    pub(crate) plant: String,
    /// Weight on the sensitivity S (ny×ny model JSON).
    #[arg(long)]
    pub(crate) w1: Option<String>,
    /// Weight on the control sensitivity KS (nu×nu).
    #[arg(long)]
    pub(crate) w2: Option<String>,
    /// Weight on the complementary sensitivity T (ny×ny).
    #[arg(long)]
    pub(crate) w3: Option<String>,
    /// Input (force) disturbance shaping (nu×nu): adds the process sensitivity SG; needed when
    /// the plant has poles on the stability boundary (a rigid body).
    #[arg(long)]
    pub(crate) wd: Option<String>,
    /// Design at this γ (at least γ_min) instead of at γ_min.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) gamma: Option<f64>,
    /// Relative tolerance of the γ iteration.
    #[arg(long, default_value_t = sd_hinf::tol::GAMMA_TOL, allow_negative_numbers = true)]
    pub(crate) tol: f64,
    /// Print gamma, gamma_min, achieved_norm and the controller as JSON.
    #[arg(long)]
    pub(crate) json: bool,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let g = read_model(&self.plant)?;
        let read = |p: &Option<String>| -> Result<Option<StateSpace>, CliError> {
            p.as_deref().map(read_model).transpose()
        };
        let (w1, w2, w3, wd) = (
            read(&self.w1)?,
            read(&self.w2)?,
            read(&self.w3)?,
            read(&self.wd)?,
        );
        let tol = finite_pos(self.tol, "--tol")?;
        if let Some(gm) = self.gamma {
            finite_pos(gm, "--gamma")?;
        }
        let w = sd_hinf::MixsynWeights {
            w1: w1.as_ref(),
            w2: w2.as_ref(),
            w3: w3.as_ref(),
            wd: wd.as_ref(),
        };
        let opt = sd_hinf::HinfOptions {
            gamma: self.gamma,
            tolerance: tol,
            ..Default::default()
        };
        let (r, p) = sd_hinf::mixsyn(&g, &w, &opt).map_err(|e| from_hinf(&self.plant, e))?;
        let controller = model_json(&r.controller)?;
        if self.json {
            let v = report_json(
                &r,
                &controller,
                vec![
                    ("generalized_plant_states", p.n().into()),
                    ("convention", "u = K (r − y) (negative feedback)".into()),
                ],
            )?;
            emit(&v, self.output.as_deref())
        } else {
            eprintln!(
                "γ_min {:.6}, γ {:.6}, achieved {:.6}, closed loop {}, controller order {} \
                 (use as u = K (r − y))",
                r.gamma_min,
                r.gamma,
                r.achieved_norm,
                if r.closed_loop_stable {
                    "stable"
                } else {
                    "UNSTABLE"
                },
                r.controller_order
            );
            emit(&controller, self.output.as_deref())
        }
    }
}
