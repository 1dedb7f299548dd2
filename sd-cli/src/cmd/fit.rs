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
    /// Lowest damping ratio a fitted pole pair may take (0 = none): pairs below it are moved
    /// onto it at the same natural frequency during the fit.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub(crate) min_damping: f64,
    /// A MIMO FRD's residue ranks (one set of poles for every entry): `select` (the rank the
    /// data support, a χ² test at 1 % per pole; default), `full`, or a number (every pole).
    #[arg(long, default_value = "select", value_parser = |s: &str| s.parse::<sd_ident::ResidueRank>())]
    pub(crate) rank: sd_ident::ResidueRank,
    /// Write a JSON object instead of the model: `model` (model JSON), `cost`,
    /// `median_rel_error`, and for a SISO FRD `lines` (each line's `freq_hz` and `cost` term)
    /// and `warnings`; for a MIMO FRD `full_rank_cost`, `entry_cost` (ny × nu), `states` and
    /// `modes` (per free pole `freq_hz`, `damping`, `singular_values`, `rank`,
    /// `output_direction`, `input_direction`).
    #[arg(long)]
    pub(crate) json: bool,
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
            min_damping,
            rank,
            json,
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
            min_damping,
            ..Default::default()
        };
        if data.shape() != (1, 1) {
            return run_mimo(&frd, &data, opt, rank, json, output.as_deref());
        }
        let r = sd_ident::fit_with_progress(&data, &opt, &mut |p| {
            eprintln!(
                "[fit] {} iteration {:>3}: cost {:.6e}",
                p.stage, p.iteration, p.cost
            );
        })
        .map_err(|e| from_ident(&frd, e))?;
        eprintln!(
            "[fit] order {}: cost {:.6e}, median relative error {:.3} %; largest line terms: {}",
            r.model.n(),
            r.cost,
            100.0 * r.median_rel_error,
            largest_terms(data.freq_hz(), &r.line_cost, r.cost)
        );
        for w in &r.warnings {
            eprintln!("sdctl: warning: {frd}: {w}");
        }
        if !json {
            return emit(&model_json(&r.model)?, output.as_deref());
        }
        let bad = |e: serde_json::Error| CliError::numerical(format!("fit JSON: {e}"));
        let model: serde_json::Value = serde_json::from_str(&model_json(&r.model)?).map_err(bad)?;
        let lines: Vec<serde_json::Value> = data
            .freq_hz()
            .iter()
            .zip(&r.line_cost)
            .map(|(f, c)| serde_json::json!({"freq_hz": f, "cost": c}))
            .collect();
        let out = serde_json::json!({
            "model": model,
            "cost": r.cost,
            "median_rel_error": r.median_rel_error,
            "lines": lines,
            "warnings": crate::io::warnings_json(&r.warnings),
        });
        emit(
            &serde_json::to_string_pretty(&out).map_err(bad)?,
            output.as_deref(),
        )
    }
}

/// A MIMO FRD: one set of poles for every entry ([`sd_ident::fit_common_poles`]).
fn run_mimo(
    name: &str,
    data: &sd_model::Frd,
    fit: sd_ident::FitOptions,
    rank: sd_ident::ResidueRank,
    json: bool,
    output: Option<&str>,
) -> Result<(), CliError> {
    let opt = sd_ident::MimoFitOptions {
        fit,
        rank,
        ..Default::default()
    };
    let r = sd_ident::fit_common_poles_with_progress(data, &opt, &mut |p| {
        eprintln!(
            "[fit] {} iteration {:>3}: cost {:.6e}",
            p.stage, p.iteration, p.cost
        );
    })
    .map_err(|e| from_ident(name, e))?;
    let (ny, nu) = data.shape();
    eprintln!(
        "[fit] {ny}x{nu}, order {} (poles common to every entry): cost {:.6e} (free residues {:.6e}), {} states, \
         residue ranks {:?}, median relative error {:.3} %",
        opt.fit.order,
        r.cost,
        r.full_rank_cost,
        r.model.n(),
        r.modes.iter().map(|m| m.rank).collect::<Vec<_>>(),
        100.0 * r.median_rel_error
    );
    if !json {
        return emit(&model_json(&r.model)?, output);
    }
    let bad = |e: serde_json::Error| CliError::numerical(format!("fit JSON: {e}"));
    let model: serde_json::Value = serde_json::from_str(&model_json(&r.model)?).map_err(bad)?;
    let entry_cost: Vec<Vec<f64>> = (0..ny)
        .map(|a| (0..nu).map(|b| r.entry_cost[(a, b)]).collect())
        .collect();
    let out = serde_json::json!({
        "model": model,
        "cost": r.cost,
        "full_rank_cost": r.full_rank_cost,
        "entry_cost": entry_cost,
        "median_rel_error": r.median_rel_error,
        "states": r.model.n(),
        "modes": r.modes,
    });
    emit(&serde_json::to_string_pretty(&out).map_err(bad)?, output)
}

/// The three lines with the largest cost terms, as "f Hz (share %)".
fn largest_terms(freq_hz: &[f64], line_cost: &[f64], total: f64) -> String {
    let mut idx: Vec<usize> = (0..line_cost.len()).collect();
    idx.sort_by(|a, b| line_cost[*b].total_cmp(&line_cost[*a]));
    idx.iter()
        .take(3)
        .map(|&i| {
            format!(
                "{:.2} Hz ({:.1} %)",
                freq_hz[i],
                100.0 * line_cost[i] / total.max(f64::MIN_POSITIVE)
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}
