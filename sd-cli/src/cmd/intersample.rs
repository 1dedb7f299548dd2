//! `sdctl intersample`.

use crate::cmd::uncertainty::{from_unc, read_bound_and_weight};
use crate::io::{emit, from_analysis, read_model, CliError};
use serde_json::json;

/// Arguments of `sdctl intersample`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Fast discrete plant (period h).
    #[arg(long)]
    pub(crate) plant_fast: String,
    /// Slow discrete controller (period F·h, F an integer).
    #[arg(long)]
    pub(crate) controller: String,
    /// Force disturbance rms per fast sample (white).
    #[arg(long, default_value_t = 0.05, allow_negative_numbers = true)]
    pub(crate) force_rms: f64,
    /// Sensor disturbance rms per fast sample (white).
    #[arg(long, default_value_t = 3e-10, allow_negative_numbers = true)]
    pub(crate) sensor_rms: f64,
    /// Frequency points per band.
    #[arg(long, default_value_t = 2000)]
    pub(crate) points: usize,
    /// Uncertainty JSON of the fast plant (from `sdctl uncertainty` on the fast FRF, at the
    /// plant's period): the fast error bounded over every plant inside its overbounding
    /// weight, with the slow loop's robust stability margin against it.
    #[arg(long)]
    pub(crate) uncertainty: Option<String>,
    /// Fit an overbounding weight of this order when the uncertainty file has none.
    #[arg(long)]
    pub(crate) weight_order: Option<usize>,
    #[arg(help = crate::commands::JSON_HELP, long)]
    pub(crate) json: bool,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            plant_fast,
            controller,
            force_rms,
            sensor_rms,
            points,
            uncertainty,
            weight_order,
            json,
        } = self;
        if uncertainty.is_none() && weight_order.is_some() {
            return Err(CliError::input("--weight-order needs --uncertainty"));
        }
        let p = read_model(&plant_fast)?;
        let k = read_model(&controller)?;
        let (h, t) = match (p.ts(), k.ts()) {
            (Some(h), Some(t)) => (h, t),
            _ => {
                return Err(CliError::input(
                    "intersample needs discrete plant and controller models",
                ))
            }
        };
        let ratio = t / h;
        if !(ratio.is_finite() && ratio >= 1.0 && (ratio - ratio.round()).abs() <= 1e-9 * ratio) {
            return Err(CliError::input(format!(
                "the controller period {t} s must be an integer multiple of the plant period {h} s"
            )));
        }
        for (v, what) in [(force_rms, "--force-rms"), (sensor_rms, "--sensor-rms")] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CliError::input(format!(
                    "{what} {v} must be finite and >= 0"
                )));
            }
        }
        let factor = ratio.round() as usize;
        let (pd, pn) = (
            2.0 * h * force_rms * force_rms,
            2.0 * h * sensor_rms * sensor_rms,
        );
        let r = sd_analysis::intersample(&p, &k, factor, &|_| pd, &|_| pn, points)
            .map_err(|e| from_analysis("intersample", e))?;
        let robust = uncertainty
            .as_deref()
            .map(|path| robust(&p, &k, factor, (path, weight_order), (pd, pn), points))
            .transpose()?;
        let argmax = |f: &[f64], v: &[f64]| {
            (0..v.len())
                .max_by(|&a, &b| v[a].total_cmp(&v[b]))
                .map(|i| f[i])
                .unwrap_or(f64::NAN)
        };
        let (df, ds, dk) = (
            argmax(&r.fast_hz, &r.fast_psd),
            argmax(&r.slow_hz, &r.slow_psd),
            argmax(&r.slow_hz, &r.control_sensitivity),
        );
        let (robust, lines) = match robust {
            Some((r, l)) => (Some(r), l),
            None => (None, None),
        };
        if json {
            let v = json!({
                "factor": factor,
                "rms_fast": r.rms_fast, "rms_slow": r.rms_slow,
                "dominant_hz_fast": df, "dominant_hz_slow": ds,
                "control_sensitivity_peak_hz": dk,
                "fast_hz": r.fast_hz, "fast_psd": r.fast_psd,
                "slow_hz": r.slow_hz, "slow_psd": r.slow_psd,
                "control_sensitivity": r.control_sensitivity,
                "robust": robust,
                "robust_lines": lines,
            });
            emit(&v.to_string(), None)
        } else {
            let mut text = format!(
                "predicted error rms: fast rate {:.4e}, at the samples {:.4e}\ndominant frequency: fast {:.2} Hz, slow {:.2} Hz\n|K S| peaks at {:.2} Hz",
                r.rms_fast, r.rms_slow, df, ds, dk
            );
            if let Some(rb) = &robust {
                text.push('\n');
                text.push_str(&robust_text(rb, lines.as_ref()));
            }
            emit(&text, None)
        }
    }
}

/// The fast error bounded over the uncertainty file `path` (its weight, or one fitted of the
/// given order), with white densities `(pd, pn)`.
fn robust(
    p: &sd_model::StateSpace,
    k: &sd_model::StateSpace,
    factor: usize,
    (path, weight_order): (&str, Option<usize>),
    (pd, pn): (f64, f64),
    points: usize,
) -> Result<
    (
        sd_uncertainty::RobustIntersample,
        Option<sd_uncertainty::LinesMargin>,
    ),
    CliError,
> {
    let (bound, weight) = read_bound_and_weight(path, weight_order)?;
    let weight = weight.ok_or_else(|| {
        CliError::input(format!(
            "{path} carries no overbounding weight, which the intersample bound needs between \
             the lines: give --weight-order N (4 to 8 is typical)"
        ))
    })?;
    // the margin on the bound's own lines beside the weight's: why the two verdicts can
    // differ (none when no slow line has all its folds on the fast lines)
    let lines = sd_uncertainty::slow_margin_on_lines(p, k, factor, &bound, &weight).ok();
    let r = sd_uncertainty::robust_intersample(
        p,
        k,
        factor,
        (&weight, bound.form),
        &|_| pd,
        &|_| pn,
        points,
    )
    .map_err(|e| from_unc(path, e))?;
    Ok((r, lines))
}

/// The robust lines of the text output: the margin with the weight, and beside it the margin
/// on the bound's own lines with the weight's conservatism there (why `analyze --uncertainty`
/// on the downsampled bound can say "robustly stable" where the weight does not).
fn robust_text(
    r: &sd_uncertainty::RobustIntersample,
    lines: Option<&sd_uncertainty::LinesMargin>,
) -> String {
    let mut head = format!(
        "uncertainty ({}): slow-loop robust stability margin {:.3} with the weight, between the \
         lines too (> 1: every plant inside the weight is stabilised)",
        match r.form {
            sd_uncertainty::Form::Additive => "additive",
            sd_uncertainty::Form::Multiplicative => "multiplicative",
        },
        r.slow_margin
    );
    if let Some(l) = lines {
        head += &format!(
            "
on the bound's {} slow lines (as `sdctl analyze --uncertainty` on the downsampled \
             bound): margin {:.3} (worst at {:.2} Hz); the weight's downsampled bound is up to \
             {:.2}× the lines' (at {:.2} Hz){}",
            l.lines,
            l.margin,
            l.worst_hz,
            l.weight_over_bound,
            l.weight_over_bound_hz,
            if l.margin > 1.0 && r.slow_margin <= 1.0 {
                ": the lines are robustly stable, the weight's conservatism between or at the \
                 lines is what fails — refit it tighter (a higher --weight-order) before \
                 changing the controller"
            } else {
                ""
            }
        );
    }
    match (r.rms_bound, r.worst_hz, r.worst_ratio) {
        (Some(b), Some(f), Some(x)) => format!(
            "{head}\nfast error rms over every plant inside the weight: at most {b:.4e} (nominal \
             {:.4e}); the bound is furthest above the nominal density at {f:.2} Hz ({:.1} dB)",
            r.rms_nominal,
            10.0 * x.log10()
        ),
        _ => format!(
            "{head}\nno intersample bound: a plant inside the weight may destabilise the loop \
             (see `sdctl analyze --uncertainty` on the downsampled bound for one)"
        ),
    }
}
