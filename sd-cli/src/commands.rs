//! The `sdctl` command line: the subcommands (one module each in [`crate::cmd`]) and the helpers they share.

use crate::io::{from_model, CliError};
use clap::{Parser, Subcommand};
use sd_model::StateSpace;

/// Help of every `-o/--output` option.
pub(crate) const OUTPUT_HELP: &str = "Output file (written atomically; default: stdout)";
/// Help of every model-file argument that accepts any model.
pub(crate) const MODEL_HELP: &str = "Model JSON file (docs/formats.md; \"-\" reads stdin)";
/// Help of every `--json` switch.
pub(crate) const JSON_HELP: &str = "Print JSON (keys in docs/formats.md) instead of text";

/// Sampled-data control design on files: models (JSON), FRDs (JSON), experiments (TOML + CSV).
#[derive(Parser, Debug)]
#[command(name = "sdctl", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Discretise a continuous model (exact ZOH by default).
    C2d(crate::cmd::c2d::Args),
    /// Lemma 6: a fast discrete model seen through a hold and sampler F times slower.
    Downsample(crate::cmd::downsample::Args),
    /// Continuous model from a discrete one (principal branch); alias candidates on stderr.
    D2c(crate::cmd::d2c::Args),
    /// Where a continuous frequency appears after sampling, and what folds onto it.
    Alias(crate::cmd::alias::Args),
    /// Frequency response on a grid `FMIN:FMAX:N[:log]` (Hz) as FRD JSON.
    Freqresp(crate::cmd::freqresp::Args),
    /// Bode plot (SVG) of models and measured FRDs: dB re 1 unit, unwrapped phase.
    Bode(crate::cmd::bode::Args),
    /// Poles with frequency (Hz) and damping.
    Poles(crate::cmd::roots::Args),
    /// Invariant zeros.
    Zeros(crate::cmd::roots::Args),
    /// H2 and H∞ norms (with the H∞ peak frequency).
    Norm(crate::cmd::norm::Args),
    /// Balanced truncation to N states (unstable/marginal poles kept); summary on stderr.
    Reduce(crate::cmd::reduce::Args),
    /// Interconnect two models: series (A then B), parallel, feedback (negative by default).
    Connect(crate::cmd::connect::Args),
    /// McFarlane–Glover loopshaping: the controller K = W1·Ks·W2 for negative feedback u = −K y.
    Loopshape(crate::cmd::loopshape::Args),
    /// H∞ synthesis on a generalized plant (γ-iteration, central controller u = K y, the
    /// achieved closed-loop norm checked independently).
    Hinfsyn(crate::cmd::hinfsyn::Args),
    /// H2 synthesis on a generalized plant (u = K y; the achieved norm by the closed loop's
    /// Gramian).
    H2syn(crate::cmd::h2syn::Args),
    /// Mixed-sensitivity H∞ design [W1·S; W2·K·S; W3·T] (optionally with an input
    /// disturbance): the controller for negative feedback u = K (r − y).
    Mixsyn(crate::cmd::mixsyn::Args),
    /// Multisine excitations as CSV with their manifest; with --inputs N, orthogonal
    /// multisines (one experiment per input).
    Multisine(crate::cmd::multisine::Args),
    /// FRF of one experiment of a manifest (periodic: averaged over periods; otherwise LPM),
    /// FRD JSON with var; several experiments (or one with several inputs or outputs): the
    /// MIMO FRF.
    Frf(crate::cmd::frf::Args),
    /// Fit a discrete-time model of order N to an FRD; a MIMO FRD gets one set of poles for
    /// every entry (progress on stderr).
    Fit(crate::cmd::fit::Args),
    /// Closed loop of a plant and a controller (negative feedback): stability, bandwidth, |S| peak, margins.
    Analyze(crate::cmd::analyze::Args),
    /// Intersample analysis of a slow controller around a fast plant: predicted error spectra at both rates.
    Intersample(crate::cmd::intersample::Args),
    /// Run the virtual stage: writes DIR/experiments.toml, one CSV per experiment, DIR/truth.json.
    Testbed(crate::cmd::testbed::Args),
    /// What the model's simulation gets wrong on the validation experiments, its cause, the
    /// extended model and its gain on held-out data.
    Diagnose(crate::cmd::diagnose::Args),
    /// What a diagnosis's model and extension predict on new experiments (at each one's rate
    /// and amplitude): DIR/prediction.json, report.md and figures.
    Predict(crate::cmd::predict::Args),
    /// Loopshaping weights as model JSON (continuous unless --ts is given).
    Weight(crate::cmd::weight::Args),
    /// Bound on a model's error from a measured FRF at a stated confidence (uncertainty JSON),
    /// optionally with an overbounding weight W(z).
    Uncertainty(crate::cmd::uncertainty::Args),
    /// Fraction of a measured FRF's lines inside nominal ± an uncertainty bound.
    Coverage(crate::cmd::uncertainty::CoverageArgs),
}

pub(crate) fn finite_pos(v: f64, what: &str) -> Result<f64, CliError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(CliError::input(format!(
            "{what} = {v} must be finite and > 0"
        )))
    }
}

pub(crate) fn model_json(sys: &StateSpace) -> Result<String, CliError> {
    sd_model::model_to_json_string(sys).map_err(|e| from_model("output", e))
}

/// Parses `FMIN:FMAX:N[:log]`.
pub(crate) fn parse_grid(g: &str) -> Result<Vec<f64>, CliError> {
    let parts: Vec<&str> = g.split(':').collect();
    let bad = || {
        CliError::input(format!(
            "--grid {g}: expected FMIN:FMAX:N[:log], e.g. 1:500:1000:log"
        ))
    };
    if parts.len() < 3 || parts.len() > 4 {
        return Err(bad());
    }
    let fmin: f64 = parts[0].trim().parse().map_err(|_| bad())?;
    let fmax: f64 = parts[1].trim().parse().map_err(|_| bad())?;
    let n: usize = parts[2].trim().parse().map_err(|_| bad())?;
    let log = match parts.get(3).map(|s| s.trim()) {
        None | Some("lin") => false,
        Some("log") => true,
        Some(_) => return Err(bad()),
    };
    sd_model::grid(fmin, fmax, n, log).map_err(|e| from_model("--grid", e))
}

pub fn run(cli: Cli) -> Result<(), CliError> {
    match cli.cmd {
        Cmd::C2d(a) => a.run(),
        Cmd::Downsample(a) => a.run(),
        Cmd::D2c(a) => a.run(),
        Cmd::Alias(a) => a.run(),
        Cmd::Freqresp(a) => a.run(),
        Cmd::Bode(a) => a.run(),
        Cmd::Poles(a) => a.run(true),
        Cmd::Zeros(a) => a.run(false),
        Cmd::Norm(a) => a.run(),
        Cmd::Reduce(a) => a.run(),
        Cmd::Connect(a) => a.run(),
        Cmd::Loopshape(a) => a.run(),
        Cmd::Hinfsyn(a) => a.run(),
        Cmd::H2syn(a) => a.run(),
        Cmd::Mixsyn(a) => a.run(),
        Cmd::Frf(a) => a.run(),
        Cmd::Multisine(a) => a.run(),
        Cmd::Fit(a) => a.run(),
        Cmd::Analyze(a) => a.run(),
        Cmd::Intersample(a) => a.run(),
        Cmd::Testbed(a) => a.run(),
        Cmd::Diagnose(a) => a.run(),
        Cmd::Predict(a) => a.run(),
        Cmd::Weight(a) => a.run(),
        Cmd::Uncertainty(a) => a.run(),
        Cmd::Coverage(a) => a.run(),
    }
}

pub(crate) fn factor_arg(f: i64) -> Result<usize, CliError> {
    if f < 1 || f > sd_multirate::tol::MAX_FACTOR as i64 {
        return Err(CliError::input(format!(
            "--factor {f}: the rate factor must be an integer in 1..={}",
            sd_multirate::tol::MAX_FACTOR
        )));
    }
    Ok(f as usize)
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;

    fn missing_help(c: &clap::Command, path: &str, out: &mut Vec<String>) {
        for a in c.get_arguments() {
            let id = a.get_id().as_str();
            if id != "help" && id != "version" && a.get_help().is_none() {
                out.push(format!("{path} {id}"));
            }
        }
        for s in c.get_subcommands() {
            missing_help(s, &format!("{path} {}", s.get_name()), out);
        }
    }

    /// Every option and argument of every command says what it is in `--help`.
    #[test]
    fn every_option_has_a_help_text() {
        let mut missing = Vec::new();
        missing_help(&Cli::command(), "sdctl", &mut missing);
        assert!(missing.is_empty(), "options without help: {missing:?}");
    }
}
