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
