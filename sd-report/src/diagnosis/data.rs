//! The data's side of the report: how the records were used, the best linear
//! approximation's noise and distortion per band, and what the model's misfit on its own
//! experiment is.

use sd_diagnose::{Diagnosis, ExperimentReport};
use std::fmt::Write as _;

/// How the model experiment's distortion was measured, as a phrase.
fn model_distortion(d: &Diagnosis) -> String {
    d.experiments
        .iter()
        .find(|x| x.role == sd_diagnose::Role::Model)
        .and_then(|x| x.bla.as_ref())
        .map_or_else(
            || "distortion not measured".to_string(),
            |b| b.distortion.to_string(),
        )
}

/// One experiment's best linear approximation: how the distortion was measured and its noise
/// and distortion per band (standard deviations relative to |Ĝ|, in dB).
fn bla_rows(md: &mut String, x: &ExperimentReport) {
    let Some(b) = &x.bla else { return };
    let _ = writeln!(md, "`{}`: {}.\n", x.name, b.distortion);
    let _ = writeln!(
        md,
        "| band [Hz] | lines | noise σ/\\|Ĝ\\| [dB] | distortion σ/\\|Ĝ\\| [dB] |\n|---|---|---|---|"
    );
    let db = |r: f64| 20.0 * r.max(1e-300).log10();
    for band in &b.bands {
        let dist = match (band.distortion_rel, &b.distortion) {
            (Some(r), _) => format!("{:.1}", db(r)),
            (None, sd_diagnose::Distortion::InLpmResidual) => "in the noise column".into(),
            (None, _) => "not measurable".into(),
        };
        let _ = writeln!(
            md,
            "| {:.3}–{:.3} | {} | {:.1} | {dist} |",
            band.f_lo,
            band.f_hi,
            band.lines,
            db(band.noise_rel)
        );
    }
    let _ = writeln!(md);
}

/// The best linear approximation of every experiment: the variance the statistic uses is the
/// noise plus the stochastic nonlinear distortion wherever the data measure it.
pub(super) fn bla_section(md: &mut String, d: &Diagnosis) {
    if d.experiments.iter().all(|x| x.bla.is_none()) {
        return;
    }
    let _ = writeln!(
        md,
        "## Noise and nonlinear distortion\n\nThe statistic's variance is the noise plus the \
         stochastic nonlinear distortion wherever the data measure it (odd multisines' \
         non-excited lines, several realisations, a full random-phase multisine's roughness \
         over neighbouring lines, a sibling experiment of the same channel, band and level, \
         or the LPM's residual, which holds both). Where it cannot be \
         measured the report says so: a misfit there may be distortion or a fit error.\n"
    );
    for x in &d.experiments {
        bla_rows(md, x);
    }
}

/// How the non-periodic records were used: the windows without excitation (free decays,
/// pauses) kept with the excitation before them, and the records cut into pieces of constant
/// amplitude.
pub(super) fn pieces_section(md: &mut String, d: &Diagnosis) {
    use sd_diagnose::pieces::{MIN_PIECE, QUIET, QUIET_RUN, STEP, WINDOW};
    if d.records.is_empty() && d.pieces.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "## How the records were used\n\nA window of {WINDOW} samples is without excitation \
         when its excitation rms is below {:.0} dB of the loudest windows around it (the 90th \
         percentile within one minimum piece), in runs of at least {QUIET_RUN} windows: a free \
         decay or a pause is never an experiment; it stays with the excitation before it (its \
         response, which the LPM's FRF and transient term describe). A non-periodic record \
         whose excited parts change their rms by more than a factor {STEP} is cut there \
         (binary segmentation of the excited windows' log-rms, cuts moved to whole seconds, \
         pieces of at least {MIN_PIECE} samples or an eighth of the record); each piece is an \
         experiment of its own level, estimated by the LPM, and the lowest piece of the model \
         record is the model experiment.\n\n| record | length [s] | excited [s] | bursts | \
         used as |\n|---|---|---|---|---|",
        20.0 * QUIET.log10()
    );
    for r in &d.records {
        let used = if r.pieces == 1 {
            "one experiment (whole record)".to_string()
        } else {
            format!("{} pieces", r.pieces)
        };
        let _ = writeln!(
            md,
            "| {} | {:.2} | {:.2} | {} | {used} |",
            r.record, r.length_s, r.excited_s, r.bursts
        );
    }
    if !d.pieces.is_empty() {
        let _ = writeln!(
            md,
            "\n| piece | from [s] | to [s] | excited [s] | excitation rms (excited part) \
             |\n|---|---|---|---|---|"
        );
    }
    for p in &d.pieces {
        let _ = writeln!(
            md,
            "| {} | {:.2} | {:.2} | {:.2} | {:.4} |",
            p.name, p.start_s, p.end_s, p.excited_s, p.rms
        );
    }
    let _ = writeln!(md);
}

/// How far the model is from its own experiment, and what the excess is.
pub(super) fn own_fit_sentence(md: &mut String, d: &Diagnosis) {
    if let (Some(s), Some(_)) = (&d.model_info.own_data, d.model_info.own_fit) {
        let _ = writeln!(
            md,
            "On its own experiment the model's statistic is {:.3} (threshold {:.3}): {}.\n",
            s.value,
            s.threshold,
            own_excess(d)
        );
    }
}

/// What to do about a fitted model's excess on its own data: a scan stopped by `--max-order`
/// may go higher; one stopped by its held-out data says that more poles do not help there.
fn fit_error_advice(d: &Diagnosis) -> String {
    match d.model_info.fitted {
        Some(c) if c.order < c.max_order => {
            let why = match c.rule {
                sd_diagnose::OrderRule::HeldOutPeriods => {
                    "higher orders predict the held-out periods no better"
                }
                sd_diagnose::OrderRule::HeldOutLines => {
                    "higher orders predict the held-out interleaved lines no better"
                }
                sd_diagnose::OrderRule::Fpe => "higher orders have no lower prediction error",
            };
            format!(
                "a fit error that more poles do not remove (order {} of up to {}: {why}), \
                 so the model's structure \
                 misses something linear fits cannot follow here; give a model of the \
                 physics (`--model`) or compare `sdctl fit --stabilization` on this \
                 experiment's FRF",
                c.order, c.max_order
            )
        }
        _ => format!(
            "a fit error (raise `--max-order`, now order {}, or give a model)",
            d.model.n()
        ),
    }
}

/// What the model's excess on its own experiment is: noise, distortion, the named cause acting
/// at that rate too, a given model that does not describe its data, or a fit too coarse.
pub(super) fn own_excess(d: &Diagnosis) -> String {
    let extended_own = d
        .experiments
        .iter()
        .find(|x| x.role == sd_diagnose::Role::Model)
        .and_then(|x| x.extended_stat);
    match d.model_info.own_fit {
        None | Some(sd_diagnose::OwnFit::Noise) => "at the noise level".into(),
        Some(sd_diagnose::OwnFit::Distortion) => "above the noise, and the non-excited lines \
             show nonlinear distortion: the excess is the system's, not the fit's"
            .into(),
        Some(sd_diagnose::OwnFit::NotSeparable) => format!(
            "above the noise, and the {}: the excess may be the system's nonlinear distortion \
             or a fit error, which this excitation cannot tell apart (record an odd random-phase \
             multisine, whose non-excited lines measure the distortion, or several phase \
             realisations at this level)",
            model_distortion(d)
        ),
        Some(sd_diagnose::OwnFit::FitError) => match extended_own {
            Some(x) if x.passes() && d.verdict == sd_diagnose::Verdict::Discrepancy => format!(
                "above the noise, but the named cause ({}) acts at this rate too: with it the \
                 statistic is {:.3}, within its threshold {:.3}; the model is right apart from \
                 that effect",
                d.cause, x.value, x.threshold
            ),
            _ if d.model_info.source == "given" => format!(
                "above the noise and the distortion ({}): the given model does not describe \
                 the data it is judged at (leave out `--model` to fit one, or correct the model)",
                model_distortion(d)
            ),
            _ => format!(
                "above the noise and the distortion ({}): {}",
                model_distortion(d),
                fit_error_advice(d)
            ),
        },
    }
}
