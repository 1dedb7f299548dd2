//! `sdctl connect`.

use crate::commands::model_json;
use crate::io::{emit, from_model, read_model, CliError};

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub(crate) enum Conn {
    Series,
    Parallel,
    Feedback,
    /// Block diagonal: A's inputs and outputs first, then B's (diagonal weights of a MIMO
    /// loop).
    Append,
}

/// Arguments of `sdctl connect`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// series (A then B), parallel (A + B), feedback (A with B in negative feedback) or append
    /// (block diagonal diag(A, B)).
    #[arg(value_enum)]
    pub(crate) kind: Conn,
    /// First model JSON file (A).
    pub(crate) a: String,
    /// Second model JSON file (B).
    pub(crate) b: String,
    /// Feedback sign: -1 (negative, default) or +1.
    #[arg(long, default_value_t = -1.0, allow_negative_numbers = true)]
    pub(crate) sign: f64,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            kind,
            a,
            b,
            sign,
            output,
        } = self;
        let ga = read_model(&a)?;
        let gb = read_model(&b)?;
        let r = match kind {
            Conn::Series => sd_model::series(&ga, &gb),
            Conn::Parallel => sd_model::parallel(&ga, &gb),
            Conn::Feedback => sd_model::feedback(&ga, &gb, sign),
            Conn::Append => sd_model::append(&ga, &gb),
        }
        .map_err(|e| from_model("connect", e))?;
        emit(&model_json(&r)?, output.as_deref())
    }
}
