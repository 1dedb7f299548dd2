//! the delayed-hold and averaging-sampler discretisations against a
//! brute-force fine-step simulation of the continuous system (to 1e-8), and the fast-model
//! route against a direct fast-rate simulation.
//!
//! Brute force: N sub-steps per period, each split in two exact half-steps (so the input switch
//! at τ = αh and the window start h − βh fall on sub-step boundaries), the output integral by
//! Simpson's rule on each sub-step — independent of the block-exponential integrals under test.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::{DMatrix, DVector};
use sd_model::{c2d, Discretization, StateSpace};
use sd_multirate::{c2d_nonideal, downsample_nonideal, NonIdeal};
use sd_tests::gen::{model, with_blocks, Rng};

fn brute_force(
    p: &StateSpace,
    h: f64,
    m: usize,
    q: usize,
    subs: usize,
    u: &DMatrix<f64>,
) -> DMatrix<f64> {
    let half = c2d(p, h / subs as f64 / 2.0, Discretization::Zoh).unwrap();
    let (phi, gam, c, d) = (half.a(), half.b(), p.c(), p.d());
    let dt = h / subs as f64;
    let (k_max, ny) = (u.nrows(), p.ny());
    let mut x = DVector::<f64>::zeros(p.n());
    let mut y = DMatrix::zeros(k_max, ny);
    let zero = DVector::<f64>::zeros(p.nu());
    // the command in force at sub-step s of period k: the last one issued m sub-steps earlier
    // (any m, also beyond one period)
    let input = |k: usize, s: usize| -> DVector<f64> {
        let t = (k * subs + s) as i64 - m as i64;
        if t < 0 {
            zero.clone()
        } else {
            u.row(t as usize / subs).transpose()
        }
    };
    let mut avg = DVector::<f64>::zeros(ny); // average over the window ending at kh
    for k in 0..k_max {
        let at_sample = input(k, 0);
        let yk = if q > 0 {
            avg.clone()
        } else {
            c * &x + d * &at_sample
        };
        y.row_mut(k).copy_from(&yk.transpose());
        let mut integral = DVector::<f64>::zeros(ny);
        for s in 0..subs {
            let us = &input(k, s);
            let y0 = c * &x + d * us;
            let xm = phi * &x + gam * us;
            let ym = c * &xm + d * us;
            let x1 = phi * &xm + gam * us;
            let y1 = c * &x1 + d * us;
            if s + q >= subs {
                integral += (y0 + ym * 4.0 + y1) * (dt / 6.0);
            }
            x = x1;
        }
        if q > 0 {
            avg = integral / (q as f64 * dt);
        }
    }
    y
}

fn check(p: &StateSpace, h: f64, subs: usize, cases: &[(usize, usize)], seed: u64) -> f64 {
    let mut r = Rng::new(seed);
    let u = r.matrix(300, p.nu());
    let mut worst: f64 = 0.0;
    for &(m, q) in cases {
        let ni = NonIdeal {
            hold_delay: m as f64 / subs as f64,
            averaging: q as f64 / subs as f64,
        };
        let dm = c2d_nonideal(p, h, ni).unwrap();
        let y = dm.simulate(&u, None).unwrap().y;
        let yb = brute_force(p, h, m, q, subs, &u);
        let e = (&y - &yb).norm() / yb.norm();
        println!(
            "α = {:.3}, β = {:.3}: relative difference {e:.2e}",
            ni.hold_delay, ni.averaging
        );
        assert!(e <= 1e-8, "α {} β {}: {e:e}", ni.hold_delay, ni.averaging);
        worst = worst.max(e);
        if (m, q) != (0, 0) {
            // the effect is far above the tolerance: an ideal ZOH model would fail this test
            let y0 = c2d(p, h, Discretization::Zoh)
                .unwrap()
                .simulate(&u, None)
                .unwrap()
                .y;
            let e0 = (&y0 - &yb).norm() / yb.norm();
            assert!(
                e0 > 1e-3,
                "α {} β {}: effect only {e0:e}",
                ni.hold_delay,
                ni.averaging
            );
        }
    }
    worst
}

const CASES: [(usize, usize); 8] = [
    (0, 0),
    (300, 0),
    (1000, 0),
    (0, 500),
    (0, 1000),
    (250, 800),
    (600, 700),
    (777, 1),
];

/// Hold delays beyond one period (α = m + φ: whole periods of input delay, then the fractional
/// hold), alone and with an averaging window, against the same brute force.
#[test]
fn delayed_hold_beyond_one_period_vs_fine_simulation() {
    let p = sd_model::stage::paper_stage(0.01).unwrap();
    let worst = check(
        &p,
        1e-3,
        1000,
        &[(1400, 0), (2000, 0), (1250, 600), (3700, 0)],
        4,
    );
    assert!(worst <= 1e-8);
}

#[test]
fn nonideal_paper_stage_at_1khz_vs_fine_simulation() {
    // the 653 Hz mode above the 500 Hz Nyquist frequency is where the effects matter
    let p = sd_model::stage::paper_stage_two_modes().unwrap();
    let w = check(&p, 1e-3, 1000, &CASES, 1);
    println!("paper stage (two modes) at 1 kHz: worst {w:.2e}");
}

#[test]
fn nonideal_random_mimo_with_feedthrough_vs_fine_simulation() {
    let mut r = Rng::new(42);
    let h = 1e-3;
    let pairs: Vec<(f64, f64)> = [300.0, 650.0, 1400.0]
        .iter()
        .map(|&f: &f64| {
            let w = 2.0 * std::f64::consts::PI * f;
            (-0.01 * w, w)
        })
        .collect();
    let a = with_blocks(&mut r, 1, &[-2000.0], &pairs);
    let p = model(&mut r, a, 2, 3, true);
    let w = check(&p, h, 1000, &CASES, 2);
    println!("random 3x2 with feedthrough and a rigid body: worst {w:.2e}");
}

#[test]
fn nonideal_from_fast_model_equals_direct_fast_simulation() {
    // slow hold delayed by m fast samples, mean of the last q fast outputs
    let p = sd_model::stage::paper_stage_two_modes().unwrap();
    let (h, f) = (2e-4, 5usize);
    let ph = c2d(&p, h, Discretization::Zoh).unwrap();
    let ph = StateSpace::new(
        ph.a().clone(),
        ph.b().clone(),
        ph.c().clone(),
        DMatrix::from_element(1, 1, 3e-8),
        ph.time(),
    )
    .unwrap();
    let mut r = Rng::new(3);
    let us = r.matrix(200, 1);
    for m in 0..=f {
        for q in 1..=f {
            let ni = NonIdeal {
                hold_delay: m as f64 / f as f64,
                averaging: q as f64 / f as f64,
            };
            let slow = downsample_nonideal(&ph, f, ni).unwrap();
            let ys = slow.simulate(&us, None).unwrap().y;
            // direct: fast input sequence with the delayed slow hold, then average
            let n = us.nrows() * f;
            let uf = DMatrix::from_fn(n, 1, |j, _| {
                let (k, i) = (j / f, j % f);
                if i < m {
                    if k > 0 {
                        us[(k - 1, 0)]
                    } else {
                        0.0
                    }
                } else {
                    us[(k, 0)]
                }
            });
            let yf = ph.simulate(&uf, None).unwrap().y;
            let yd = DMatrix::from_fn(us.nrows(), 1, |k, _| {
                (0..q)
                    .filter(|&i| k * f >= i)
                    .map(|i| yf[(k * f - i, 0)])
                    .sum::<f64>()
                    / q as f64
            });
            let e = (&ys - &yd).norm() / yd.norm();
            assert!(e <= 1e-10, "m {m} q {q}: {e:e}");
        }
    }
}
