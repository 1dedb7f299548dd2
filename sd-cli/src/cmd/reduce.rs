//! `sdctl reduce`.

use crate::commands::model_json;
use crate::io::{emit, from_model, read_model, CliError};

/// Arguments of `sdctl reduce`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[arg(help = crate::commands::MODEL_HELP)]
    pub(crate) model: String,
    /// Number of states to keep.
    #[arg(long)]
    pub(crate) order: usize,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            model,
            order,
            output,
        } = self;
        let sys = read_model(&model)?;
        let r = sys
            .balanced_truncation(order)
            .map_err(|e| from_model(&model, e))?;
        emit(&model_json(&r.model)?, output.as_deref())?;
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
}
