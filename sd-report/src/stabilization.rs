//! The stabilisation chart of experimental modal analysis: each fitted order's poles at their
//! natural frequency (x, Hz) and order (left axis), marked by their class against the order
//! below, over the measured FRF's magnitude (right axis, dB). No toolkit types: plain slices.

use plotters::prelude::*;

/// A pole's class on the chart (the order below has a pole of the same frequency and damping,
/// of the same frequency only, or none alike).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// Frequency and damping stable.
    Stable,
    /// Frequency stable.
    Frequency,
    /// New.
    New,
}

/// What the chart shows.
pub struct StabilizationChart<'a> {
    /// Title.
    pub title: &'a str,
    /// Measured lines (Hz).
    pub freq_hz: &'a [f64],
    /// Their magnitude (dB) and its unit, e.g. "dB re 1 rad/A".
    pub db: (&'a [f64], &'a str),
    /// Poles: frequency (Hz), order, class.
    pub poles: &'a [(f64, usize, Mark)],
    /// The chosen order (drawn as a dashed line).
    pub chosen: usize,
}

/// Draws the chart as SVG at `path`.
///
/// # Errors
/// No line or no finite magnitude; the file cannot be written.
pub fn stabilization_chart(path: &str, c: &StabilizationChart<'_>) -> crate::Result<()> {
    let (db, unit) = c.db;
    let fin: Vec<(f64, f64)> = c
        .freq_hz
        .iter()
        .zip(db)
        .filter(|(f, d)| f.is_finite() && d.is_finite())
        .map(|(f, d)| (*f, *d))
        .collect();
    let (Some(first), Some(last)) = (fin.first(), fin.last()) else {
        return Err(crate::ReportError::Plot(format!(
            "{}: nothing to plot",
            c.title
        )));
    };
    let (flo, fhi) = (first.0, last.0.max(first.0 * 1.001 + 1e-9));
    let (dlo, dhi) = fin.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
        (a.0.min(p.1), a.1.max(p.1))
    });
    let pad = 0.05 * (dhi - dlo).max(1.0);
    let max_order = c.poles.iter().map(|p| p.1).max().unwrap_or(2).max(c.chosen) + 2;
    let root = SVGBackend::new(path, (1000 + crate::plot::LEGEND_WIDTH, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(crate::plot_err)?;
    // the title across the figure, the legend in a strip right of the axes (off the data)
    let titled = root
        .titled(c.title, ("sans-serif", 20))
        .map_err(crate::plot_err)?;
    let (plot_area, strip) = titled.split_horizontally(1000);
    let styles = [
        (
            Mark::Stable,
            "stable (frequency and damping)",
            RGBColor(0, 140, 60),
            true,
        ),
        (
            Mark::Frequency,
            "frequency stable",
            RGBColor(30, 90, 200),
            false,
        ),
        (Mark::New, "new", RGBColor(200, 40, 40), false),
    ];
    let chosen_label = format!("chosen order {}", c.chosen);
    let mut entries = vec![
        ("measured |G| (right axis)", RGBColor(150, 150, 150)),
        (chosen_label.as_str(), BLACK),
    ];
    entries.extend(styles.iter().map(|s| (s.1, s.2)));
    crate::plot::legend_strip(&strip, &entries)?;
    let mut chart = ChartBuilder::on(&plot_area)
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .right_y_label_area_size(70)
        .build_cartesian_2d(flo..fhi, 0f64..max_order as f64)
        .map_err(crate::plot_err)?
        .set_secondary_coord(flo..fhi, (dlo - pad)..(dhi + pad));
    chart
        .configure_mesh()
        .x_desc("frequency [Hz]")
        .y_desc("model order (states)")
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(crate::plot_err)?;
    chart
        .configure_secondary_axes()
        .y_desc(format!("|G| [{unit}]"))
        .draw()
        .map_err(crate::plot_err)?;
    let grey = RGBColor(150, 150, 150);
    chart
        .draw_secondary_series(LineSeries::new(fin.iter().cloned(), grey.stroke_width(2)))
        .map_err(crate::plot_err)?;
    let chosen = c.chosen as f64;
    chart
        .draw_series(DashedLineSeries::new(
            [(flo, chosen), (fhi, chosen)],
            6,
            4,
            BLACK.stroke_width(1),
        ))
        .map_err(crate::plot_err)?;
    for (mark, _, color, filled) in styles {
        let pts: Vec<(f64, f64)> = c
            .poles
            .iter()
            .filter(|p| p.2 == mark && p.0 >= flo && p.0 <= fhi)
            .map(|p| (p.0, p.1 as f64))
            .collect();
        let style = if filled {
            color.filled()
        } else {
            color.stroke_width(1)
        };
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 4, style)))
            .map_err(crate::plot_err)?;
    }
    root.present().map_err(crate::plot_err)?;
    Ok(())
}
