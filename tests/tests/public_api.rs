//! Public functions no other test reaches: the closed loop's other transfer functions, a
//! spectrum's band power, Hankel singular values, `into_parts`, `is_discrete` and the
//! multirate loop's plant accessor, each against an independent value.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use sd_model::{c2d, Discretization, SampleTime, StateSpace, TransferFunction};

fn tf(num: Vec<f64>, den: Vec<f64>, t: SampleTime) -> StateSpace {
    TransferFunction::new(num, den, t).unwrap().to_ss().unwrap()
}

/// `S + T = I`, `L = PK`, `PS = P·S` at every frequency of a grid, to rounding.
#[test]
fn closed_loop_transfer_functions_agree_with_their_definitions() {
    let ts = 1e-3;
    let p = c2d(
        &sd_model::stage::paper_stage(0.01).unwrap(),
        ts,
        Discretization::Zoh,
    )
    .unwrap();
    let k = sd_tests::pid(20.0, 20.0, ts);
    let cl = sd_analysis::ClosedLoop::new(&p, &k).unwrap();
    let f = sd_model::grid(1.0, 490.0, 200, true).unwrap();
    let at = |m: &StateSpace| -> Vec<num_complex::Complex64> {
        m.freqresp(&f)
            .unwrap()
            .response()
            .iter()
            .map(|g| g[(0, 0)])
            .collect()
    };
    let (pf, kf) = (at(&p), at(&k));
    let (l, s, t, ps) = (
        at(cl.loop_gain()),
        at(cl.sensitivity()),
        at(cl.complementary()),
        at(cl.process_sensitivity()),
    );
    for i in 0..f.len() {
        let lij = pf[i] * kf[i];
        let tol = 1e-9 * (1.0 + lij.norm());
        assert!((l[i] - lij).norm() <= tol, "L at {} Hz", f[i]);
        assert!(
            (s[i] + t[i] - 1.0).norm() <= 1e-9 * (1.0 + t[i].norm()),
            "S + T at {} Hz",
            f[i]
        );
        assert!(
            (ps[i] - pf[i] * s[i]).norm() <= 1e-9 * pf[i].norm().max(1e-300) * (1.0 + s[i].norm()),
            "PS at {} Hz",
            f[i]
        );
    }
}

/// A sine of amplitude A has power A²/2, all of it in the band around its frequency.
#[test]
fn band_power_of_a_sine() {
    let fs = 1000.0;
    let x: Vec<f64> = (0..100_000)
        .map(|k| 2.0 * (std::f64::consts::TAU * 125.0 * k as f64 / fs).sin())
        .collect();
    let w = sd_analysis::welch(&x, fs, 1000, 0.5, sd_analysis::Window::Hann).unwrap();
    let inside = w.band_power(120.0, 130.0);
    assert!((inside - 2.0).abs() < 1e-3 * 2.0, "{inside}");
    assert!(w.band_power(200.0, 400.0) < 1e-9);
}

/// The Hankel singular value of `1/(s + a)` is `1/(2a)`; of a diagonal pair, the two.
#[test]
fn hankel_singular_values_of_first_order_systems() {
    let one = tf(vec![1.0], vec![1.0, 2.0], SampleTime::Continuous);
    let h = one.hankel_singular_values().unwrap();
    assert_eq!(h.len(), 1);
    assert!((h[0] - 0.25).abs() < 1e-12, "{h:?}");
    let two = sd_model::parallel(
        &one,
        &tf(vec![1.0], vec![1.0, 10.0], SampleTime::Continuous),
    )
    .unwrap();
    let h2 = two.hankel_singular_values().unwrap();
    assert_eq!(h2.len(), 2);
    assert!(h2[0] >= h2[1] && h2[1] > 0.0, "{h2:?}");
    // the sum bounds the H∞ norm from above, which is at least the largest value
    let hinf = two.hinf_norm().unwrap().value;
    assert!(hinf <= 2.0 * h2.iter().sum::<f64>() + 1e-12 && hinf >= h2[0] - 1e-12);
}

/// `into_parts` returns the matrices and the sample time the model was built from.
#[test]
fn into_parts_round_trips() {
    let m = tf(
        vec![1.0, 0.5],
        vec![1.0, -0.9],
        SampleTime::discrete(1e-3).unwrap(),
    );
    let (a, b, c, d, t) = m.clone().into_parts();
    assert!(t.is_discrete() && !SampleTime::Continuous.is_discrete());
    let back = StateSpace::new(a, b, c, d, t).unwrap();
    assert_eq!(back.a(), m.a());
    assert_eq!(back.b(), m.b());
    assert_eq!(back.c(), m.c());
    assert_eq!(back.d(), m.d());
}

/// The multirate loop keeps the fast plant it was given.
#[test]
fn multirate_loop_keeps_its_fast_plant() {
    let p = c2d(
        &sd_model::stage::paper_stage(0.01).unwrap(),
        2e-4,
        Discretization::Zoh,
    )
    .unwrap();
    let k = sd_tests::pid(20.0, 20.0, 1e-3);
    let l = sd_multirate::MultirateLoop::new(&p, &k, 5).unwrap();
    assert_eq!(l.fast_plant().a(), p.a());
    assert_eq!(l.factor(), 5);
}
