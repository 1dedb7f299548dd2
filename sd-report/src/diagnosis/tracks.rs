//! The report's table of every physical mode followed over the excitation levels by local fits
//! (`sd_diagnose::tracks`).

use sd_diagnose::{Cause, DampingTrend, Diagnosis, FreqTrend, ModeTrack};
use std::fmt::Write as _;

fn freq_word(t: FreqTrend) -> &'static str {
    match t {
        FreqTrend::Hardening => "rises (hardening)",
        FreqTrend::Softening => "falls (softening)",
        FreqTrend::None => "no trend beyond its errors",
    }
}

fn damping_word(t: DampingTrend) -> &'static str {
    match t {
        DampingTrend::Increasing => "rises",
        DampingTrend::Decreasing => "falls",
        DampingTrend::None => "no trend beyond its errors",
    }
}

/// One moving mode's levels: frequency and damping with their standard errors.
fn points(md: &mut String, t: &ModeTrack) {
    let _ = writeln!(
        md,
        "\nMode at {:.3} Hz{}:\n\n| experiment | level ρ | f [Hz] | ζ |\n|---|---|---|---|",
        t.freq_hz,
        if t.dominant { " (dominant)" } else { "" }
    );
    for p in &t.points {
        let _ = writeln!(
            md,
            "| {} | {:.3} | {:.4} ± {:.4} | {:.5} ± {:.5} |",
            p.experiment, p.relative_level, p.freq_hz, p.freq_std, p.damping, p.damping_std
        );
    }
}

/// Every tracked mode: its trend, its shift in half-power bandwidths, its share; then the
/// levels of each moving one.
pub(super) fn tracks_section(md: &mut String, d: &Diagnosis) {
    for c in &d.causes {
        let Cause::Nonlinearity { tracks, .. } = c else {
            continue;
        };
        if tracks.is_empty() {
            continue;
        }
        let _ = writeln!(
            md,
            "## Every physical mode over the levels\n\nEach mode of the model experiment's \
             physical fit (stabilisation diagram, no pair narrower than the line spacing unless \
             the data demand it) followed at every level by a local fit in its band (one pole \
             pair and an affine background, weighted by the level's noise + distortion \
             variance). A mode moves when its levels differ beyond their standard errors (χ² \
             at the verdict's per-test false-alarm probability); the dominant moving mode — \
             the largest shift in half-power bandwidths times its share of the response — is \
             marked; its frequency and damping trends are the kind and damping trend named \
             above (none when no tracked mode moves). `tracks.svg` shows every mode.\n\n| mode [Hz] | ζ | share | band [Hz] | \
             frequency | damping | shift [bandwidths] |\n|---|---|---|---|---|---|---|"
        );
        for t in tracks {
            let _ = writeln!(
                md,
                "| {:.3}{} | {:.4} | {:.2} | {:.3}–{:.3} | {} | {} | {:+.2} |",
                t.freq_hz,
                if t.dominant { " **dominant**" } else { "" },
                t.damping,
                t.share,
                t.band_hz.0,
                t.band_hz.1,
                if t.frequency_moves {
                    freq_word(t.frequency_trend)
                } else {
                    "does not move"
                },
                if t.damping_moves {
                    damping_word(t.damping_trend)
                } else {
                    "does not move"
                },
                t.shift_bandwidths
            );
        }
        for t in tracks
            .iter()
            .filter(|t| t.frequency_moves || t.damping_moves)
        {
            points(md, t);
        }
        let _ = writeln!(md);
    }
}

/// `tracks.svg`: every tracked mode's frequency shift (% of its frequency at the model
/// experiment) and damping against the relative excitation level, ±2σ; `None` without
/// tracks.
pub(super) fn tracks_figure(dir: &std::path::Path, d: &Diagnosis) -> crate::Result<Option<String>> {
    let Some(tracks) = d.causes.iter().find_map(|c| match c {
        Cause::Nonlinearity { tracks, .. } if !tracks.is_empty() => Some(tracks),
        _ => None,
    }) else {
        return Ok(None);
    };
    let labels: Vec<String> = tracks
        .iter()
        .map(|t| {
            format!(
                "{:.1} Hz{}",
                t.freq_hz,
                if t.dominant { " (dominant)" } else { "" }
            )
        })
        .collect();
    let shift: Vec<Vec<(f64, f64, f64)>> = tracks
        .iter()
        .map(|t| {
            t.points
                .iter()
                .map(|p| {
                    let k = 100.0 / t.freq_hz;
                    (
                        p.relative_level,
                        (p.freq_hz - t.freq_hz) * k,
                        p.freq_std * k,
                    )
                })
                .collect()
        })
        .collect();
    let damping: Vec<Vec<(f64, f64, f64)>> = tracks
        .iter()
        .map(|t| {
            t.points
                .iter()
                .map(|p| (p.relative_level, p.damping, p.damping_std))
                .collect()
        })
        .collect();
    fn view<'a>(
        labels: &'a [String],
        v: &'a [Vec<(f64, f64, f64)>],
    ) -> Vec<crate::plot::PointSeries<'a>> {
        v.iter()
            .zip(labels)
            .map(|(p, l)| crate::plot::PointSeries {
                label: l,
                points: p,
            })
            .collect()
    }
    let name = "tracks.svg".to_string();
    crate::plot::series_plot(
        &dir.join(&name).display().to_string(),
        "Every physical mode over the levels (local fits, ±2σ)",
        "relative excitation level (input rms / the model experiment's)",
        &[
            (
                "frequency shift [% of f at the model experiment]",
                view(&labels, &shift),
            ),
            ("damping ratio ζ [-]", view(&labels, &damping)),
        ],
    )?;
    Ok(Some(name))
}
