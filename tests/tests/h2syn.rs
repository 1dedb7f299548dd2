//! Discrete LQR, Kalman filter and H2 synthesis: python-control's `dlqr` / `dlqe` and SLICOT's
//! documented SB10ED example (`test_data/lqg_reference.json`, generated once by
//! `tools/gen_lqg_reference.py`), a Lyapunov check of the filter with a cross covariance, and
//! the H2 controller's optimality under perturbation.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use sd_hinf::{dlqe, dlqr, h2syn, lft_lower, Partition};
use sd_model::linalg::lyap::{lyap, LyapKind};
use sd_model::{model_from_json_str, StateSpace};
use sd_tests::{mat, read_json, rel_err};

fn sorted_abs(p: &[num_complex::Complex64]) -> Vec<f64> {
    let mut v: Vec<f64> = p.iter().map(|z| z.norm()).collect();
    v.sort_by(f64::total_cmp);
    v
}

/// K, X and the closed-loop pole moduli of `dlqr` with a cross weight against python-control
/// on twelve seeded systems (some open-loop unstable): relative errors ≤ 1e-9.
#[test]
fn dlqr_matches_python_control() {
    let refs = read_json("lqg_reference.json");
    let mut worst: f64 = 0.0;
    for (i, c) in refs["dlqr"].as_array().unwrap().iter().enumerate() {
        let n = mat(&c["n"]);
        let r = dlqr(
            &mat(&c["a"]),
            &mat(&c["b"]),
            &mat(&c["q"]),
            &mat(&c["r"]),
            Some(&n),
        )
        .unwrap_or_else(|e| panic!("case {i}: {e}"));
        let ek = rel_err(&r.gain, &mat(&c["k"]));
        let ex = rel_err(&r.x, &mat(&c["x"]));
        let pr: Vec<f64> = c["poles_abs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let ep = sorted_abs(&r.poles)
            .iter()
            .zip(&pr)
            .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        assert!(
            ek <= 1e-9 && ex <= 1e-9 && ep <= 1e-9,
            "case {i}: {ek:e} {ex:e} {ep:e}"
        );
        worst = worst.max(ek).max(ex);
    }
    println!("dlqr: worst relative error of K, X against python-control {worst:.1e}");
}

/// The predictor gain and the prediction covariance of `dlqe` against python-control's `dlqe`
/// (G = I, no cross covariance) on twelve seeded systems: relative errors ≤ 1e-9.
#[test]
fn dlqe_matches_python_control() {
    let refs = read_json("lqg_reference.json");
    let mut worst: f64 = 0.0;
    for (i, c) in refs["dlqe"].as_array().unwrap().iter().enumerate() {
        let k = dlqe(
            &mat(&c["a"]),
            &mat(&c["g"]),
            &mat(&c["c"]),
            &mat(&c["qn"]),
            &mat(&c["rn"]),
            None,
        )
        .unwrap_or_else(|e| panic!("case {i}: {e}"));
        let el = rel_err(&k.predictor_gain, &mat(&c["l"]));
        let ep = rel_err(&k.p, &mat(&c["p"]));
        assert!(el <= 1e-9 && ep <= 1e-9, "case {i}: {el:e} {ep:e}");
        worst = worst.max(el).max(ep);
    }
    println!("dlqe: worst relative error of L, P against python-control {worst:.1e}");
}

/// With a cross covariance (which python-control refuses): the error `e⁺ = (A − LC)e + Gw − Lv`
/// of the predictor has covariance P by the Stein equation
/// `P = (A − LC)P(A − LC)ᵀ + [G −L]Σ[G −L]ᵀ`, `Σ = [Q_N N_N; N_Nᵀ R_N]` (solved here by the
/// Bartels–Stewart Lyapunov solver, not the DARE), and any other gain gives a larger trace.
#[test]
fn dlqe_with_cross_covariance_is_the_optimal_predictor() {
    let refs = read_json("lqg_reference.json");
    let mut solved = 0;
    for (i, c) in refs["dlqr"].as_array().unwrap().iter().enumerate() {
        // reuse the LQR systems: G = B, the weights as noise covariances
        let (a, g) = (mat(&c["a"]), mat(&c["b"]));
        let n = a.nrows();
        let cm = DMatrix::from_fn(1.max(n / 2), n, |r, s| ((r * 7 + s * 3) % 5) as f64 - 2.0);
        let p = cm.nrows();
        let qn = mat(&c["r"]);
        let rn = DMatrix::<f64>::identity(p, p) * 0.5;
        let nn = DMatrix::from_fn(g.ncols(), p, |r, s| 0.1 * ((r + s) % 3) as f64 - 0.1);
        let Ok(k) = dlqe(&a, &g, &cm, &qn, &rn, Some(&nn)) else {
            continue; // an undetectable (C, A) of this synthetic C: nothing to check
        };
        let cov = |l: &DMatrix<f64>| {
            let acl = &a - l * &cm;
            let mut gl = DMatrix::<f64>::zeros(n, g.ncols() + p);
            gl.view_mut((0, 0), g.shape()).copy_from(&g);
            gl.view_mut((0, g.ncols()), (n, p)).copy_from(&(-l));
            let mut sig = DMatrix::<f64>::zeros(g.ncols() + p, g.ncols() + p);
            sig.view_mut((0, 0), qn.shape()).copy_from(&qn);
            sig.view_mut((0, g.ncols()), nn.shape()).copy_from(&nn);
            sig.view_mut((g.ncols(), 0), (p, g.ncols()))
                .copy_from(&nn.transpose());
            sig.view_mut((g.ncols(), g.ncols()), (p, p)).copy_from(&rn);
            lyap(&acl, &(&gl * sig * gl.transpose()), LyapKind::Discrete).unwrap()
        };
        solved += 1;
        let pl = cov(&k.predictor_gain);
        let e = rel_err(&pl, &k.p);
        assert!(e <= 1e-9, "case {i}: {e:e}");
        for s in 0..4 {
            let d = DMatrix::from_fn(n, p, |r, q| (((r + 2 * q + s) % 3) as f64 - 1.0) * 1e-3);
            let lp = &k.predictor_gain + d;
            if (&a - &lp * &cm)
                .complex_eigenvalues()
                .iter()
                .all(|z| z.norm() < 1.0)
            {
                assert!(cov(&lp).trace() >= pl.trace() * (1.0 - 1e-12), "case {i}");
            }
        }
    }
    assert!(
        solved >= 8,
        "only {solved} of the twelve systems were detectable"
    );
}

fn model(v: &serde_json::Value) -> StateSpace {
    model_from_json_str(&v.to_string()).unwrap()
}

fn h2_of(p: &StateSpace, k: &StateSpace, part: Partition) -> Option<f64> {
    let cl = lft_lower(p, k, part).ok()?;
    if cl.poles().ok()?.iter().any(|z| z.norm() >= 1.0) {
        return None;
    }
    cl.h2_norm().ok()
}

/// SLICOT's documented SB10ED example: our H2 controller's closed-loop norm is at most that of
/// the controller SLICOT's documentation prints (78.6034 with the plant's D₁₁, by the
/// generator's numpy LFT and scipy Lyapunov solve), and our own LFT and H2 norm reproduce that
/// printed loop's value within 1e-9.
#[test]
fn sb10ed_documented_example() {
    let refs = read_json("lqg_reference.json");
    let c = &refs["sb10ed"];
    let p = model(&c["plant"]);
    let part = Partition { nmeas: 2, ncon: 2 };
    let printed = model(&c["controller"]);
    let ref_norm = c["printed_loop_h2"].as_f64().unwrap();
    let ours_of_printed = h2_of(&p, &printed, part).unwrap();
    assert!((ours_of_printed - ref_norm).abs() <= 1e-9 * ref_norm);
    let r = h2syn(&p, part).unwrap();
    println!(
        "SB10ED example: our H2 controller {:.6}, SLICOT's printed controller {ref_norm:.6}",
        r.achieved_norm
    );
    assert!(r.closed_loop_stable);
    assert!(r.achieved_norm <= ref_norm * (1.0 + 1e-9));
    assert!(r.achieved_norm >= 0.99 * ref_norm);
}

/// Optimality: on the discrete random plants of `hinfsyn_slicot.json` (D₁₁, D₂₂ ≠ 0), twenty
/// perturbations of every controller matrix by 1e-4 relative never lower the closed-loop H2
/// norm (by more than 1e-12 relative), and the norm from the Gramian is finite.
#[test]
fn h2_controller_is_not_improved_by_perturbation() {
    let refs = read_json("hinfsyn_slicot.json");
    let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut checked = 0;
    for case in refs["cases"].as_array().unwrap() {
        let p = model(&case["plant"]);
        if !p.time().is_discrete() {
            continue;
        }
        let part = Partition {
            nmeas: case["nmeas"].as_u64().unwrap() as usize,
            ncon: case["ncon"].as_u64().unwrap() as usize,
        };
        let r = h2syn(&p, part).unwrap();
        let k = &r.controller;
        let j0 = r.achieved_norm;
        assert!(j0.is_finite() && r.closed_loop_stable);
        for _ in 0..20 {
            let mut pert = |m: &DMatrix<f64>| {
                let s = 1e-4 * m.norm().max(1e-3);
                m.map(|v| v + s * next())
            };
            let kp = StateSpace::new(pert(k.a()), pert(k.b()), pert(k.c()), pert(k.d()), k.time())
                .unwrap();
            if let Some(j) = h2_of(&p, &kp, part) {
                assert!(j >= j0 * (1.0 - 1e-12), "{}: {j} < {j0}", case["name"]);
                checked += 1;
            }
        }
    }
    assert!(checked >= 100, "{checked}");
}
