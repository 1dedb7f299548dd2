//! SVG figures with plotters: magnitude plots in dB against frequency in Hz.

use plotters::prelude::*;

/// One curve: label, frequencies (Hz), magnitudes (dB).
pub struct Curve<'a> {
    pub label: &'a str,
    pub freq_hz: &'a [f64],
    pub db: &'a [f64],
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
) -> Result<(), String> {
    let root = SVGBackend::new(path, (900, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
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
        return Err(format!("{title}: nothing to plot"));
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
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("frequency [Hz]")
        .y_desc("magnitude [dB]")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .draw()
        .map_err(|e| e.to_string())?;
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
            .map_err(|e| e.to_string())?
            .label(c.label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    for (f, label) in marks {
        chart
            .draw_series(LineSeries::new(vec![(*f, lo), (*f, hi)], BLACK.mix(0.35)))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(std::iter::once(Text::new(
                label.to_string(),
                (*f * 1.02, hi - 4.0),
                ("sans-serif", 14),
            )))
            .map_err(|e| e.to_string())?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerLeft)
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}
