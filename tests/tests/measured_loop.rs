//! Issue #40 item 5: a controller model on a *measured* plant FRF (`sd_analysis::analyze_measured`)
//! and the slow loop on a fast FRF through the model-free Lemma 6
//! (`sd_multirate::downsample_frd`). Reference: the same loop analysed from the plant's model
//! (`ClosedLoop`: margins by bisection on the model, stability by the closed loop's
//! eigenvalues) — another numerical form than the line-based reading.
//! `cargo test --release -p sd-tests --test measured_loop -- --nocapture` prints the figures.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use num_complex::Complex64 as C;
use sd_analysis::{analyze_measured, ClosedLoop, MeasuredNyquist, MeasuredPlant};
use sd_model::stage::paper_stage;
use sd_model::{c2d, Discretization, Frd, StateSpace};
use sd_tests::pid;

fn lines(df: f64, top: f64) -> Vec<f64> {
    (1..)
        .map(|i| f64::from(i) * df)
        .take_while(|&f| f <= top + 1e-9)
        .collect()
}

fn unstable_eigenvalues(cl: &ClosedLoop) -> i64 {
    cl.closed_loop()
        .poles()
        .unwrap()
        .iter()
        .filter(|p| p.norm() > 1.0)
        .count() as i64
}

/// A 1 kHz loop: the paper's stage (rigid body, 653 Hz mode) and a 30 Hz PID, measured on
/// 0.5 Hz lines to the Nyquist frequency.
fn loop_1khz() -> (StateSpace, StateSpace, Frd) {
    let p = c2d(&paper_stage(0.01).unwrap(), 1e-3, Discretization::Zoh).unwrap();
    let k = pid(30.0, 20.0, 1e-3);
    let frd = p.freqresp(&lines(0.5, 499.5)).unwrap();
    (p, k, frd)
}

#[test]
fn margins_and_peaks_on_lines_match_the_model() {
    let (p, k, frd) = loop_1khz();
    let (a, resp) = analyze_measured(&frd, &k, MeasuredPlant::default()).unwrap();
    let cl = ClosedLoop::new(&p, &k).unwrap();
    let m = cl.margins().unwrap();
    let s = cl.summary().unwrap();
    println!("{a:#?}");
    println!("model: {s:?}");
    assert_eq!(a.plant_integrators, 2);
    assert!(a.integrators_from_lines);
    match a.nyquist {
        MeasuredNyquist::Counted {
            stable,
            loop_integrators,
            ..
        } => {
            assert!(stable && s.stable);
            assert_eq!(loop_integrators, 3); // the rigid body and the PID's integrator
        }
        other => panic!("{other:?}"),
    }
    assert!((a.phase_margin_deg - m.phase_margin_deg).abs() < 0.05, "PM");
    assert!(
        (a.phase_margin_hz / m.gain_crossover_hz - 1.0).abs() < 1e-3,
        "PM frequency"
    );
    assert!((a.gain_margin_db - m.gain_margin_db()).abs() < 0.05, "GM");
    assert!(
        (a.gain_margin_hz / m.phase_crossover_hz - 1.0).abs() < 1e-3,
        "GM frequency"
    );
    // line peaks: at most the model's, within what 0.5 Hz lines can miss
    assert!(a.sensitivity_peak_db <= s.sensitivity_peak_db + 1e-9);
    assert!(
        s.sensitivity_peak_db - a.sensitivity_peak_db < 0.05,
        "|S| peak"
    );
    assert_eq!(resp.s.len(), frd.len());
}

#[test]
fn the_nyquist_count_on_lines_equals_the_closed_loop_eigenvalues() {
    let (p, k, frd) = loop_1khz();
    let mut counted = 0;
    for gain in [0.05, 0.2, 1.0, 3.0, 6.0, 10.0, 30.0, 100.0] {
        let kg = StateSpace::new(
            k.a().clone(),
            k.b().clone(),
            k.c() * gain,
            k.d() * gain,
            k.time(),
        )
        .unwrap();
        let (a, _) = analyze_measured(&frd, &kg, MeasuredPlant::default()).unwrap();
        let want = unstable_eigenvalues(&ClosedLoop::new(&p, &kg).unwrap());
        match &a.nyquist {
            MeasuredNyquist::Counted {
                closed_loop_unstable,
                ..
            } => {
                counted += 1;
                assert_eq!(*closed_loop_unstable, want, "gain ×{gain}");
            }
            MeasuredNyquist::Undetermined { reason } => println!("gain ×{gain}: {reason}"),
        }
        println!(
            "gain ×{gain}: eigenvalues outside: {want}; lines: {:?}",
            a.nyquist
        );
    }
    assert!(counted >= 7, "only {counted} of 8 gains counted");
}

#[test]
fn a_slow_loop_on_a_fast_frf_by_lemma_6() {
    let fast_model = c2d(&paper_stage(0.01).unwrap(), 2e-4, Discretization::Zoh).unwrap();
    let fast = fast_model.freqresp(&lines(0.5, 2500.0)).unwrap();
    let slow = sd_multirate::downsample_frd(&fast, 5, None).unwrap();
    assert!(slow.missing_hz.is_empty());
    let k = pid(30.0, 20.0, 1e-3);
    let (a, _) = analyze_measured(&slow.frd, &k, MeasuredPlant::default()).unwrap();
    let model = sd_multirate::downsample(&fast_model, 5).unwrap();
    let m = ClosedLoop::new(&model, &k).unwrap().margins().unwrap();
    println!(
        "slow on lines: PM {:.3}° GM {:.3} dB; model: PM {:.3}° GM {:.3} dB",
        a.phase_margin_deg,
        a.gain_margin_db,
        m.phase_margin_deg,
        m.gain_margin_db()
    );
    assert!((a.phase_margin_deg - m.phase_margin_deg).abs() < 0.05);
    assert!((a.gain_margin_db - m.gain_margin_db()).abs() < 0.05);
    assert!(matches!(
        a.nyquist,
        MeasuredNyquist::Counted { stable: true, .. }
    ));
}

#[test]
fn noisy_lines_keep_the_verdict_and_coarse_lines_say_undetermined() {
    let (_, k, frd) = loop_1khz();
    // 2 % complex noise from a fixed sequence (a linear congruential generator)
    let mut state = 12345u64;
    let mut rnd = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let noisy: Vec<_> = frd
        .response()
        .iter()
        .map(|r| r.map(|v| v * C::new(1.0 + 0.04 * rnd(), 0.04 * rnd())))
        .collect();
    let noisy = Frd::new(frd.freq_hz().to_vec(), noisy, None, frd.time()).unwrap();
    let (a, _) = analyze_measured(&noisy, &k, MeasuredPlant::default()).unwrap();
    assert!(
        matches!(a.nyquist, MeasuredNyquist::Counted { stable: true, .. }),
        "{:?}",
        a.nyquist
    );
    // lines from 8 Hz on (a multisine that starts there): the plant's rigid-body asymptote
    // and the controller's model close the contour below the lowest line
    let from8 = frd.select(|i| i >= 15).unwrap();
    let (a, _) = analyze_measured(&from8, &k, MeasuredPlant::default()).unwrap();
    assert!(
        matches!(a.nyquist, MeasuredNyquist::Counted { stable: true, .. }),
        "{:?}",
        a.nyquist
    );
    // ten lines from 50 Hz on cannot close the contour at its low end ...
    let plant = MeasuredPlant {
        integrators: Some(2),
        unstable_poles: 0,
    };
    let coarse = frd.select(|i| i % 100 == 99).unwrap();
    let (a, _) = analyze_measured(&coarse, &k, plant).unwrap();
    println!("coarse: {:?}", a.nyquist);
    assert!(
        matches!(&a.nyquist, MeasuredNyquist::Undetermined { reason } if reason.contains("lowest line"))
    );
    // ... and lines every 50 Hz above 5 Hz cannot follow det(I + L) around the critical point
    let sparse = frd.select(|i| i < 10 || i % 100 == 99).unwrap();
    let (a, _) = analyze_measured(&sparse, &k, plant).unwrap();
    println!("sparse: {:?}", a.nyquist);
    assert!(
        matches!(&a.nyquist, MeasuredNyquist::Undetermined { reason } if reason.contains("turns by"))
    );
}

#[test]
fn bad_input_is_named() {
    let (_, k, frd) = loop_1khz();
    let k5 = pid(30.0, 20.0, 2e-4);
    let e = analyze_measured(&frd, &k5, MeasuredPlant::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("sample time") && e.contains("--downsample"),
        "{e}"
    );
    let k2 = sd_model::connect::append(&k, &k).unwrap();
    let e = analyze_measured(&frd, &k2, MeasuredPlant::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("K must be 1x1"), "{e}");
}
