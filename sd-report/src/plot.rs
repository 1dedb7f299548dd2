//! SVG figures with plotters: magnitude plots in dB against frequency in Hz.

use plotters::prelude::*;

/// One curve: label, frequencies (Hz), magnitudes (dB).
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
    let (lo, hi) = (
        (lo / 10.0).floor() * 10.0 - 5.0,
        (hi / 10.0).ceil() * 10.0 + 5.0,
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d((fmin..fmax).log_scale(), lo..hi)
        .map_err(crate::plot_err)?;
    chart
        .configure_mesh()
        .x_desc("frequency [Hz]")
        .y_desc("magnitude [dB]")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .draw()
        .map_err(crate::plot_err)?;
    for c in curves {
        let pts: Vec<(f64, f64)> = c
            .freq_hz
            .iter()
            .zip(c.db)
            .filter(|(f, d)| **f >= fmin && **f <= fmax && d.is_finite())
            .map(|(f, d)| (*f, *d))
            .collect();
        let color = c.color;
        chart
            .draw_series(LineSeries::new(pts, color.stroke_width(2)))
            .map_err(crate::plot_err)?
            .label(c.label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    for (f, label) in marks {
        chart
            .draw_series(LineSeries::new(vec![(*f, lo), (*f, hi)], BLACK.mix(0.35)))
            .map_err(crate::plot_err)?;
        chart
            .draw_series(std::iter::once(Text::new(
                label.to_string(),
                (*f * 1.02, hi - 4.0),
                ("sans-serif", 14),
            )))
            .map_err(crate::plot_err)?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerLeft)
        .draw()
        .map_err(crate::plot_err)?;
    root.present().map_err(crate::plot_err)?;
    Ok(())
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
    let root = SVGBackend::new(path, (900, 560)).into_drawing_area();
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
    let (ylo, yhi) = (ymin - pad, ymax + pad);
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(title, ("sans-serif", 22))
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
                let color = l.color;
                chart
                    .draw_series(LineSeries::new(pts, color.stroke_width(2)))
                    .map_err(crate::plot_err)?
                    .label(l.label)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                    });
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperLeft)
                .draw()
                .map_err(crate::plot_err)?;
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
