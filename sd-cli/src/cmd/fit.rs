//! `sdctl fit`.

use crate::commands::model_json;
use crate::io::{emit, from_ident, from_model, CliError};

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub(crate) enum WeightingArg {
    Variance,
    Relative,
    Uniform,
}

/// Arguments of `sdctl fit`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// FRD JSON (discrete).
    pub(crate) frd: String,
    /// Model order: the number of poles, rigid-body poles included.
    #[arg(long)]
    pub(crate) order: usize,
    /// Poles fixed at z = 1 (0, 1 or 2).
    #[arg(long, default_value_t = 0)]
    pub(crate) rigid_body: usize,
    /// No feedthrough term.
    #[arg(long)]
    pub(crate) strictly_proper: bool,
    /// Line weights: variance (1/σ from the FRD's var, relative when it has none; default), relative (1/|G|) or uniform.
    #[arg(long, value_enum, default_value = "variance")]
    pub(crate) weighting: WeightingArg,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            frd,
            order,
            rigid_body,
            strictly_proper,
            weighting,
            output,
        } = self;
        let text = crate::io::read_text(&frd)?;
        let data = sd_model::frd_from_json_str(&text).map_err(|e| from_model(&frd, e))?;
        let opt = sd_ident::FitOptions {
            order,
            rigid_body,
            feedthrough: !strictly_proper,
            weighting: match weighting {
                WeightingArg::Variance => sd_ident::Weighting::Variance,
                WeightingArg::Relative => sd_ident::Weighting::Relative,
                WeightingArg::Uniform => sd_ident::Weighting::Uniform,
            },
            ..Default::default()
        };
        let r = sd_ident::fit_with_progress(&data, &opt, &mut |p| {
            eprintln!(
                "[fit] {} iteration {:>3}: cost {:.6e}",
                p.stage, p.iteration, p.cost
            );
        })
        .map_err(|e| from_ident(&frd, e))?;
        eprintln!(
            "[fit] order {}: cost {:.6e}, median relative error {:.3} %",
            r.model.n(),
            r.cost,
            100.0 * r.median_rel_error
        );
        emit(&model_json(&r.model)?, output.as_deref())
    }
}
