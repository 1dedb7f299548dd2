//! `sdctl h2syn`.

use super::hinfsyn::report_json;
use crate::commands::model_json;
use crate::io::{emit, from_hinf, read_model, CliError};
use serde_json::json;

/// Arguments of `sdctl h2syn`.
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
    /// Print achieved_norm, stability, the controller and the Riccati residuals as JSON
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
        let part = sd_hinf::Partition {
            nmeas: self.nmeas,
            ncon: self.ncon,
        };
        let r = sd_hinf::h2syn(&p, part).map_err(|e| from_hinf(&self.plant, e))?;
        let controller = model_json(&r.controller)?;
        if self.json {
            let v = report_json(
                &r,
                &controller,
                vec![("convention", json!(super::hinfsyn::LFT_CONVENTION))],
            )?;
            emit(&v, self.output.as_deref())
        } else {
            eprintln!(
                "achieved ‖F_l(P, K)‖₂ {:.6}, closed loop {}, controller order {}",
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
