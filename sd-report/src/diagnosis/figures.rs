//! The diagnosis's figures: per experiment the FRF, the residual against the noise level and
//! the time domain; per moving mode its frequency and damping against amplitude.

use super::*;

pub(crate) const MEASURED: RGBColor = RGBColor(0, 0, 0);

pub(crate) const MODEL: RGBColor = RGBColor(200, 30, 30);

pub(super) const EXTENDED: RGBColor = RGBColor(20, 110, 200);

pub(super) const NOISE: RGBColor = RGBColor(150, 150, 150);

pub(crate) fn db(x: &[C]) -> Vec<f64> {
    x.iter().map(|v| 20.0 * v.norm().log10()).collect()
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
pub(super) fn deg_ratio(a: &[C], b: &[C]) -> Vec<f64> {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a / b).arg().to_degrees())
        .collect()
}

/// Writes the figures of one experiment into `dir`; returns their file names.
pub(super) fn figures(dir: &Path, x: &ExperimentReport, ext_label: &str) -> Result<Vec<String>> {
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
pub(super) fn time_figure(
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
        "output [the sensor's unit]",
        &lines,
        false,
    )?;
    Ok(name)
}

/// Per moving mode of a nonlinearity, `amplitude_<f>hz.svg`: its natural frequency and damping
/// against the relative amplitude ρ (log axis), each experiment's fit with ±2σ bars, the
/// fitted trend with its ±2σ band, and the values predicted for each left-out level.
pub(super) fn amplitude_figures(dir: &Path, d: &Diagnosis) -> Result<Vec<String>> {
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
