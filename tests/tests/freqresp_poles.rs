//! Issue #40 item 2: the frequency response at a pole is infinite (or refused), never a huge
//! finite number; a point near a pole, or a non-normal realization's point far from one, keeps
//! its finite value. References are the closed forms of the transfer functions. The user-facing
//! evaluations mark poles (`StateSpace::freqresp`, `FreqRespEvaluator::mark_poles`, as
//! `sdctl freqresp` and Python's `freqresp` use); `eval_at` stays the raw value internal
//! computations take limits through (the Nyquist contour's indentation 1e-8 from a rigid
//! body's z = 1 is in the rounding pseudospectrum of that defective pole).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::{c2d, series, Discretization, FreqRespEvaluator, SampleTime, StateSpace};
use std::f64::consts::TAU;

/// `G` at `f` as a user sees it: entries at a pole are `+∞`.
fn at(ev: &FreqRespEvaluator, f: f64) -> Vec<C> {
    let mut g = ev.eval_many_flat(&[f]);
    ev.mark_poles(&[f], &mut g);
    g
}

fn ss(a: &[f64], n: usize, b: &[f64], c: &[f64], d: f64, time: SampleTime) -> StateSpace {
    StateSpace::new(
        DMatrix::from_row_slice(n, n, a),
        DMatrix::from_row_slice(n, 1, b),
        DMatrix::from_row_slice(1, n, c),
        DMatrix::from_element(1, 1, d),
        time,
    )
    .unwrap()
}

/// `1/s²` in companion form and in a non-orthogonal basis (conditioning ~10).
fn double_integrators() -> Vec<StateSpace> {
    let p = ss(
        &[0.0, 1.0, 0.0, 0.0],
        2,
        &[0.0, 1.0],
        &[1.0, 0.0],
        0.0,
        SampleTime::Continuous,
    );
    let t = DMatrix::from_row_slice(2, 2, &[1.0, 0.7, -0.3, 2.0]);
    let ti = t.clone().try_inverse().unwrap();
    let r = StateSpace::new(
        &ti * p.a() * &t,
        &ti * p.b(),
        p.c() * &t,
        p.d().clone(),
        p.time(),
    )
    .unwrap();
    vec![p, r]
}

#[test]
fn an_integrators_dc_is_infinite_and_refused_as_an_frd() {
    for p in double_integrators() {
        let ev = FreqRespEvaluator::new(&p).unwrap();
        assert!(at(&ev, 0.0)[0].re.is_infinite());
        // 1 mHz off: −1/ω², to rounding
        let w = TAU * 1e-3;
        let g = at(&ev, 1e-3)[0];
        assert!(
            (g - C::new(-1.0 / (w * w), 0.0)).norm() < 1e-9 / (w * w),
            "{g}"
        );
        let e = p.freqresp(&[0.0, 1.0]).unwrap_err().to_string();
        assert!(e.contains("0 Hz is a pole"), "{e}");
        // the batch path marks the same point
        let grid = [1.0, 0.0, 2.0, 3.0, 4.0];
        let mut flat = ev.eval_many_flat(&grid);
        ev.mark_poles(&grid, &mut flat);
        assert!(flat[1].re.is_infinite());
        assert!(flat
            .iter()
            .enumerate()
            .all(|(k, v)| k == 1 || v.re.is_finite()));
    }
}

#[test]
fn a_sampled_double_integrator_at_z_one() {
    let h = 1e-3;
    for p in double_integrators() {
        let d = c2d(&p, h, Discretization::Zoh).unwrap();
        let ev = FreqRespEvaluator::new(&d).unwrap();
        assert!(at(&ev, 0.0)[0].re.is_infinite());
        // G(z) = h²(z + 1)/(2(z − 1)²), the ZOH of 1/s²
        for f in [0.5, 3.0, 120.0, 499.0] {
            let z = C::from_polar(1.0, TAU * f * h);
            let want = (z + 1.0) * (h * h) / ((z - 1.0) * (z - 1.0) * 2.0);
            let g = at(&ev, f)[0];
            assert!(
                (g - want).norm() <= 1e-8 * want.norm(),
                "{f} Hz: {g} vs {want}"
            );
        }
    }
}

#[test]
fn an_undamped_mode_at_its_frequency() {
    let w = TAU * 10.0;
    let p = ss(
        &[0.0, 1.0, -w * w, 0.0],
        2,
        &[0.0, 1.0],
        &[1.0, 0.0],
        0.0,
        SampleTime::Continuous,
    );
    let ev = FreqRespEvaluator::new(&p).unwrap();
    assert!(at(&ev, 10.0)[0].re.is_infinite());
    // 1 mHz off the mode: 1/(w² − ω²), large and finite
    let wo = TAU * 10.001;
    let g = at(&ev, 10.001)[0];
    let want = 1.0 / (w * w - wo * wo);
    assert!((g.re - want).abs() < 1e-8 * want.abs() && g.im.abs() < 1e-8 * want.abs());
}

/// The case that defeated a resolvent-norm criterion (stop 48): a sampled rigid body with tiny
/// gains (a Jordan block at z = 1) in series with a PID with its integrator, at 0.5 Hz — far
/// from any pole, its value is the product of the two parts' closed forms.
#[test]
fn a_non_normal_series_far_from_its_poles_is_finite_and_right() {
    let h = 1e-3;
    let body = ss(
        &[0.0, 1.0, 0.0, 0.0],
        2,
        &[0.0, 1e-7],
        &[1e-6, 0.0],
        0.0,
        SampleTime::Continuous,
    );
    let body = c2d(&body, h, Discretization::Zoh).unwrap();
    // PID: kp + ki·h/(z − 1) + kd(z − 1)/(h z) as (A, B, C, D) with states (integral, previous)
    let (kp, ki, kd) = (2.0e5, 4.0e6, 3.0e2);
    let pid = ss(
        &[1.0, 0.0, 0.0, 0.0],
        2,
        &[h, 1.0],
        &[ki, -kd / h],
        kp + kd / h + ki * h,
        SampleTime::Discrete { ts: h },
    );
    let l = series(&pid, &body).unwrap();
    let ev = FreqRespEvaluator::new(&l).unwrap();
    assert!(at(&ev, 0.0)[0].re.is_infinite());
    for f in [0.5, 2.0, 50.0] {
        let z = C::from_polar(1.0, TAU * f * h);
        let body_z = (z + 1.0) * (1e-13 * h * h) / ((z - 1.0) * (z - 1.0) * 2.0);
        let pid_z = kp + ki * h * z / (z - 1.0) + kd * (z - 1.0) / (h * z);
        let want = body_z * pid_z;
        let g = at(&ev, f)[0];
        assert!(
            g.re.is_finite() && (g - want).norm() <= 1e-8 * want.norm(),
            "{f} Hz: {g} vs {want}"
        );
    }
}

/// A pole that one input cannot excite is no pole of that entry.
#[test]
fn an_uncontrollable_integrator_leaves_its_entry_finite() {
    // states: an integrator driven by input 1 only, a first-order lag driven by input 2
    let p = StateSpace::new(
        DMatrix::from_row_slice(2, 2, &[0.0, 0.0, 0.0, -1.0]),
        DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 1.0]),
        DMatrix::from_row_slice(1, 2, &[1.0, 1.0]),
        DMatrix::zeros(1, 2),
        SampleTime::Continuous,
    )
    .unwrap();
    let g = at(&FreqRespEvaluator::new(&p).unwrap(), 0.0);
    assert!(g[0].re.is_infinite());
    assert!((g[1] - C::new(1.0, 0.0)).norm() < 1e-14, "{}", g[1]);
}
