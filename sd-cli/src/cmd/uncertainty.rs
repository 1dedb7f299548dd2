//! `sdctl uncertainty` and `sdctl coverage`.

use crate::io::{emit, from_model, read_model, read_text, CliError};

/// Form of the bound.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub(crate) enum FormArg {
    Additive,
    Multiplicative,
}

/// Arguments of `sdctl uncertainty`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[arg(help = crate::commands::MODEL_HELP)]
    pub(crate) model: String,
    /// Measured FRD JSON with variances (`var`), at the model's sample time.
    pub(crate) frd: String,
    /// Probability per line that the bound holds (with --simultaneous: on all lines at once).
    #[arg(long, default_value_t = 0.95, allow_negative_numbers = true)]
    pub(crate) confidence: f64,
    /// The confidence holds for all lines at once (per line 1 − (1 − c)/K, Bonferroni): a
    /// bound the true error stays under everywhere, not only on a share c of the lines.
    #[arg(long)]
    pub(crate) simultaneous: bool,
    /// Additive (plant units) or multiplicative (relative) bound.
    #[arg(long, value_enum, default_value = "additive")]
    pub(crate) form: FormArg,
    /// Also fit an overbounding weight W(z) of this order (|W| ≥ bound on every line).
    #[arg(long)]
    pub(crate) weight_order: Option<usize>,
    /// Also write the model JSON with the bound (and weight) carried in it under
    /// "uncertainty" to this file: `downsample` takes it along, `analyze` and `coverage` read it.
    #[arg(long)]
    pub(crate) embed: Option<String>,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

/// Maps an `sd-uncertainty` error: bad input exits 2, numerical failures 1.
pub(crate) fn from_unc(context: &str, e: sd_uncertainty::UncertaintyError) -> CliError {
    match e {
        sd_uncertainty::UncertaintyError::Model(m) => from_model(context, m),
        sd_uncertainty::UncertaintyError::Input(_) => CliError::input(format!("{context}: {e}")),
        other => CliError::numerical(format!("{context}: {other}")),
    }
}

/// Reads an uncertainty JSON file.
pub(crate) fn read_bound(path: &str) -> Result<sd_uncertainty::Bound, CliError> {
    sd_uncertainty::from_json_str(&read_text(path)?).map_err(|e| from_unc(path, e))
}

/// The bound of the uncertainty file `path` and its overbounding weight: the file's, else one
/// fitted of `weight_order` when given, else none.
pub(crate) fn read_bound_and_weight(
    path: &str,
    weight_order: Option<usize>,
) -> Result<(sd_uncertainty::Bound, Option<sd_model::StateSpace>), CliError> {
    let bound = read_bound(path)?;
    let mut weight =
        sd_uncertainty::weight_from_json_str(&read_text(path)?).map_err(|e| from_unc(path, e))?;
    if weight.is_none() {
        if let Some(n) = weight_order {
            weight = Some(
                sd_uncertainty::overbound(&bound, n)
                    .map_err(|e| from_unc("--weight-order", e))?
                    .model,
            );
        }
    }
    Ok((bound, weight))
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let model = read_model(&self.model)?;
        let frd = sd_model::frd_from_json_str(&read_text(&self.frd)?)
            .map_err(|e| from_model(&self.frd, e))?;
        let form = match self.form {
            FormArg::Additive => sd_uncertainty::Form::Additive,
            FormArg::Multiplicative => sd_uncertainty::Form::Multiplicative,
        };
        let per_line = if self.simultaneous {
            sd_uncertainty::per_line_confidence(self.confidence, frd.len())
                .map_err(|e| from_unc("--confidence", e))?
        } else {
            self.confidence
        };
        let b = sd_uncertainty::from_data(&model, &frd, form, per_line)
            .map_err(|e| from_unc(&self.frd, e))?;
        let w = self
            .weight_order
            .map(|n| sd_uncertainty::overbound(&b, n))
            .transpose()
            .map_err(|e| from_unc("--weight-order", e))?;
        let v = b.values();
        eprintln!(
            "[uncertainty] {} lines, {} bound at {} % per line{}: median {:.3e}, largest {:.3e} \
             at {:.2} Hz{}",
            v.len(),
            match form {
                sd_uncertainty::Form::Additive => "additive",
                sd_uncertainty::Form::Multiplicative => "multiplicative",
            },
            (1e6 * 100.0 * per_line).round() / 1e6,
            if self.simultaneous {
                format!(" ({} % on all lines at once)", 100.0 * self.confidence)
            } else {
                String::new()
            },
            sd_model::median(&v),
            v.iter().cloned().fold(0.0, f64::max),
            b.freq_hz[v
                .iter()
                .enumerate()
                .fold(0, |k, (i, x)| if *x > v[k] { i } else { k })],
            match &w {
                Some(w) => format!(
                    "; weight of order {}: |W|/bound median {:.2}, largest {:.1}",
                    w.model.n(),
                    w.median_ratio,
                    w.max_ratio
                ),
                None => String::new(),
            }
        );
        if let Some(out) = &self.embed {
            let carried = sd_uncertainty::embed(&read_text(&self.model)?, &b, w.as_ref())
                .map_err(|e| from_unc("--embed", e))?;
            emit(&carried, Some(out))?;
        }
        let text =
            sd_uncertainty::to_json_string(&b, w.as_ref()).map_err(|e| from_unc("output", e))?;
        emit(&text, self.output.as_deref())
    }
}

/// Arguments of `sdctl coverage`.
#[derive(clap::Args, Debug)]
pub(crate) struct CoverageArgs {
    /// Uncertainty JSON (from `sdctl uncertainty` or `sdctl downsample --uncertainty`).
    pub(crate) bound: String,
    /// Measured FRD JSON to check (its variance, if any, widens the bound by its own noise).
    pub(crate) frd: String,
    #[arg(long, help = crate::commands::JSON_HELP)]
    pub(crate) json: bool,
}

impl CoverageArgs {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let b = read_bound(&self.bound)?;
        let frd = sd_model::frd_from_json_str(&read_text(&self.frd)?)
            .map_err(|e| from_model(&self.frd, e))?;
        let c = sd_uncertainty::coverage(&b, &frd).map_err(|e| from_unc(&self.frd, e))?;
        if self.json {
            let s = serde_json::to_string(&c).map_err(|e| CliError::numerical(e.to_string()))?;
            println!("{s}");
        } else {
            println!(
                "{} of {} lines inside nominal ± bound: {:.1} % (the bound's confidence: {:.1} % per line)",
                c.covered,
                c.lines,
                100.0 * c.fraction,
                100.0 * b.confidence
            );
            // below the confidence by more than three binomial standard deviations: the
            // model's error here is not what the data the bound came from show
            let n = c.lines.max(1) as f64;
            let sd = (b.confidence * (1.0 - b.confidence) / n).sqrt();
            if c.fraction < b.confidence - 3.0 * sd {
                println!(
                    "the measurement lies outside the bound more often than its confidence allows: \
                     the model misses something the bound's data do not show (at a slower rate, a \
                     rate-tied effect): run `sdctl diagnose` on both experiments, then take the \
                     bound down through the named cause (`sdctl downsample … --hold-delay/--averaging \
                     --uncertainty …`)"
                );
            }
        }
        Ok(())
    }
}
