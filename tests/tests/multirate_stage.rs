//! Acceptance on the 60-state stage: Lemma 6 from 5 kHz with F = 5 equals Lemma 5 at
//! 1 kHz to 1e-8 relative in frequency response over 0–500 Hz.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_model::{c2d, grid, Discretization, FreqRespEvaluator};
use sd_multirate::downsample;
use sd_tests::rel_err;

#[test]
fn stage60_downsampled_equals_zoh_at_1khz() {
    let p = sd_model::stage::stage60().unwrap();
    assert_eq!(p.n(), 60);
    let fast = c2d(&p, 2e-4, Discretization::Zoh).unwrap();
    let slow = downsample(&fast, 5).unwrap();
    let direct = c2d(&p, 1e-3, Discretization::Zoh).unwrap();
    let (ea, eb) = (rel_err(slow.a(), direct.a()), rel_err(slow.b(), direct.b()));
    println!("stage60 matrices: A {ea:.2e}, B {eb:.2e}");
    assert!(ea <= 1e-10 && eb <= 1e-10);
    // 0–500 Hz: the rigid body makes f = 0 infinite, so the grid starts at 0.1 Hz and ends at
    // the slow Nyquist frequency
    let f = grid(0.1, 500.0, 5000, false).unwrap();
    let (e1, e2) = (
        FreqRespEvaluator::new(&slow).unwrap(),
        FreqRespEvaluator::new(&direct).unwrap(),
    );
    let mut worst: f64 = 0.0;
    for &fi in &f {
        let (a, b) = (e1.eval_hz(fi)[(0, 0)], e2.eval_hz(fi)[(0, 0)]);
        worst = worst.max((a - b).norm() / b.norm());
    }
    println!("stage60 frequency response 0.1–500 Hz: max relative difference {worst:.2e}");
    assert!(worst <= 1e-8);
}
