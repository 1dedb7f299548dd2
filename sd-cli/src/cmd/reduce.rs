//! `sdctl reduce`: balanced truncation of a model, or of a controller keeping its loop.

use crate::commands::model_json;
use crate::io::{emit, from_analysis, from_model, read_model, CliError};
use sd_analysis::{reduce_controller, ReductionMethod};
use serde_json::json;

/// Arguments of `sdctl reduce`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[arg(help = crate::commands::MODEL_HELP, required_unless_present = "controller")]
    pub(crate) model: Option<String>,
    /// Number of states to keep.
    #[arg(long)]
    pub(crate) order: usize,
    /// Reduce this controller (negative feedback u = −K y) keeping its loop with --plant:
    /// balanced truncation weighted by the closed loop, judged by |ΔS|, |ΔT| and the margins.
    #[arg(long, requires = "plant", conflicts_with = "model")]
    pub(crate) controller: Option<String>,
    /// The plant of the controller's loop (with --controller).
    #[arg(long)]
    pub(crate) plant: Option<String>,
    /// With --controller: `auto` (the default: `fit` for a SISO discrete loop, else
    /// `weighted`), `fit` (a rational fit of K's response weighted by the loop's
    /// sensitivities: often far fewer states for the same |ΔS|, |ΔT|), `weighted` (balanced
    /// truncation with the closed-loop weight), `coprime` (balanced truncation of the
    /// loop-scaled controller's normalized coprime factors) or `plain`.
    #[arg(long, default_value = "auto")]
    pub(crate) method: String,
    /// With --controller: print the comparison as JSON (the reduced controller under
    /// "controller") instead of the controller's model JSON with a summary on stderr.
    #[arg(long)]
    pub(crate) json: bool,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        match (&self.controller, &self.plant, &self.model) {
            (Some(k), Some(p), _) => self.controller_run(k, p),
            (None, _, Some(m)) => self.model_run(m),
            _ => Err(CliError::input(
                "give a model, or --controller K.json with --plant P.json",
            )),
        }
    }

    fn model_run(&self, model: &str) -> Result<(), CliError> {
        let sys = read_model(model)?;
        let r = sys
            .balanced_truncation(self.order)
            .map_err(|e| from_model(model, e))?;
        emit(&model_json(&r.model)?, self.output.as_deref())?;
        eprintln!(
            "balanced truncation {} -> {} states ({} unstable/marginal kept); error bound ‖G−Gr‖∞ ≤ {:.6e}",
            sys.n(),
            r.model.n(),
            r.n_unstable,
            r.error_bound
        );
        let hs: Vec<String> = r
            .hankel_sv
            .iter()
            .take(20)
            .map(|v| format!("{v:.4e}"))
            .collect();
        eprintln!("Hankel singular values (stable part): {}", hs.join(" "));
        Ok(())
    }

    fn controller_run(&self, kpath: &str, ppath: &str) -> Result<(), CliError> {
        let method: ReductionMethod = self
            .method
            .parse()
            .map_err(|e: sd_analysis::AnalysisError| CliError::input(format!("--method: {e}")))?;
        let (k, p) = (read_model(kpath)?, read_model(ppath)?);
        let r =
            reduce_controller(&p, &k, self.order, method).map_err(|e| from_analysis(kpath, e))?;
        let kjson = model_json(&r.controller)?;
        if self.json {
            let k: serde_json::Value = serde_json::from_str(&kjson)
                .map_err(|e| CliError::numerical(format!("model JSON: {e}")))?;
            let v = json!({
                "method": r.method, "order_before": r.orders.0, "order_after": r.orders.1,
                "hankel_sv": r.hankel_sv, "band_hz": r.band_hz,
                "max_delta_s_db": r.max_delta_s_db, "max_delta_t_db": r.max_delta_t_db,
                "before": r.before, "after": r.after, "controller": k,
            });
            emit(&v.to_string(), self.output.as_deref())
        } else {
            eprintln!(
                "controller {} -> {} states ({:?}); loop stable; below {:.1} Hz |ΔS| ≤ {:.3} dB, \
                 |ΔT| ≤ {:.3} dB; margins before/after: gain {:.2}/{:.2} dB, phase {:.1}/{:.1}°, \
                 modulus {:.3}/{:.3}",
                r.orders.0,
                r.orders.1,
                r.method,
                r.band_hz,
                r.max_delta_s_db,
                r.max_delta_t_db,
                r.before.gain_margin_db,
                r.after.gain_margin_db,
                r.before.phase_margin_deg,
                r.after.phase_margin_deg,
                r.before.modulus_margin,
                r.after.modulus_margin
            );
            emit(&kjson, self.output.as_deref())
        }
    }
}
