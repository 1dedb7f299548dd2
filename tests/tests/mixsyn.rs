//! Mixed-sensitivity design on Skogestad & Postlethwaite's Example 2.11
//! (`test_data/mixsyn_reference.json`, generated once by `tools/gen_mixsyn_reference.py`:
//! python-control's `mixsyn`/`augw` with slycot), and an independent frequency-grid evaluation
//! of `[W₁S; W₂KS; W₃T]` from G, K and the weights themselves (no generalized plant).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_hinf::{mixsyn, weights, HinfOptions, MixsynWeights};
use sd_model::{model_from_json_str, StateSpace};
use sd_tests::read_json;

fn model(v: &serde_json::Value) -> StateSpace {
    model_from_json_str(&v.to_string()).unwrap()
}

fn at(sys: &StateSpace, f_hz: f64) -> DMatrix<C> {
    sys.freqresp(&[f_hz]).unwrap().response()[0].clone()
}

/// `max_f σ̄([W₁S; W₂KS; W₃T; −W₁SGW_d; …])` over a log grid, from the blocks' own responses.
fn grid_norm(g: &StateSpace, k: &StateSpace, w: &MixsynWeights<'_>, fmax: f64) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..4000 {
        let f = 1e-4 * (fmax / 1e-4f64).powf(i as f64 / 3999.0);
        let (gf, kf) = (at(g, f), at(k, f));
        let ny = gf.nrows();
        let s = (DMatrix::<C>::identity(ny, ny) + &gf * &kf)
            .try_inverse()
            .unwrap();
        let t = &gf * &kf * &s;
        let mut blocks: Vec<DMatrix<C>> = Vec::new();
        if let Some(w1) = w.w1 {
            blocks.push(at(w1, f) * &s);
        }
        if let Some(w2) = w.w2 {
            blocks.push(at(w2, f) * &kf * &s);
        }
        if let Some(w3) = w.w3 {
            blocks.push(at(w3, f) * &t);
        }
        let rows: usize = blocks.iter().map(|b| b.nrows()).sum();
        let mut m = DMatrix::<C>::zeros(rows, ny);
        let mut r = 0;
        for b in &blocks {
            m.rows_mut(r, b.nrows()).copy_from(b);
            r += b.nrows();
        }
        worst = worst.max(m.singular_values().max());
    }
    worst
}

/// Continuous: γ_min within 3·tol of the checked SLICOT optimum and of python-control's `mixsyn`
/// γ (1.3659 — the book's 1.37). Discrete (ts = 0.01 s, a W₁ pole at z = 0.99999): γ_min
/// 1.3971, *below* the least γ at which SB10DD's controllers pass the check (1.4064) — between
/// 1.398 and 1.402 SB10DD returns controllers whose loops reach norms of 17 to 69 (recorded by
/// the generator); ours is confirmed by the grid. Both: the frequency-grid norm of the stacked
/// closed loop, computed without the generalized plant, is at most γ(1 + 1e-6) and within 1e-3
/// of the achieved norm.
#[test]
fn skogestad_postlethwaite_example_2_11() {
    let refs = read_json("mixsyn_reference.json");
    for (name, fmax) in [("continuous", 1e4), ("discrete", 49.999)] {
        let c = &refs[name];
        let (g, w1, w2) = (model(&c["g"]), model(&c["w1"]), model(&c["w2"]));
        let w = MixsynWeights {
            w1: Some(&w1),
            w2: Some(&w2),
            ..Default::default()
        };
        let opt = HinfOptions::default();
        let (r, p) = mixsyn(&g, &w, &opt).unwrap();
        let g_ref = c["gamma_opt"].as_f64().unwrap();
        let grid = grid_norm(&g, &r.controller, &w, fmax);
        println!(
            "{name}: γ_min {:.6} vs checked SLICOT {g_ref:.6}; achieved {:.6}, grid {grid:.6}; \
             generalized plant {} states",
            r.gamma_min,
            r.achieved_norm,
            p.n()
        );
        if name == "continuous" {
            assert!((r.gamma_min - g_ref).abs() <= 3.0 * opt.tolerance * g_ref);
        } else {
            assert!(r.gamma_min <= g_ref);
            for (gam, n) in c["slicot_loop_norm_at"].as_object().unwrap() {
                let n = n.as_f64().unwrap_or(f64::INFINITY);
                println!("  SB10DD's controller at γ {gam}: loop norm {n:.3}");
                assert!(n > gam.parse::<f64>().unwrap());
            }
        }
        assert!(grid <= r.gamma * (1.0 + 1e-6));
        assert!(grid >= r.achieved_norm * (1.0 - 1e-3));
        if let Some(pc) = c["python_control_gamma"].as_f64() {
            assert!((r.gamma_min - pc).abs() <= 3.0 * opt.tolerance * pc);
        }
    }
}

/// The weights' sizes, sample times and presence are checked: no S/KS/T weight, a weight of
/// the wrong size, a continuous weight on a discrete plant — each an error naming it.
#[test]
fn mixsyn_refuses_inconsistent_weights() {
    let refs = read_json("mixsyn_reference.json");
    let g = model(&refs["discrete"]["g"]);
    let opt = HinfOptions::default();
    let e = mixsyn(&g, &MixsynWeights::default(), &opt).unwrap_err();
    assert!(e.to_string().contains("at least one of W1"), "{e}");
    let ct = weights::makeweight(100.0, 1.0, 1.0, 0.5, 1, None).unwrap();
    let e = mixsyn(
        &g,
        &MixsynWeights {
            w1: Some(&ct),
            ..Default::default()
        },
        &opt,
    )
    .unwrap_err();
    assert!(e.to_string().contains("different sample times"), "{e}");
    let two = sd_model::connect::append(&ct, &ct).unwrap();
    let e = mixsyn(
        &g,
        &MixsynWeights {
            w2: Some(&two),
            ..Default::default()
        },
        &opt,
    )
    .unwrap_err();
    assert!(e.to_string().contains("W2"), "{e}");
}
