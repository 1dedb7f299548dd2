//! The diagnosis as a person reads it: `report.md` and SVG figures.
//!
//! Figures per experiment: `frf_<name>.svg` (measured FRF against the model's simulation and
//! the extended model's, with the noise level), `residual_<name>.svg` (|measured − simulated|
//! before and after the extension against the noise level σ), and for periodic experiments
//! `time_<name>.svg` (one averaged steady period: the measured output and the errors of both
//! simulations).

use crate::plot::{bode_plot, line_plot, magnitude_plot, Curve, Line};
use crate::{ReportError, Result};
use num_complex::Complex64 as C;
use plotters::style::RGBColor;
use sd_diagnose::{
    Cause, CornerTrend, DampingTrend, Diagnosis, DriftCheck, DriftSign, ExperimentReport,
    Extension, FreqTrend, PoleKind,
};
use std::fmt::Write as _;
use std::path::Path;

mod data;
mod tracks;
use data::{bla_section, own_excess, own_fit_sentence, pieces_section};
use tracks::tracks_section;

pub(crate) const MEASURED: RGBColor = RGBColor(0, 0, 0);
pub(crate) const MODEL: RGBColor = RGBColor(200, 30, 30);
const EXTENDED: RGBColor = RGBColor(20, 110, 200);
const NOISE: RGBColor = RGBColor(150, 150, 150);

pub(crate) fn db(x: &[C]) -> Vec<f64> {
    x.iter().map(|v| 20.0 * v.norm().log10()).collect()
}

/// A file-name-safe version of an experiment name.
pub(crate) fn slug(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// What the extension is, in words.
pub fn describe(h: &Extension) -> String {
    match h {
        Extension::None => "none".into(),
        Extension::RateTied(p) => {
            let mut parts = Vec::new();
            if p.hold_delay > 0.0 {
                parts.push(format!(
                    "hold switching {:.3} of each sample period late",
                    p.hold_delay
                ));
            }
            if p.averaging > 0.0 {
                parts.push(format!(
                    "sensor averaging over {:.3} of each sample period",
                    p.averaging
                ));
            }
            if !p.clock_error.is_empty() {
                let e: Vec<String> = p
                    .clock_error
                    .iter()
                    .map(|e| format!("{:+.3} %", 100.0 * e))
                    .collect();
                parts.push(format!("sample clock off by {}", e.join(", ")));
            }
            if parts.is_empty() {
                "the plain continuous modal model".into()
            } else {
                parts.join("; ")
            }
        }
        Extension::FastFrf => {
            "the measured fast FRF in place of the model (model-free Lemma 6)".into()
        }
        Extension::PerLevel => "one best linear approximation per excitation level".into(),
        Extension::Amplitude(modes) => {
            let m: Vec<String> = modes
                .iter()
                .map(|m| {
                    format!(
                        "the {:.1} Hz mode's {}",
                        m.linear_freq_hz,
                        match (m.frequency_moves, m.damping_moves) {
                            (true, true) => "frequency and damping",
                            (true, false) => "frequency",
                            _ => "damping",
                        }
                    )
                })
                .collect();
            format!(
                "the modal model with amplitude-dependent modes: {}, as trends in the mode's \
                 output amplitude",
                m.join("; ")
            )
        }
    }
}

/// One magnitude figure: the given curves, the extension's (if any) and the noise level σ;
/// returns its file name.
#[allow(clippy::too_many_arguments)]
pub(crate) fn magnitude_figure<'a>(
    dir: &Path,
    name: String,
    title: &str,
    mut curves: Vec<Curve<'a>>,
    ext: Option<(&'a str, &'a [f64])>,
    noise: (&'a [f64], &'a [f64]),
    (fmin, fmax): (f64, f64),
    marks: &[(f64, &str)],
    mut phases: Vec<Option<&'a [f64]>>,
) -> Result<String> {
    if let Some((label, db)) = ext {
        curves.push(Curve {
            label,
            freq_hz: noise.0,
            db,
            color: EXTENDED,
        });
    }
    curves.push(Curve {
        label: "noise level σ",
        freq_hz: noise.0,
        db: noise.1,
        color: NOISE,
    });
    let path = dir.join(&name).to_string_lossy().into_owned();
    if phases.iter().any(Option::is_some) {
        phases.resize(curves.len(), None);
        bode_plot(&path, title, &curves, &phases, fmin, fmax, marks)?;
    } else {
        magnitude_plot(&path, title, &curves, fmin, fmax, marks)?;
    }
    Ok(name)
}

/// Phase in degrees of each value.
pub(crate) fn deg(x: &[C]) -> Vec<f64> {
    x.iter().map(|v| v.arg().to_degrees()).collect()
}

/// Phase in degrees of `a/b`, line by line.
fn deg_ratio(a: &[C], b: &[C]) -> Vec<f64> {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a / b).arg().to_degrees())
        .collect()
}

/// Writes the figures of one experiment into `dir`; returns their file names.
fn figures(dir: &Path, x: &ExperimentReport, ext_label: &str) -> Result<Vec<String>> {
    let c = &x.curves;
    let mut out = Vec::new();
    if c.freq_hz.is_empty() {
        return Ok(out);
    }
    let (fmin, fmax) = (c.freq_hz[0], c.freq_hz[c.freq_hz.len() - 1]);
    let s = slug(&x.name);
    let meas = db(&c.measured);
    let model = db(&c.model);
    let ext = c.extended.as_deref().map(db);
    let sigma: Vec<f64> = c.noise_var.iter().map(|v| 10.0 * v.log10()).collect();
    let sim_label = if x.factor > 1 {
        format!("model, Lemma 6 to 1/{}", x.factor)
    } else {
        "model".to_string()
    };
    let marks: Vec<(f64, String)> = x
        .bands
        .iter()
        .take(3)
        .map(|b| (b.worst_hz, format!("{:.1} Hz", b.worst_hz)))
        .collect();
    let marks_ref: Vec<(f64, &str)> = marks.iter().map(|(f, l)| (*f, l.as_str())).collect();
    let range = (fmin, fmax);
    let mut figure = |name: String,
                      title: String,
                      curves: Vec<Curve<'_>>,
                      ext: Option<(&str, &[f64])>,
                      phases: Vec<Option<&[f64]>>|
     -> Result<()> {
        let noise = (c.freq_hz.as_slice(), sigma.as_slice());
        out.push(magnitude_figure(
            dir, name, &title, curves, ext, noise, range, &marks_ref, phases,
        )?);
        Ok(())
    };
    let (ph_meas, ph_model) = (deg(&c.measured), deg(&c.model));
    let ph_ext = c.extended.as_deref().map(deg);
    let err_model = deg_ratio(&c.measured, &c.model);
    let err_ext = c.extended.as_deref().map(|e| deg_ratio(&c.measured, e));
    figure(
        format!("frf_{s}.svg"),
        format!("{} ({} Hz): measured and simulated FRF", x.name, x.rate_hz),
        vec![
            Curve {
                label: "measured",
                freq_hz: &c.freq_hz,
                db: &meas,
                color: MEASURED,
            },
            Curve {
                label: &sim_label,
                freq_hz: &c.freq_hz,
                db: &model,
                color: MODEL,
            },
        ],
        ext.as_deref().map(|e| (ext_label, e)),
        vec![
            Some(ph_meas.as_slice()),
            Some(ph_model.as_slice()),
            ph_ext.as_deref(),
        ],
    )?;
    // residuals against the noise level, and the phase error ∠(measured/simulated)
    let res = |p: &[C]| -> Vec<f64> {
        c.measured
            .iter()
            .zip(p)
            .map(|(m, p)| 20.0 * (m - p).norm().max(1e-300).log10())
            .collect()
    };
    let rm = res(&c.model);
    let re = c.extended.as_deref().map(res);
    let ext_res_label = format!("|measured − {ext_label}|");
    figure(
        format!("residual_{s}.svg"),
        format!(
            "{}: residual against the noise level; phase of measured/simulated",
            x.name
        ),
        vec![Curve {
            label: "|measured − model|",
            freq_hz: &c.freq_hz,
            db: &rm,
            color: MODEL,
        }],
        re.as_deref().map(|r| (ext_res_label.as_str(), r)),
        vec![Some(err_model.as_slice()), err_ext.as_deref()],
    )?;
    if let Some(td) = &x.time_domain {
        out.push(time_figure(dir, x, td, ext_label)?);
    }
    Ok(out)
}

/// The time-domain figure of an experiment (one averaged period through the model; a long
/// record by its first 4000 samples); its file name.
fn time_figure(
    dir: &Path,
    x: &ExperimentReport,
    td: &sd_diagnose::TimeDomain,
    ext_label: &str,
) -> Result<String> {
    let s = slug(&x.name);
    // a long record is shown by its first 4000 samples
    let shown = td.measured.len().min(4000);
    let td = &sd_diagnose::TimeDomain {
        measured: td.measured[..shown].to_vec(),
        model: td.model[..shown.min(td.model.len())].to_vec(),
        extended: td
            .extended
            .as_ref()
            .map(|e| e[..shown.min(e.len())].to_vec()),
        ..td.clone()
    };
    let t: Vec<f64> = (0..td.measured.len())
        .map(|i| i as f64 / td.rate_hz)
        .collect();
    let mean = td.measured.iter().sum::<f64>() / td.measured.len().max(1) as f64;
    let y: Vec<f64> = td.measured.iter().map(|v| v - mean).collect();
    let em: Vec<f64> = td
        .measured
        .iter()
        .zip(&td.model)
        .map(|(a, b)| a - b)
        .collect();
    let ee: Option<Vec<f64>> = td
        .extended
        .as_ref()
        .map(|e| td.measured.iter().zip(e).map(|(a, b)| a - b).collect());
    let mut lines = vec![
        Line {
            label: "measured output (mean removed)",
            x: &t,
            y: &y,
            color: MEASURED,
        },
        Line {
            label: "measured − model",
            x: &t,
            y: &em,
            color: MODEL,
        },
    ];
    let ext_err_label = format!("measured − {ext_label}");
    if let Some(e) = &ee {
        lines.push(Line {
            label: &ext_err_label,
            x: &t,
            y: e,
            color: EXTENDED,
        });
    }
    let name = format!("time_{s}.svg");
    line_plot(
        &dir.join(&name).to_string_lossy(),
        &format!(
            "{}: one averaged period, measured input through the model",
            x.name
        ),
        "time [s]",
        "output",
        &lines,
        false,
    )?;
    Ok(name)
}

/// Per moving mode of a nonlinearity, `amplitude_<f>hz.svg`: its natural frequency and damping
/// against the relative amplitude ρ (log axis), each experiment's fit with ±2σ bars, the
/// fitted trend with its ±2σ band, and the values predicted for each left-out level.
fn amplitude_figures(dir: &Path, d: &Diagnosis) -> Result<Vec<String>> {
    let mut out = Vec::new();
    for c in &d.causes {
        let Cause::Nonlinearity { modes, .. } = c else {
            continue;
        };
        for m in modes {
            let rho: Vec<f64> = m.points.iter().map(|p| p.relative_amplitude).collect();
            let (lo, hi) = rho
                .iter()
                .filter(|r| **r > 0.0 && r.is_finite())
                .fold((f64::INFINITY, 0.0f64), |a, r| (a.0.min(*r), a.1.max(*r)));
            if !(lo.is_finite() && hi > 0.0) {
                continue;
            }
            let grid: Vec<f64> = (0..=60)
                .map(|k| lo * (hi / lo).powf(k as f64 / 60.0))
                .collect();
            let curve = |t: &sd_diagnose::Trend| -> Vec<(f64, f64, f64)> {
                grid.iter()
                    .map(|r| {
                        let (v, s) = t.at(*r);
                        (*r, v, s)
                    })
                    .collect()
            };
            let fp: Vec<(f64, f64, f64)> = m
                .points
                .iter()
                .map(|p| (p.relative_amplitude, p.freq_hz, p.freq_hz_std))
                .collect();
            let zp: Vec<(f64, f64, f64)> = m
                .points
                .iter()
                .map(|p| (p.relative_amplitude, p.damping, p.damping_std))
                .collect();
            let pred = |k: usize| -> Vec<(f64, f64)> {
                m.points
                    .iter()
                    .filter_map(|p| {
                        let q = p.held_out_prediction?;
                        Some((p.relative_amplitude, if k == 0 { q.0 } else { q.1 }))
                    })
                    .collect()
            };
            let (fc, zc, fpred, zpred) = (curve(&m.frequency), curve(&m.damping), pred(0), pred(1));
            let name = format!("amplitude_{:.0}hz.svg", m.linear_freq_hz);
            let real = m.pole == PoleKind::Real;
            let freq = crate::plot::ErrorBarPanel {
                y_desc: if real {
                    "corner frequency a/2π [Hz]"
                } else {
                    "natural frequency [Hz]"
                },
                points: &fp,
                curve: &fc,
                predicted: &fpred,
            };
            let damp = crate::plot::ErrorBarPanel {
                y_desc: "damping ratio ζ [-]",
                points: &zp,
                curve: &zc,
                predicted: &zpred,
            };
            let title = if real {
                format!(
                    "Damped rigid body's corner at {:.1} Hz against amplitude (friction)",
                    m.linear_freq_hz
                )
            } else {
                format!(
                    "Mode at {:.1} Hz: frequency and damping against amplitude",
                    m.linear_freq_hz
                )
            };
            // a real pole has no damping of its own: one panel
            let panels = if real { vec![freq] } else { vec![freq, damp] };
            crate::plot::error_bar_plot(
                &dir.join(&name).display().to_string(),
                &title,
                "relative amplitude ρ (band rms of the output / the model experiment's)",
                &panels,
            )?;
            out.push(name);
        }
    }
    Ok(out)
}

/// Writes `report.md` and the figures of a diagnosis into `dir` (which must exist); returns
/// the figure file names.
///
/// # Errors
/// A figure or the report cannot be written.
pub fn write(dir: &Path, d: &Diagnosis, title: &str) -> Result<Vec<String>> {
    let ext_label = match d.extension {
        Extension::RateTied(_) => "extended model",
        Extension::FastFrf => "model-free Lemma 6",
        _ => "extended",
    };
    let mut figs = Vec::new();
    for x in &d.experiments {
        figs.extend(figures(dir, x, ext_label)?);
    }
    figs.extend(amplitude_figures(dir, d)?);
    let md = markdown(d, title, &figs);
    crate::write_atomic(&dir.join("report.md"), &md)?;
    Ok(figs)
}

/// Everything a diagnosis writes, for `sdctl diagnose` and `cargo xtask paper` alike:
/// `diagnosis.json` (its fields in docs/diagnosis.md), the model files, `predictor.json` (what
/// `sdctl predict` reads, docs/formats.md), `report.md` and the
/// figures, into `dir` (created when missing); returns the figure file names. Each file is
/// written atomically; `sdctl diagnose` stages the whole folder so that a run is published as
/// a whole.
///
/// # Errors
/// The folder, a figure or a file cannot be written.
pub fn write_all(dir: &Path, d: &Diagnosis, title: &str) -> Result<Vec<String>> {
    std::fs::create_dir_all(dir).map_err(|source| ReportError::Io {
        path: dir.display().to_string(),
        source,
    })?;
    let js =
        serde_json::to_string_pretty(&d.to_json()).map_err(|e| ReportError::Json(e.to_string()))?;
    crate::write_atomic(&dir.join("diagnosis.json"), &js)?;
    for (file, model) in model_files(d) {
        let text =
            sd_model::model_to_json_string(model).map_err(|e| ReportError::Json(e.to_string()))?;
        crate::write_atomic(&dir.join(&file), &text)?;
    }
    let predictor = d
        .predictor
        .to_json_string()
        .map_err(|e| ReportError::Json(e.to_string()))?;
    crate::write_atomic(&dir.join("predictor.json"), &predictor)?;
    write(dir, d, title)
}

/// The model files a diagnosis writes: `model.json` (the model judged), `extended_model.json`
/// (the rate-tied extension as a continuous model) and `extended_model_<experiment>.json` (the
/// extended model at each experiment's rate, where the extension is a model).
pub fn model_files(d: &Diagnosis) -> Vec<(String, &sd_model::StateSpace)> {
    let mut out = vec![("model.json".to_string(), &d.model)];
    if let Some(x) = &d.extended_model {
        out.push(("extended_model.json".into(), &x.continuous));
    }
    for x in &d.experiments {
        if let Some(m) = &x.extended_model {
            out.push((format!("extended_model_{}.json", file_safe(&x.name)), m));
        }
    }
    out
}

/// An experiment name as part of a file name (anything but letters, digits, `-`, `_` and `.`
/// becomes `_`).
fn file_safe(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The slowest experiment (largest rate factor), where a controller would run.
fn slowest(d: &Diagnosis) -> Option<&ExperimentReport> {
    d.experiments.iter().max_by_key(|x| x.factor)
}

/// "What to do next": the files written and the commands that use them, from the verdict and
/// the named causes.
fn next_steps(md: &mut String, d: &Diagnosis) {
    let _ = writeln!(md, "\n## Next steps\n");
    let files: Vec<String> = model_files(d)
        .iter()
        .map(|(f, _)| format!("`{f}`"))
        .collect();
    let _ = writeln!(
        md,
        "Model files written beside this report: {}.\n",
        files.join(", ")
    );
    let slow = slowest(d);
    let (ts, factor) = slow
        .map(|x| (1.0 / x.rate_hz, x.factor))
        .unwrap_or((d.model.ts().unwrap_or(0.0), 1));
    let names: Vec<&str> = d.causes.iter().map(Cause::name).collect();
    if d.verdict == sd_diagnose::Verdict::Consistent {
        let _ = writeln!(
            md,
            "- The model reproduces every experiment within the noise: design on it. \
             `sdctl downsample model.json --factor {factor} -o plant_slow.json` gives the plant at \
             {:.6} s (Lemma 6); then `sdctl analyze --plant plant_slow.json --controller \
             controller.json` checks a controller on it.",
            ts
        );
        return;
    }
    if let Some(x) = &d.extended_model {
        let _ = writeln!(
            md,
            "- Design on the extended model: `sdctl c2d extended_model.json --ts {ts:.6} \
             --hold-delay {:.4} --averaging {:.4} -o plant_slow.json` discretises it with the named \
             hold and sampler at the controller's period; then \
             `sdctl analyze --plant plant_slow.json --controller controller.json` checks a \
             controller on it.",
            x.hold_delay, x.averaging
        );
    }
    for name in names {
        let step = match name {
            "clock_error" => {
                "- A sample clock runs off its nominal period: check the time base \
                 of the named experiments' data acquisition; the extended models \
                 `extended_model_<experiment>.json` include the measured error."
            }
            "fast_model_error" => {
                "- The experiments agree with each other but the model misses \
                 them: fit a higher order (`sdctl diagnose ... --max-order N` with N above the \
                 model's order, or `sdctl fit frd.json --order N`) or pass a better model with \
                 `--model`."
            }
            "nonlinearity" => {
                "- The dynamics depend on the excitation level: design at the level \
                 of operation (`extended_model_<experiment>.json` is the model at each measured \
                 level) and check the controller on the models of the other levels."
            }
            "drift" => {
                "- The plant changed with time between the experiments: repeat the model \
                 experiment after the others and fit the model on data taken in the state the \
                 controller will meet."
            }
            "unexplained" => {
                "- No cataloged cause explains the excess (see the best partial \
                 explanation above): check that the rates are exact integer ratios, the timing \
                 of hold and sampler, and the sensor chain; a repeat of the model experiment \
                 separates drift from a rate effect."
            }
            _ => continue,
        };
        let _ = writeln!(md, "{step}");
    }
}

/// A table cell: the number (3 decimals, or 3 significant digits in scientific notation), or
/// "–" when there is none or it is not finite.
fn cell(v: Option<f64>, sci: bool) -> String {
    match v.filter(|e| e.is_finite()) {
        Some(e) if sci => format!("{e:.3e}"),
        Some(e) => format!("{e:.3}"),
        None => "–".into(),
    }
}

/// The hypotheses, the evidence and the held-out gain of `report.md`.
fn hypotheses_section(md: &mut String, d: &Diagnosis) {
    let _ = writeln!(
        md,
        "\n## Hypotheses\n\nFitted on the training data (earlier periods), ranked by the penalised criterion \
         (score sum + ½ ln K per parameter), judged on the held-out data.\n\n| hypothesis | \
         parameters | statistic (training) | criterion | statistic (held out) |\n|---|---|---|---|---|"
    );
    for r in &d.ranking {
        let _ = writeln!(
            md,
            "| {} | {} | {:.3} | {:.1} | {} |",
            r.cause,
            r.n_params,
            r.cost,
            r.criterion,
            cell(r.held_out, false)
        );
    }
    if let Some(p) = &d.partial {
        let _ = writeln!(
            md,
            "\nBest partial explanation (not named: its held-out statistic {} is above the \
             threshold): {}.",
            cell(p.held_out, false),
            p.cause
        );
    }
    let _ = writeln!(
        md,
        "\nExtension: {}.\n\n## Evidence\n\n| test | statistic | threshold | passed |\n|---|---|---|---|",
        describe(&d.extension)
    );
    for e in &d.evidence {
        let _ = writeln!(
            md,
            "| {} | {:.3} | {:.3} | {} |",
            e.test,
            e.statistic,
            e.threshold,
            if e.passed { "yes" } else { "**no**" }
        );
    }
    let failed: Vec<&sd_diagnose::Evidence> = d.evidence.iter().filter(|e| !e.passed).collect();
    if !failed.is_empty() {
        let _ = writeln!(
            md,
            "\nWhy the failed rows failed, beside the verdict `{}`:\n",
            d.verdict
        );
        for e in failed {
            let _ = writeln!(md, "- *{}*: {}.", e.test, explain_failed(d, e));
        }
    }
    let g = &d.gain;
    let _ = match (g.before, g.after, g.ratio) {
        (Some(b), Some(a), Some(r)) => writeln!(
            md,
            "\n## Gain on held-out data\n\nStatistic {b:.3} before (plain modal model) and {a:.3} \
             after the extension: ratio {r:.1} (held out: {}).",
            g.held_out.join(", ")
        ),
        _ => writeln!(
            md,
            "\n## Gain on held-out data\n\nNot measured: {}.",
            g.why.as_deref().unwrap_or("no held-out data")
        ),
    };
    held_out_levels(md, d);
}

/// Per held-out experiment (levels left out in turn): the linear model's statistic, the
/// extension's, their ratio, and the experiment's own fit in the extension's model class (the
/// floor a prediction can approach).
fn held_out_levels(md: &mut String, d: &Diagnosis) {
    let rows: Vec<(&str, sd_diagnose::HeldOut)> = d
        .experiments
        .iter()
        .filter_map(|x| x.held_out.map(|h| (x.name.as_str(), h)))
        .collect();
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "\nEach experiment left out in turn (statistics on its lines in the moving modes' bands; \
         1 is the noise):\n\n| experiment | linear model | extension | ratio | own fit (floor) | \
         |---|---|---|---|---|---|"
    );
    for (name, h) in rows {
        let _ = writeln!(
            md,
            "| {name} | {:.3} | {:.3} | {:.1} | {} | {} |",
            h.before,
            h.after,
            h.ratio,
            cell(Some(h.floor), false),
            if h.extrapolated {
                "extrapolated: beyond the fitted amplitudes"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(
        md,
        "\nAn extension statistic near the floor means the prediction from the other experiments \
         does as well as a fit to this experiment's own data in the same model class; well above \
         it, the trend between the levels is what misses (more levels, or a level nearer this \
         one, would help)."
    );
}

/// `x ± s` with the standard error when there is one.
fn pm(x: f64, s: Option<f64>, scale: f64, digits: usize) -> String {
    match s {
        Some(s) if s.is_finite() && s > 0.0 => {
            // the standard error to two significant digits, the value to the same place
            let s = s * scale;
            let d = (1 - s.log10().floor() as i64).clamp(0, 12) as usize;
            format!("{} ± {}", fixed(x * scale, d), fixed(s, d))
        }
        Some(s) => format!(
            "{} ± {}",
            fixed(x * scale, digits),
            fixed(s * scale, digits)
        ),
        None => fixed(x * scale, digits),
    }
}

/// `v` with `d` decimals, without the sign of a value that rounds to zero ("0.000", not
/// "-0.000").
fn fixed(v: f64, d: usize) -> String {
    let t = format!("{v:.d$}");
    if t.starts_with('-') && t[1..].chars().all(|c| c == '0' || c == '.') {
        t[1..].to_string()
    } else {
        t
    }
}

/// The named causes of a diagnosis in words (see [`cause_text`]), the averaging window also in
/// µs at each experiment's rate.
pub fn causes_text(d: &Diagnosis) -> Vec<String> {
    d.causes
        .iter()
        .filter_map(|c| {
            let mut t = cause_text(c)?;
            if let Cause::AveragingSampler { window_frac, .. } = c {
                let per: Vec<String> = d
                    .experiments
                    .iter()
                    .map(|x| format!("{:.1} µs at `{}`", 1e6 * window_frac / x.rate_hz, x.name))
                    .collect();
                if !per.is_empty() {
                    t = format!("{t} ({})", per.join(", "));
                }
            }
            Some(t)
        })
        .collect()
}

/// A named cause's parameters in words, with their standard errors (`None` for causes
/// without parameters): the report's sentence, and `sdctl diagnose`'s summary line.
pub fn cause_text(c: &Cause) -> Option<String> {
    Some(match c {
        Cause::HoldDelay {
            delay_frac,
            delay_frac_std,
            delay_s,
            combined_lag_frac,
            combined_lag_frac_std,
        } => {
            let per: Vec<String> = delay_s
                .iter()
                .map(|(n, t)| format!("{:.1} µs at `{n}`", t * 1e6))
                .collect();
            let lag = combined_lag_frac
                .map(|l| {
                    format!(
                        "; with the averaging window, the combined lag (delay + half the window) \
                         is {} of a period, determined even where the split between the two is \
                         not",
                        pm(l, *combined_lag_frac_std, 1.0, 3)
                    )
                })
                .unwrap_or_default();
            format!(
                "The hold switches {} of each sample period late ({}){lag}",
                pm(*delay_frac, *delay_frac_std, 1.0, 3),
                per.join(", ")
            )
        }
        Cause::AveragingSampler {
            window_frac,
            window_frac_std,
        } => format!(
            "The sensor averages over {} of each sample period",
            pm(*window_frac, *window_frac_std, 1.0, 3)
        ),
        Cause::ClockError {
            clock_error,
            clock_error_std,
        } => {
            let per: Vec<String> = clock_error
                .iter()
                .map(|(n, e)| {
                    format!(
                        "`{n}` {} %",
                        pm(*e, clock_error_std.get(n).copied(), 100.0, 3)
                    )
                })
                .collect();
            format!(
                "The sample clock runs off its nominal period (true = nominal·(1 + e)): {}",
                per.join(", ")
            )
        }
        Cause::Nonlinearity { .. } => nonlinearity_text(c)?,
        Cause::Drift { experiments, sign } => drift_text(experiments, *sign),
        Cause::FastModelError {
            model_misfit_on_fast_data,
            worst_fast_hz,
        } => {
            let f: Vec<String> = worst_fast_hz.iter().map(|f| format!("{f:.1}")).collect();
            format!(
                "The model misses its own fast data (statistic {model_misfit_on_fast_data:.3}); \
                 worst lines {} Hz",
                f.join(", ")
            )
        }
        Cause::None | Cause::Unexplained => return None,
    })
}

/// The sentence of a nonlinearity (`None` for any other cause).
fn nonlinearity_text(c: &Cause) -> Option<String> {
    let Cause::Nonlinearity {
        relative_levels,
        kind,
        damping_trend,
        corner_trend,
        modes,
        tracks,
        drift_check,
    } = c
    else {
        return None;
    };
    Some({
        let per: Vec<String> = relative_levels
            .iter()
            .map(|(n, l)| format!("`{n}` at {l:.2}×"))
            .collect();
        let kind = match kind {
            FreqTrend::Hardening => {
                "the dominant moving mode hardens (its frequency rises \
                                         with amplitude)"
            }
            FreqTrend::Softening => {
                "the dominant moving mode softens (its frequency falls \
                                         with amplitude)"
            }
            FreqTrend::None => "no mode's frequency moves beyond its uncertainty",
        };
        let damp = match damping_trend {
            DampingTrend::Increasing => "its damping rises with amplitude",
            DampingTrend::Decreasing => "its damping falls with amplitude",
            DampingTrend::None => "no damping trend beyond the uncertainty",
        };
        let drift = match drift_check {
            DriftCheck::DistortionSeen => {
                "not drift: the non-excited lines show nonlinear distortion"
            }
            DriftCheck::RepeatAgrees => {
                "not drift: a repeat at the model experiment's level agrees with it"
            }
            DriftCheck::Unchecked => {
                "drift over time is not ruled out (no repeat of the model experiment's \
                     level, no non-excited lines): repeat that level at the end of the \
                     campaign, or excite with odd multisines that leave detection lines"
            }
        };
        let corner = match corner_trend {
            CornerTrend::Falling => {
                "; a real pole's corner falls with amplitude (friction-like: Coulomb \
                     friction's equivalent damping shrinks as the motion grows)"
            }
            CornerTrend::Rising => "; a real pole's corner rises with amplitude",
            CornerTrend::None => "",
        };
        let dominant = tracks
            .iter()
            .find(|t| t.dominant)
            .map(|t| {
                format!(
                    " (the mode at {:.3} Hz, shifted {:+.2} half-power bandwidths over the \
                     levels)",
                    t.freq_hz, t.shift_bandwidths
                )
            })
            .unwrap_or_default();
        let moving = tracks
            .iter()
            .filter(|t| t.frequency_moves || t.damping_moves)
            .count();
        format!(
            "Experiments at other excitation levels disagree with the model \
                 experiment's ({}); {kind}{dominant}, {damp}{corner}; {moving} of {} tracked \
                 physical mode(s) move; {} moving pole(s) in the amplitude model; {drift}",
            per.join(", "),
            tracks.len(),
            modes.len()
        )
    })
}

/// The sentence of a drift.
fn drift_text(experiments: &[String], sign: DriftSign) -> String {
    let names: Vec<String> = experiments.iter().map(|n| format!("`{n}`")).collect();
    let why = match sign {
        DriftSign::RepeatWithoutDistortion => {
            "a repeat at the model experiment's level and rate disagrees with it, \
                     without nonlinear distortion at the non-excited lines"
        }
        DriftSign::LevelsWithoutDistortion => {
            "experiments at other levels disagree, yet none shows nonlinear \
                     distortion at its non-excited lines (an FRF that changes with amplitude \
                     brings distortion with it)"
        }
    };
    format!(
        "The plant changed between experiments ({}): {why}. No time-invariant model \
                 predicts this; identify the model on data recorded close in time to its use, \
                 and check what changes over the campaign (temperature, settling, mounting)",
        names.join(", ")
    )
}

/// The modes that move with amplitude: per mode its trend and every level's fit, with the
/// frequency and damping the model fitted without that level predicted for it.
fn moving_modes_section(md: &mut String, d: &Diagnosis) {
    for c in &d.causes {
        let Cause::Nonlinearity { modes, .. } = c else {
            continue;
        };
        if modes.is_empty() {
            continue;
        }
        let _ = writeln!(md, "## Modes (and poles) that move with amplitude\n");
        let _ = writeln!(
            md,
            "Amplitude: rms of the measured output in the mode's band (f ± max(3ζ, 2 %) f), \
             relative to the model experiment's (ρ). Trend: value = at ρ = 1 + slope·(ρ^k − \
             1).\n"
        );
        for m in modes {
            if m.pole == PoleKind::Real {
                corner_rows(md, m);
                continue;
            }
            let _ = writeln!(
                md,
                "**Mode at {:.2} Hz (ζ = {:.4} linear).** Frequency {}: {:.2} ± {:.2} Hz + \
                 ({:.3} ± {:.3}) Hz·(ρ^{} − 1); damping {}: {:.4} + ({:.2e} ± {:.1e})·(ρ^{} − 1).\n",
                m.linear_freq_hz,
                m.linear_damping,
                if m.frequency_moves { "moves" } else { "does not move beyond its errors" },
                m.frequency.at_reference,
                m.frequency.at_reference_std,
                m.frequency.slope,
                m.frequency.slope_std,
                m.frequency.exponent,
                if m.damping_moves { "moves" } else { "does not move beyond its errors" },
                m.damping.at_reference,
                m.damping.slope,
                m.damping.slope_std,
                m.damping.exponent
            );
            points_table(md, m);
        }
    }
}

/// A friction-damped rigid body's corner: its trend and every level's point.
fn corner_rows(md: &mut String, m: &sd_diagnose::MovingMode) {
    let _ = writeln!(
        md,
        "**Damped rigid body, corner at {:.2} Hz linear** (the pole −2πf of `1/(s(s + a))`: \
         friction's equivalent damping over the mass). Corner {}: {:.2} ± {:.2} Hz + ({:.3} ± \
         {:.3}) Hz·(ρ^{} − 1).\n",
        m.linear_freq_hz,
        if m.frequency_moves {
            "moves"
        } else {
            "does not move beyond its errors"
        },
        m.frequency.at_reference,
        m.frequency.at_reference_std,
        m.frequency.slope,
        m.frequency.slope_std,
        m.frequency.exponent
    );
    points_table(md, m);
}

/// Every level's point of a moving pole: frequency and damping of a mode, the corner of a
/// real pole, with what the model fitted without that level predicted.
fn points_table(md: &mut String, m: &sd_diagnose::MovingMode) {
    let real = m.pole == PoleKind::Real;
    let _ = writeln!(
        md,
        "{}",
        if real {
            "| experiment | ρ | corner [Hz] | predicted without it [Hz] |\n|---|---|---|---|"
        } else {
            "| experiment | ρ | frequency [Hz] | damping | predicted without it [Hz, ζ] |\n|---|---|---|---|---|"
        }
    );
    for p in &m.points {
        let damping = if real {
            String::new()
        } else {
            format!(" {:.4} ± {:.4} |", p.damping, p.damping_std)
        };
        let predicted = p.held_out_prediction.map_or("–".to_string(), |(f, z)| {
            if real {
                format!("{f:.2}")
            } else {
                format!("{f:.2}, {z:.4}")
            }
        });
        let _ = writeln!(
            md,
            "| {} | {:.2} | {:.2} ± {:.2} |{damping} {predicted} |",
            p.experiment, p.relative_amplitude, p.freq_hz, p.freq_hz_std,
        );
    }
    let _ = writeln!(md);
}

/// Why an evidence row failed, and what the failure means beside the verdict.
fn explain_failed(d: &Diagnosis, e: &sd_diagnose::Evidence) -> String {
    use sd_diagnose::EvidenceKind as K;
    let consistent = d.verdict == sd_diagnose::Verdict::Consistent;
    let chance = "a single test fails by chance with its false-alarm probability (the verdict's α \
                  shared among its tests), and the pooled test the verdict rests on passes";
    let named = !matches!(
        d.causes.first(),
        None | Some(sd_diagnose::Cause::None) | Some(sd_diagnose::Cause::Unexplained)
    );
    match e.kind {
        K::OwnData => format!("the model against its own experiment: {}", own_excess(d)),
        K::ModelFree if consistent => format!(
            "the exact downsampling of the measured fast FRF \
             misses this slower experiment, yet the verdict is consistent: {chance}"
        ),
        K::ModelFree if named => format!(
            "the measured slower FRF is not what exact downsampling (Lemma 6) of the measured \
             fast FRF predicts, whatever the model: something acts between the rates, named \
             here as `{}`",
            d.cause
        ),
        K::ModelFree => "the measured slower FRF is not what exact downsampling (Lemma 6) of \
             the measured fast FRF predicts, and no cataloged cause (hold delay, averaging \
             sampler, clock error, level) explains it: check the hold and sensor timing and the \
             clocks of the two experiments"
            .into(),
        K::ModelSimulation | K::AllValidation if consistent => {
            format!("the model's simulation misses here, yet the verdict is consistent: {chance}")
        }
        K::ModelSimulation | K::AllValidation if named => format!(
            "the plain model's simulation misses; the extension `{}` is what brings it to the \
             noise level (column \"extended\" above)",
            d.cause
        ),
        K::ModelSimulation | K::AllValidation => {
            "the model's simulation misses and no cataloged cause explains it: see the bands \
             above for where, and the next steps below"
                .into()
        }
        K::Distortion if consistent => "power at lines that were not excited: the system is \
             nonlinear at this level (or the excitation leaks); the FRF at the excited lines is \
             its best linear approximation, which the model predicts within the noise, so the \
             verdict stays consistent"
            .into(),
        K::Distortion => "power at lines that were not excited: the system is nonlinear at this \
             level (or the excitation leaks); the FRFs are best linear approximations at their \
             levels"
            .into(),
        K::DistortionVariance => "the model's misfit on this experiment is within the noise \
             once the nonlinear distortion's variance is counted: another phase realisation at \
             the same level differs by the nonlinearity's stochastic distortion, not by a fault \
             of the model"
            .into(),
        K::SameLevel => "this experiment ran at another excitation level than the model \
             experiment: it is compared as a level (a test for nonlinearity), not as a repeat"
            .into(),
        K::NotRepeatable | K::Drift => "this is the verdict's reason (the test says it)".into(),
    }
}

/// The text of `report.md`.
pub fn markdown(d: &Diagnosis, title: &str, figures: &[String]) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Diagnosis of {title}\n");
    let named = causes_text(d);
    let _ = writeln!(
        md,
        "**Verdict: {}. Cause: {}.**{}\n",
        d.verdict,
        d.cause,
        if named.is_empty() {
            String::new()
        } else {
            format!(" {}.", named.join("; "))
        }
    );
    let _ = writeln!(
        md,
        "The model: {} ({} states at {:.6} s).\n",
        d.model_source(),
        d.model.n(),
        d.model.ts().unwrap_or(0.0)
    );
    own_fit_sentence(&mut md, d);
    bla_section(&mut md, d);
    pieces_section(&mut md, d);
    tracks_section(&mut md, d);
    moving_modes_section(&mut md, d);
    let _ = writeln!(md, "## What the model's simulation gets wrong\n");
    let _ = writeln!(
        md,
        "Statistic: mean calibrated score per line (|P_meas − P_sim|²/variance, corrected for \
         the degrees of freedom of the estimated variances); 1 is the noise level; a \
         discrepancy is above the threshold at false-alarm probability {} (per test: shared \
         by the verdict's tests).\n",
        d.alpha
    );
    let _ = writeln!(
        md,
        "| experiment | rate [Hz] | F | level | lines | threshold | model-free Lemma 6 | model | extended |\n|---|---|---|---|---|---|---|---|---|"
    );
    for x in &d.experiments {
        let _ = writeln!(
            md,
            "| {} ({:?}) | {} | {} | {:.2} | {} | {:.3} | {} | {:.3} | {} |",
            x.name,
            x.role,
            x.rate_hz,
            x.factor,
            x.relative_level,
            x.model_stat.lines,
            x.model_stat.threshold,
            cell(x.model_free.map(|m| m.value), false),
            x.model_stat.value,
            cell(x.extended_stat.map(|m| m.value), false)
        );
    }
    for x in &d.experiments {
        if x.bands.is_empty() {
            continue;
        }
        let _ = writeln!(
            md,
            "\n**{}**: bands where the model misses beyond 3σ (largest share of the statistic first)\n\n| band [Hz] | worst line [Hz] | measured/simulated [dB] | phase [°] | comes from [Hz] | share |\n|---|---|---|---|---|---|",
            x.name
        );
        for b in &x.bands {
            let _ = writeln!(
                md,
                "| {:.1}–{:.1} | {:.1} | {:+.2} | {:+.1} | {:.1} | {:.0} % |",
                b.f_lo,
                b.f_hi,
                b.worst_hz,
                b.worst_db,
                b.worst_deg,
                b.from_fast_hz,
                100.0 * b.share
            );
        }
    }
    let tds: Vec<&ExperimentReport> = d
        .experiments
        .iter()
        .filter(|x| x.time_domain.is_some())
        .collect();
    if !tds.is_empty() {
        let _ = writeln!(
            md,
            "\n## Time domain (measured input through the model, one averaged steady period)\n\nAll bins where the input is measured, then only the bands above (where a discrepancy of the\nfrequency domain shows in time without the low-frequency input noise around it).\n\n| experiment | output rms | noise rms | error rms, model | error rms, extended | in the bands: noise | model | extended |\n|---|---|---|---|---|---|---|---|"
        );
        for x in tds {
            if let Some(t) = &x.time_domain {
                let opt = |v: Option<f64>| cell(v, true);
                let _ = writeln!(
                    md,
                    "| {} | {:.3e} | {} | {:.3e} | {} | {} | {} | {} |",
                    x.name,
                    t.output_rms,
                    opt(t.noise_rms),
                    t.error_rms_model,
                    opt(t.error_rms_extended),
                    opt(t.in_bands.map(|b| b.noise_rms)),
                    opt(t.in_bands.map(|b| b.error_rms_model)),
                    opt(t.in_bands.and_then(|b| b.error_rms_extended)),
                );
            }
        }
    }
    hypotheses_section(&mut md, d);
    next_steps(&mut md, d);
    if !figures.is_empty() {
        let _ = writeln!(md, "\n## Figures\n");
        for f in figures {
            let _ = writeln!(md, "![{f}]({f})");
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_read_with_their_uncertainty() {
        // the standard error sets the digits: two significant ones
        assert_eq!(pm(0.80071, Some(1.2e-4), 1.0, 3), "0.80071 ± 0.00012");
        assert_eq!(pm(0.3, Some(0.04), 1.0, 3), "0.300 ± 0.040");
        assert_eq!(pm(-0.002, Some(0.0005), 100.0, 3), "-0.200 ± 0.050");
        // no sign on a value that rounds to zero
        assert_eq!(pm(-1e-9, None, 1.0, 3), "0.000");
        assert_eq!(fixed(-0.0, 2), "0.00");
        assert_eq!(fixed(-0.5, 1), "-0.5");
    }
}
