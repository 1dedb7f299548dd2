//! Issue #8: hide an effect in virtual-stage data and require the diagnosis to find it.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_diagnose::{diagnose, DiagnoseOptions};
use sd_ident::{Experiment, Lines, MultisineSpec, Phases, Role};
use sd_testbed::{run_identification, Identification, Injection, Noise, NonIdealities, Truth};

/// One closed-loop identification experiment on the virtual stage, as the diagnosis reads it:
/// a PID-like controller (bandwidth `bw`, low-pass at `lowpass` Hz or none), a full random-phase
/// multisine on the 0.5 Hz grid up to just below Nyquist, 7 periods (1 transient), white force
/// and sensor noise. `None` when the controller does not stabilize the stage.
#[allow(clippy::too_many_arguments)]
fn identify(
    truth: &Truth,
    name: &str,
    rate: f64,
    bw: f64,
    lowpass: Option<f64>,
    rms: f64,
    noise: (f64, f64),
    fold_rate: f64,
    ni: NonIdealities,
    seed: u64,
    role: Role,
    lines: Lines,
) -> Option<Experiment> {
    let ts = 1.0 / rate;
    let opt = sd_hinf::weights::PidOptions {
        lowpass_ratio: lowpass.map(|f| f / bw).unwrap_or(0.0),
        ..Default::default()
    };
    let k = sd_hinf::weights::pid(bw, truth.mass, Some(ts), &opt).ok()?;
    let excitation = sd_ident::design(&MultisineSpec {
        fs: rate,
        period: (2.0 * rate) as usize,
        f_min: 0.5,
        f_max: 0.5 * rate - 0.5,
        lines,
        phases: Phases::Random { seed },
        rms,
        fold_rate_hz: Some(fold_rate),
    })
    .ok()?;
    let d = run_identification(
        truth,
        &Identification {
            name: name.into(),
            controller: k,
            excitation,
            periods: 7,
            transient_periods: 1,
            injection: Injection::Input,
            noise: Noise {
                force_rms: noise.0,
                sensor_rms: noise.1,
                seed: seed + 1000,
            },
            nonideal: ni,
            role,
            substeps: None,
            fine_steps: None,
        },
    )
    .ok()?;
    Some(d.to_experiment())
}

fn experiment(
    truth: &Truth,
    name: &str,
    rate: f64,
    ni: NonIdealities,
    seed: u64,
    role: Role,
) -> Experiment {
    let fast = rate > 2000.0;
    let scale = (rate / 5000.0).sqrt();
    identify(
        truth,
        name,
        rate,
        if fast { 30.0 } else { 20.0 },
        if fast { Some(1000.0) } else { None },
        2.0,
        (0.05 * scale, 0.3e-9 * scale),
        1000.0,
        ni,
        seed,
        role,
        Lines::Full,
    )
    .unwrap()
}

fn run(truth: &Truth, ni: NonIdealities, seed: u64) -> sd_diagnose::Diagnosis {
    // a clock error belongs to the slow controller's own oscillator: the fast experiment runs on
    // time (a common clock error would rescale both frequency axes alike, and the data would be
    // consistent with each other)
    let fast_ni = NonIdealities {
        clock_error: 0.0,
        ..ni
    };
    let fast = experiment(truth, "fast", 5000.0, fast_ni, seed, Role::Model);
    let slow = experiment(truth, "slow", 1000.0, ni, seed + 1, Role::Validation);
    diagnose(&[fast, slow], &Default::default()).unwrap()
}

#[test]
fn issue8_hidden_effects() {
    let truth = Truth::default();
    let mut filtered = truth.clone();
    filtered.sensor_filters.push(
        sd_model::TransferFunction::new(
            vec![1.0],
            vec![1.0 / (2.0 * std::f64::consts::PI * 3000.0), 1.0],
            sd_model::SampleTime::Continuous,
        )
        .unwrap()
        .to_ss()
        .unwrap(),
    );
    // a transport delay of 100 µs common to both rates (Padé (2,2): an all-pass with the
    // delay's phase to within 1° up to 1.5 kHz)
    let tau: f64 = 100e-6;
    let mut delayed = truth.clone();
    delayed.sensor_filters.push(
        sd_model::TransferFunction::new(
            vec![tau * tau / 12.0, -tau / 2.0, 1.0],
            vec![tau * tau / 12.0, tau / 2.0, 1.0],
            sd_model::SampleTime::Continuous,
        )
        .unwrap()
        .to_ss()
        .unwrap(),
    );
    let cases: Vec<(&str, Truth, NonIdealities)> = vec![
        ("none", truth.clone(), NonIdealities::default()),
        ("common filter", filtered, NonIdealities::default()),
        ("common delay", delayed, NonIdealities::default()),
        (
            "hold delay 0.4",
            truth.clone(),
            NonIdealities {
                hold_delay: 0.4,
                ..Default::default()
            },
        ),
        (
            "averaging 0.7",
            truth.clone(),
            NonIdealities {
                averaging: 0.7,
                ..Default::default()
            },
        ),
        (
            "slow clock 0.2 % fast",
            truth.clone(),
            NonIdealities {
                clock_error: -0.002,
                ..Default::default()
            },
        ),
    ];
    for (i, (name, t, ni)) in cases.into_iter().enumerate() {
        let d = run(&t, ni, 40 + i as u64);
        println!(
            "{name}: {} / {} {} | ranking {:?} | gain {:.2} -> {:.2}",
            d.verdict,
            d.cause,
            d.parameters,
            d.ranking
                .iter()
                .map(|r| (r.0.as_str(), (r.1 * 100.0).round() / 100.0))
                .collect::<Vec<_>>(),
            d.gain_before,
            d.gain_after
        );
        match name {
            "none" | "common filter" | "common delay" => assert_eq!(
                (d.verdict.as_str(), d.cause.as_str()),
                ("consistent", "none")
            ),
            "hold delay 0.4" => {
                assert_eq!(d.cause, "hold_delay");
                assert!((d.parameters["delay_frac"].as_f64().unwrap() - 0.4).abs() <= 0.04);
                assert!(d.gain_before / d.gain_after >= 3.0);
            }
            "averaging 0.7" => {
                assert_eq!(d.cause, "averaging_sampler");
                assert!((d.parameters["window_frac"].as_f64().unwrap() - 0.7).abs() <= 0.1);
                assert!(d.gain_before / d.gain_after >= 3.0);
            }
            _ => {
                assert_eq!(d.verdict, "discrepancy");
                assert!(
                    d.cause != "hold_delay" && d.cause != "averaging_sampler",
                    "{}",
                    d.cause
                );
            }
        }
    }
}

/// One seeded case: a random plant, rates and noise, one hidden effect. Returns (effect,
/// diagnosed cause, parameter error or NaN, gain ratio).
fn random_case(seed: u64) -> (String, String, f64, f64) {
    // plants whose identification loop the low-bandwidth controller cannot stabilize are
    // redrawn (the test is about the diagnosis, not about the controller)
    for attempt in 0..20 {
        let out = random_case_attempt(seed, attempt);
        if out.1 != "unstable setup" {
            return out;
        }
    }
    random_case_attempt(seed, 20)
}

/// The hidden effects of the random cases, drawn in turn by seed.
const EFFECTS: [&str; 6] = [
    "none",
    "filter",
    "hold_delay",
    "averaging",
    "cubic",
    "clock",
];
fn random_case_attempt(seed: u64, attempt: u64) -> (String, String, f64, f64) {
    let mut r = sd_tests::gen::Rng::new(seed * 7919 + 1 + attempt * 104_729);
    let fast_rate = [4000.0, 5000.0, 6000.0][(r.uniform() * 3.0) as usize % 3];
    let factor = 2 + (r.uniform() * 4.0) as usize % 4; // 2..5
    let slow_rate = fast_rate / factor as f64;
    let mass = r.range(5.0, 50.0);
    let nmodes = 1 + (r.uniform() * 2.0) as usize % 2;
    let modes: Vec<sd_testbed::ModeSpec> = (0..nmodes)
        .map(|_| sd_testbed::ModeSpec {
            freq_hz: r.range(0.6 * slow_rate, 0.4 * fast_rate),
            zeta: r.range(0.005, 0.03),
            residue: r.range(0.3, 2.0),
            cubic: 0.0,
        })
        .collect();
    let mut truth = Truth {
        mass,
        modes,
        ..Truth::default()
    };
    let noise = r.range(0.3, 3.0);
    let effect = EFFECTS[(seed % EFFECTS.len() as u64) as usize];
    let mut ni = NonIdealities::default();
    let mut truth_param = f64::NAN;
    match effect {
        "filter" => truth.sensor_filters.push(
            sd_model::TransferFunction::new(
                vec![1.0],
                vec![
                    1.0 / (2.0 * std::f64::consts::PI * r.range(0.3, 0.45) * fast_rate),
                    1.0,
                ],
                sd_model::SampleTime::Continuous,
            )
            .unwrap()
            .to_ss()
            .unwrap(),
        ),
        "hold_delay" => {
            ni.hold_delay = r.range(0.2, 0.8);
            truth_param = ni.hold_delay;
        }
        "averaging" => {
            ni.averaging = r.range(0.5, 1.0);
            truth_param = ni.averaging;
        }
        "cubic" => {
            let m0 = &truth.modes[0];
            // modal deflection at the high level ~ r·F/(m ω² 2ζ)·(fraction of power near the mode)
            let w = 2.0 * std::f64::consts::PI * m0.freq_hz;
            let q = m0.residue * 4.0 / (mass * w * w * 2.0 * m0.zeta) * 0.05;
            truth.modes[0].cubic = 0.3 / (q * q);
        }
        "clock" => {
            ni.clock_error = r.range(0.005, 0.02) * if r.uniform() < 0.5 { -1.0 } else { 1.0 }
        }
        _ => {}
    }
    let mk = |name: &str, rate: f64, ni: NonIdealities, rms: f64, s: u64, role: Role| {
        let scale = (rate / 5000.0).sqrt();
        identify(
            &truth,
            name,
            rate,
            10.0,
            Some(0.2 * rate),
            rms,
            (0.02 * noise * rms * scale, 0.1e-9 * noise * scale),
            slow_rate,
            ni,
            s,
            role,
            Lines::Full,
        )
    };
    let fast_ni = NonIdealities {
        clock_error: 0.0,
        ..ni
    };
    let mut exps = Vec::new();
    let low = 0.5;
    exps.push(mk(
        "fast",
        fast_rate,
        fast_ni,
        low,
        seed * 3 + 1,
        Role::Model,
    ));
    exps.push(mk(
        "slow",
        slow_rate,
        ni,
        low,
        seed * 3 + 2,
        Role::Validation,
    ));
    if effect == "cubic" {
        exps.push(mk(
            "fast_high",
            fast_rate,
            fast_ni,
            4.0,
            seed * 3 + 3,
            Role::Validation,
        ));
    }
    let exps: Option<Vec<Experiment>> = exps.into_iter().collect();
    let Some(exps) = exps else {
        return (effect.into(), "unstable setup".into(), f64::NAN, f64::NAN);
    };
    let d = diagnose(&exps, &Default::default()).unwrap();
    if std::env::var("DIAG_VERBOSE").is_ok() {
        println!(
            "  seed {seed}: {effect} F {factor} fast {fast_rate} modes {:?} -> ranking {:?}",
            truth
                .modes
                .iter()
                .map(|m| m.freq_hz.round())
                .collect::<Vec<_>>(),
            d.ranking
                .iter()
                .map(|r| (r.0.clone(), (r.1 * 100.0).round() / 100.0))
                .collect::<Vec<_>>()
        );
    }
    let perr = match d.cause.as_str() {
        // relative for the delay (within 10 %), absolute for the window (within 0.1)
        "hold_delay" => {
            (d.parameters["delay_frac"].as_f64().unwrap() - truth_param).abs() / truth_param
        }
        "averaging_sampler" => (d.parameters["window_frac"].as_f64().unwrap() - truth_param).abs(),
        _ => f64::NAN,
    };
    (
        effect.into(),
        d.cause,
        perr,
        d.gain_before / d.gain_after.max(f64::MIN_POSITIVE),
    )
}

fn expected(effect: &str) -> &'static str {
    match effect {
        "none" | "filter" => "none",
        "hold_delay" => "hold_delay",
        "averaging" => "averaging_sampler",
        "cubic" => "nonlinearity",
        _ => "unexplained",
    }
}

fn run_cases(n: u64) -> Vec<(String, String, f64, f64)> {
    (0..n).map(random_case).collect()
}

fn check_and_print(cases: &[(String, String, f64, f64)]) -> usize {
    let mut wrong = 0;
    for (i, (effect, cause, perr, gain)) in cases.iter().enumerate() {
        let want = expected(effect);
        let ok = cause == want
            && match effect.as_str() {
                "hold_delay" => *perr <= 0.1 && *gain >= 3.0,
                "averaging" => *perr <= 0.1 && *gain >= 3.0,
                "cubic" => *gain >= 3.0,
                _ => true,
            };
        if !ok {
            wrong += 1;
        }
        println!(
            "case {i:3}: {effect:<10} -> {cause:<18} param err {perr:.3} gain {gain:.1}{}",
            if ok { "" } else { "   WRONG" }
        );
    }
    wrong
}

#[test]
fn issue8_seeded_random_cases() {
    let cases = run_cases(24);
    let wrong = check_and_print(&cases);
    // never a wrong named cause: consistent plants stay consistent, the unknown effect is never
    // given a catalogued name, nonlinearity is found
    for (effect, cause, _, _) in &cases {
        let named =
            cause == "hold_delay" || cause == "averaging_sampler" || cause == "nonlinearity";
        assert!(
            !named || cause == expected(effect),
            "{effect} diagnosed as {cause}"
        );
    }
    assert_eq!(wrong, 0, "{wrong} of {} cases misdiagnosed", cases.len());
}

/// A given model that is wrong at a folding frequency (its 1.65 kHz mode placed at 1.55 kHz;
/// 1.65 kHz folds onto 350 Hz at 1 kHz) while the data are consistent with each other: the
/// cause is `fast_model_error`, the model-free Lemma 6 prediction is the extension, and the
/// report points at the band around 350 Hz and its fast origin.
#[test]
fn issue8_wrong_given_model_is_a_fast_model_error() {
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
    assert_eq!(
        (d.verdict.as_str(), d.cause.as_str()),
        ("consistent", "none")
    );
    assert_eq!(d.model_source, "given");
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
        (d.verdict.as_str(), d.cause.as_str()),
        ("discrepancy", "fast_model_error")
    );
    assert!(d.gain_ratio() >= 3.0, "{}", d.gain_ratio());
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
    let (noise, err_model, err_ext) = td.in_bands.unwrap();
    println!(
        "time domain: output {:.3e}, noise {:.3e}, model {:.3e}, extended {:.3e}; in the bands: noise {noise:.3e}, model {err_model:.3e}, extended {:.3e}",
        td.output_rms, td.noise_rms, td.error_rms_model, td.error_rms_extended.unwrap(), err_ext.unwrap()
    );
    assert!(err_model > 3.0 * noise);
    assert!(err_ext.unwrap() < 2.0 * noise);
    assert!(td.error_rms_extended.unwrap() <= td.error_rms_model * 1.001);
}

/// The confusion matrix over 100 seeded cases:
/// `cargo test --release -p sd-tests --test diagnose_hidden -- --ignored --nocapture`.
#[test]
#[ignore]
fn issue8_confusion_matrix_100() {
    let cases = run_cases(100);
    let wrong = check_and_print(&cases);
    let causes = [
        "none",
        "hold_delay",
        "averaging_sampler",
        "nonlinearity",
        "unexplained",
        "unstable setup",
    ];
    println!("\neffect \\ diagnosed: {causes:?}");
    for e in EFFECTS {
        let row: Vec<usize> = causes
            .iter()
            .map(|c| cases.iter().filter(|x| x.0 == e && x.1 == *c).count())
            .collect();
        println!("{e:<12} {row:?}");
    }
    println!("misdiagnosed: {wrong} of {}", cases.len());
}

/// Units: the same data in other units (input ×1e6, output ×1e-3, reference ×1e6) give the
/// same diagnosis — nothing depends on the absolute scale of the signals.
#[test]
fn issue8_units_do_not_matter() {
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
    assert!((a.gain_ratio() / b.gain_ratio() - 1.0).abs() < 0.05);
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
fn issue8_distortion_at_non_excited_lines() {
    let odd = Lines::RandomOdd { group: 3, seed: 9 };
    let run = |truth: &Truth, seed: u64| {
        let mk = |name: &str, rms: f64, s: u64, role: Role| {
            identify(
                truth,
                name,
                5000.0,
                30.0,
                Some(1000.0),
                rms,
                (0.02 * rms, 0.1e-9),
                1000.0,
                NonIdealities::default(),
                s,
                role,
                odd,
            )
            .unwrap()
        };
        let exps = [
            mk("low", 0.5, seed, Role::Model),
            mk("high", 4.0, seed + 1, Role::Validation),
        ];
        diagnose(&exps, &Default::default()).unwrap()
    };
    let odd_ratio = |d: &sd_diagnose::Diagnosis, i: usize| {
        d.experiments[i].distortion.as_ref().unwrap().odd_ratio
    };
    let linear = Truth::default();
    let d = run(&linear, 91);
    for e in d.evidence.iter().filter(|e| e.test.contains("non-excited")) {
        println!(
            "linear: {}: {:.2} (threshold {:.2})",
            e.test, e.statistic, e.threshold
        );
    }
    assert_eq!(
        (d.verdict.as_str(), d.cause.as_str()),
        ("consistent", "none")
    );
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
