//! Bode figures: magnitude, unwrapped phase and, for measured FRFs, the per-line SNR, on one
//! logarithmic frequency axis with the legend in a strip on the right.

use super::{db_range, draw_magnitude, freq_chart, magnitude_plot, split_strip, Curve};
use plotters::prelude::*;

/// Bode plot: magnitude (dB) above, phase (degrees, unwrapped) below, on one logarithmic
/// frequency axis; `phase_deg[i]` is curve `i`'s phase (`None` for curves without one, such as
/// a noise level). A band narrower than a factor 3 falls back to [`magnitude_plot`] (a log axis
/// has no ticks there).
///
/// # Errors
/// Nothing finite to plot; the file cannot be written.
pub fn bode_plot(
    path: &str,
    title: &str,
    curves: &[Curve<'_>],
    phase_deg: &[Option<&[f64]>],
    fmin: f64,
    fmax: f64,
    marks: &[(f64, &str)],
) -> crate::Result<()> {
    bode_plot_in(path, title, curves, phase_deg, (fmin, fmax), marks, "")
}

/// The phase unwrapped: a jump of more than 180° between neighbouring points is taken as a
/// wrap and removed (multiples of 360°), so the curve runs continuously; non-finite points
/// are kept and skipped over. The branch is the one whose first finite value lies in
/// (−300°, 60°]: an integrator starts at −90°, a double integrator at −180°, a PID around a
/// double integrator at −270° + its lead, as a control engineer reads them.
pub fn unwrap_deg(phase_deg: &[f64]) -> Vec<f64> {
    let mut out = unwrap_continuous(phase_deg);
    if let Some(first) = out.iter().copied().find(|p| p.is_finite()) {
        let k = ((first - 60.0) / 360.0).ceil();
        for p in &mut out {
            *p -= 360.0 * k;
        }
    }
    out
}

/// [`unwrap_deg`] before the branch is chosen.
fn unwrap_continuous(phase_deg: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(phase_deg.len());
    let (mut shift, mut last) = (0.0f64, None::<f64>);
    for &p in phase_deg {
        if !p.is_finite() {
            out.push(p);
            continue;
        }
        if let Some(q) = last {
            shift -= 360.0 * ((p + shift - q) / 360.0).round();
        }
        last = Some(p + shift);
        out.push(p + shift);
    }
    out
}

/// [`bode_plot`] with the magnitude's unit named on its axis (`dB re 1 unit`; empty: `dB`).
///
/// # Errors
/// As [`bode_plot`].
pub fn bode_plot_in(
    path: &str,
    title: &str,
    curves: &[Curve<'_>],
    phase_deg: &[Option<&[f64]>],
    band: (f64, f64),
    marks: &[(f64, &str)],
    unit: &str,
) -> crate::Result<()> {
    bode_snr_plot_in(path, title, (curves, phase_deg), &[], band, marks, unit)
}

/// A Bode figure with a third panel below the phase: the per-line signal-to-noise ratio of
/// measured FRFs, `|Ĝ|/σ_Ĝ` in dB (`snr`: one curve per FRF; empty: no third panel). 0 dB
/// is a line where the estimate is as large as its own standard deviation; an FRF is read
/// with confidence where this stays well above 20 dB.
///
/// # Errors
/// As [`bode_plot`].
pub fn bode_snr_plot_in(
    path: &str,
    title: &str,
    (curves, phase_deg): (&[Curve<'_>], &[Option<&[f64]>]),
    snr: &[Curve<'_>],
    (fmin, fmax): (f64, f64),
    marks: &[(f64, &str)],
    unit: &str,
) -> crate::Result<()> {
    if fmax / fmin < 3.0 {
        return magnitude_plot(path, title, curves, fmin, fmax, marks);
    }
    let height = if snr.is_empty() { 780 } else { 980 };
    let root = SVGBackend::new(path, (900, height)).into_drawing_area();
    root.fill(&WHITE).map_err(crate::plot_err)?;
    let (top, rest) = root.split_vertically(520);
    let y = if unit.is_empty() {
        "magnitude [dB]".to_string()
    } else {
        format!("magnitude [dB re 1 {unit}]")
    };
    draw_magnitude(&top, title, curves, (fmin, fmax), marks, &y)?;
    let (phase_area, snr_area) = rest.split_vertically(260);
    draw_phase(&phase_area, curves, phase_deg, (fmin, fmax))?;
    if !snr.is_empty() {
        draw_snr(&snr_area, snr, (fmin, fmax))?;
    }
    root.present().map_err(crate::plot_err)?;
    Ok(())
}

/// The phase panel: each curve's phase unwrapped ([`unwrap_deg`]), on a 45°-aligned axis.
fn draw_phase<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    curves: &[Curve<'_>],
    phase_deg: &[Option<&[f64]>],
    (fmin, fmax): (f64, f64),
) -> crate::Result<()> {
    let in_band = |c: &Curve<'_>, ph: &[f64]| -> Vec<(f64, f64)> {
        c.freq_hz
            .iter()
            .zip(unwrap_deg(ph))
            .filter(|(f, p)| **f >= fmin && **f <= fmax && p.is_finite())
            .map(|(f, p)| (*f, p))
            .collect()
    };
    let mut phases: Vec<Vec<(f64, f64)>> = curves
        .iter()
        .zip(phase_deg)
        .map(|(c, ph)| ph.map_or_else(Vec::new, |ph| in_band(c, ph)))
        .collect();
    align_branches(&mut phases);
    let (lo, hi) = phases
        .iter()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (_, p)| {
            (lo.min(*p), hi.max(*p))
        });
    let (lo, hi) = if lo.is_finite() {
        (
            (lo / 45.0).floor() * 45.0 - 15.0,
            (hi / 45.0).ceil() * 45.0 + 15.0,
        )
    } else {
        (-180.0, 180.0)
    };
    // the plotting part left of the legend strip: every panel's frequency axis lines up
    let (plot_area, _) = split_strip(area);
    let mut chart = freq_chart(&plot_area, (fmin, fmax), (lo, hi), ("phase [°]", 9))?;
    for (c, pts) in curves.iter().zip(phases) {
        if pts.len() > 1 {
            chart
                .draw_series(LineSeries::new(pts, c.color.stroke_width(2)))
                .map_err(crate::plot_err)?;
        }
    }
    Ok(())
}

/// Every phase curve moved by the whole turns that bring it nearest the first curve (the
/// median difference over the frequencies both cover, the first curve read at its nearest
/// point): overlays of one plant — a model and its noisy measurement, whose lowest lines may
/// start the unwrapping on another branch — are drawn on one branch.
fn align_branches(phases: &mut [Vec<(f64, f64)>]) {
    let Some(r) = phases.iter().position(|p| p.len() > 1) else {
        return;
    };
    let reference = phases[r].clone();
    for (i, p) in phases.iter_mut().enumerate() {
        if i == r || p.is_empty() {
            continue;
        }
        let mut d: Vec<f64> = p
            .iter()
            .filter(|(f, _)| *f >= reference[0].0 && *f <= reference[reference.len() - 1].0)
            .map(|(f, ph)| {
                let j = reference
                    .partition_point(|q| q.0 < *f)
                    .min(reference.len() - 1);
                let j = if j > 0 && (reference[j - 1].0 - f).abs() < (reference[j].0 - f).abs() {
                    j - 1
                } else {
                    j
                };
                reference[j].1 - ph
            })
            .collect();
        if d.is_empty() {
            continue;
        }
        d.sort_by(f64::total_cmp);
        let k = (d[d.len() / 2] / 360.0).round();
        for q in p.iter_mut() {
            q.1 += 360.0 * k;
        }
    }
}

/// The SNR panel (dB), with its reference lines at 0 and 20 dB.
fn draw_snr<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    snr: &[Curve<'_>],
    (fmin, fmax): (f64, f64),
) -> crate::Result<()> {
    let pts: Vec<Vec<(f64, f64)>> = snr
        .iter()
        .map(|c| {
            c.freq_hz
                .iter()
                .zip(c.db)
                .filter(|(f, d)| **f >= fmin && **f <= fmax && d.is_finite())
                .map(|(f, d)| (*f, *d))
                .collect()
        })
        .collect();
    let hi = pts.iter().flatten().map(|p| p.1).fold(20.0f64, f64::max);
    let lo = pts.iter().flatten().map(|p| p.1).fold(0.0f64, f64::min);
    let (lo, hi) = db_range(lo, hi);
    let (plot_area, _) = split_strip(area);
    let mut chart = freq_chart(&plot_area, (fmin, fmax), (lo, hi), ("SNR |Ĝ|/σ [dB]", 10))?;
    for level in [0.0, 20.0] {
        chart
            .draw_series(LineSeries::new(
                vec![(fmin, level), (fmax, level)],
                BLACK.mix(0.35),
            ))
            .map_err(crate::plot_err)?;
    }
    for (c, p) in snr.iter().zip(pts) {
        chart
            .draw_series(LineSeries::new(p, c.color.stroke_width(1)))
            .map_err(crate::plot_err)?;
    }
    Ok(())
}
