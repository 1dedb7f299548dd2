//! The diagnosis on hidden effects: fixed cases on the exact route, and seeded cases made by the
//! testbed's fine-step route (another numerical form than the hypotheses), with the confusion
//! matrix reported on seeds disjoint from those the method was developed on.
//!
//! Seed ranges: development (looked at while building the search and the naming rule)
//! `0..100` and `1000..1100`; the CI subset `3000..3032` (a regression check, run at every
//! commit); `2000..2100`, `4000..4100`, `5000..5100`, `6000..6100`, `8000..8100` and
//! `10000..10100` were reported once for earlier versions and are spent (development now;
//! the standard errors' model term was checked on `8000..8100`; `24000..24100` was reported
//! before the clock-error significance test; `25000..25100` with it at 6047e07 (one wrong
//! name, seed 25082, then looked at); reported now (not looked at before the figures were
//! taken): `26000..26100`. `14000..14100`, `15000..15100` and
//! `16000..16100` were reported once each while the parameter criterion took its present
//! form (absolute limits alone; then within three stated standard errors; then the pair's
//! combined lag), `17000..17100` before the clock search's window followed a minimum on its
//! edge, `18000..18100` and `20000..20100` with the present code (one pair-split miss on
//! the first, none on the second); all are spent:
//! `cargo test --release -p sd-tests --test diagnose_hidden -- --ignored --nocapture`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
use sd_model::median;

use sd_diagnose::{diagnose, Cause, DiagnoseOptions, Diagnosis, Verdict};
use sd_ident::{Experiment, Lines, Role};
use sd_testbed::{NonIdealities, Truth};
use sd_tests::diagcases::{hidden_effect, per_seed, Case, Effect, FINE_STEPS};
use sd_tests::stage::{closed_loop_experiment, identification_experiment, ExperimentSpec};

/// Seeds the confusion matrix is reported on (disjoint from the development seeds).
const REPORT_SEEDS: std::ops::Range<u64> = 26000..26100;
/// The default run's regression subset (disjoint from both).
const CI_SEEDS: std::ops::Range<u64> = 3000..3032;

/// The standard closed-loop experiment (`sd_tests::stage`), 7 periods, exact route.
fn experiment(
    truth: &Truth,
    name: &str,
    rate: f64,
    ni: NonIdealities,
    seed: u64,
    role: Role,
) -> Experiment {
    closed_loop_experiment(truth, name, rate, ni, seed, role, 7, None).unwrap()
}

fn run(truth: &Truth, ni: NonIdealities, seed: u64) -> Diagnosis {
    // a clock error belongs to the slow controller's own oscillator: the fast experiment runs on
    // time (a common clock error would rescale both frequency axes alike)
    let fast_ni = NonIdealities {
        clock_error: 0.0,
        ..ni
    };
    let fast = experiment(truth, "fast", 5000.0, fast_ni, seed, Role::Model);
    let slow = experiment(truth, "slow", 1000.0, ni, seed + 1, Role::Validation);
    diagnose(&[fast, slow], &Default::default()).unwrap()
}

fn first_order(tf_num: Vec<f64>, tf_den: Vec<f64>) -> sd_model::StateSpace {
    sd_model::TransferFunction::new(tf_num, tf_den, sd_model::SampleTime::Continuous)
        .unwrap()
        .to_ss()
        .unwrap()
}

/// Fixed cases on the exact route: effects common to both rates are consistent, each rate-tied
/// effect is named with its parameter, a slow clock 0.2 % fast is a clock error.
#[test]
fn hidden_effects_fixed_cases() {
    let truth = Truth::default();
    let mut filtered = truth.clone();
    filtered.sensor_filters.push(first_order(
        vec![1.0],
        vec![1.0 / (2.0 * std::f64::consts::PI * 3000.0), 1.0],
    ));
    // a transport delay of 100 µs common to both rates (Padé (2,2))
    let tau: f64 = 100e-6;
    let mut delayed = truth.clone();
    delayed.sensor_filters.push(first_order(
        vec![tau * tau / 12.0, -tau / 2.0, 1.0],
        vec![tau * tau / 12.0, tau / 2.0, 1.0],
    ));
    let ni = |a: f64, b: f64, e: f64| NonIdealities {
        hold_delay: a,
        averaging: b,
        clock_error: e,
        ..Default::default()
    };
    let cases: Vec<(&str, Truth, NonIdealities)> = vec![
        ("none", truth.clone(), ni(0.0, 0.0, 0.0)),
        ("common filter", filtered, ni(0.0, 0.0, 0.0)),
        ("common delay", delayed, ni(0.0, 0.0, 0.0)),
        ("hold delay 0.4", truth.clone(), ni(0.4, 0.0, 0.0)),
        ("averaging 0.7", truth.clone(), ni(0.0, 0.7, 0.0)),
        ("slow clock 0.2 % fast", truth.clone(), ni(0.0, 0.0, -0.002)),
    ];
    for (i, (name, t, n)) in cases.into_iter().enumerate() {
        let d = run(&t, n, 40 + i as u64);
        println!(
            "{name}: {} / {} {} | gain {:?}",
            d.verdict, d.cause, d.parameters, d.gain.ratio
        );
        for r in &d.ranking {
            println!(
                "   {} training {:.3} held out {:?}",
                r.cause, r.cost, r.held_out
            );
        }
        match name {
            "none" | "common filter" | "common delay" => {
                assert_eq!((d.verdict, d.cause.as_str()), (Verdict::Consistent, "none"))
            }
            "hold delay 0.4" => {
                assert_eq!(d.cause, "hold_delay");
                assert!((d.parameters["delay_frac"].as_f64().unwrap() - 0.4).abs() <= 0.02);
                assert!(d.gain.ratio.unwrap() >= 3.0);
            }
            "averaging 0.7" => {
                assert_eq!(d.cause, "averaging_sampler");
                assert!((d.parameters["window_frac"].as_f64().unwrap() - 0.7).abs() <= 0.03);
                assert!(d.gain.ratio.unwrap() >= 3.0);
            }
            _ => {
                assert_eq!(d.cause, "clock_error");
                let e = d.parameters["clock_error"]["slow"].as_f64().unwrap();
                assert!((e + 0.002).abs() < 2e-4, "{e}");
                assert!(d.gain.ratio.unwrap() >= 3.0);
            }
        }
    }
}

/// One seeded case's outcome.
struct Outcome {
    case: Case,
    cause: String,
    /// Parameter errors: delay (periods), window (fraction), clock (relative), with the
    /// diagnosis's standard error.
    errors: Vec<(&'static str, f64, Option<f64>)>,
    gain: Option<f64>,
    seconds: f64,
}

impl Outcome {
    fn wrong_name(&self) -> bool {
        let c = self.cause.as_str();
        c != "none" && c != "unexplained" && c != self.case.effect.expected()
    }
    fn right(&self) -> bool {
        self.cause == self.case.effect.expected()
    }
    /// Within [`limit`], or beyond it only within three of the parameter's stated standard
    /// errors (the diagnosis said the data do not pin it closer).
    fn params_ok(&self) -> bool {
        self.errors
            .iter()
            .all(|(k, e, s)| *e <= limit(k) || s.is_some_and(|s| *e <= 3.0 * s))
    }

    /// Outside the absolute limit alone (reported beside `params_ok`).
    fn beyond_limit(&self) -> bool {
        self.errors.iter().any(|(k, e, _)| *e > limit(k))
    }
}

/// The absolute limit of a parameter's error: delay and combined lag `α + β/2` 0.03 periods
/// (the fine-step grid alone is ±0.01), window 0.05, clock 5e-4 (relative).
fn limit(kind: &str) -> f64 {
    match kind {
        "delay" | "lag" => 0.03,
        "window" => 0.05,
        _ => 5e-4,
    }
}

/// Errors of the named parameters against what the simulation applied: the fine-step route
/// switches the hold and sums the window on a grid of `FINE_STEPS` sub-steps per period, so
/// its delay and window are `round(αN)/N` and `round(βN)/N`, not α and β (up to 1/100 of a
/// period apart at N = 50).
fn parameter_errors(effect: Effect, d: &Diagnosis) -> Vec<(&'static str, f64, Option<f64>)> {
    let grid = |x: f64| (x * FINE_STEPS as f64).round() / FINE_STEPS as f64;
    let effect = match effect {
        Effect::Delay(a) => Effect::Delay(grid(a)),
        Effect::Averaging(b) => Effect::Averaging(grid(b)),
        Effect::DelayAveraging(a, b) => Effect::DelayAveraging(grid(a), grid(b)),
        Effect::DelayClock(a, e) => Effect::DelayClock(grid(a), e),
        other => other,
    };
    let (a, b, e) = match effect {
        Effect::Delay(a) => (Some(a), None, None),
        Effect::Averaging(b) => (None, Some(b), None),
        Effect::Clock(e) => (None, None, Some(e)),
        Effect::DelayAveraging(a, b) => (Some(a), Some(b), None),
        Effect::DelayClock(a, e) => (Some(a), None, Some(e)),
        _ => (None, None, None),
    };
    let mut out = Vec::new();
    for c in &d.causes {
        match c {
            Cause::HoldDelay {
                delay_frac,
                delay_frac_std,
                combined_lag_frac,
                combined_lag_frac_std,
                ..
            } => {
                if let Some(a) = a {
                    out.push(("delay", (delay_frac - a).abs(), *delay_frac_std))
                }
                if let (Some(a), Some(b), Some(l)) = (a, b, combined_lag_frac) {
                    out.push(("lag", (l - a - 0.5 * b).abs(), *combined_lag_frac_std))
                }
            }
            Cause::AveragingSampler {
                window_frac,
                window_frac_std,
            } => {
                if let Some(b) = b {
                    out.push(("window", (window_frac - b).abs(), *window_frac_std))
                }
            }
            Cause::ClockError {
                clock_error,
                clock_error_std,
            } => {
                if let (Some(e), Some(x)) = (e, clock_error.get("slow")) {
                    out.push(("clock", (x - e).abs(), clock_error_std.get("slow").copied()))
                }
            }
            _ => {}
        }
    }
    out
}

fn run_case(seed: u64) -> Outcome {
    let case = hidden_effect(seed);
    let t = std::time::Instant::now();
    let d = diagnose(&case.experiments, &Default::default()).unwrap();
    let seconds = t.elapsed().as_secs_f64();
    if std::env::var("DIAG_VERBOSE").is_ok() {
        println!(
            "  seed {seed}: {:?} {:?} -> {} {} ({}) over none by {:?} ranking {:?}",
            case.effect,
            case.recording,
            d.cause,
            d.parameters,
            d.model_source(),
            d.advantage_over_none(),
            d.ranking
                .iter()
                .map(|r| (
                    r.cause.clone(),
                    (r.cost * 100.0).round() / 100.0,
                    r.held_out
                ))
                .collect::<Vec<_>>()
        );
    }
    if std::env::var("DIAG_EVIDENCE").is_ok() {
        for e in &d.evidence {
            println!("    {:.3} / {:.3} {}", e.statistic, e.threshold, e.test);
        }
        println!("    partial {:?}", d.partial);
    }
    Outcome {
        errors: parameter_errors(case.effect, &d),
        cause: d.cause.clone(),
        gain: d.gain.ratio,
        seconds,
        case,
    }
}

const KINDS: [&str; 8] = [
    "none",
    "common filter",
    "hold delay",
    "averaging",
    "clock error",
    "delay + averaging",
    "delay + clock",
    "cubic stiffness",
];
const NAMES: [&str; 9] = [
    "none",
    "hold_delay",
    "averaging_sampler",
    "clock_error",
    "averaging_sampler+hold_delay",
    "clock_error+hold_delay",
    "nonlinearity",
    "drift",
    "unexplained",
];

/// The standardized errors `|θ̂ − θ|/σ̂` (those with a standard error) of what the data
/// determine: single causes' parameters, clock errors, and a delay-and-window pair's combined
/// lag `α + β/2`. The pair's split is left out (printed apart): on some seeds it errs along
/// `α + β/2 = const` by 3–10 of its stated errors (0.01–0.02 of a period, within the absolute
/// limits). The cause is not known: it is not the fine-step route's grid (50 or 200 sub-steps
/// per period give the same errors on seeds 16000..16100).
fn z_scores(out: &[Outcome]) -> Vec<f64> {
    out.iter()
        .flat_map(|o| {
            let pair = matches!(o.case.effect, Effect::DelayAveraging(..));
            o.errors
                .iter()
                .filter(move |x| !(pair && matches!(x.0, "delay" | "window")))
        })
        .filter_map(|x| Some(x.1 / x.2?))
        .collect()
}

/// Prints every case and the confusion matrix; returns (wrong names, right, parameter misses).
fn summarize(out: &[Outcome]) -> (usize, usize, usize) {
    for (i, o) in out.iter().enumerate() {
        println!(
            "case {i:3}: {:<18} {:<40} -> {:<30} errors {:?} gain {:?} ({:.1} s){}",
            o.case.effect.kind(),
            format!("{:?}", o.case.recording),
            o.cause,
            o.errors,
            o.gain.map(|g| (g * 10.0).round() / 10.0),
            o.seconds,
            if o.wrong_name() { "   WRONG NAME" } else { "" }
        );
    }
    println!("\n| truth \\ diagnosed | {} | other |", NAMES.join(" | "));
    println!("|---|{}---|", "---|".repeat(NAMES.len()));
    for k in KINDS {
        let rows: Vec<&Outcome> = out.iter().filter(|o| o.case.effect.kind() == k).collect();
        let cells: Vec<String> = NAMES
            .iter()
            .map(|n| rows.iter().filter(|o| o.cause == *n).count().to_string())
            .collect();
        let other = rows
            .iter()
            .filter(|o| !NAMES.contains(&o.cause.as_str()))
            .count();
        println!("| {k} | {} | {other} |", cells.join(" | "));
    }
    for kind in ["delay", "window", "clock", "lag"] {
        let e: Vec<f64> = out
            .iter()
            .flat_map(|o| o.errors.iter().filter(|x| x.0 == kind).map(|x| x.1))
            .collect();
        let z: Vec<f64> = out
            .iter()
            .flat_map(|o| o.errors.iter().filter(|x| x.0 == kind))
            .filter_map(|x| Some(x.1 / x.2?))
            .collect();
        if !e.is_empty() {
            println!(
                "{kind} error: worst {:.4}, median {:.4} over {}; within 2 / 3 standard errors: \
                 {} / {} of {} with one",
                e.iter().cloned().fold(0.0, f64::max),
                median(&e),
                e.len(),
                z.iter().filter(|z| **z <= 2.0).count(),
                z.iter().filter(|z| **z <= 3.0).count(),
                z.len()
            );
        }
    }
    let gains: Vec<f64> = out
        .iter()
        .filter(|o| o.right())
        .filter_map(|o| o.gain)
        .collect();
    if !gains.is_empty() {
        println!(
            "held-out gain of the named extensions: median {:.1}, worst {:.1} over {}",
            median(&gains),
            gains.iter().cloned().fold(f64::INFINITY, f64::min),
            gains.len()
        );
    }
    let t: Vec<f64> = out.iter().map(|o| o.seconds).collect();
    println!(
        "diagnosis time: median {:.2} s, worst {:.2} s",
        median(&t),
        t.iter().cloned().fold(0.0, f64::max)
    );
    let wrong = out.iter().filter(|o| o.wrong_name()).count();
    let right = out.iter().filter(|o| o.right()).count();
    let pmiss = out.iter().filter(|o| o.right() && !o.params_ok()).count();
    let beyond = out.iter().filter(|o| o.right() && o.beyond_limit()).count();
    println!(
        "right {right} of {}, wrong names {wrong}, parameter misses {pmiss} (beyond the \
         absolute limit alone: {beyond})",
        out.len()
    );
    (wrong, right, pmiss)
}

/// The cases of `seeds`, on every core (in seed order).
fn run_cases(seeds: std::ops::Range<u64>) -> Vec<Outcome> {
    per_seed(seeds, run_case)
}

/// The default subset: 32 seeds (4 of every effect kind). Never a wrong named cause, named
/// parameters within their limits, at least 3/4 of the cases right.
#[test]
fn held_out_suite_default_subset() {
    let out = run_cases(CI_SEEDS);
    let (wrong, right, pmiss) = summarize(&out);
    assert_eq!(wrong, 0, "wrong named causes");
    assert_eq!(pmiss, 0, "named parameters outside their limits");
    assert!(
        4 * right >= 3 * out.len(),
        "only {right} of {} right",
        out.len()
    );
}

/// The whole reported seed range (100 cases):
/// `cargo test --release -p sd-tests --test diagnose_hidden -- --ignored --nocapture`.
#[test]
#[ignore]
fn held_out_confusion_matrix_100() {
    let out = run_cases(REPORT_SEEDS);
    let (wrong, _, pmiss) = summarize(&out);
    assert_eq!(wrong, 0, "wrong named causes");
    assert_eq!(pmiss, 0, "named parameters outside their limits");
    // the standard errors are calibrated: with n errors, about 95 % lie within 2σ̂; the test
    // fails below 0.95 n − 3 sd of the binomial (false-alarm probability ≈ 0.2 % when they are)
    let z = z_scores(&out);
    let n = z.len() as f64;
    let within = z.iter().filter(|z| **z <= 2.0).count() as f64;
    let floor = 0.95 * n - 3.0 * (n * 0.05 * 0.95).sqrt();
    println!("standard errors: {within} of {n} within 2σ (floor {floor:.1})");
    assert!(
        within >= floor,
        "standard errors optimistic: {within} of {n} within 2σ"
    );
}

/// Development seeds (not reported): `DIAG_SEEDS=0..40 cargo test --release -p sd-tests --test
/// diagnose_hidden development -- --ignored --nocapture`.
#[test]
#[ignore]
fn development_seeds() {
    let std::ops::Range { start: a, end: b } = sd_tests::env_seeds("DIAG_SEEDS", 0..16);
    assert!(
        b <= REPORT_SEEDS.start || a >= REPORT_SEEDS.end,
        "development seeds must not touch the reported range"
    );
    let out = run_cases(a..b);
    summarize(&out);
}

/// A given model that is wrong at a folding frequency (its 1.65 kHz mode placed at 1.55 kHz;
/// 1.65 kHz folds onto 350 Hz at 1 kHz) while the data are consistent with each other: the
/// cause is `fast_model_error`, the model-free Lemma 6 prediction is the extension, and the
/// report points at the band around 350 Hz and its fast origin.
#[test]
fn wrong_given_model_is_a_fast_model_error() {
    let truth = Truth::default();
    let fast = experiment(&truth, "fast", 5000.0, Default::default(), 71, Role::Model);
    let slow = experiment(
        &truth,
        "slow",
        1000.0,
        Default::default(),
        72,
        Role::Validation,
    );
    let exps = [fast, slow];
    // the right model: consistent
    let right = truth.linear_model().unwrap();
    let d = diagnose(
        &exps,
        &DiagnoseOptions {
            model: Some(right),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((d.verdict, d.cause.as_str()), (Verdict::Consistent, "none"));
    assert_eq!(d.model_source(), "given");
    // the wrong one
    let mut wrong_truth = truth.clone();
    wrong_truth.modes[1].freq_hz = 1550.0;
    let d = diagnose(
        &exps,
        &DiagnoseOptions {
            model: Some(wrong_truth.linear_model().unwrap()),
            ..Default::default()
        },
    )
    .unwrap();
    println!("{}", serde_json::to_string_pretty(&d.to_json()).unwrap());
    assert_eq!(
        (d.verdict, d.cause.as_str()),
        (Verdict::Discrepancy, "fast_model_error")
    );
    let g = d.gain_ratio().unwrap();
    assert!(g >= 3.0, "{g}");
    let slow = &d.experiments[1];
    let band = &slow.bands[0];
    assert!(
        band.worst_hz > 300.0 && band.worst_hz < 500.0,
        "worst line {} Hz",
        band.worst_hz
    );
    assert!(
        (band.from_fast_hz - 1550.0).abs() < 150.0,
        "folds from {} Hz",
        band.from_fast_hz
    );
    // in the time domain the whole-band error is dominated by low-frequency input noise, but
    // inside the band the model's error stands out above the noise and the extension removes it
    let td = slow.time_domain.as_ref().unwrap();
    let b = td.in_bands.unwrap();
    let (noise, err_model, err_ext) = (b.noise_rms, b.error_rms_model, b.error_rms_extended);
    println!(
        "time domain: output {:.3e}, noise {:?}, model {:.3e}, extended {:.3e}; in the bands: noise {noise:.3e}, model {err_model:.3e}, extended {:.3e}",
        td.output_rms, td.noise_rms, td.error_rms_model, td.error_rms_extended.unwrap(), err_ext.unwrap()
    );
    assert!(err_model > 3.0 * noise);
    assert!(err_ext.unwrap() < 2.0 * noise);
    assert!(td.error_rms_extended.unwrap() <= td.error_rms_model * 1.001);
}

/// Units: the same data in other units (input ×1e6, output ×1e-3, reference ×1e6) give the
/// same diagnosis — nothing depends on the absolute scale of the signals.
#[test]
fn units_do_not_matter() {
    let truth = Truth::default();
    let ni = NonIdealities {
        hold_delay: 0.55,
        ..Default::default()
    };
    let fast = experiment(&truth, "fast", 5000.0, ni, 81, Role::Model);
    let slow = experiment(&truth, "slow", 1000.0, ni, 82, Role::Validation);
    let scale = |e: &Experiment| {
        let mut e = e.clone();
        e.u.iter_mut().for_each(|v| *v *= 1e6);
        e.y.iter_mut().for_each(|v| *v *= 1e-3);
        if let Some(r) = e.r.as_mut() {
            r.iter_mut().for_each(|v| *v *= 1e6);
        }
        e
    };
    let a = diagnose(&[fast.clone(), slow.clone()], &Default::default()).unwrap();
    let b = diagnose(&[scale(&fast), scale(&slow)], &Default::default()).unwrap();
    assert_eq!(a.cause, "hold_delay");
    assert_eq!(b.cause, a.cause);
    let (pa, pb) = (
        a.parameters["delay_frac"].as_f64().unwrap(),
        b.parameters["delay_frac"].as_f64().unwrap(),
    );
    assert!(
        (pa - 0.55).abs() < 0.055 && (pa - pb).abs() < 1e-3,
        "{pa} {pb}"
    );
    assert!((a.gain_ratio().unwrap() / b.gain_ratio().unwrap() - 1.0).abs() < 0.05);
}

/// Step 1 of the diagnosis: distortion levels where the excitation leaves lines out. Random-odd
/// multisines at two levels: on the linear stage the two experiments agree (`consistent`) and
/// the low level's non-excited lines are at the noise; on the stage with cubic stiffness of its
/// first mode the cause is `nonlinearity` and the low level's odd non-excited lines carry power
/// far above the noise (odd-order distortion). At the high level the hardened mode no longer
/// responds periodically: the spread between periods, counted as noise, grows ~70× and hides the
/// distortion there. The linear stage's high level is not exactly at the noise either (1.4–1.6):
/// what is left of the loop's slowest transient after the skipped period leaks into every line.
#[test]
fn distortion_at_non_excited_lines() {
    let odd = Lines::RandomOdd { group: 3, seed: 9 };
    let run = |truth: &Truth, seed: u64| {
        let mk = |name: &str, rms: f64, s: u64, role: Role| {
            let spec = ExperimentSpec {
                bandwidth_hz: 30.0,
                lowpass_hz: Some(1000.0),
                rms,
                noise: (0.02 * rms, 0.1e-9),
                fold_rate_hz: 1000.0,
                lines: odd,
                periods: 7,
                fine_steps: None,
            };
            identification_experiment(
                truth,
                name,
                5000.0,
                &spec,
                NonIdealities::default(),
                s,
                role,
            )
            .unwrap()
        };
        let exps = [
            mk("low", 0.5, seed, Role::Model),
            mk("high", 4.0, seed + 1, Role::Validation),
        ];
        diagnose(&exps, &Default::default()).unwrap()
    };
    let odd_ratio =
        |d: &Diagnosis, i: usize| d.experiments[i].distortion.as_ref().unwrap().odd_ratio;
    let linear = Truth::default();
    let d = run(&linear, 91);
    for e in d.evidence.iter().filter(|e| e.test.contains("non-excited")) {
        println!(
            "linear: {}: {:.2} (threshold {:.2})",
            e.test, e.statistic, e.threshold
        );
    }
    assert_eq!((d.verdict, d.cause.as_str()), (Verdict::Consistent, "none"));
    assert!(d.evidence.iter().any(|e| e.test.contains("non-excited")));
    let low_linear = odd_ratio(&d, 0);
    assert!(low_linear < 1.2, "{low_linear}");
    let mut cubic = linear.clone();
    let m0 = &cubic.modes[0];
    let w = 2.0 * std::f64::consts::PI * m0.freq_hz;
    let q = m0.residue * 4.0 / (cubic.mass * w * w * 2.0 * m0.zeta) * 0.05;
    cubic.modes[0].cubic = 0.3 / (q * q);
    let d = run(&cubic, 93);
    for e in d.evidence.iter().filter(|e| e.test.contains("non-excited")) {
        println!(
            "cubic: {}: {:.2} (threshold {:.2})",
            e.test, e.statistic, e.threshold
        );
    }
    assert_eq!(d.cause, "nonlinearity");
    assert!(
        odd_ratio(&d, 0) > 10.0 * low_linear,
        "{} vs {low_linear}",
        odd_ratio(&d, 0)
    );
    assert!(d
        .evidence
        .iter()
        .any(|e| e.test.contains("non-excited odd lines of `low`") && !e.passed));
}

/// Two same-level slower experiments (1 kHz and 2.5 kHz): the cause chosen on both their
/// earlier periods and judged on the later ones; the gain measured on each whole experiment
/// left out in turn (`gain.held_out` names them).
#[test]
fn two_slow_experiments_are_left_out_in_turn() {
    let truth = Truth::default();
    let ni = NonIdealities {
        hold_delay: 0.3,
        ..Default::default()
    };
    let fast = experiment(&truth, "fast", 5000.0, ni, 61, Role::Model);
    let slow = experiment(&truth, "slow", 1000.0, ni, 62, Role::Validation);
    let mid = experiment(&truth, "mid", 2500.0, ni, 63, Role::Validation);
    let d = diagnose(&[fast, slow, mid], &Default::default()).unwrap();
    println!("{} {} {:?}", d.cause, d.parameters, d.gain);
    assert_eq!(d.cause, "hold_delay");
    assert!((d.parameters["delay_frac"].as_f64().unwrap() - 0.3).abs() < 0.02);
    assert_eq!(
        d.gain.held_out,
        vec![
            "slow (whole experiment, left out)".to_string(),
            "mid (whole experiment, left out)".to_string()
        ]
    );
    assert!(d.gain.ratio.unwrap() >= 3.0);
}

/// Speed of a three-experiment diagnosis, 3 × 70 000 samples: the 5 kHz model experiment
/// (7 periods of 2 s) and two 1 kHz validation experiments (35 periods of 2 s each), with a
/// hold delay. At most 5 s on this 2-core machine:
/// `cargo test --release -p sd-tests --test diagnose_hidden three_experiments_speed -- --ignored
/// --nocapture`.
#[test]
#[ignore]
fn three_experiments_speed() {
    let truth = Truth::default();
    let ni = NonIdealities {
        hold_delay: 0.3,
        ..Default::default()
    };
    let mk = |name: &str, rate: f64, periods: usize, seed: u64, role: Role| {
        closed_loop_experiment(&truth, name, rate, ni, seed, role, periods, None).unwrap()
    };
    let exps = [
        mk("fast", 5000.0, 7, 70, Role::Model),
        mk("slow_a", 1000.0, 35, 71, Role::Validation),
        mk("slow_b", 1000.0, 35, 72, Role::Validation),
    ];
    let n: Vec<usize> = exps.iter().map(|e| e.y.len()).collect();
    assert_eq!(n, [70_000, 70_000, 70_000]);
    let t = std::time::Instant::now();
    let d = sd_diagnose::diagnose_with_progress(&exps, &Default::default(), &mut |m| {
        println!("  [{:6.2} s] {m}", t.elapsed().as_secs_f64())
    })
    .unwrap();
    let secs = t.elapsed().as_secs_f64();
    println!(
        "3 × 70 000 samples: {} / {} in {secs:.2} s (gain {:?}, held out {:?})",
        d.verdict, d.cause, d.gain.ratio, d.gain.held_out
    );
    assert_eq!(d.cause, "hold_delay");
    assert!(secs <= 5.0, "{secs:.2} s");
}
