//! Property tests (proptest, 256 cases each by default).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use proptest::prelude::*;
use sd_model::{c2d, Discretization, StateSpace};
use sd_tests::gen::{model, with_poles, Rng};

fn stable_model(
    seed: u64,
    n_pairs: usize,
    n_real: usize,
    nu: usize,
    ny: usize,
    fb: bool,
) -> StateSpace {
    let mut r = Rng::new(seed);
    let pairs: Vec<(f64, f64)> = (0..n_pairs)
        .map(|_| (-r.range(0.05, 5.0), r.range(0.5, 50.0)))
        .collect();
    let real: Vec<f64> = (0..n_real.max(if n_pairs == 0 { 1 } else { 0 }))
        .map(|_| -r.range(0.1, 20.0))
        .collect();
    let a = with_poles(&mut r, &real, &pairs);
    model(&mut r, a, nu, ny, fb)
}

fn maxabs(m: &DMatrix<C>) -> f64 {
    m.iter().map(|v| v.norm()).fold(0.0, f64::max)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn c2d_keeps_dc_gain(seed in any::<u64>(), np in 0usize..4, nr in 0usize..3, nu in 1usize..4, ny in 1usize..4, fb in any::<bool>(), h in 1e-3f64..0.5) {
        let g = stable_model(seed, np, nr, nu, ny, fb);
        for method in [Discretization::Zoh, Discretization::Foh, Discretization::Tustin { prewarp_hz: None }] {
            let gd = c2d(&g, h, method).unwrap();
            let dc_c = g.eval_direct(C::new(0.0, 0.0)).unwrap();
            let dc_d = gd.eval_direct(C::new(1.0, 0.0)).unwrap();
            let scale = maxabs(&dc_c).max(1e-3);
            prop_assert!(maxabs(&(dc_c - dc_d)) <= 1e-9 * scale, "{:?}", method);
        }
    }

    #[test]
    fn zoh_stability_preserved(seed in any::<u64>(), np in 1usize..5, unstable in any::<bool>(), h in 1e-3f64..0.2) {
        let mut r = Rng::new(seed);
        let mut pairs: Vec<(f64, f64)> = (0..np).map(|_| (-r.range(0.05, 5.0), r.range(0.5, 50.0))).collect();
        if unstable {
            pairs[0].0 = r.range(0.05, 5.0);
        }
        let a = with_poles(&mut r, &[], &pairs);
        let g = model(&mut r, a, 1, 1, false);
        let gd = c2d(&g, h, Discretization::Zoh).unwrap();
        let rho = gd.poles().unwrap().iter().map(|p| p.norm()).fold(0.0, f64::max);
        let alpha = g.poles().unwrap().iter().map(|p| p.re).fold(f64::NEG_INFINITY, f64::max);
        prop_assert_eq!(rho < 1.0, alpha < 0.0, "rho {} alpha {}", rho, alpha);
        // and ρ = e^{α h} exactly
        prop_assert!((rho - (alpha * h).exp()).abs() <= 1e-10 * rho);
    }

    #[test]
    fn interconnections_match_frequency_responses(seed in any::<u64>(), n1 in 0usize..3, n2 in 0usize..3, m in 1usize..3, dt in any::<bool>()) {
        let mut g1 = stable_model(seed, n1, 1, m, m, true);
        let mut g2 = stable_model(seed ^ 0xabcdef, n2, 1, m, m, true);
        let mut s = C::new(0.3, 1.7);
        if dt {
            g1 = c2d(&g1, 0.05, Discretization::Zoh).unwrap();
            g2 = c2d(&g2, 0.05, Discretization::Zoh).unwrap();
            s = C::from_polar(1.0, 0.9);
        }
        let e1 = g1.eval_direct(s).unwrap();
        let e2 = g2.eval_direct(s).unwrap();
        let ser = sd_model::series(&g1, &g2).unwrap().eval_direct(s).unwrap();
        prop_assert!(maxabs(&(&ser - &e2 * &e1)) <= 1e-9 * maxabs(&ser).max(1.0));
        let par = sd_model::parallel(&g1, &g2).unwrap().eval_direct(s).unwrap();
        prop_assert!(maxabs(&(&par - (&e1 + &e2))) <= 1e-9 * maxabs(&par).max(1.0));
        // negative feedback: (I + G1 G2)⁻¹ G1 (skip ill-posed loops)
        let id = DMatrix::<C>::identity(m, m);
        if let Some(inv) = (&id + &e1 * &e2).try_inverse() {
            if let Ok(fbk) = sd_model::feedback(&g1, &g2, -1.0) {
                let want = inv * &e1;
                let got = fbk.eval_direct(s).unwrap();
                prop_assert!(maxabs(&(&got - &want)) <= 1e-8 * maxabs(&want).max(1.0));
            }
        }
        // the fast evaluator equals the direct solve
        let ev = sd_model::FreqRespEvaluator::new(&g1).unwrap();
        prop_assert!(maxabs(&(ev.eval_at(s) - &e1)) <= 1e-10 * maxabs(&e1).max(1.0));
    }
}
