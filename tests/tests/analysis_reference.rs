//! margins, |S| peaks and sensitivities against python-control on six
//! reference loops (`test_data/analysis_reference.json`, generated once by
//! `tools/gen_analysis_reference.py` with python-control 0.10.1 and scipy).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_analysis::ClosedLoop;
use sd_model::{model_from_json_str, StateSpace};
use sd_tests::read_json;

fn model(v: &serde_json::Value) -> StateSpace {
    model_from_json_str(&v.to_string()).unwrap()
}

fn rel(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / b.abs().max(1e-300)
    }
}

#[test]
fn margins_and_peaks_match_python_control() {
    let refs = read_json("analysis_reference.json");
    let mut worst: f64 = 0.0;
    for case in refs["loops"].as_array().unwrap() {
        let name = case["name"].as_str().unwrap();
        let cl = ClosedLoop::new(&model(&case["plant"]), &model(&case["controller"])).unwrap();
        let m = cl.margins().unwrap();
        let (stable_radius, stable) = cl.stability().unwrap();
        let (peak, peak_hz) = cl.sensitivity_peak().unwrap();
        let g = |k: &str| case[k].as_f64().unwrap_or(f64::INFINITY);
        println!(
            "{name}: GM {:.9} (pc {:.9}) PM {:.9} (pc {:.9}) | MM {:.9} (pc sm {:.9}) | |S| peak {:.9} at {:.6} Hz (ref {:.9} at {:.6}) | stable {stable} ({stable_radius:.6})",
            m.gain_margin, g("gm"), m.phase_margin_deg, g("pm"), m.modulus_margin, g("sm"), peak, peak_hz, g("s_peak"), g("s_peak_hz")
        );
        assert_eq!(stable, case["stable"].as_bool().unwrap(), "{name}");
        let mut check = |what: &str, ours: f64, theirs: f64, tol: f64| {
            if theirs.is_finite() || ours.is_finite() {
                let e = rel(ours, theirs);
                assert!(e <= tol, "{name}: {what} {ours} vs {theirs} ({e:e})");
                worst = worst.max(e);
            }
        };
        if g("gm").is_finite() {
            check("gain margin", m.gain_margin, g("gm"), 1e-6);
        } else {
            // python-control misses a phase crossover at the Nyquist frequency (L(−1) < 0)
            println!(
                "  python-control reports no gain margin; ours is {} at {} Hz",
                m.gain_margin, m.phase_crossover_hz
            );
        }
        // independent check of every finite gain margin: K·GM puts a closed-loop pole on the
        // stability boundary
        if m.gain_margin.is_finite() && m.gain_margin > 0.0 {
            let k = model(&case["controller"]);
            let ks = StateSpace::new(
                k.a().clone(),
                k.b().clone(),
                k.c() * m.gain_margin,
                k.d() * m.gain_margin,
                k.time(),
            )
            .unwrap();
            let (r, _) = ClosedLoop::new(&model(&case["plant"]), &ks)
                .unwrap()
                .stability()
                .unwrap();
            let boundary = if k.time().is_continuous() { 0.0 } else { 1.0 };
            assert!(
                (r - boundary).abs() < 1e-6,
                "{name}: K·GM gives {r}, not {boundary}"
            );
        }
        if g("wpc_hz").is_finite() {
            if g("wpc_hz") == 0.0 {
                assert_eq!(m.phase_crossover_hz, 0.0);
            } else {
                check("phase crossover", m.phase_crossover_hz, g("wpc_hz"), 1e-6);
            }
        }
        check("phase margin", m.phase_margin_deg, g("pm"), 1e-6);
        check("gain crossover", m.gain_crossover_hz, g("wgc_hz"), 1e-6);
        // |S| peak: value to 1e-6; our modulus margin is its inverse
        check("|S| peak", peak, g("s_peak"), 1e-6);
        check("modulus margin", m.modulus_margin, 1.0 / g("s_peak"), 1e-6);
        // python-control's sm keeps interior minima only; where it found the global one, equal
        if g("sm").is_finite() && rel(g("sm"), 1.0 / g("s_peak")) < 1e-4 {
            check(
                "modulus margin vs python-control sm",
                m.modulus_margin,
                g("sm"),
                1e-6,
            );
        }
        // (the reference grid ends at 1 kHz for continuous loops: a peak there is at ω → ∞)
        if !(g("s_peak_hz") > 999.0 && peak_hz.is_infinite()) {
            check("|S| peak frequency", peak_hz, g("s_peak_hz"), 1e-4);
        }
        for p in case["points"].as_array().unwrap() {
            let f = p["freq_hz"].as_f64().unwrap();
            let r = cl.responses(f).unwrap();
            for (key, v) in [("S", &r.s), ("T", &r.t), ("PS", &r.ps), ("KS", &r.ks)] {
                check(key, v[(0, 0)].norm(), p[key].as_f64().unwrap(), 1e-6);
            }
        }
    }
    println!("worst relative difference: {worst:.2e}");
}
