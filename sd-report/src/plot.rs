//! SVG figures with plotters: magnitude and Bode plots (dB and degrees against frequency in
//! Hz), line plots and error-bar panels.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

mod bode;
pub use bode::{bode_plot, bode_plot_in, bode_snr_plot_in, unwrap_deg};
/// The colour of a curve (plotters' RGB colour, re-exported so a user needs no plotters dependency).
pub use plotters::style::RGBColor;

/// One curve: label (empty: no legend entry), frequencies (Hz), magnitudes (dB).
pub struct Curve<'a> {
    /// Legend entry.
    pub label: &'a str,
    /// Frequencies (Hz).
    pub freq_hz: &'a [f64],
    /// Magnitudes (dB).
    pub db: &'a [f64],
    /// Colour.
    pub color: RGBColor,
}

/// Magnitude plot with a logarithmic frequency axis; vertical markers at `marks` (Hz, label).
pub fn magnitude_plot(
    path: &str,
    title: &str,
    curves: &[Curve<'_>],
    fmin: f64,
    fmax: f64,
    marks: &[(f64, &str)],
) -> crate::Result<()> {
    if fmax / fmin < 3.0 {
        // a narrow band reads better on a linear axis (a log axis has no ticks there)
        let clipped: Vec<(Vec<f64>, Vec<f64>)> = curves
            .iter()
            .map(|c| {
                c.freq_hz
                    .iter()
                    .zip(c.db)
                    .filter(|(f, _)| **f >= fmin && **f <= fmax)
                    .map(|(f, d)| (*f, *d))
                    .unzip()
            })
            .collect();
        let lines: Vec<Line<'_>> = curves
            .iter()
            .zip(&clipped)
            .map(|(c, (x, y))| Line {
                label: c.label,
                x,
                y,
                color: c.color,
            })
            .collect();
        return line_plot(
            path,
            title,
            "frequency [Hz]",
            "magnitude [dB]",
            &lines,
            false,
        );
    }
    let root = SVGBackend::new(path, (900, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(crate::plot_err)?;
    draw_magnitude(&root, title, curves, (fmin, fmax), marks, "magnitude [dB]")?;
    root.present().map_err(crate::plot_err)?;
    Ok(())
}

/// The magnitude panel of [`magnitude_plot`] and [`bode_plot`].
pub(crate) fn draw_magnitude<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    curves: &[Curve<'_>],
    (fmin, fmax): (f64, f64),
    marks: &[(f64, &str)],
    y_desc: &str,
) -> crate::Result<()> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for c in curves {
        for (f, d) in c.freq_hz.iter().zip(c.db) {
            if *f >= fmin && *f <= fmax && d.is_finite() {
                lo = lo.min(*d);
                hi = hi.max(*d);
            }
        }
    }
    if !lo.is_finite() {
        return Err(crate::ReportError::Plot(format!(
            "{title}: nothing to plot"
        )));
    }
    let (lo, hi) = db_range(lo, hi);
    // the legend in a strip right of the axes, never over the data
    let titled = root
        .titled(title, ("sans-serif", 20))
        .map_err(crate::plot_err)?;
    let (plot_area, strip) = split_strip(&titled);
    let entries: Vec<(&str, RGBColor)> = curves
        .iter()
        .filter(|c| !c.label.is_empty())
        .map(|c| (c.label, c.color))
        .collect();
    legend_strip(&strip, &entries)?;
    let mut chart = freq_chart(&plot_area, (fmin, fmax), (lo, hi), (y_desc, 10))?;
    for c in curves {
        let pts: Vec<(f64, f64)> = c
            .freq_hz
            .iter()
            .zip(c.db)
            .filter(|(f, d)| **f >= fmin && **f <= fmax && d.is_finite())
            .map(|(f, d)| (*f, *d))
            .collect();
        chart
            .draw_series(LineSeries::new(pts, c.color.stroke_width(2)))
            .map_err(crate::plot_err)?;
    }
    for (i, (f, label)) in marks.iter().enumerate() {
        chart
            .draw_series(LineSeries::new(vec![(*f, lo), (*f, hi)], BLACK.mix(0.35)))
            .map_err(crate::plot_err)?;
        // a label in the right third of the axis is written to the left of its line (inside
        // the figure); every second label a line lower, so that neighbours do not overlap
        let right = (f / fmin).ln() > 0.66 * (fmax / fmin).ln();
        let (x, anchor) = if right {
            (*f / 1.02, HPos::Right)
        } else {
            (*f * 1.02, HPos::Left)
        };
        let y = hi - 4.0 - 0.05 * (hi - lo) * (i % 2) as f64;
        let style = ("sans-serif", 14)
            .into_text_style(root)
            .pos(Pos::new(anchor, VPos::Top));
        chart
            .draw_series(std::iter::once(Text::new(label.to_string(), (x, y), style)))
            .map_err(crate::plot_err)?;
    }
    Ok(())
}

/// Width (pixels) of the legend strip right of a magnitude panel.
pub(crate) const LEGEND_WIDTH: u32 = 230;

/// A legend drawn in its own strip (a line sample and the label, wrapped at 30 characters),
/// so that it never covers the data.
pub(crate) fn legend_strip<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    entries: &[(&str, RGBColor)],
) -> crate::Result<()> {
    let mut y = 16i32;
    for (label, color) in entries {
        area.draw(&PathElement::new(
            vec![(6, y + 7), (30, y + 7)],
            color.stroke_width(3),
        ))
        .map_err(crate::plot_err)?;
        for line in wrap(label, 30) {
            area.draw(&Text::new(line, (36, y), ("sans-serif", 13)))
                .map_err(crate::plot_err)?;
            y += 16;
        }
        y += 6;
    }
    Ok(())
}

/// An area split into its plotting part and the legend strip on its right.
pub(crate) fn split_strip<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
) -> (
    DrawingArea<DB, plotters::coord::Shift>,
    DrawingArea<DB, plotters::coord::Shift>,
) {
    let width = area.dim_in_pixel().0;
    area.split_horizontally(width.saturating_sub(LEGEND_WIDTH))
}

/// A panel's axes: logarithmic frequency (Hz) over `(fmin, fmax)`, ordinate `(lo, hi)` described
/// by `y_desc` with about `y_labels` labels, the mesh drawn (the magnitude, phase and SNR panels).
pub(crate) fn freq_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, plotters::coord::Shift>,
    (fmin, fmax): (f64, f64),
    (lo, hi): (f64, f64),
    (y_desc, y_labels): (&str, usize),
) -> crate::Result<
    ChartContext<'a, DB, Cartesian2d<LogCoord<f64>, plotters::coord::types::RangedCoordf64>>,
> {
    let mut chart = ChartBuilder::on(area)
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d((fmin..fmax).log_scale(), lo..hi)
        .map_err(crate::plot_err)?;
    chart
        .configure_mesh()
        .x_desc("frequency [Hz]")
        .y_desc(y_desc)
        .y_labels(y_labels)
        .x_label_formatter(&|v| format!("{v:.0}"))
        .draw()
        .map_err(crate::plot_err)?;
    Ok(chart)
}

/// A dB range widened to whole 10 dB steps with 5 dB to spare.
pub(crate) fn db_range(lo: f64, hi: f64) -> (f64, f64) {
    (
        (lo / 10.0).floor() * 10.0 - 5.0,
        (hi / 10.0).ceil() * 10.0 + 5.0,
    )
}

/// `text` broken at spaces into lines of at most `width` characters (a longer word alone).
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for word in text.split(' ') {
        match lines.last_mut() {
            Some(l) if l.chars().count() + 1 + word.chars().count() <= width => {
                l.push(' ');
                l.push_str(word);
            }
            _ => lines.push(word.to_string()),
        }
    }
    lines
}

/// One curve of a generic line plot.
pub struct Line<'a> {
    /// Legend entry.
    pub label: &'a str,
    /// Abscissae.
    pub x: &'a [f64],
    /// Ordinates.
    pub y: &'a [f64],
    /// Colour.
    pub color: RGBColor,
}

/// A line plot with linear axes (or a logarithmic x axis when `xlog`).
pub fn line_plot(
    path: &str,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    lines: &[Line<'_>],
    xlog: bool,
) -> crate::Result<()> {
    line_plot_in(path, (title, x_desc, y_desc), lines, xlog, false)
}

/// A line plot of a complex-plane figure: linear axes of equal scale on a square canvas (a
/// circle stays round).
pub fn plane_plot(
    path: &str,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    lines: &[Line<'_>],
) -> crate::Result<()> {
    line_plot_in(path, (title, x_desc, y_desc), lines, false, true)
}

fn line_plot_in(
    path: &str,
    (title, x_desc, y_desc): (&str, &str, &str),
    lines: &[Line<'_>],
    xlog: bool,
    equal: bool,
) -> crate::Result<()> {
    let size = if equal {
        (760 + LEGEND_WIDTH, 760)
    } else {
        (900, 560)
    };
    let root = SVGBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(crate::plot_err)?;
    let finite = |v: &f64| v.is_finite();
    let xs = lines
        .iter()
        .flat_map(|l| l.x.iter().cloned())
        .filter(|v| finite(v) && (!xlog || *v > 0.0));
    let (xmin, xmax) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |a, v| {
        (a.0.min(v), a.1.max(v))
    });
    let ys = lines
        .iter()
        .flat_map(|l| l.y.iter().cloned())
        .filter(finite);
    let (ymin, ymax) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |a, v| {
        (a.0.min(v), a.1.max(v))
    });
    if !(xmin.is_finite() && ymin.is_finite()) || xmax <= xmin {
        return Err(crate::ReportError::Plot(format!(
            "{title}: nothing to plot"
        )));
    }
    let pad = 0.05 * (ymax - ymin).abs().max(1e-300);
    let (mut ylo, mut yhi) = (ymin - pad, ymax + pad);
    let (mut xmin, mut xmax) = (xmin, xmax);
    if equal {
        // one span for both axes, centred on the data
        let span = 1.1 * (xmax - xmin).max(ymax - ymin).max(1e-300);
        let (cx, cy) = (0.5 * (xmin + xmax), 0.5 * (ymin + ymax));
        (xmin, xmax, ylo, yhi) = (
            cx - span / 2.0,
            cx + span / 2.0,
            cy - span / 2.0,
            cy + span / 2.0,
        );
    }
    // the title across the figure, the legend in a strip right of the axes (off the data)
    let titled = root
        .titled(title, ("sans-serif", 20))
        .map_err(crate::plot_err)?;
    let (plot_area, strip) = split_strip(&titled);
    let entries: Vec<(&str, RGBColor)> = lines
        .iter()
        .filter(|l| !l.label.is_empty())
        .map(|l| (l.label, l.color))
        .collect();
    legend_strip(&strip, &entries)?;
    let mut builder = ChartBuilder::on(&plot_area);
    builder
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(80);
    macro_rules! draw {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart
                .configure_mesh()
                .x_desc(x_desc)
                .y_desc(y_desc)
                .y_label_formatter(&|v| {
                    if *v == 0.0 || (v.abs() >= 1e-3 && v.abs() < 1e4) {
                        format!("{v:.1}")
                    } else {
                        format!("{v:.1e}")
                    }
                })
                .draw()
                .map_err(crate::plot_err)?;
            for l in lines {
                let pts: Vec<(f64, f64)> =
                    l.x.iter()
                        .zip(l.y)
                        .filter(|(x, y)| x.is_finite() && y.is_finite() && (!xlog || **x > 0.0))
                        .map(|(x, y)| (*x, *y))
                        .collect();
                chart
                    .draw_series(LineSeries::new(pts, l.color.stroke_width(2)))
                    .map_err(crate::plot_err)?;
            }
        }};
    }
    if xlog {
        draw!(builder
            .build_cartesian_2d((xmin..xmax).log_scale(), ylo..yhi)
            .map_err(crate::plot_err)?);
    } else {
        draw!(builder
            .build_cartesian_2d(xmin..xmax, ylo..yhi)
            .map_err(crate::plot_err)?);
    }
    root.present().map_err(crate::plot_err)?;
    Ok(())
}

/// Measured points with ±2σ error bars, a fitted curve and its ±2σ band, in one panel.
pub struct ErrorBarPanel<'a> {
    /// Ordinate description (with unit).
    pub y_desc: &'a str,
    /// Measured points: abscissa, value, standard error (a non-finite error draws no bar).
    pub points: &'a [(f64, f64, f64)],
    /// Fitted curve: abscissa, value, standard error.
    pub curve: &'a [(f64, f64, f64)],
    /// Predictions of left-out points: abscissa, value (drawn as hollow squares).
    pub predicted: &'a [(f64, f64)],
}

/// Panels stacked vertically over one logarithmic abscissa `x_desc` (each with its own
/// ordinate): measured points with error bars, the fitted curve with its band, left-out
/// predictions.
pub fn error_bar_plot(
    path: &str,
    title: &str,
    x_desc: &str,
    panels: &[ErrorBarPanel<'_>],
) -> crate::Result<()> {
    stacked(path, title, panels.len(), |area, k| {
        error_bar_panel(area, x_desc, &panels[k])
    })
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

/// `n` panels stacked vertically under `title` in one SVG, each drawn by `draw(area, k)`.
fn stacked(
    path: &str,
    title: &str,
    n: usize,
    draw: impl Fn(&Area<'_>, usize) -> crate::Result<()>,
) -> crate::Result<()> {
    let root = SVGBackend::new(path, (900, 360 * n.max(1) as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(crate::plot_err)?;
    let root = root
        .titled(title, ("sans-serif", 22))
        .map_err(crate::plot_err)?;
    for (k, area) in root.split_evenly((n.max(1), 1)).iter().enumerate().take(n) {
        draw(area, k)?;
    }
    root.present().map_err(crate::plot_err)?;
    Ok(())
}

/// A value and its ±2σ bounds (no bar for a non-finite σ).
fn two_sigma(q: &(f64, f64, f64)) -> [f64; 2] {
    let s = if q.2.is_finite() { 2.0 * q.2 } else { 0.0 };
    [q.1 - s, q.1 + s]
}

/// A panel's chart: logarithmic abscissa over `(x0, x1)`, ordinate `(y0, y1)`, its mesh drawn.
fn log_x_chart<'a, 'b>(
    area: &'a Area<'b>,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    (x_desc, y_desc): (&str, &str),
) -> crate::Result<
    ChartContext<
        'a,
        SVGBackend<'b>,
        Cartesian2d<LogCoord<f64>, plotters::coord::types::RangedCoordf64>,
    >,
> {
    let mut chart = ChartBuilder::on(area)
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(90)
        .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
        .map_err(crate::plot_err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .y_label_formatter(&|v| {
            if v.abs() >= 0.1 && v.abs() < 1e5 {
                format!("{v:.2}")
            } else {
                format!("{v:.2e}")
            }
        })
        .draw()
        .map_err(crate::plot_err)?;
    Ok(chart)
}

/// The range of `v` padded by 8 % (and a tiny absolute amount for a constant).
fn padded(v: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, x| {
            (a.0.min(x), a.1.max(x))
        });
    if !lo.is_finite() {
        return None;
    }
    let pad = 0.08 * (hi - lo).max(1e-9 * hi.abs().max(1e-300));
    Some((lo - pad, hi + pad))
}

fn error_bar_panel(area: &Area<'_>, x_desc: &str, p: &ErrorBarPanel<'_>) -> crate::Result<()> {
    let xs = p
        .points
        .iter()
        .map(|q| q.0)
        .chain(p.curve.iter().map(|q| q.0))
        .filter(|x| *x > 0.0);
    let Some((x0, x1)) = padded(xs.map(f64::ln)) else {
        return Err(crate::ReportError::Plot(format!(
            "{}: nothing to plot",
            p.y_desc
        )));
    };
    let bar = two_sigma;
    let ys = p
        .points
        .iter()
        .flat_map(bar)
        .chain(p.curve.iter().flat_map(bar))
        .chain(p.predicted.iter().map(|q| q.1));
    let (y0, y1) = padded(ys).unwrap_or((0.0, 1.0));
    let blue = RGBColor(31, 119, 180);
    let red = RGBColor(214, 39, 40);
    let (plot_area, strip) = split_strip(area);
    legend_strip(
        &strip,
        &[
            ("fitted trend ± 2σ", blue),
            ("measured (each experiment) ± 2σ", BLACK),
            ("predicted with that experiment left out", red),
        ],
    )?;
    let mut chart = log_x_chart(
        &plot_area,
        (x0.exp(), x1.exp()),
        (y0, y1),
        (x_desc, p.y_desc),
    )?;
    let lo: Vec<(f64, f64)> = p.curve.iter().map(|q| (q.0, bar(q)[0])).collect();
    let hi: Vec<(f64, f64)> = p.curve.iter().rev().map(|q| (q.0, bar(q)[1])).collect();
    chart
        .draw_series(std::iter::once(Polygon::new(
            lo.into_iter().chain(hi).collect::<Vec<_>>(),
            blue.mix(0.15).filled(),
        )))
        .map_err(crate::plot_err)?;
    chart
        .draw_series(LineSeries::new(
            p.curve.iter().map(|q| (q.0, q.1)),
            blue.stroke_width(2),
        ))
        .map_err(crate::plot_err)?;
    chart
        .draw_series(p.points.iter().map(|q| {
            let [a, b] = bar(q);
            ErrorBar::new_vertical(q.0, a, q.1, b, BLACK.filled(), 8)
        }))
        .map_err(crate::plot_err)?;
    chart
        .draw_series(p.predicted.iter().map(|q| {
            EmptyElement::at((q.0, q.1)) + Rectangle::new([(-5, -5), (5, 5)], red.stroke_width(2))
        }))
        .map_err(crate::plot_err)?;
    Ok(())
}

/// One series of measured points with standard errors (joined in abscissa order).
pub struct PointSeries<'a> {
    /// Legend entry.
    pub label: &'a str,
    /// Abscissa, value, standard error (a non-finite error draws no bar).
    pub points: &'a [(f64, f64, f64)],
}

/// Panels stacked vertically over one logarithmic abscissa `x_desc`, each with its ordinate
/// description and several series of points with ±2σ error bars, one colour per series (the
/// same series index, the same colour, in every panel).
pub fn series_plot(
    path: &str,
    title: &str,
    x_desc: &str,
    panels: &[(&str, Vec<PointSeries<'_>>)],
) -> crate::Result<()> {
    stacked(path, title, panels.len(), |area, k| {
        series_panel(area, x_desc, panels[k].0, &panels[k].1)
    })
}

fn series_panel(
    area: &Area<'_>,
    x_desc: &str,
    y_desc: &str,
    series: &[PointSeries<'_>],
) -> crate::Result<()> {
    let bar = two_sigma;
    let all = || series.iter().flat_map(|s| s.points.iter());
    let Some((x0, x1)) = padded(all().map(|q| q.0).filter(|x| *x > 0.0).map(f64::ln)) else {
        return Err(crate::ReportError::Plot(format!(
            "{y_desc}: nothing to plot"
        )));
    };
    let (y0, y1) = padded(all().flat_map(bar)).unwrap_or((0.0, 1.0));
    let color = |k: usize| {
        let c = Palette99::pick(k).to_rgba();
        RGBColor(c.0, c.1, c.2)
    };
    let entries: Vec<(&str, RGBColor)> = series
        .iter()
        .enumerate()
        .map(|(k, s)| (s.label, color(k)))
        .collect();
    let (plot_area, strip) = split_strip(area);
    legend_strip(&strip, &entries)?;
    let mut chart = log_x_chart(&plot_area, (x0.exp(), x1.exp()), (y0, y1), (x_desc, y_desc))?;
    for (k, s) in series.iter().enumerate() {
        let c = Palette99::pick(k).to_rgba();
        let mut pts: Vec<(f64, f64, f64)> = s.points.to_vec();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|q| (q.0, q.1)),
                c.stroke_width(1),
            ))
            .map_err(crate::plot_err)?;
        chart
            .draw_series(pts.iter().map(|q| {
                let [a, b] = bar(q);
                ErrorBar::new_vertical(q.0, a, q.1, b, c.filled(), 8)
            }))
            .map_err(crate::plot_err)?;
    }
    Ok(())
}

#[cfg(test)]
mod unwrap_tests {
    use super::unwrap_deg;

    /// A phase that falls steadily through −180° (a resonance and a delay) comes back
    /// continuous; NaN points are skipped over.
    #[test]
    fn a_falling_phase_runs_on_past_minus_180() {
        let truth: Vec<f64> = (0..200).map(|k| -3.0 * k as f64).collect();
        // the branch: the first value in (−300°, 60°]
        assert_eq!(unwrap_deg(&[120.0, 100.0])[0], -240.0);
        assert_eq!(unwrap_deg(&[-400.0])[0], -40.0);
        assert_eq!(unwrap_deg(&[60.0])[0], 60.0);
        let wrapped: Vec<f64> = truth
            .iter()
            .map(|p| (p + 180.0).rem_euclid(360.0) - 180.0)
            .collect();
        let mut w = wrapped.clone();
        w[50] = f64::NAN;
        let u = unwrap_deg(&w);
        for (k, (a, b)) in u.iter().zip(&truth).enumerate() {
            if k != 50 {
                assert!((a - b).abs() < 1e-9, "{k}: {a} vs {b}");
            }
        }
    }
}
