//! Issue #42 item 3: the distortion test on non-excited lines (`sd_ident::DistortionReport`'s
//! odd and even scores against the `1 − α` quantile of `Gamma(L, 1)/L`) is calibrated at every
//! rate and fold pattern. Linear closed-loop experiments on the virtual stage (exact route:
//! a linear sampled-data system, its non-excited lines carry only noise) with a random-odd
//! multisine (one detection line per group of three odd lines, even lines free) on the 0.5 Hz
//! grid folding onto 1 kHz, at 5 kHz, 2.5 kHz, 1.25 kHz and 1 kHz; each experiment gives two
//! tests (odd, even) at α = 1 %. The reported run (seeds `2800..2850` per rate, never used for
//! anything else) counts the false alarms against the binomial interval:
//! `cargo test --release -p sd-tests --test distortion_calibration -- --ignored --nocapture`.
//!
//! The same for the roughness of full random-phase multisines (`sd_ident::roughness`, the
//! distortion measure of records whose lines are all excited): the share of lines whose
//! roughness passes its 1 % gate on linear experiments at the four rates.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_ident::{frf_periodic, Lines, PeriodicOptions, Role};
use sd_testbed::{NonIdealities, Truth};
use sd_tests::diagcases::per_seed;
use sd_tests::stage::{identification_experiment, ExperimentSpec};

const ALPHA: f64 = 0.01;
const RATES: [f64; 4] = [5000.0, 2500.0, 1250.0, 1000.0];

/// The `1 − α` quantile of `Gamma(L, 1)/L` (the score's law without distortion).
fn threshold(lines: usize) -> f64 {
    let nu = 2.0 * lines as f64;
    sd_model::chi2_quantile(1.0 - ALPHA, nu) / nu
}

/// The periodic estimate of one linear closed-loop experiment at `rate` exciting `lines`, or
/// `None` when the controller does not stabilise the stage.
fn linear_estimate(rate: f64, seed: u64, lines: Lines) -> Option<sd_ident::FrfEstimate> {
    let truth = Truth::default();
    let spec = ExperimentSpec {
        bandwidth_hz: if rate >= 2000.0 { 30.0 } else { 20.0 },
        lowpass_hz: (rate >= 2000.0).then_some(1000.0),
        rms: 2.0,
        noise: (
            0.05 * (rate / 5000.0).sqrt(),
            3e-10 * (rate / 5000.0).sqrt(),
        ),
        fold_rate_hz: 1000.0,
        lines,
        periods: 4,
        fine_steps: None,
    };
    let e = identification_experiment(
        &truth,
        "x",
        rate,
        &spec,
        NonIdealities::default(),
        seed,
        Role::Validation,
    )?;
    let period = e.spec.period_samples?;
    frf_periodic(
        rate,
        None,
        &e.u,
        &e.y,
        &PeriodicOptions::new(period, e.spec.skip_periods),
    )
    .ok()
}

/// `(odd alarm, even alarm)` of one linear experiment at `rate`, or `None` when the
/// controller does not stabilise the stage or the record has no detection lines.
fn alarms(rate: f64, seed: u64) -> Option<(bool, bool)> {
    let lines = Lines::RandomOdd {
        group: 3,
        seed: seed ^ 0x5eed,
    };
    let est = linear_estimate(rate, seed, lines)?;
    let d = est.distortion?;
    Some((
        d.odd_lines > 0 && d.odd_score > threshold(d.odd_lines),
        d.even_lines > 0 && d.even_score > threshold(d.even_lines),
    ))
}

/// Per rate: tests run and false alarms.
fn run(seeds: std::ops::Range<u64>) -> Vec<(f64, usize, usize)> {
    RATES
        .iter()
        .map(|&rate| {
            let out = per_seed(seeds.clone(), |s| alarms(rate, s));
            let tests = 2 * out.iter().flatten().count();
            let fired = out
                .iter()
                .flatten()
                .map(|(o, e)| usize::from(*o) + usize::from(*e))
                .sum();
            println!("{rate} Hz: {fired} false alarms in {tests} tests (α = {ALPHA})");
            (rate, tests, fired)
        })
        .collect()
}

/// The default run: 6 experiments per rate (48 tests); more than 3 alarms in all (a
/// calibrated test: P = 0.16 %) or 2 at one rate (P = 0.6 % per rate) fails.
#[test]
fn distortion_test_is_calibrated_at_every_rate() {
    let r = run(100..106);
    let total: usize = r.iter().map(|x| x.2).sum();
    let tests: usize = r.iter().map(|x| x.1).sum();
    assert!(tests >= 40, "only {tests} tests");
    assert!(total <= 3 && r.iter().all(|x| x.2 <= 1), "{r:?}");
}

/// The reported run: 50 experiments per rate (100 tests each, 400 in all); a calibrated test
/// gives 4 alarms in 400 on average, [0, 9] at 99 %.
#[test]
#[ignore]
fn distortion_false_alarms_report() {
    let r = run(2800..2850);
    let total: usize = r.iter().map(|x| x.2).sum();
    let tests: usize = r.iter().map(|x| x.1).sum();
    println!(
        "all rates: {total} false alarms in {tests} tests ({:.2} %)",
        100.0 * total as f64 / tests as f64
    );
}

/// `(lines, lines whose roughness passed the gate)` of one linear experiment at `rate` with a
/// full random-phase multisine (every line excited: the distortion measured by the FRF's
/// roughness, `sd_ident::roughness`), or `None` when the controller does not stabilise the
/// stage or the roughness is not what measured it.
fn roughness_alarms(rate: f64, seed: u64) -> Option<(usize, usize)> {
    let est = linear_estimate(rate, seed, Lines::Full)?;
    match sd_ident::Bla::from_periodic(&est).ok()?.distortion {
        sd_ident::Distortion::Roughness {
            lines,
            significant_lines,
        } => Some((lines, significant_lines)),
        _ => None,
    }
}

/// Per rate: lines judged and lines whose roughness passed the 1 % gate.
fn roughness_run(seeds: std::ops::Range<u64>) -> Vec<(f64, usize, usize)> {
    RATES
        .iter()
        .map(|&rate| {
            let out = per_seed(seeds.clone(), |s| roughness_alarms(rate, s));
            let lines = out.iter().flatten().map(|x| x.0).sum();
            let fired = out.iter().flatten().map(|x| x.1).sum();
            println!(
                "{rate} Hz: roughness gate passed at {fired} of {lines} lines of linear \
                 experiments ({} experiments)",
                out.iter().flatten().count()
            );
            (rate, lines, fired)
        })
        .collect()
}

/// The roughness of linear experiments on the stage (its lightly damped modes and their
/// aliases at 1 kHz, the local rational model's hardest case) passes its 1 % gate
/// (`sd_ident::roughness::roughness_gate`) at about 1 % of the lines: in this run 0.6–1.5 %
/// per rate. Six experiments per rate; above 3 % at a rate fails (a curvature the local model
/// left behind would show near every resonance: far more). The alarms come in clusters (the
/// windows overlap), so the line count is no binomial sample size.
#[test]
fn roughness_is_calibrated_at_every_rate() {
    for (rate, lines, fired) in roughness_run(100..106) {
        assert!(lines >= 500, "{rate} Hz: only {lines} lines");
        let share = fired as f64 / lines as f64;
        assert!(
            share <= 0.03,
            "{rate} Hz: {fired} of {lines} lines ({share:.3})"
        );
    }
}

/// The reported run of the roughness (the detection test's seeds, which never ran a full
/// multisine before): lines passing the gate per rate.
#[test]
#[ignore]
fn roughness_false_alarms_report() {
    let r = roughness_run(2800..2850);
    let (lines, fired) = r.iter().fold((0, 0), |a, x| (a.0 + x.1, a.1 + x.2));
    println!(
        "all rates: roughness gate passed at {fired} of {lines} lines ({:.2} %)",
        100.0 * fired as f64 / lines as f64
    );
}
