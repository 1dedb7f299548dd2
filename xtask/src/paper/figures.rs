//! The paper run's figures (Figs. 3–7), each from this run's numbers.

use super::*;
/// Phases (degrees) of an FRD's first entry.
fn frd_deg(f: &Frd) -> Vec<f64> {
    f.response()
        .iter()
        .map(|g| g[(0, 0)].arg().to_degrees())
        .collect()
}

/// Phases (degrees) of a model's first entry at `f` (Hz).
fn model_deg(m: &StateSpace, f: &[f64]) -> Result<Vec<f64>, String> {
    Ok(frd_deg(&m.freqresp(f).map_err(s)?))
}

/// Per-line SNR `|Ĝ|/σ` (dB) of an FRD with variances (NaN where the variance is 0 or absent).
fn frd_snr_db(f: &Frd) -> Vec<f64> {
    let var = f.variance();
    f.response()
        .iter()
        .enumerate()
        .map(|(i, g)| {
            let v = var.map_or(0.0, |v| v[i][(0, 0)]);
            if v > 0.0 {
                db(g[(0, 0)].norm() / v.sqrt())
            } else {
                f64::NAN
            }
        })
        .collect()
}

/// Fig. 3: the measured FRFs at both rates and the fit at 5 kHz — magnitude, phase and the
/// measurements' per-line SNR; the measurements drawn last (on top).
pub(super) fn fig3(
    out: &str,
    id: &Identified,
    fitted: &Fitted,
    pk: &Peaks,
) -> Result<&'static str, String> {
    let f_f = id.est_f.frd.freq_hz().to_vec();
    let fit_db = model_db(&fitted.p_fast, &f_f)?;
    let fit_deg = model_deg(&fitted.p_fast, &f_f)?;
    let (mf_db, mf_deg) = (frd_db(&id.est_f.frd), frd_deg(&id.est_f.frd));
    let ms_deg = frd_deg(&id.est_s.frd);
    let (snr_f, snr_s) = (frd_snr_db(&id.est_f.frd), frd_snr_db(&id.est_s.frd));
    let curves = [
        Curve {
            label: "fit at 5 kHz",
            freq_hz: &f_f,
            db: &fit_db,
            color: BLUE,
        },
        Curve {
            label: "measured, 5 kHz",
            freq_hz: &f_f,
            db: &mf_db,
            color: GREY,
        },
        Curve {
            label: "measured, 1 kHz",
            freq_hz: &pk.f_s,
            db: &pk.meas_s_db,
            color: RED,
        },
    ];
    let snr = [
        Curve {
            label: "SNR, 5 kHz",
            freq_hz: &f_f,
            db: &snr_f,
            color: GREY,
        },
        Curve {
            label: "SNR, 1 kHz",
            freq_hz: &pk.f_s,
            db: &snr_s,
            color: RED,
        },
    ];
    bode_snr_plot_in(
        &format!("{out}/fig3_frf.svg"),
        "Fig. 3: measured FRFs at 5 kHz and 1 kHz, and the fit at 5 kHz",
        (&curves, &[Some(&fit_deg), Some(&mf_deg), Some(&ms_deg)]),
        &snr,
        (1.0, 2500.0),
        &[(653.0, "653 Hz"), (347.0, "347 Hz")],
        "m/N",
    )
    .map_err(s)?;
    Ok("fig3_frf.svg")
}

/// Fig. 4: the downsampled fit and the design model against the measured 1 kHz FRF
/// (magnitude and phase; the measurement drawn last).
pub(super) fn fig4(
    out: &str,
    id: &Identified,
    fitted: &Fitted,
    pk: &Peaks,
) -> Result<&'static str, String> {
    let design_db = model_db(&fitted.p_design, &pk.f_s)?;
    let design_deg = model_deg(&fitted.p_design, &pk.f_s)?;
    let down_deg = model_deg(&fitted.p_down, &pk.f_s)?;
    let meas_deg = frd_deg(&id.est_s.frd);
    bode_plot_in(
        &format!("{out}/fig4_downsampled.svg"),
        "Fig. 4: the 5 kHz fit downsampled to 1 kHz (Lemma 6) vs the measured 1 kHz FRF",
        &[
            Curve {
                label: "design model",
                freq_hz: &pk.f_s,
                db: &design_db,
                color: GREEN,
            },
            Curve {
                label: "fit downsampled (Lemma 6)",
                freq_hz: &pk.f_s,
                db: &pk.down_db,
                color: BLUE,
            },
            Curve {
                label: "measured, 1 kHz",
                freq_hz: &pk.f_s,
                db: &pk.meas_s_db,
                color: RED,
            },
        ],
        &[Some(&design_deg), Some(&down_deg), Some(&meas_deg)],
        (1.0, 500.0),
        &[(347.0, "347 Hz")],
        "m/N",
    )
    .map_err(s)?;
    Ok("fig4_downsampled.svg")
}

/// Fig. 4 (detail): the aliased resonance with the model-free Lemma 6 prediction from the
/// 5 kHz FRF and the model extended with the diagnosed cause; the measurement drawn last.
pub(super) fn fig4_detail(
    out: &str,
    id: &Identified,
    pk: &Peaks,
    diag: &sd_diagnose::Diagnosis,
) -> Result<&'static str, String> {
    let pred_plain: Vec<f64> = sd_diagnose::predict(&id.est_f.frd, 2e-4, 5, &pk.f_s)
        .into_iter()
        .map(|g| g.map(|g| db(g.norm())).unwrap_or(f64::NAN))
        .collect();
    let slow_rep = diag
        .experiments
        .iter()
        .find(|x| x.factor == 5)
        .ok_or("the diagnosis has no 1 kHz experiment")?;
    let f_ext = slow_rep.curves.freq_hz.clone();
    let pred_ext: Vec<f64> = match &slow_rep.curves.extended {
        Some(e) => e.iter().map(|g| db(g.norm())).collect(),
        None => vec![f64::NAN; f_ext.len()],
    };
    // the legend says what the extension achieved on this run's held-out data
    let ext_label = format!(
        "fit extended with the diagnosed cause ({})",
        extension_summary(diag)
    );
    magnitude_plot(
        &format!("{out}/fig4_detail.svg"),
        "Fig. 4 (detail): the aliased resonance, with the diagnosis",
        &[
            Curve {
                label: "fit downsampled (Lemma 6)",
                freq_hz: &pk.fine,
                db: &pk.fine_db,
                color: BLUE,
            },
            Curve {
                label: "Lemma 6 from the 5 kHz FRF",
                freq_hz: &pk.f_s,
                db: &pred_plain,
                color: GREY,
            },
            Curve {
                label: &ext_label,
                freq_hz: &f_ext,
                db: &pred_ext,
                color: GREEN,
            },
            Curve {
                label: "measured, 1 kHz",
                freq_hz: &pk.f_s,
                db: &pk.meas_s_db,
                color: RED,
            },
        ],
        300.0,
        400.0,
        &[(347.0, "347 Hz")],
    )
    .map_err(s)?;
    Ok("fig4_detail.svg")
}

/// Fig. 4 (uncertainty): the 5 kHz fit's error bound taken to 1 kHz by Lemma 6, around the
/// downsampled fit and, through the diagnosed non-idealities, around the extended model,
/// against the measured 1 kHz FRF. The bounds end at 400 Hz: above, a fold frequency
/// `f + 2 kHz` lies beyond the 5 kHz data's last trusted line (2.4 kHz).
pub(super) fn fig4_uncertainty(
    out: &str,
    pk: &Peaks,
    u: &crate::uncertainty::Uncertain,
) -> Result<&'static str, String> {
    let (up, lo) = crate::uncertainty::band_db(&u.slow);
    let nominal: Vec<f64> = u.slow.nominal.iter().map(|n| db(n.norm())).collect();
    let mut curves = vec![
        Curve {
            label: "fit downsampled (Lemma 6)",
            freq_hz: &u.slow.freq_hz,
            db: &nominal,
            color: BLUE,
        },
        Curve {
            label: "± its 5 kHz error bound, downsampled (95 %/line)",
            freq_hz: &u.slow.freq_hz,
            db: &up,
            color: LIGHT_BLUE,
        },
        Curve {
            label: "",
            freq_hz: &u.slow.freq_hz,
            db: &lo,
            color: LIGHT_BLUE,
        },
    ];
    let ext = u.slow_extended.as_ref().map(|(b, _)| {
        let (xu, xl) = crate::uncertainty::band_db(b);
        let xn: Vec<f64> = b.nominal.iter().map(|n| db(n.norm())).collect();
        (b.freq_hz.clone(), xn, xu, xl)
    });
    if let Some((f, xn, xu, xl)) = &ext {
        curves.push(Curve {
            label: "extended model (diagnosed cause)",
            freq_hz: f,
            db: xn,
            color: GREEN,
        });
        curves.push(Curve {
            label: "± the bound through the diagnosed cause",
            freq_hz: f,
            db: xu,
            color: LIGHT_GREEN,
        });
        curves.push(Curve {
            label: "",
            freq_hz: f,
            db: xl,
            color: LIGHT_GREEN,
        });
    }
    // the measurement last, on top
    curves.push(Curve {
        label: "measured, 1 kHz",
        freq_hz: &pk.f_s,
        db: &pk.meas_s_db,
        color: RED,
    });
    magnitude_plot(
        &format!("{out}/fig4_uncertainty.svg"),
        "Fig. 4 (uncertainty): the 5 kHz error bound at 1 kHz, plain and through the diagnosed cause",
        &curves,
        250.0,
        450.0,
        &[(347.0, "347 Hz")],
    )
    .map_err(s)?;
    Ok("fig4_uncertainty.svg")
}

/// What the diagnosis's extension reached on held-out data, in words.
pub(super) fn extension_summary(diag: &sd_diagnose::Diagnosis) -> String {
    match (diag.gain.after, diag.gain_ratio()) {
        (Some(a), Some(r)) => format!("held out: statistic {a:.2} (1 = noise), gain ×{r:.1}"),
        _ => "gain not measured".into(),
    }
}

/// The phase (degrees) of a SISO model on a grid, unwrapped along it.
pub(super) fn phase_deg(k: &StateSpace, grid: &[f64]) -> Result<Vec<f64>, String> {
    let r = k.freqresp(grid).map_err(s)?;
    let mut out: Vec<f64> = Vec::with_capacity(grid.len());
    for g in r.response() {
        let mut p = g[(0, 0)].arg().to_degrees();
        if let Some(&prev) = out.last() {
            p += 360.0 * ((prev - p) / 360.0).round();
        }
        out.push(p);
    }
    Ok(out)
}

/// Fig. 5: the controllers' Bode magnitude and phase, and |S_d| with the design model.
pub(super) fn fig5(out: &str, c: &Controllers) -> Result<[&'static str; 3], String> {
    let g = &c.grid;
    let two = |a: &[f64], b: &[f64]| {
        [
            ("Controller 1", a.to_vec(), BLUE),
            ("Controller 2", b.to_vec(), RED),
        ]
    };
    let mag = two(&model_db(&c.c1, g)?, &model_db(&c.c2, g)?);
    let mut sens = two(&c.s_curves[0], &c.s_curves[1]).to_vec();
    if let Some(m) = c.s_curves.get(2) {
        sens.push(("mixed sensitivity", m.clone(), GREEN));
    }
    for (file, title, curves) in [
        (
            "fig5_controllers.svg",
            "Fig. 5a: Controller 1 (loopshaping) and Controller 2 (PID alone)",
            &mag[..],
        ),
        (
            "fig5_sensitivity.svg",
            "Fig. 5b: |S_d| with the design model",
            &sens[..],
        ),
    ] {
        let cs: Vec<Curve<'_>> = curves
            .iter()
            .map(|(label, db, color)| Curve {
                label,
                freq_hz: g,
                db,
                color: *color,
            })
            .collect();
        magnitude_plot(
            &format!("{out}/{file}"),
            title,
            &cs,
            1.0,
            500.0,
            &[(347.0, "347 Hz")],
        )
        .map_err(s)?;
    }
    let ph = two(&phase_deg(&c.c1, g)?, &phase_deg(&c.c2, g)?);
    let lines: Vec<Line<'_>> = ph
        .iter()
        .map(|(label, y, color)| Line {
            label,
            x: g,
            y,
            color: *color,
        })
        .collect();
    line_plot(
        &format!("{out}/fig5_controllers_phase.svg"),
        "Fig. 5a (phase): Controller 1 (loopshaping) and Controller 2 (PID alone)",
        "frequency [Hz]",
        "phase [deg]",
        &lines,
        true,
    )
    .map_err(s)?;
    Ok([
        "fig5_controllers.svg",
        "fig5_controllers_phase.svg",
        "fig5_sensitivity.svg",
    ])
}

/// Fig. 6: Controller 2's standstill error in time at both rates, and the cumulative power
/// spectra of both controllers' errors.
pub(super) fn fig6(out: &str, stand: &[Run]) -> Result<[&'static str; 2], String> {
    let c2 = stand.get(1).ok_or("no standstill run of Controller 2")?;
    let n_show = 1000.min(c2.fast.len());
    let t_fast: Vec<f64> = (0..n_show).map(|i| i as f64 / 5000.0).collect();
    let t_slow: Vec<f64> = (0..n_show / 5).map(|i| i as f64 / 1000.0).collect();
    line_plot(
        &format!("{out}/fig6_time.svg"),
        "Fig. 6a: standstill error with Controller 2, at 5 kHz and at 1 kHz",
        "time [s]",
        "error [m]",
        &[
            Line {
                label: "5 kHz",
                x: &t_fast,
                y: &c2.fast[..n_show],
                color: GREY,
            },
            Line {
                label: "1 kHz (at the samples)",
                x: &t_slow,
                y: &c2.slow[..n_show / 5],
                color: RED,
            },
        ],
        false,
    )
    .map_err(s)?;
    let nm2 = |v: Vec<f64>| -> Vec<f64> { v.into_iter().map(|x| x * 1e18).collect() };
    // the paper's two controllers (Fig. 7 compares the syntheses)
    let cps_lines: Vec<(String, Vec<f64>, Vec<f64>)> = stand
        .iter()
        .filter(|r| r.name == "controller1" || r.name == "controller2")
        .flat_map(|r| {
            vec![
                // in nm² (plotters finds no ticks on a 1e-17 range)
                (
                    format!("{}, 5 kHz", r.name),
                    r.wf.freq_hz.clone(),
                    nm2(cps(&r.wf)),
                ),
                (
                    format!("{}, 1 kHz", r.name),
                    r.ws.freq_hz.clone(),
                    nm2(cps(&r.ws)),
                ),
            ]
        })
        .collect();
    let colors = [BLUE, GREEN, RED, GREY];
    let lines: Vec<Line<'_>> = cps_lines
        .iter()
        .zip(colors)
        .map(|((l, x, y), c)| Line {
            label: l,
            x,
            y,
            color: c,
        })
        .collect();
    line_plot(
        &format!("{out}/fig6_cps.svg"),
        "Fig. 6b: cumulative power spectra of the standstill errors",
        "frequency [Hz]",
        "CPS [nm²]",
        &lines,
        false,
    )
    .map_err(s)?;
    Ok(["fig6_time.svg", "fig6_cps.svg"])
}

/// Fig. 7: the standstill error's spectrum at 5 kHz (between the samples included) with
/// Controller 1, the single-rate design and the multirate design of the same problem.
pub(super) fn fig7(out: &str, stand: &[Run]) -> Result<&'static str, String> {
    const FILE: &str = "fig7_multirate.svg";
    let shown = [
        ("controller1", "Controller 1 (loopshaping)", BLUE),
        (SINGLE_SAME, "single-rate H∞, same weights", GREY),
        ("controller_multirate", "multirate H∞ (5 kHz model)", GREEN),
    ];
    let mut curves = Vec::new();
    for (name, label, color) in shown {
        let r = stand
            .iter()
            .find(|r| r.name == name)
            .ok_or_else(|| format!("no standstill run of {name}"))?;
        // dB re 1 nm²/Hz, DC left out (a log axis)
        let db: Vec<f64> = r.wf.psd[1..]
            .iter()
            .map(|p| 10.0 * (p * 1e18).max(1e-30).log10())
            .collect();
        curves.push((label, r.wf.freq_hz[1..].to_vec(), db, color));
    }
    let cs: Vec<Curve<'_>> = curves
        .iter()
        .map(|(label, f, db, color)| Curve {
            label,
            freq_hz: f,
            db,
            color: *color,
        })
        .collect();
    magnitude_plot(
        &format!("{out}/{FILE}"),
        "Fig. 7: standstill error PSD at 5 kHz [dB re 1 nm²/Hz]",
        &cs,
        2.0,
        2500.0,
        &[(500.0, "1 kHz Nyquist"), (653.0, "653 Hz")],
    )
    .map_err(s)?;
    Ok(FILE)
}
