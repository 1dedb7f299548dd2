//! The named causes in words (the verdict line of `sdctl diagnose`, the report's summary) and
//! every failed test explained.

use super::*;

/// `x ± s` with the standard error when there is one.
pub(super) fn pm(x: f64, s: Option<f64>, scale: f64, digits: usize) -> String {
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
pub(super) fn fixed(v: f64, d: usize) -> String {
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
pub(super) fn nonlinearity_text(c: &Cause) -> Option<String> {
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
            // a pair moved, but the moving friction corner outweighs it
            // (`sd_diagnose::tracks::corner_dominates`)
            FreqTrend::None
                if *corner_trend != CornerTrend::None
                    && tracks.iter().any(|t| t.frequency_moves)
                    && !tracks.iter().any(|t| t.dominant) =>
            {
                "no mode's frequency trend is named: the moving corner outweighs the tracked \
                 modes' shifts (each in half-power bandwidths, weighted by its share of the \
                 response)"
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
            .unwrap_or_else(|| buried_note(tracks));
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

/// Where no tracked mode moves, the tracked modes buried in distortion at higher levels
/// ([`sd_diagnose::ModeTrack::buried`]): the trend stated is then the amplitude model's.
fn buried_note(tracks: &[sd_diagnose::ModeTrack]) -> String {
    let buried: Vec<String> = tracks
        .iter()
        .filter(|t| !t.buried.is_empty())
        .map(|t| {
            let at: Vec<String> = t.buried.iter().map(|n| format!("`{n}`")).collect();
            format!("{:.3} Hz at {}", t.freq_hz, at.join(", "))
        })
        .collect();
    if buried.is_empty() {
        return String::new();
    }
    format!(
        " (by the amplitude model over every level: the tracked mode(s) at {} are buried in \
         their distortion there, where they would move most)",
        buried.join("; ")
    )
}

/// The sentence of a drift.
pub(super) fn drift_text(experiments: &[String], sign: DriftSign) -> String {
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

/// Why an evidence row failed, and what the failure means beside the verdict.
pub(super) fn explain_failed(d: &Diagnosis, e: &sd_diagnose::Evidence) -> String {
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

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use sd_diagnose::{ModeTrack, TrackPoint};

    fn track(moves: bool, dominant: bool) -> ModeTrack {
        let point = |l: f64, f: f64| TrackPoint {
            experiment: format!("l{l}"),
            relative_level: l,
            freq_hz: f,
            freq_std: 0.01,
            damping: 0.01,
            damping_std: 1e-4,
        };
        ModeTrack {
            freq_hz: 1776.0,
            damping: 0.0138,
            share: 1e-4,
            band_hz: (1700.0, 1850.0),
            frequency_moves: moves,
            damping_moves: false,
            frequency_trend: if moves {
                FreqTrend::Softening
            } else {
                FreqTrend::None
            },
            damping_trend: DampingTrend::None,
            shift_bandwidths: -0.005,
            dominant,
            points: vec![point(1.0, 1776.08), point(4.0, 1775.84)],
            buried: Vec::new(),
        }
    }

    fn cause(tracks: Vec<ModeTrack>, corner: CornerTrend) -> Cause {
        Cause::Nonlinearity {
            relative_levels: [("level_4".to_string(), 4.0)].into_iter().collect(),
            kind: FreqTrend::None,
            damping_trend: DampingTrend::None,
            corner_trend: corner,
            modes: Vec::new(),
            tracks,
            drift_check: DriftCheck::DistortionSeen,
        }
    }

    /// A pair that moved but was outweighed by the friction corner is said so; without a
    /// moving corner, a kind of `none` means no mode moved.
    #[test]
    fn the_corner_outweighing_a_moving_pair_is_said() {
        let t = nonlinearity_text(&cause(vec![track(true, false)], CornerTrend::Falling)).unwrap();
        assert!(t.contains("the moving corner outweighs"), "{t}");
        assert!(t.contains("friction-like"), "{t}");
        let t = nonlinearity_text(&cause(vec![track(false, false)], CornerTrend::None)).unwrap();
        assert!(
            t.contains("no mode's frequency moves beyond its uncertainty"),
            "{t}"
        );
    }
}
