//! frequency response of the 60-state stage at 5 kHz on 200 000
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! frequencies, against dense LU solves of (zI − A) X = B.

use num_complex::Complex64 as C;
use sd_model::{c2d, grid, Discretization, FreqRespEvaluator};

fn check(step: usize) -> f64 {
    let p = sd_model::stage::stage60().unwrap();
    let pd = c2d(&p, 2e-4, Discretization::Zoh).unwrap();
    let f = grid(0.1, 2500.0, 200_000, true).unwrap();
    let frd = pd.freqresp(&f).unwrap();
    assert_eq!(frd.len(), 200_000);
    let ev = FreqRespEvaluator::new(&pd).unwrap();
    let mut worst: f64 = 0.0;
    for i in (0..f.len()).step_by(step) {
        let z = C::from_polar(1.0, 2.0 * std::f64::consts::PI * f[i] * 2e-4);
        let r = pd.eval_direct(z).unwrap()[(0, 0)];
        let g = frd.response()[i][(0, 0)];
        assert_eq!(g, ev.eval_hz(f[i])[(0, 0)]);
        worst = worst.max((g - r).norm() / r.norm());
    }
    println!(
        "stage60 @ 5 kHz: block sizes {:?}",
        ev.block_sizes()
            .iter()
            .filter(|&&s| s > 1)
            .collect::<Vec<_>>()
    );
    println!(
        "max relative error vs LU over {} of 200000 frequencies: {worst:.3e}",
        f.len().div_ceil(step)
    );
    worst
}

#[test]
fn freqresp_stage60_vs_lu_subset() {
    assert!(check(40) <= 1e-10);
}

/// All 200 000 frequencies against LU (about a minute): `cargo test -p sd-tests --release --test freqresp_stage -- --ignored`.
#[test]
#[ignore]
fn freqresp_stage60_vs_lu_all() {
    assert!(check(1) <= 1e-10);
}

#[test]
fn freqresp_stage60_at_1khz_with_folded_modes() {
    // At 1 kHz most of the 29 modes (300 Hz – 6 kHz) fold below 500 Hz: close poles.
    let pd = c2d(
        &sd_model::stage::stage60().unwrap(),
        1e-3,
        Discretization::Zoh,
    )
    .unwrap();
    let f = grid(0.1, 500.0, 20_000, true).unwrap();
    let frd = pd.freqresp(&f).unwrap();
    let mut worst: f64 = 0.0;
    for i in (0..f.len()).step_by(10) {
        let r = pd
            .eval_direct(C::from_polar(1.0, 2.0 * std::f64::consts::PI * f[i] * 1e-3))
            .unwrap()[(0, 0)];
        worst = worst.max((frd.response()[i][(0, 0)] - r).norm() / r.norm());
    }
    println!("stage60 @ 1 kHz: max relative error vs LU {worst:.3e}");
    assert!(worst <= 1e-10);
}

/// Scaling of the frequency response with the state dimension: a lightly damped modal stage
/// (n/2 modes, ζ = 0.01, 20 Hz–2.2 kHz, sampled at 5 kHz), 10⁵ points. Prints the path the
/// evaluator took, its construction time and the time per point:
/// `cargo test --release -p sd-tests --test freqresp_stage freqresp_scaling -- --ignored --nocapture`.
#[test]
#[ignore]
fn freqresp_scaling() {
    use sd_model::{SampleTime, StateSpace};
    for n in [20usize, 60, 120, 240] {
        let m = n / 2;
        let mut a = nalgebra::DMatrix::zeros(n, n);
        let mut b = nalgebra::DMatrix::zeros(n, 1);
        let mut c = nalgebra::DMatrix::zeros(1, n);
        for k in 0..m {
            let f = 20.0 * (2200.0f64 / 20.0).powf(k as f64 / (m - 1) as f64);
            let w = std::f64::consts::TAU * f;
            a[(2 * k, 2 * k + 1)] = 1.0;
            a[(2 * k + 1, 2 * k)] = -w * w;
            a[(2 * k + 1, 2 * k + 1)] = -0.02 * w;
            b[(2 * k + 1, 0)] = 1.0;
            c[(0, 2 * k)] = 1.0 + 0.1 * (k % 7) as f64;
        }
        let ct = StateSpace::new(
            a,
            b,
            c,
            nalgebra::DMatrix::zeros(1, 1),
            SampleTime::Continuous,
        )
        .unwrap();
        let dt = sd_model::c2d(&ct, 2e-4, sd_model::Discretization::Zoh).unwrap();
        let f = sd_model::grid(1.0, 2499.0, 100_000, true).unwrap();
        let t0 = std::time::Instant::now();
        let ev = sd_model::FreqRespEvaluator::new(&dt).unwrap();
        let t_new = t0.elapsed().as_secs_f64();
        let t1 = std::time::Instant::now();
        let r = ev.eval_many(&f);
        let t_eval = t1.elapsed().as_secs_f64();
        assert_eq!(r.len(), f.len());
        println!(
            "n {n}: path {:?}, reduction {t_new:.3} s, 1e5 points {t_eval:.3} s ({:.2} µs/point)",
            ev.path(),
            1e6 * t_eval / f.len() as f64
        );
    }
}
