//! `sdctl analyze`.

use crate::io::{emit, from_analysis, read_model, CliError};
use serde_json::json;

/// Arguments of `sdctl analyze`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Plant model JSON (same sample time as the controller).
    #[arg(long)]
    pub(crate) plant: String,
    /// Controller model JSON (negative feedback u = −K y).
    #[arg(long)]
    pub(crate) controller: String,
    #[arg(help = crate::commands::JSON_HELP, long)]
    pub(crate) json: bool,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            plant,
            controller,
            json,
        } = self;
        let p = read_model(&plant)?;
        let k = read_model(&controller)?;
        let cl = sd_analysis::ClosedLoop::new(&p, &k).map_err(|e| from_analysis("analyze", e))?;
        let s = cl.summary().map_err(|e| from_analysis("analyze", e))?;
        if json {
            let v = json!({
                "stable": s.stable,
                "closed_loop_radius": s.closed_loop_radius,
                "bandwidth_hz": s.bandwidth_hz,
                "crossover_hz": s.crossover_hz,
                "sensitivity_peak_db": s.sensitivity_peak_db,
                "sensitivity_peak_hz": s.sensitivity_peak_hz,
                "gain_margin_db": s.gain_margin_db,
                "phase_margin_deg": s.phase_margin_deg,
                "modulus_margin": s.modulus_margin,
            });
            emit(&v.to_string(), None)
        } else {
            emit(
            &format!(
                "closed loop {} (spectral {} {:.6})\ncrossover {:.3} Hz (|L| = 1), closed-loop bandwidth {:.3} Hz (|T| −3 dB)\n|S| peak {:.2} dB at {:.3} Hz (modulus margin {:.4})\ngain margin {:.2} dB, phase margin {:.2} deg",
                if s.stable { "stable" } else { "UNSTABLE" },
                if p.time().is_continuous() { "abscissa" } else { "radius" },
                s.closed_loop_radius,
                s.crossover_hz,
                s.bandwidth_hz,
                s.sensitivity_peak_db,
                s.sensitivity_peak_hz,
                s.modulus_margin,
                s.gain_margin_db,
                s.phase_margin_deg
            ),
            None,
        )
        }
    }
}
