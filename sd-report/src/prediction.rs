//! `sdctl predict`'s report: `prediction.json`, `report.md` and one figure per predicted
//! experiment (`frf_<name>.svg`: the measured FRF against the plain model's and the extended
//! model's predictions, with the noise level σ; magnitude and phase).

use crate::diagnosis::{db, deg, magnitude_figure, slug, MEASURED, MODEL};
use crate::plot::Curve;
use crate::{ReportError, Result};
use sd_diagnose::{PredictedExperiment, Prediction};
use std::fmt::Write as _;
use std::path::Path;

/// Writes `prediction.json`, `report.md` and the figures of a prediction into `dir` (which
/// must exist); `source` names the diagnosis folder in the report. Returns the figure names.
///
/// # Errors
/// A figure or a file cannot be written.
pub fn write_prediction(dir: &Path, p: &Prediction, source: &str) -> Result<Vec<String>> {
    let js = serde_json::to_string_pretty(p).map_err(|e| ReportError::Json(e.to_string()))?;
    crate::write_atomic(&dir.join("prediction.json"), &js)?;
    let mut figs = Vec::new();
    for x in &p.experiments {
        if let Some(f) = figure(dir, x)? {
            figs.push(f);
        }
    }
    crate::write_atomic(&dir.join("report.md"), &markdown(p, source, &figs))?;
    Ok(figs)
}

/// The figure of one experiment (`None` without lines).
fn figure(dir: &Path, x: &PredictedExperiment) -> Result<Option<String>> {
    let c = &x.curves;
    let (Some(&fmin), Some(&fmax)) = (c.freq_hz.first(), c.freq_hz.last()) else {
        return Ok(None);
    };
    let meas = db(&c.measured);
    let plain = db(&c.model);
    let ext = c.extended.as_deref().map(db);
    let sigma: Vec<f64> = c.noise_var.iter().map(|v| 10.0 * v.log10()).collect();
    let (ph_meas, ph_plain) = (deg(&c.measured), deg(&c.model));
    let ph_ext = c.extended.as_deref().map(deg);
    let plain_label = match x.factor {
        Some(k) if k > 1 => format!("plain model, Lemma 6 to 1/{k}"),
        _ => "plain model".to_string(),
    };
    let name = format!("frf_{}.svg", slug(&x.name));
    let title = format!(
        "{} ({} Hz): measured FRF and the diagnosis's predictions",
        x.name, x.rate_hz
    );
    let curves = vec![
        Curve {
            label: "measured",
            freq_hz: &c.freq_hz,
            db: &meas,
            color: MEASURED,
        },
        Curve {
            label: &plain_label,
            freq_hz: &c.freq_hz,
            db: &plain,
            color: MODEL,
        },
    ];
    let f = magnitude_figure(
        dir,
        name,
        &title,
        curves,
        ext.as_deref().map(|e| ("extended model", e)),
        (&c.freq_hz, &sigma),
        (fmin, fmax),
        &[],
        vec![Some(&ph_meas), Some(&ph_plain), ph_ext.as_deref()],
    )?;
    Ok(Some(f))
}

fn num(v: Option<f64>) -> String {
    match v {
        Some(v) if v >= 1e4 => format!("{v:.3e}"),
        Some(v) => format!("{v:.3}"),
        None => "—".into(),
    }
}

/// `report.md`.
fn markdown(p: &Prediction, source: &str, figs: &[String]) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Prediction of new experiments\n");
    let _ = writeln!(
        md,
        "The diagnosis in `{source}` (extension `{}`, model at {} Hz) predicts {} of {} \
         experiments it has never seen. Statistic: the mean of |G_meas − G_pred|²/σ² over \
         each experiment's lines, σ² its measured total variance (noise, and the nonlinear \
         distortion where the excitation measures it); 1 is the noise level, `threshold` the \
         value a consistent prediction stays below with probability {:.0} %.\n",
        p.extension,
        p.model_rate_hz,
        p.predicted(),
        p.experiments.len(),
        100.0 * (1.0 - p.alpha)
    );
    let _ = writeln!(
        md,
        "| experiment | rate (Hz) | factor | lines | plain | extended | plain/extended | \
         threshold | note |\n|---|---|---|---|---|---|---|---|---|"
    );
    for x in &p.experiments {
        let note = match (&x.why, x.extrapolated) {
            (Some(w), _) => w.clone(),
            (None, true) => "amplitude beyond the fitted range (extrapolated)".into(),
            (None, false) => String::new(),
        };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {note} |",
            x.name,
            x.rate_hz,
            x.factor.map_or("—".into(), |k| k.to_string()),
            x.lines,
            num(x.plain),
            num(x.extended),
            num(x.ratio),
            num(x.threshold)
        );
    }
    amplitudes_section(&mut md, p);
    reading(&mut md, p);
    if !figs.is_empty() {
        let _ = writeln!(md, "\n## Figures\n");
        for f in figs {
            let _ = writeln!(md, "![{f}]({f})");
        }
    }
    md
}

/// The moving modes' amplitudes per experiment (amplitude-dependent extension).
fn amplitudes_section(md: &mut String, p: &Prediction) {
    if p.experiments.iter().all(|x| x.amplitudes.is_empty()) {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Moving modes at each experiment's amplitude\n\n| experiment | mode (Hz, \
         linear) | amplitude (× model experiment's) | frequency there (Hz) | damping there \
         |\n|---|---|---|---|---|"
    );
    for x in &p.experiments {
        for a in &x.amplitudes {
            let _ = writeln!(
                md,
                "| {} | {:.2} | {:.3} | {:.3} | {:.4} |",
                x.name, a.mode_hz, a.relative, a.freq_hz, a.damping
            );
        }
    }
}

/// What the numbers say and what to do next.
fn reading(md: &mut String, p: &Prediction) {
    let _ = writeln!(md, "\n## Reading\n");
    for x in &p.experiments {
        let (Some(r), Some(e), Some(t)) = (x.ratio, x.extended, x.threshold) else {
            continue;
        };
        let verdict = if e <= t {
            "within the noise: the extension explains this experiment"
        } else if r > 1.0 {
            "better than the plain model but still above the noise: part of what this \
             experiment shows is not in the extension"
        } else {
            "no better than the plain model: the extension does not carry to this experiment"
        };
        let _ = writeln!(
            md,
            "- `{}`: the extension's prediction reads {e:.3} (plain {:.3}, ×{r:.2}), {verdict}.",
            x.name,
            x.plain.unwrap_or(f64::NAN)
        );
    }
    if p.predicted() < p.experiments.len() {
        let _ = writeln!(
            md,
            "\nExperiments with a note were not predicted; the note says why (a rate that is \
             no whole fraction of the model's, a moving mode beyond the Nyquist frequency, an \
             amplitude far beyond the diagnosis's levels). Diagnose again with an experiment \
             near that rate or amplitude among the levels."
        );
    }
}
