//! Nonlinearity as a model: seeded cases at several excitation levels on the virtual stage
//! (cubic hardening and softening of the first mode through the testbed's Lawson–RK4
//! integrator, a linear stage, a stage whose mode drifts with time), diagnosed with the
//! amplitude-dependent modal model and its leave-one-level-out gain.
//!
//! A held-out level counts as *visible* when the linear model's statistic on it (in the moving
//! mode's band, the gain's metric) is at least [`VISIBLE`]: there the extension must gain at
//! least 3, or predict the level within [`FLOOR_SLACK`] of the level's own fit in the model
//! class (`HeldOut::floor`: a level whose own fit cannot reach a third of the linear model's
//! statistic caps every prediction's gain).
//!
//! Every tracked mode's frequency at every level is judged against that mode's best linear
//! approximation computed apart ([`sd_tests::modal_truth`]: the mode integrated alone under
//! random-phase forces with the level's spectrum): within
//! [`Z_TRACK`](sd_tests::modal_truth::Z_TRACK) of its standard errors
//! on at least [`TRUTH_SHARE_DEFAULT`] of the points in the default run and
//! [`TRUTH_SHARE_REPORTED`] in the reported ones, none beyond [`GROSS`](sd_tests::modal_truth::GROSS), no track near no true
//! mode. Seeds: development `0..20` (and `100..125`, `150..170`, `300..325`, `350..386`,
//! `400..425`, `450..466`, `800..825`, `850..866`, `1100..1125`, `1150..1166`, `1200..1225`,
//! `1250..1266`, `1300..1325`, `1350..1366`, `1400..1425`, `1450..1466`, `1500..1525`,
//! `1550..1566`, `1600..1625`, `1650..1666`, `1700..1725`, `1750..1766`, `1800..1825`,
//! `1850..1866`, `1900..1925`, `1950..1966`, `2200..2225`, `2250..2266`, `2400..2425`,
//! `2450..2466`, `2500..2525`, `2550..2566` (its linear rising cases 2550 and 2560, the false
//! alarms `compare`'s degrees of freedom fixed, were looked at one by one), `2650..2675` and
//! `2600..2616` (the neighbouring modes in the local fits were developed on the periodic
//! misses there), `2900..2925` and `2950..2966` (reported by the neighbouring modes'
//! version; the friction corner's weight against the pairs and the `none` answer with no
//! level visible were developed on its three wrong cases, 2909, 2913 and 2962), reported by
//! earlier versions; `2000..2150` for the linear and drifting
//! stages' false alarms); the default run `50..53` (non-periodic `50..52`); reported by the
//! friction corner's version (commit 7bd8c30) `3600..3625` (periodic) and `3650..3666`
//! (non-periodic); full multisines of one realization (`LEVEL_REC=full`): development
//! `3700..3712` (the per-level answer's kind from the tracks was developed there) and
//! `3720..3745` (reported by commit f4c2b02; the ripples, the slope test and the
//! distortion-shaped standard errors were developed on its four wrong cases, 3723, 3726,
//! 3728, 3732, and checked on `3700..3745`); reported by that version (commits c82e073,
//! e952644) `3800..3825` (periodic), `3850..3866` (non-periodic) and `3870..3895` (full
//! multisines); the roughness (`sd_ident::roughness`, commits 3117345, 7abc527) was checked
//! on the full multisines of `3700..3712` and reported on `3900..3925` (4 wrong: seeds 3903
//! Coulomb and 3909 softening, which the version before answers right); the anchored tracks
//! and the amplitude model on the levels the model's simulation misses were developed on
//! those two seeds and reported on `3930..3955`; the constants below;
//! all of them:
//! `cargo test --release -p sd-tests --test diagnose_levels -- --ignored --nocapture`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
use sd_model::median;
use sd_tests::modal_truth::{TrackError, TruthCheck};

use sd_diagnose::{Cause, CornerTrend, DampingTrend, DriftCheck, FreqTrend};
use sd_tests::diagcases::{
    burst_case, level_case, level_case_realization, level_rate_case, per_seed, rising_case,
    LevelCase, LevelEffect, Recording,
};

/// The linear model's held-out statistic from which a level's nonlinearity counts as visible.
const VISIBLE: f64 = 5.0;
/// A visible level's prediction that gains less than 3 still counts when its statistic is
/// within this factor of the level's own fit in the model class (`HeldOut::floor`): the
/// class cannot do better on that level with the level's own data, so the prediction from
/// the other levels is not what falls short. Set on seed 1519 (`1500..1525`, level 2 of a
/// friction stage: before 5.22, own fit 1.92, prediction 1.95).
const FLOOR_SLACK: f64 = 1.1;

/// One held-out level's figures (`sd_diagnose::HeldOut`).
#[derive(Debug)]
struct LevelGain {
    name: String,
    before: f64,
    after: f64,
    /// The level's own fit in the model class on the same lines.
    floor: f64,
    /// Its amplitude lay beyond the levels the model was fitted on.
    extrapolated: bool,
}

impl LevelGain {
    fn gain(&self) -> f64 {
        self.before / self.after
    }

    /// Visible and gaining less than 3 while its prediction is worse than the model class
    /// reaches on it ([`FLOOR_SLACK`]).
    fn weak(&self) -> bool {
        self.before >= VISIBLE && self.gain() < 3.0 && self.after > FLOOR_SLACK * self.floor
    }
}
const REPORT_SEEDS: std::ops::Range<u64> = 3800..3825;
const CI_SEEDS: std::ops::Range<u64> = 50..53;
/// Reported seeds of the non-periodic forms (separate noise records, one rising record).
const REPORT_SEEDS_NOISE: std::ops::Range<u64> = 3850..3866;
/// Reported seeds of full multisines of one realization ([`levels_reported_full`]); 3900..3925
/// before the anchored tracks and the levels the model misses (developed on its seeds 3903 and
/// 3909).
const REPORT_SEEDS_FULL: std::ops::Range<u64> = 3930..3955;
/// The default run's non-periodic subset.
const CI_SEEDS_NOISE: std::ops::Range<u64> = 50..52;

const PERIODIC: Recording = Recording::PERIODIC;

/// One non-periodic record of filtered noise per level, as long as four periods (LPM).
const NOISE: Recording = Recording::NOISE;

struct Outcome {
    case: LevelCase,
    cause: String,
    kind: Option<FreqTrend>,
    /// The dominant tracked mode's frequency trend (`sd_diagnose::tracks`; `None` without a
    /// dominant moving mode), measured beside `kind`.
    track_kind: Option<FreqTrend>,
    damping: Option<DampingTrend>,
    drift_check: Option<DriftCheck>,
    corner: Option<CornerTrend>,
    /// Pooled held-out gain.
    gain: Option<f64>,
    /// Per held-out level.
    levels: Vec<LevelGain>,
    /// Relative error of the predicted frequency shift at each held-out level.
    shift_errors: Vec<f64>,
    seconds: f64,
    /// A record the diagnosis cut: one piece per level, every piece excited (no free decay
    /// or pause as an experiment); `true` for separate records.
    pieces_right: bool,
    /// Every tracked point against the true mode's BLA ([`sd_tests::modal_truth`]).
    track_errors: Vec<TrackError>,
    /// Tracks near no true mode (their frequencies, Hz).
    spurious: Vec<f64>,
    /// The largest statistic of the linear model's simulation of one validation level
    /// (`EvidenceKind::ModelSimulation`, the whole band): whether any level shows the
    /// effect where the answer has no held-out levels (`none`).
    simulation_peak: f64,
    /// A moving mode of the amplitude model takes its points from the tracks' local fits
    /// (`sd_diagnose::PointFit::Local`).
    on_tracks: bool,
}

impl Outcome {
    /// Whether any held-out level shows the nonlinearity above noise (the linear model's
    /// statistic there at least [`VISIBLE`]).
    fn visible(&self) -> bool {
        self.levels.iter().any(|l| l.before >= VISIBLE) || self.simulation_peak >= VISIBLE
    }

    /// No kind stated (`none` as the kind of a nonlinearity, or the answer `none`) and no
    /// level shows the effect: a miss of what the data do not show, not a wrong name.
    fn unseen(&self) -> bool {
        !self.visible()
            && (self.kind == Some(FreqTrend::None) || (self.cause == "none" && self.kind.is_none()))
    }

    /// The kind named (`hardening`/`softening`), or — where no level shows the nonlinearity
    /// above noise — no kind ([`Outcome::unseen`]: the kind is stated only beyond the
    /// frequency trend's uncertainty, and a trend the data hardly show may stay within it;
    /// the answer `none` counts alike since seed 2909, a three-level softening whose largest
    /// level statistic was 1.17). The opposite kind is always wrong.
    fn kind_right(&self, expected: FreqTrend) -> bool {
        self.kind == Some(expected) || self.unseen()
    }

    fn right(&self) -> bool {
        self.pieces_right && self.effect_right()
    }

    fn effect_right(&self) -> bool {
        match self.case.effect {
            LevelEffect::Hardening => self.kind_right(FreqTrend::Hardening),
            LevelEffect::Softening => self.kind_right(FreqTrend::Softening),
            LevelEffect::Linear => self.cause == "none",
            // named, no frequency trend claimed (friction moves the rigid body's corner; its
            // held-out gain is required by `summarize`)
            LevelEffect::Coulomb => {
                self.cause == "nonlinearity" && self.kind.is_none_or(|k| k == FreqTrend::None)
            }
            // a same-level repeat that disagrees names drift
            LevelEffect::Drift => self.cause == "drift",
            // without a repeat, the non-excited lines of a periodic recording name drift;
            // without them (a non-periodic record, a full multisine) nothing can tell a drift
            // that follows the order of the levels from an amplitude effect: the diagnosis
            // must say that drift is not ruled out
            LevelEffect::DriftLevels
                if self.case.recording.periodic && !self.case.recording.full =>
            {
                self.cause == "drift"
            }
            LevelEffect::DriftLevels => {
                self.kind.is_none_or(|k| k == FreqTrend::None)
                    || self.drift_check == Some(DriftCheck::Unchecked)
            }
        }
    }
}

fn shift_errors(d: &sd_diagnose::Diagnosis, mode_hz: f64) -> Vec<f64> {
    let mut out = Vec::new();
    for c in &d.causes {
        if let Cause::Nonlinearity { modes, .. } = c {
            // the moving mode nearest the truth's first mode
            if let Some(m) = modes.iter().min_by(|a, b| {
                (a.linear_freq_hz - mode_hz)
                    .abs()
                    .total_cmp(&(b.linear_freq_hz - mode_hz).abs())
            }) {
                let f0 = m.points[0].freq_hz;
                for p in &m.points {
                    if let Some((fp, _)) = p.held_out_prediction {
                        let measured = p.freq_hz - f0;
                        out.push(((fp - f0) - measured).abs() / measured.abs().max(1e-12));
                    }
                }
            }
        }
    }
    out
}

/// How the levels are recorded.
#[derive(Clone, Copy, Debug)]
enum Form {
    /// One record per level.
    Separate(Recording),
    /// One non-periodic record whose amplitude steps through the levels (the diagnosis cuts).
    Rising,
    /// [`Form::Rising`] as burst random: each level's force on for 60 % of its seconds, then
    /// a free decay (the diagnosis cuts at the level changes only).
    Burst,
    /// [`Form::Separate`] with another realization of the excitation and noise on the
    /// seed's stage.
    Repeat(Recording, u64),
}

fn run(seed: u64, effect: LevelEffect, levels: &[f64], form: Form) -> Option<Outcome> {
    let case = match form {
        Form::Separate(rec) => level_case(seed, effect, levels, rec)?,
        Form::Rising => rising_case(seed, effect, levels, NOISE)?,
        Form::Burst => burst_case(seed, effect, levels, NOISE)?,
        Form::Repeat(rec, r) => {
            let top = levels.iter().cloned().fold(1.0, f64::max);
            level_case_realization(seed, effect, levels, rec, top, r)?
        }
    };
    let form_label = format!("{form:?}");
    let t = std::time::Instant::now();
    let show = std::env::var_os("LEVEL_PROGRESS").is_some();
    let d = sd_diagnose::diagnose_with_progress(&case.experiments, &Default::default(), &mut |m| {
        if show {
            eprintln!("{:6.2} s  {m}", t.elapsed().as_secs_f64());
        }
    })
    .unwrap();
    let seconds = t.elapsed().as_secs_f64();
    if std::env::var_os("LEVEL_EVIDENCE").is_some() {
        let h = d.model.ts().unwrap_or(1.0);
        for z in d.model.poles().unwrap() {
            let s = z.ln() / h;
            println!(
                "    pole s = {:.3} {:+.3}j (|s|/2π {:.2} Hz)",
                s.re,
                s.im,
                s.norm() / std::f64::consts::TAU
            );
        }
        for e in &d.evidence {
            println!("    {:.3} / {:.3} {}", e.statistic, e.threshold, e.test);
        }
        for c in &d.causes {
            if let Cause::Nonlinearity { tracks, .. } = c {
                for t in tracks {
                    println!(
                        "    track {:.2} Hz ζ {:.4} share {:.3} moves f {} ζ {} {:?} {:?} shift {:.3} bw dominant {}",
                        t.freq_hz, t.damping, t.share, t.frequency_moves, t.damping_moves,
                        t.frequency_trend, t.damping_trend, t.shift_bandwidths, t.dominant
                    );
                    for p in &t.points {
                        println!(
                            "      {} ρ {:.2} f {:.3}±{:.3} ζ {:.4}±{:.4}",
                            p.experiment,
                            p.relative_level,
                            p.freq_hz,
                            p.freq_std,
                            p.damping,
                            p.damping_std
                        );
                    }
                }
            }
            if let Cause::Nonlinearity { modes, .. } = c {
                for m in modes {
                    println!(
                        "    mode {:?} lin {:.2} Hz ζ {:.4} moves f {} ζ {} trend k {} slope {:.3e}",
                        m.pole,
                        m.linear_freq_hz,
                        m.linear_damping,
                        m.frequency_moves,
                        m.damping_moves,
                        m.frequency.exponent,
                        m.frequency.slope
                    );
                    for p in &m.points {
                        println!(
                            "      {} ρ {:.2} f {:.3}±{:.3} ζ {:.4}±{:.4} loo {:?}",
                            p.experiment,
                            p.relative_amplitude,
                            p.freq_hz,
                            p.freq_hz_std,
                            p.damping,
                            p.damping_std,
                            p.held_out_prediction
                        );
                    }
                }
            }
        }
    }
    let (track_errors, spurious) = sd_tests::modal_truth::track_errors(&d, &case);
    if std::env::var_os("LEVEL_EVIDENCE").is_some() {
        for e in &track_errors {
            println!(
                "    truth {:.1} Hz{} {}: f z {:+.2} ({:+.2e}) ζ z {:+.2} ({:+.3})",
                e.mode_hz,
                if e.nonlinear { " (cubic)" } else { "" },
                e.experiment,
                e.z_freq,
                e.rel_freq,
                e.z_damping,
                e.rel_damping
            );
        }
    }
    let (mut kind, mut damping, mut drift_check, mut corner) = (None, None, None, None);
    let mut track_kind = None;
    for c in &d.causes {
        if let Cause::Nonlinearity {
            kind: k,
            damping_trend,
            drift_check: dc,
            corner_trend,
            tracks,
            ..
        } = c
        {
            corner = Some(*corner_trend);
            kind = Some(*k);
            track_kind = tracks
                .iter()
                .find(|t| t.dominant)
                .map(|t| t.frequency_trend);
            damping = Some(*damping_trend);
            drift_check = Some(*dc);
        }
    }
    let out = Outcome {
        cause: d.cause.clone(),
        kind,
        track_kind,
        damping,
        drift_check,
        corner,
        gain: d.gain.ratio,
        levels: d
            .experiments
            .iter()
            .filter_map(|x| {
                let h = x.held_out?;
                Some(LevelGain {
                    name: x.name.clone(),
                    before: h.before,
                    after: h.after,
                    floor: h.floor,
                    extrapolated: h.extrapolated,
                })
            })
            .collect(),
        shift_errors: shift_errors(&d, case.mode_hz),
        on_tracks: d.causes.iter().any(|c| match c {
            Cause::Nonlinearity { modes, .. } => modes.iter().any(|m| {
                m.points
                    .iter()
                    .any(|p| p.fit == sd_diagnose::PointFit::Local)
            }),
            _ => false,
        }),
        seconds,
        pieces_right: matches!(form, Form::Separate(_) | Form::Repeat(..))
            || (d.pieces.len() == levels.len() && d.pieces.iter().all(|p| p.excited_s >= 1.0)),
        case,
        track_errors,
        spurious,
        simulation_peak: d
            .evidence
            .iter()
            .filter(|e| e.kind == sd_diagnose::EvidenceKind::ModelSimulation)
            .map(|e| e.statistic)
            .fold(0.0, f64::max),
    };
    println!(
        "seed {seed} {effect:?} {levels:?} {form_label:.9}: {} kind {:?} (tracks {:?}) damping {:?} corner {:?} gain {:?} levels {:?} \
         shift errors {:?} ({:.1} s){}",
        out.cause,
        out.kind,
        out.track_kind,
        out.damping,
        out.corner,
        out.gain.map(|g| (g * 10.0).round() / 10.0),
        out.levels
            .iter()
            .map(|l| format!(
                "{} {:.2}→{:.2} (own fit {:.2}){}",
                l.name,
                l.before,
                l.after,
                l.floor,
                if l.extrapolated { " (extrapolated)" } else { "" }
            ))
            .collect::<Vec<_>>(),
        out.shift_errors
            .iter()
            .map(|e| (e * 1000.0).round() / 1000.0)
            .collect::<Vec<_>>(),
        out.seconds,
        if out.right() { "" } else { "   WRONG" }
    );
    Some(out)
}

/// Every case of `seeds`: hardening and softening at four levels (1, 2, 4, 8) and at three
/// (1, 2, 4), a linear stage and two drifting ones (with and without a repeat) at four.
fn cases(seeds: std::ops::Range<u64>, form: Form) -> Vec<Outcome> {
    cases_with(seeds, form, true)
}

/// [`cases`], with `with_three` false without the three-level cases (the default run's
/// non-periodic forms: the suite's time; the three-level route runs in the periodic subset).
fn cases_with(seeds: std::ops::Range<u64>, form: Form, with_three: bool) -> Vec<Outcome> {
    let four = [1.0, 2.0, 4.0, 8.0];
    let three = [1.0, 2.0, 4.0];
    per_seed(seeds, |s| {
        [
            (LevelEffect::Hardening, &four[..]),
            (LevelEffect::Softening, &four[..]),
            (LevelEffect::Hardening, &three[..]),
            (LevelEffect::Softening, &three[..]),
            (LevelEffect::Linear, &four[..]),
            (LevelEffect::Drift, &four[..]),
            (LevelEffect::DriftLevels, &four[..]),
            (LevelEffect::Coulomb, &four[..]),
            (LevelEffect::Coulomb, &three[..]),
        ]
        .into_iter()
        // development: LEVEL_ONLY=Coulomb (or Hardening,Softening) runs those effects
        .filter(|(effect, _)| {
            std::env::var("LEVEL_ONLY").map_or(true, |o| {
                o.split(',').any(|e| format!("{effect:?}") == e.trim())
            })
        })
        // a rising record has no repeat of its first level: drift is tested on separate records
        .filter(|(effect, _)| {
            !matches!(
                (form, effect),
                (
                    Form::Rising | Form::Burst,
                    LevelEffect::Drift | LevelEffect::DriftLevels
                )
            )
        })
        .filter(|(_, levels)| with_three || levels.len() != 3)
        .filter_map(|(effect, levels)| run(s, effect, levels, form))
        .collect::<Vec<_>>()
    })
    .into_iter()
    .flatten()
    .collect()
}

/// Gains (before/after) of the visible held-out levels of `out`: (interpolated, extrapolated).
fn visible_gains(out: &[&Outcome]) -> (Vec<f64>, Vec<f64>) {
    let vis = |extra: bool| -> Vec<f64> {
        out.iter()
            .flat_map(|o| o.levels.iter())
            .filter(|l| l.before >= VISIBLE && l.extrapolated == extra)
            .map(LevelGain::gain)
            .collect()
    };
    (vis(false), vis(true))
}

/// `n with gain median m, worst w, ≥ 3 in k`.
fn gain_line(g: &[f64]) -> String {
    format!(
        "{} with gain median {:.2}, worst {:.2}, ≥ 3 in {}",
        g.len(),
        median(g),
        g.iter().cloned().fold(f64::INFINITY, f64::min),
        g.iter().filter(|x| **x >= 3.0).count()
    )
}

/// Prints the summary; returns (wrong, visible levels inside the fitted amplitudes with a
/// gain below 3 and a prediction worse than [`FLOOR_SLACK`] times their own fit, cubic and
/// friction cases). A level beyond the others' amplitudes (the top level,
/// left out) is an extrapolation, reported apart.
fn summarize(out: &[Outcome]) -> (usize, usize) {
    let wrong = out.iter().filter(|o| !o.right()).count();
    let of = |effects: &[LevelEffect]| -> Vec<&Outcome> {
        out.iter()
            .filter(|o| effects.contains(&o.case.effect))
            .collect()
    };
    let nl = of(&[LevelEffect::Hardening, LevelEffect::Softening]);
    let gains: Vec<f64> = nl.iter().filter_map(|o| o.gain).collect();
    let (vis, vis_x) = visible_gains(&nl);
    let errs: Vec<f64> = nl
        .iter()
        .flat_map(|o| o.shift_errors.iter().copied())
        .collect();
    let t: Vec<f64> = out.iter().map(|o| o.seconds).collect();
    let nonlinear = out.iter().filter(|o| o.cause == "nonlinearity").count();
    println!(
        "amplitude model with a moving mode on the tracks' local fits: {} of {nonlinear} \
         nonlinearity answers",
        out.iter().filter(|o| o.on_tracks).count()
    );
    println!(
        "{} cases, {wrong} wrong (kind of the nonlinear ones, `none` for the linear, no kind for \
         the drifting); cubic: pooled held-out gain median {:.2}, worst {:.2} over {}; visible \
         levels (before ≥ {VISIBLE}) {}; extrapolated {}; predicted frequency shift at \
         held-out levels: relative error median {:.3}, worst {:.3} over {}; diagnosis median \
         {:.2} s, worst {:.2} s",
        out.len(),
        median(&gains),
        gains.iter().cloned().fold(f64::INFINITY, f64::min),
        gains.len(),
        gain_line(&vis),
        gain_line(&vis_x),
        median(&errs),
        errs.iter().cloned().fold(0.0, f64::max),
        errs.len(),
        median(&t),
        t.iter().cloned().fold(0.0, f64::max)
    );
    let expected = |o: &&Outcome| match o.case.effect {
        LevelEffect::Hardening => FreqTrend::Hardening,
        _ => FreqTrend::Softening,
    };
    let named = nl.iter().filter(|o| o.kind == Some(expected(o))).count();
    let unseen = nl.iter().filter(|o| o.unseen()).count();
    println!(
        "cubic kind: {named} of {} named right, {unseen} without a kind (or the answer `none`) \
         with no level visible, {} wrong",
        nl.len(),
        nl.iter().filter(|o| !o.right()).count()
    );
    let tracks_named = nl
        .iter()
        .filter(|o| o.track_kind == Some(expected(o)))
        .count();
    let others = of(&[
        LevelEffect::Coulomb,
        LevelEffect::Linear,
        LevelEffect::Drift,
        LevelEffect::DriftLevels,
    ]);
    let tracks_claimed = others
        .iter()
        .filter(|o| o.track_kind.is_some_and(|k| k != FreqTrend::None))
        .count();
    println!(
        "tracked dominant mode (what names the kind where modes are tracked): cubic kind right in \
         {tracks_named} of {}; a frequency trend claimed in {tracks_claimed} of {} \
         friction, linear and drifting cases",
        nl.len(),
        others.len()
    );
    let coulomb = of(&[LevelEffect::Coulomb]);
    let (cvis, cvis_x) = visible_gains(&coulomb);
    if !coulomb.is_empty() {
        let falling = coulomb
            .iter()
            .filter(|o| o.corner == Some(CornerTrend::Falling))
            .count();
        let claimed = coulomb
            .iter()
            .filter(|o| o.kind.is_some_and(|k| k != FreqTrend::None))
            .count();
        println!(
            "Coulomb friction: {} cases, rigid-body corner falling in {falling}, a mode's \
             frequency trend claimed in {claimed}; visible levels {}; extrapolated {}",
            coulomb.len(),
            gain_line(&cvis),
            gain_line(&cvis_x),
        );
    }
    // every visible level inside the fitted amplitudes, cubic or friction, must gain 3 or
    // be predicted as well as the model class fits it ([`FLOOR_SLACK`])
    let inside: Vec<&LevelGain> = nl
        .iter()
        .chain(&coulomb)
        .flat_map(|o| o.levels.iter())
        .filter(|l| l.before >= VISIBLE && !l.extrapolated)
        .collect();
    let at_floor: Vec<String> = inside
        .iter()
        .filter(|l| l.gain() < 3.0 && !l.weak())
        .map(|l| {
            format!(
                "{} {:.2}→{:.2} (own fit {:.2})",
                l.name, l.before, l.after, l.floor
            )
        })
        .collect();
    println!(
        "visible levels gaining < 3 but predicted within {FLOOR_SLACK}× their own fit (the \
         model class's floor): {} {at_floor:?}",
        at_floor.len()
    );
    let weak = inside.iter().filter(|l| l.weak()).count();
    truth_check(out).print();
    (wrong, weak)
}

/// Every tracked point of `out` against the truth, its per-class lines printed.
fn truth_check(out: &[Outcome]) -> TruthCheck {
    let errors: Vec<TrackError> = out
        .iter()
        .flat_map(|o| o.track_errors.iter().cloned())
        .collect();
    TruthCheck::of(&errors, out.iter().map(|o| o.spurious.len()).sum())
}

/// Share of tracked frequencies within [`Z_TRACK`](sd_tests::modal_truth::Z_TRACK) standard
/// errors of the truth the default subsets require: 40–80 points each; were the intervals to cover only 95 % (the issue's
/// requirement) a share below 85 % would come by chance with probability about 1 % (binomial,
/// 42 points).
const TRUTH_SHARE_DEFAULT: f64 = 0.85;
/// What the reported runs require (issue #39: within the stated uncertainty on ≥ 95 %).
const TRUTH_SHARE_REPORTED: f64 = 0.95;

/// The default run's subset: every case right, every visible level gains ≥ 3.
#[test]
fn levels_default_subset() {
    let out = cases(CI_SEEDS, Form::Separate(PERIODIC));
    let (wrong, weak) = summarize(&out);
    assert!(out.len() >= 12, "only {} cases ran", out.len());
    assert_eq!(wrong, 0, "wrong kinds or causes");
    assert_eq!(weak, 0, "visible levels with a gain below 3");
    truth_check(&out).assert(TRUTH_SHARE_DEFAULT, "periodic");
}

/// The default run's non-periodic subset: separate noise records per level (LPM), one record of
/// rising amplitude and one of bursts with free decays, each cut into pieces by the diagnosis.
#[test]
fn levels_default_subset_nonperiodic() {
    for form in [Form::Separate(NOISE), Form::Rising, Form::Burst] {
        // at four levels only (three levels: the periodic subset here, every form in
        // `levels_reported_nonperiodic`)
        let out = cases_with(CI_SEEDS_NOISE, form, false);
        let (wrong, weak) = summarize(&out);
        assert!(out.len() >= 6, "only {} cases ran", out.len());
        assert_eq!(wrong, 0, "{form:?}: wrong kinds or causes");
        assert_eq!(weak, 0, "{form:?}: visible levels with a gain below 3");
        truth_check(&out).assert(TRUTH_SHARE_DEFAULT, &format!("{form:?}"));
    }
}

/// The reported seeds of the non-periodic forms ([`REPORT_SEEDS_NOISE`]); `LEVEL_FORMS=burst` (or
/// `noise`, `rising`, comma-separated) runs only those forms.
#[test]
#[ignore]
fn levels_reported_nonperiodic() {
    let mut wrong = 0;
    let mut checks = Vec::new();
    let only = std::env::var("LEVEL_FORMS").ok();
    let wanted = |name: &str| {
        only.as_deref()
            .is_none_or(|o| o.split(',').any(|x| x.trim() == name))
    };
    for (name, form) in [
        ("noise", Form::Separate(NOISE)),
        ("rising", Form::Rising),
        ("burst", Form::Burst),
    ] {
        if !wanted(name) {
            continue;
        }
        println!("{form:?}");
        let out = cases(REPORT_SEEDS_NOISE, form);
        let (w, weak) = summarize(&out);
        wrong += w;
        assert_eq!(weak, 0, "{form:?}: visible levels with a gain below 3");
        checks.push((format!("{form:?}"), truth_check(&out)));
    }
    assert_eq!(wrong, 0, "wrong kinds or causes");
    for (form, c) in &checks {
        c.assert(TRUTH_SHARE_REPORTED, form);
    }
}

/// Speed: a four-level and a seven-level diagnosis of 70 000 samples per level (14 s at 5 kHz;
/// periodic odd multisines, full multisines — the roughness measures their distortion — and
/// separate noise records), at most 10 s and 15 s on a 2-core machine:
/// `cargo test --release -p sd-tests --test diagnose_levels levels_speed -- --ignored
/// --nocapture` (`LEVEL_SPEED_FORM=noise` times one form, for a profiler).
#[test]
#[ignore]
fn levels_speed() {
    let long = Recording {
        steady: 13,
        ..PERIODIC
    };
    // the first seed from 0 whose drawn stage runs at 5 kHz
    let seed = (0..)
        .find(|s| {
            level_case(*s, LevelEffect::Linear, &[1.0], PERIODIC)
                .is_some_and(|c| c.experiments[0].spec.sample_rate_hz == 5000.0)
        })
        .unwrap();
    let four = [1.0, 2.0, 4.0, 8.0];
    let seven = [1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0];
    let mut slow = Vec::new();
    let forms = [
        ("periodic", long),
        ("full", Recording { full: true, ..long }),
        (
            "noise",
            Recording {
                periodic: false,
                ..long
            },
        ),
    ];
    let only = std::env::var("LEVEL_SPEED_FORM").ok();
    for (name, rec) in forms {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        for (levels, limit) in [(&four[..], 10.0), (&seven[..], 15.0)] {
            let o = run(seed, LevelEffect::Hardening, levels, Form::Separate(rec)).unwrap();
            let n: usize = o.case.experiments.iter().map(|e| e.y.len()).sum();
            println!(
                "{name}, {} levels: {n} samples in {:.2} s (limit {limit} s)",
                levels.len(),
                o.seconds
            );
            if o.seconds > limit {
                slow.push((name, levels.len(), o.seconds));
            }
        }
    }
    assert!(slow.is_empty(), "over the limit: {slow:?}");
}

/// The reported periodic seeds ([`REPORT_SEEDS`]).
#[test]
#[ignore]
fn levels_reported() {
    let out = cases(REPORT_SEEDS, Form::Separate(PERIODIC));
    let (wrong, weak) = summarize(&out);
    assert_eq!(wrong, 0, "wrong kinds or causes");
    assert_eq!(weak, 0, "visible levels with a gain below 3");
    truth_check(&out).assert(TRUTH_SHARE_REPORTED, "periodic");
}

/// The reported seeds of full multisines of one realization ([`REPORT_SEEDS_FULL`]: every
/// line excited, no detection lines, the distortion measured by the FRF's roughness — a
/// ground vibration test's recording): `cargo test --release -p sd-tests --test diagnose_levels levels_reported_full
/// -- --ignored --nocapture`.
#[test]
#[ignore]
fn levels_reported_full() {
    let out = cases(REPORT_SEEDS_FULL, Form::Separate(Recording::FULL));
    let (wrong, weak) = summarize(&out);
    assert_eq!(wrong, 0, "wrong kinds or causes");
    assert_eq!(weak, 0, "visible levels with a gain below 3");
    truth_check(&out).assert(TRUTH_SHARE_REPORTED, "full multisines");
}

/// Development seeds: `LEVEL_SEEDS=0..20 cargo test --release -p sd-tests --test
/// diagnose_levels development -- --ignored --nocapture` (`LEVEL_REC=noise`, `rising`,
/// `burst`, `full` for the other record forms).
#[test]
#[ignore]
fn development_levels() {
    let std::ops::Range { start: a, end: b } = sd_tests::env_seeds("LEVEL_SEEDS", 0..4);
    for r in [REPORT_SEEDS, REPORT_SEEDS_NOISE, REPORT_SEEDS_FULL] {
        assert!(
            b <= r.start || a >= r.end,
            "development seeds must not touch the reported range {r:?}"
        );
    }
    let form = match std::env::var("LEVEL_REC").as_deref() {
        Ok("noise") => Form::Separate(NOISE),
        Ok("rising") => Form::Rising,
        Ok("burst") => Form::Burst,
        Ok("full") => Form::Separate(Recording::FULL),
        _ => Form::Separate(PERIODIC),
    };
    let out = cases(a..b, form);
    summarize(&out);
}

/// Realizations of one stage's noise records (the spread of its tracked modes against their
/// truth): `LEVEL_SEED=7 LEVEL_REALIZATIONS=0..20 cargo test --release -p sd-tests --test
/// diagnose_levels realizations -- --ignored --nocapture` (Coulomb friction at the rigid body:
/// its flexible modes linear and tracked; four levels).
#[test]
#[ignore]
fn realizations_of_one_stage() {
    let seed = sd_tests::env_number("LEVEL_SEED", 7);
    let out: Vec<Outcome> = sd_tests::env_seeds("LEVEL_REALIZATIONS", 1..9)
        .filter_map(|r| {
            run(
                seed,
                LevelEffect::Coulomb,
                &[1.0, 2.0, 4.0, 8.0],
                Form::Repeat(NOISE, r),
            )
        })
        .collect();
    // per true mode (tracks within 2 % of each other): mean and spread of the errors over
    // their standard errors
    let mut errs: Vec<&TrackError> = out.iter().flat_map(|o| o.track_errors.iter()).collect();
    errs.sort_by(|a, b| a.mode_hz.total_cmp(&b.mode_hz));
    for group in errs.chunk_by(|a, b| b.mode_hz / a.mode_hz - 1.0 < 0.02) {
        let z: Vec<f64> = group.iter().map(|e| e.z_freq).collect();
        let n = z.len() as f64;
        let mean = z.iter().sum::<f64>() / n;
        let sd = (z.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
        let outside = z.iter().filter(|v| v.abs() > 2.576).count();
        println!(
            "mode near {:.1} Hz: {} points, frequency error/σ mean {mean:+.2}, spread {sd:.2}, \
             outside 2.576σ {outside}",
            group[0].mode_hz,
            z.len()
        );
    }
    let check = truth_check(&out);
    check.print();
    check.assert(TRUTH_SHARE_REPORTED, "realizations");
}

/// The report of a rising record: the pieces table, the moving-modes table and one amplitude
/// figure per moving mode (two panels, measured points with error bars, the fitted trend).
#[test]
fn report_of_a_rising_record() {
    let case = (50..60)
        .find_map(|s| rising_case(s, LevelEffect::Hardening, &[1.0, 2.0, 4.0], NOISE))
        .unwrap();
    let d = sd_diagnose::diagnose(&case.experiments, &Default::default()).unwrap();
    assert_eq!(d.pieces.len(), 3, "{:?}", d.pieces);
    let dir = std::env::temp_dir().join(format!("sd_levels_report_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let figs = sd_report::diagnosis::write(&dir, &d, "a rising record").unwrap();
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(md.contains("How the records were used"), "{md}");
    assert!(md.contains("rising[0.0–5.0 s]"), "{md}");
    assert!(md.contains("that move with amplitude"), "{md}");
    let amp: Vec<&String> = figs
        .iter()
        .filter(|f| f.starts_with("amplitude_"))
        .collect();
    assert!(!amp.is_empty(), "{figs:?}");
    let svg = std::fs::read_to_string(dir.join(amp[0])).unwrap();
    assert!(svg.contains("natural frequency [Hz]") && svg.contains("damping ratio"));
    remove_unless_kept(&dir);
}

/// Level and rate changed together (a fast and a slower experiment at 4×, the model
/// experiment at 1×): on a linear stage with a hold delay of 0.4 periods the fast experiments
/// agree, so the slower one is compared as at the model's level and the delay is named; on a
/// hardening stage without a delay the fast levels disagree and the cause is the
/// nonlinearity, not a rate-tied effect. Seeds `50..53`; development `0..10`
/// (`LEVEL_RATE_SEEDS=0..10`).
#[test]
fn level_and_rate_together() {
    let seeds = sd_tests::env_seeds("LEVEL_RATE_SEEDS", 50..53);
    let out = per_seed(seeds, |s| {
        let mut rows = Vec::new();
        for (effect, delay, want) in [
            (LevelEffect::Linear, 0.4, "hold_delay"),
            (LevelEffect::Hardening, 0.0, "nonlinearity"),
        ] {
            let Some(c) = level_rate_case(s, effect, 4.0, delay, PERIODIC) else {
                continue;
            };
            let d = sd_diagnose::diagnose(&c.experiments, &Default::default()).unwrap();
            let delay_err = d
                .causes
                .iter()
                .find_map(|c| match c {
                    Cause::HoldDelay { delay_frac, .. } => Some((delay_frac - delay).abs()),
                    _ => None,
                })
                .unwrap_or(0.0);
            println!(
                "seed {s} {effect:?} delay {delay}: {} (gain {:?}, delay error {delay_err:.3})",
                d.cause, d.gain.ratio
            );
            rows.push((d.cause == want && delay_err < 0.05, s, effect));
        }
        rows
    });
    let rows: Vec<_> = out.into_iter().flatten().collect();
    assert!(rows.len() >= 4, "only {} cases ran", rows.len());
    let wrong: Vec<_> = rows.iter().filter(|r| !r.0).collect();
    assert!(wrong.is_empty(), "{wrong:?}");
}

/// Coulomb friction on the rigid body at four levels (periodic): the first seed from 50 whose
/// diagnosis finds the damped rigid body's corner falling gains ≥ 3 on each visible held-out
/// level, and its report has the corner's table and a one-panel figure of the corner against
/// amplitude. Seeds 50..53 give at least one such case.
#[test]
fn friction_corner_is_reported() {
    let found = (50..53).find_map(|s| {
        let case = level_case(s, LevelEffect::Coulomb, &[1.0, 2.0, 4.0, 8.0], PERIODIC)?;
        let d = sd_diagnose::diagnose(&case.experiments, &Default::default()).unwrap();
        let falling = d.causes.iter().any(|c| {
            matches!(
                c,
                Cause::Nonlinearity {
                    corner_trend: CornerTrend::Falling,
                    ..
                }
            )
        });
        falling.then_some((s, d))
    });
    let (seed, d) = found.expect("no seed of 50..53 finds the friction corner falling");
    println!("seed {seed}: gain {:?}", d.gain.ratio);
    let visible: Vec<(f64, f64)> = d
        .experiments
        .iter()
        .filter_map(|x| x.held_out.map(|h| (h.before, h.after)))
        .filter(|(b, _)| *b >= VISIBLE)
        .collect();
    assert!(!visible.is_empty(), "{:?}", d.experiments);
    assert!(visible.iter().all(|(b, a)| b / a >= 3.0), "{visible:?}");
    let dir = std::env::temp_dir().join(format!("sd_friction_report_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let figs = sd_report::diagnosis::write(&dir, &d, "friction").unwrap();
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(md.contains("Damped rigid body, corner at"), "{md}");
    assert!(md.contains("friction-like"), "{md}");
    // the per-level table with each left-out level's own fit (the floor)
    assert!(
        md.contains("| experiment | linear model | extension | ratio | own fit (floor) |"),
        "{md}"
    );
    for x in d.experiments.iter().filter(|x| x.held_out.is_some()) {
        assert!(md.contains(&format!("| {} | ", x.name)), "{md}");
    }
    let svg: Vec<String> = figs
        .iter()
        .filter(|f| f.starts_with("amplitude_"))
        .map(|f| std::fs::read_to_string(dir.join(f)).unwrap())
        .collect();
    assert!(
        svg.iter().any(|s| s.contains("corner frequency")),
        "{figs:?}"
    );
    remove_unless_kept(&dir);
}

/// One level and its repeat (the mode 1 % higher the second time): nothing rate-tied to test
/// and no other level, so only the non-excited lines can tell drift from a nonlinearity's
/// stochastic distortion; they show none, and the cause is `drift` with that sign.
#[test]
fn a_repeat_without_distortion_is_drift() {
    let out = per_seed(50..53, |s| {
        let c = level_case(s, LevelEffect::Drift, &[1.0], PERIODIC)?;
        let d = sd_diagnose::diagnose(&c.experiments, &Default::default()).unwrap();
        println!("seed {s}: {} {:?}", d.cause, d.causes);
        Some(d.causes)
    });
    let ran: Vec<_> = out.into_iter().flatten().collect();
    assert!(ran.len() >= 2, "only {} cases ran", ran.len());
    for causes in ran {
        assert!(
            matches!(
                causes.as_slice(),
                [Cause::Drift {
                    sign: sd_diagnose::DriftSign::RepeatWithoutDistortion,
                    ..
                }]
            ),
            "{causes:?}"
        );
    }
}

/// Removes a report directory unless `SD_KEEP` is set (then says where it is).
fn remove_unless_kept(dir: &std::path::Path) {
    if std::env::var_os("SD_KEEP").is_none() {
        std::fs::remove_dir_all(dir).unwrap();
    } else {
        println!("kept {}", dir.display());
    }
}

/// One level and its repeat on a hardening stage (a new phase realisation at 1.05× the level,
/// the same level for the diagnosis): the non-excited lines show distortion, so where the two
/// realisations disagree the cause is never `drift` (the distortion rules it out), and where
/// the model's misfit on the repeat is within the noise plus the distortion's variance it is
/// `nonlinearity` at one level (no kind: one level has no trend). Seeds `0..6` by default (of
/// which at least one must disagree); `DISTORTED_SEEDS=a..b` for another range, whose counts
/// are printed. The rule was developed on `0..6` and `20..40`; reported on `1000..1040`:
/// `DISTORTED_SEEDS=1000..1040 cargo test --release -p sd-tests --test diagnose_levels
/// a_distorted_repeat -- --nocapture`.
#[test]
fn a_distorted_repeat_is_not_drift() {
    let seeds = sd_tests::env_seeds("DISTORTED_SEEDS", 0..6);
    let out = per_seed(seeds, |s| {
        let c = level_case(s, LevelEffect::Hardening, &[1.0, 1.05], PERIODIC)?;
        let d = sd_diagnose::diagnose(&c.experiments, &Default::default()).unwrap();
        println!("seed {s}: {} / {} {:?}", d.verdict, d.cause, d.causes);
        let one_level = matches!(
            d.causes.as_slice(),
            [Cause::Nonlinearity {
                kind: FreqTrend::None,
                drift_check: DriftCheck::DistortionSeen,
                ..
            }]
        );
        Some((d.verdict.to_string(), d.cause.clone(), one_level))
    });
    let ran: Vec<_> = out.into_iter().flatten().collect();
    assert!(ran.len() >= 4, "only {} cases ran", ran.len());
    let disagree: Vec<_> = ran.iter().filter(|(v, _, _)| v == "discrepancy").collect();
    let named = disagree.iter().filter(|x| x.2).count();
    println!(
        "{} cases, {} disagree: nonlinearity at one level {named}, others {:?}",
        ran.len(),
        disagree.len(),
        disagree
            .iter()
            .filter(|x| !x.2)
            .map(|x| x.1.as_str())
            .collect::<Vec<_>>()
    );
    assert!(!disagree.is_empty(), "no repeat disagreed: {ran:?}");
    for (_, cause, one_level) in &disagree {
        assert!(*one_level, "a distorted repeat named {cause}: {ran:?}");
    }
}

/// One case with its evidence, for development: `LEVEL_CASE=2560 LEVEL_ONLY=Linear
/// LEVEL_REC=rising LEVEL_EVIDENCE=1 cargo test --release -p sd-tests --test diagnose_levels
/// one_case -- --ignored --nocapture` (the four-level cases of the named effects).
#[test]
#[ignore]
fn one_case() {
    let seed = sd_tests::env_number("LEVEL_CASE", 0);
    let form = match std::env::var("LEVEL_REC").as_deref() {
        Ok("noise") => Form::Separate(NOISE),
        Ok("rising") => Form::Rising,
        Ok("burst") => Form::Burst,
        Ok("full") => Form::Separate(Recording::FULL),
        _ => Form::Separate(PERIODIC),
    };
    let out = cases(seed..seed + 1, form);
    for o in &out {
        let t = &o.case.truths[0];
        println!(
            "truth: mass {} modes {:?} amplifier {:?} viscous {} coulomb {} sensor filters {}",
            t.mass,
            t.modes,
            t.amplifier_hz,
            t.viscous,
            t.coulomb,
            t.sensor_filters.len()
        );
    }
    summarize(&out);
}
