//! Issue #8 (partial): hide an effect in virtual-stage data and require the diagnosis to find it.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_diagnose::diagnose;
use sd_ident::{Experiment, ExperimentSpec, Lines, MultisineSpec, Phases, Role};
use sd_testbed::{run_identification, Identification, Injection, Noise, NonIdealities, Truth};

fn experiment(
    truth: &Truth,
    name: &str,
    rate: f64,
    ni: NonIdealities,
    seed: u64,
    role: Role,
) -> Experiment {
    let ts = 1.0 / rate;
    let mut opt = sd_hinf::weights::PidOptions::default();
    if rate > 2000.0 {
        opt.lowpass_ratio = 1000.0 / 30.0;
    }
    let k = sd_hinf::weights::pid(
        if rate > 2000.0 { 30.0 } else { 20.0 },
        truth.mass,
        Some(ts),
        &opt,
    )
    .unwrap();
    let period = (2.0 * rate) as usize;
    let excitation = sd_ident::design(&MultisineSpec {
        fs: rate,
        period,
        f_min: 0.5,
        f_max: 0.5 * rate - 0.5,
        lines: Lines::Full,
        phases: Phases::Random { seed },
        rms: 2.0,
        fold_rate_hz: Some(1000.0),
    })
    .unwrap();
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
                force_rms: 0.05 * (rate / 5000.0).sqrt(),
                sensor_rms: 0.3e-9 * (rate / 5000.0).sqrt(),
                seed: seed + 100,
            },
            nonideal: ni,
            role,
            substeps: None,
        },
    )
    .unwrap();
    Experiment {
        spec: ExperimentSpec {
            name: name.into(),
            file: format!("{name}.csv"),
            sample_rate_hz: rate,
            period_samples: d.period,
            skip_periods: 1,
            reference: Some("r".into()),
            input: "u".into(),
            output: "y".into(),
            role,
        },
        r: d.r,
        u: d.u,
        y: d.y,
    }
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
    diagnose(&[fast, slow]).unwrap()
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
    let cases: Vec<(&str, Truth, NonIdealities)> = vec![
        ("none", truth.clone(), NonIdealities::default()),
        ("common filter", filtered, NonIdealities::default()),
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
            "none" | "common filter" => assert_eq!(
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
