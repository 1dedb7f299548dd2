//! `sdctl fit`.

use crate::commands::model_json;
use crate::io::{emit, from_ident, from_model, CliError};

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub(crate) enum WeightingArg {
    Variance,
    Relative,
    Uniform,
}

/// `--order`: a number of poles, or `auto`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum OrderArg {
    /// Chosen by the held-out lines ([`sd_ident::physical_fit`]).
    Auto,
    /// This many poles.
    Fixed(usize),
}

impl std::str::FromStr for OrderArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s.eq_ignore_ascii_case("auto") {
            return Ok(OrderArg::Auto);
        }
        s.parse::<usize>()
            .map(OrderArg::Fixed)
            .map_err(|_| format!("`{s}` is no model order: give a number of poles or `auto`"))
    }
}

/// Arguments of `sdctl fit`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// FRD JSON (discrete).
    pub(crate) frd: String,
    /// Model order: the number of poles, rigid-body poles included, or `auto` (SISO: the
    /// order and rigid-body count the held-out odd-indexed lines choose up to --max-order, as
    /// --stabilization does, and an input delay up to --max-delay; the model is written as
    /// with a number). Not with --stabilization, which chooses it.
    #[arg(
        long,
        required_unless_present = "stabilization",
        conflicts_with = "stabilization",
        value_parser = |s: &str| s.parse::<OrderArg>()
    )]
    pub(crate) order: Option<OrderArg>,
    /// Poles fixed at z = 1 (0, 1 or 2; default 0, and with --stabilization chosen from the
    /// data unless given).
    #[arg(long)]
    pub(crate) rigid_body: Option<usize>,
    /// The physical modal model of a SISO FRD: a stabilisation diagram over the orders up to
    /// --max-order, no pole pair narrower than the line spacing unless the data demand it,
    /// order and rigid body chosen by the held-out (odd-indexed) lines, an input delay up to
    /// --max-delay samples (a fraction allowed). Writes DIR/model.json (with the delay),
    /// DIR/modes.json (modes with frequency,
    /// damping, residue, share of the response and the orders they are stable over; every
    /// order's costs; the diagram) and DIR/stabilization.svg; the mode table on stderr.
    #[arg(long, requires = "out")]
    pub(crate) stabilization: bool,
    /// Highest order of the stabilisation diagram.
    #[arg(long, default_value_t = 24)]
    pub(crate) max_order: usize,
    /// Largest input delay (samples) the stabilisation fit searches, fractions included (0:
    /// none).
    #[arg(long, default_value_t = 0)]
    pub(crate) max_delay: usize,
    /// Output folder of --stabilization.
    #[arg(long)]
    pub(crate) out: Option<String>,
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
    /// A MIMO FRD's whole-sample input delays, fitted outside the rational part: `none`
    /// (default), `auto` (each input's delay estimated in ±8 samples), `auto:N`, or one number
    /// per input (`-5,0`). Negative: the outputs respond before the input as recorded
    /// (misaligned channels or a non-causally filtered input). The model then maps the
    /// shifted inputs, u_j(t − δ_j).
    #[arg(long, default_value = "none", allow_hyphen_values = true, value_parser = |s: &str| s.parse::<sd_ident::InputDelay>())]
    pub(crate) input_delay: sd_ident::InputDelay,
    /// Write a JSON object instead of the model: `model` (model JSON), `cost`,
    /// `median_rel_error`, and for a SISO FRD `lines` (each line's `freq_hz` and `cost` term)
    /// and `warnings`; for a MIMO FRD `full_rank_cost`, `entry_cost` (ny × nu), `states` and
    /// `modes` (per free pole `freq_hz`, `damping`, `singular_values`, `rank`,
    /// `output_direction`, `input_direction`), `input_delay` (samples per input) and
    /// `delay_scans` (per estimated input: `input`, `delay`, `cost` as [δ, V] pairs,
    /// `threshold`).
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
            input_delay,
            json,
            output,
            stabilization,
            max_order,
            max_delay,
            out,
        } = self;
        let text = crate::io::read_text(&frd)?;
        let data = sd_model::frd_from_json_str(&text).map_err(|e| from_model(&frd, e))?;
        // the physical fit's options (--stabilization, --order auto)
        let physical = sd_ident::StabilizationOptions {
            max_order,
            rigid_body,
            feedthrough: !strictly_proper,
            max_delay,
        };
        if stabilization {
            let out = out.unwrap_or_default();
            return crate::cmd::fit_stabilization::run(&frd, &data, &physical, &out);
        }
        if order == Some(OrderArg::Auto) {
            let fixed_only = !matches!(weighting, WeightingArg::Variance)
                || min_damping != 0.0
                || input_delay != sd_ident::InputDelay::None;
            return run_auto(&frd, &data, &physical, fixed_only, json, output.as_deref());
        }
        let order = match order {
            Some(OrderArg::Fixed(n)) => n,
            _ => 0,
        };
        let opt = sd_ident::FitOptions {
            order,
            rigid_body: rigid_body.unwrap_or(0),
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
            let opt = sd_ident::MimoFitOptions {
                fit: opt,
                rank,
                input_delay,
                ..Default::default()
            };
            return run_mimo(&frd, &data, &opt, json, output.as_deref());
        }
        if input_delay != sd_ident::InputDelay::None {
            return Err(CliError::input(format!(
                "{frd}: --input-delay applies to a MIMO FRD; a SISO fit absorbs a delay with \
                 its poles (drop the option or fit the MIMO FRD)"
            )));
        }
        let noise_scaled = matches!(weighting, WeightingArg::Variance) && data.variance().is_some();
        run_siso(&frd, &data, &opt, noise_scaled, json, output.as_deref())
    }
}

/// A SISO FRD at a fixed order: the fit with progress on stderr, its summary (cost per line,
/// `noise_scaled`: 1 = the noise level), the model or with `json` the fit's JSON.
fn run_siso(
    frd: &str,
    data: &sd_model::Frd,
    opt: &sd_ident::FitOptions,
    noise_scaled: bool,
    json: bool,
    output: Option<&str>,
) -> Result<(), CliError> {
    // an order beyond what the lines determine (600 typed for 60) is refused at once
    sd_ident::check_order_determined(data.len(), opt).map_err(|e| from_ident(frd, e))?;
    let r = sd_ident::fit_with_progress(data, opt, &mut |p| {
        eprintln!(
            "[fit] {} iteration {:>3}: cost {:.6e}",
            p.stage, p.iteration, p.cost
        );
    })
    .map_err(|e| from_ident(frd, e))?;
    // with variance weights a line's expected term is 1 when the model is right
    eprintln!(
        "[fit] order {}: cost {:.6e} ({:.3} per line{}), median relative error {:.3} %; \
             largest line terms: {}",
        r.model.n(),
        r.cost,
        r.cost / data.len().max(1) as f64,
        if noise_scaled {
            ", 1 = the noise level"
        } else {
            ""
        },
        100.0 * r.median_rel_error,
        largest_terms(data.freq_hz(), &r.line_cost, r.cost)
    );
    for w in &r.warnings {
        eprintln!("sdctl: warning: {frd}: {w}");
    }
    if !json {
        return emit(&model_json(&r.model)?, output);
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
    emit(&serde_json::to_string_pretty(&out).map_err(bad)?, output)
}

/// `--order auto`: the physical fit's choice ([`sd_ident::physical_fit`]), its model (with the
/// input delay found) written as a fixed order's; with `json` also `order`, `rigid_body`,
/// `delay_samples`, `cost_per_line` and `orders` (every order tried).
/// `fixed_only`: an option only a fixed order takes was given (refused, as a MIMO FRD is).
fn run_auto(
    name: &str,
    data: &sd_model::Frd,
    opt: &sd_ident::StabilizationOptions,
    fixed_only: bool,
    json: bool,
    output: Option<&str>,
) -> Result<(), CliError> {
    if data.shape() != (1, 1) || fixed_only {
        return Err(CliError::input(format!(
            "{name}: --order auto chooses the order of a SISO FRD with variance weights and \
             free dampings; give a number of poles for a MIMO FRD, --input-delay, --weighting \
             or --min-damping"
        )));
    }
    let r = sd_ident::physical_fit(data, opt, &mut |s| eprintln!("[fit] {s}"))
        .map_err(|e| from_ident(name, e))?;
    eprint!("{}", crate::cmd::fit_stabilization::mode_table(&r));
    eprintln!(
        "[fit] order auto: {} ({} rigid-body poles, input delay {:.3} samples), {:.3} per line \
         (1 = the noise level), median relative error {:.3} %",
        r.order,
        r.rigid_body,
        r.delay_samples,
        r.cost_per_line,
        100.0 * r.fit.median_rel_error
    );
    for w in &r.fit.warnings {
        eprintln!("sdctl: warning: {name}: {w}");
    }
    let (model, _) = r
        .model_with_delay(data.freq_hz())
        .map_err(|e| from_ident(name, e))?;
    if !json {
        return emit(&model_json(&model)?, output);
    }
    let bad = |e: serde_json::Error| CliError::numerical(format!("fit JSON: {e}"));
    let m: serde_json::Value = serde_json::from_str(&model_json(&model)?).map_err(bad)?;
    let out = serde_json::json!({
        "model": m,
        "order": r.order,
        "rigid_body": r.rigid_body,
        "delay_samples": r.delay_samples,
        "cost": r.fit.cost,
        "cost_per_line": r.cost_per_line,
        "median_rel_error": r.fit.median_rel_error,
        "orders": r.orders,
        "warnings": crate::io::warnings_json(&r.fit.warnings),
    });
    emit(&serde_json::to_string_pretty(&out).map_err(bad)?, output)
}

/// A MIMO FRD: one set of poles for every entry ([`sd_ident::fit_common_poles`]).
fn run_mimo(
    name: &str,
    data: &sd_model::Frd,
    opt: &sd_ident::MimoFitOptions,
    json: bool,
    output: Option<&str>,
) -> Result<(), CliError> {
    let r = sd_ident::fit_common_poles_with_progress(data, opt, &mut |p| {
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
    for (j, &d) in r.input_delay.iter().enumerate().filter(|(_, d)| **d != 0) {
        let what = if d < 0 {
            "the outputs respond before it is recorded: check the channels' alignment, or a \
             non-causal filter on this input"
        } else {
            "a transport or computation delay"
        };
        eprintln!(
            "[fit] input {}: delay {d} samples ({what}); the model maps u{}(t - ({d}))",
            j + 1,
            j + 1
        );
    }
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
        "input_delay": r.input_delay,
        "delay_scans": r.delay_scans,
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
