//! `sdctl alias`.

use crate::commands::factor_arg;
use crate::io::{emit, from_model, from_multirate, CliError};
use serde_json::json;

/// Arguments of `sdctl alias`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Continuous frequency (Hz) of the component that is sampled.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) freq_hz: f64,
    /// Sample rate (Hz).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) rate_hz: f64,
    /// Highest folding frequency listed (Hz; default 5 × the rate).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) max_hz: Option<f64>,
    /// Also list the frequencies of a model F times faster that fold onto the alias, with
    /// the slow hold's weights |H_F|/F (Lemma 6).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) factor: Option<i64>,
    #[arg(help = crate::commands::JSON_HELP, long)]
    pub(crate) json: bool,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            freq_hz,
            rate_hz,
            max_hz,
            factor,
            json,
        } = self;
        let a = sd_model::alias(freq_hz, rate_hz).map_err(|e| from_model("alias", e))?;
        let max_hz = max_hz.unwrap_or(5.0 * rate_hz);
        let folds = sd_model::folding_frequencies(a.alias_hz, rate_hz, max_hz)
            .map_err(|e| from_model("alias", e))?;
        let fast = match factor {
            Some(f) => {
                let f = factor_arg(f)?;
                Some(
                    sd_multirate::fold_map(a.alias_hz, rate_hz, f)
                        .map_err(|e| from_multirate("alias", e))?,
                )
            }
            None => None,
        };
        if json {
            let mut v = json!({
                "freq_hz": a.freq_hz, "rate_hz": a.rate_hz, "alias_hz": a.alias_hz,
                "fold_index": a.fold_index, "mirrored": a.mirrored,
                "nyquist_hz": rate_hz / 2.0,
                "folding_frequencies_hz": folds, "folding_max_hz": max_hz,
            });
            if let (Some(terms), Some(f)) = (&fast, factor) {
                v["factor"] = json!(f);
                v["fast_rate_hz"] = json!(rate_hz * f as f64);
                v["fast_folds"] = terms
                    .iter()
                    .map(|t| json!({"k": t.k, "fast_hz": t.fast_hz, "weight": t.weight}))
                    .collect();
            }
            emit(&v.to_string(), None)
        } else {
            let list: Vec<String> = folds.iter().map(|f| format!("{f}")).collect();
            let mut text = format!(
            "{} Hz sampled at {} Hz appears at {} Hz (fold index {}{}).\nContinuous frequencies up to {} Hz that appear there: {}",
            a.freq_hz, a.rate_hz, a.alias_hz, a.fold_index, if a.mirrored { ", mirrored" } else { "" }, max_hz, list.join(", ")
        );
            if let (Some(terms), Some(f)) = (&fast, factor) {
                let l: Vec<String> = terms
                    .iter()
                    .map(|t| format!("{} Hz (weight {:.4})", t.fast_hz, t.weight))
                    .collect();
                text.push_str(&format!(
                    "\nAt {} Hz (F = {f}) through the slow hold, weights |H_F|/F: {}",
                    rate_hz * f as f64,
                    l.join(", ")
                ));
            }
            emit(&text, None)
        }
    }
}
