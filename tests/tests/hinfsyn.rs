//! H∞ synthesis on generalized plants against SLICOT (`test_data/hinfsyn_slicot.json`, generated
//! once by `tools/gen_hinfsyn_reference.py` with slycot 0.7.1: SB10DD for the discrete plants,
//! SB10FD for the continuous ones, γ_opt by bisection on "SLICOT returns a controller whose
//! loop is stable and meets γ on a frequency grid").
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_hinf::{hinfsyn, lft_lower, HinfOptions, Partition};
use sd_model::{model_from_json_str, StateSpace};
use sd_tests::read_json;

fn model(v: &serde_json::Value) -> StateSpace {
    model_from_json_str(&v.to_string()).unwrap()
}

/// γ_min within three times the iteration's tolerance (plus the reference's 1e-7) of SLICOT's
/// checked optimum (the bisection ends within one tolerance; the independent check of the final
/// controller may raise γ by a tolerance step or two near the optimum, where the central
/// controller is ill-conditioned; measured: 6.4e-4 at the default 1e-3, 1.4e-6 at 1e-6); the controller's loop stable with its norm ≤ γ(1 + 1e-6) by the toolkit's own
/// H∞ norm, recomputed here from the returned controller.
#[test]
fn gamma_min_matches_slicots_checked_optimum() {
    check_against_slicot(HinfOptions::default());
}

/// The same at a relative tolerance of 1e-6: the boundary where our existence test starts to
/// pass is SLICOT's checked optimum to that tolerance, not only to the default 1e-3.
#[test]
fn gamma_min_matches_slicot_to_1e_minus_6() {
    check_against_slicot(HinfOptions {
        tolerance: 1e-6,
        ..HinfOptions::default()
    });
}

fn check_against_slicot(opt: HinfOptions) {
    let refs = read_json("hinfsyn_slicot.json");
    let mut worst: f64 = 0.0;
    let mut below = 0;
    for case in refs["cases"].as_array().unwrap() {
        let name = case["name"].as_str().unwrap();
        let p = model(&case["plant"]);
        let part = Partition {
            nmeas: case["nmeas"].as_u64().unwrap() as usize,
            ncon: case["ncon"].as_u64().unwrap() as usize,
        };
        let g_ref = case["gamma_opt"].as_f64().unwrap();
        let accepts = case["slicot_accepts_down_to"].as_f64().unwrap();
        let r = hinfsyn(&p, part, &opt).unwrap_or_else(|e| panic!("{name}: {e}"));
        let rel = (r.gamma_min - g_ref) / g_ref;
        println!(
            "{name}: γ_min {:.6} SLICOT checked {:.6} (rel {rel:+.1e}), SLICOT returns \
             controllers down to {accepts:.4}; achieved {:.6}, {} steps",
            r.gamma_min,
            g_ref,
            r.achieved_norm,
            r.steps.len()
        );
        assert!(
            rel.abs() <= 3.0 * opt.tolerance + 2e-7,
            "{name}: γ_min {} vs {g_ref}",
            r.gamma_min
        );
        assert!(r.gamma_infeasible < r.gamma_min);
        assert!(r.gamma_min <= r.gamma_infeasible * (1.0 + opt.tolerance) * (1.0 + 1e-12));
        let cl = lft_lower(&p, &r.controller, part).unwrap();
        let norm = cl.hinf_norm().unwrap();
        assert!(norm.stable, "{name}: loop unstable");
        assert!(
            norm.value <= r.gamma * (1.0 + 1e-6),
            "{name}: {}",
            norm.value
        );
        worst = worst.max(rel.abs());
        if accepts < g_ref * (1.0 - 1e-3) {
            below += 1;
        }
    }
    println!(
        "worst |γ_min − γ_SLICOT|/γ_SLICOT = {worst:.1e}; SLICOT returned controllers below \
         the checked optimum on {below} plants"
    );
}

/// SLICOT's documented SB10DD example: the controller its documentation prints for γ = 111.294
/// (four decimals) closes a stable loop whose norm, by our LFT and H∞ norm, is the generator's
/// grid value (111.875: the rounding of the printed digits costs 0.5 %; slycot's full-precision
/// controller reaches 111.2939) within 1e-6; our γ_min is SLICOT's checked optimum (111.2932) within the tolerance — while
/// SB10DD itself returns controllers down to γ ≈ 23.58, almost five times lower, whose loops
/// fail the check.
#[test]
fn slicots_documented_example() {
    let refs = read_json("hinfsyn_slicot.json");
    let case = &refs["cases"][0];
    assert!(case["name"].as_str().unwrap().contains("documented"));
    let p = model(&case["plant"]);
    let part = Partition { nmeas: 2, ncon: 2 };
    let published = &case["published"];
    let k = model(&published["controller"]);
    let cl = lft_lower(&p, &k, part).unwrap();
    let norm = cl.hinf_norm().unwrap();
    let g_pub = published["gamma"].as_f64().unwrap();
    println!(
        "published controller at γ {g_pub}: loop stable {}, norm {:.6}",
        norm.stable, norm.value
    );
    assert!(norm.stable);
    let grid = published["printed_loop_norm"].as_f64().unwrap();
    assert!(
        (norm.value - grid).abs() <= 1e-6 * grid,
        "{} vs {grid}",
        norm.value
    );
    assert!(published["slycot_loop_norm"].as_f64().unwrap() <= g_pub);
    let r = hinfsyn(&p, part, &HinfOptions::default()).unwrap();
    let g_ref = case["gamma_opt"].as_f64().unwrap();
    let accepts = case["slicot_accepts_down_to"].as_f64().unwrap();
    println!(
        "γ_min {:.6} vs SLICOT checked {g_ref:.6}; SB10DD returns controllers down to \
         {accepts:.4} ({:.1}x lower)",
        r.gamma_min,
        g_ref / accepts
    );
    assert!((r.gamma_min - g_ref).abs() <= 3.0 * 1e-3 * g_ref);
    assert!(accepts < 0.25 * g_ref);
}
