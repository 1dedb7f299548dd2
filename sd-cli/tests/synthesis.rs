//! `sdctl hinfsyn`, `sdctl h2syn`, `sdctl mixsyn` and `sdctl reduce --controller`: the JSON a user gets, and the bad inputs it refuses with exit 2 and one line.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::{Command, Output};

/// `x⁺ = 1.1x + w₁ + u`, `z = [x; u]`, `y = x + w₂` at 1 kHz: an unstable plant, the control
/// penalized, the measurement noisy.
const PLANT: &str = r#"{"type":"ss","ts":0.001,"a":[[1.1]],"b":[[1,0,1]],
  "c":[[1],[0],[1]],"d":[[0,0,0],[0,0,1],[0,1,0]]}"#;
/// Continuous, the control not penalized at all (D₁₂ = 0).
const NO_D12: &str = r#"{"type":"ss","ts":null,"a":[[-1]],"b":[[1,0,1]],
  "c":[[1],[0],[1]],"d":[[0,0,0],[0,0,0],[0,1,0]]}"#;
/// A second unstable state that neither the control nor the measurement reaches.
const UNSTABILIZABLE: &str = r#"{"type":"ss","ts":0.001,"a":[[1.1,0],[0,1.5]],
  "b":[[1,0,1],[1,0,0]],"c":[[1,1],[0,0],[1,0]],"d":[[0,0,0],[0,0,1],[0,1,0]]}"#;

fn file(name: &str, text: &str) -> String {
    let d = std::env::temp_dir().join(format!("sdctl-hinfsyn-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_string_lossy().into_owned()
}

fn sdctl(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(args)
        .output()
        .unwrap()
}

/// Exit 0, else the failure's stderr.
fn succeeded(o: &Output) {
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn one_line_error(o: &Output, code: i32, must: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(code), "stderr: {err}");
    assert_eq!(err.trim().lines().count(), 1, "stderr: {err}");
    assert!(err.contains(must), "stderr: {err}");
}

/// The JSON: γ, γ_min, the achieved norm within γ(1 + 1e-6), a discrete controller at the
/// plant's rate, and the γ iteration's record.
#[test]
fn the_json_has_gamma_the_achieved_norm_and_the_controller() {
    let p = file("p.json", PLANT);
    let o = sdctl(&["hinfsyn", &p, "--nmeas", "1", "--ncon", "1", "--json"]);
    succeeded(&o);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (g, gmin, ach) = (
        v["gamma"].as_f64().unwrap(),
        v["gamma_min"].as_f64().unwrap(),
        v["achieved_norm"].as_f64().unwrap(),
    );
    assert_eq!(g, gmin);
    assert!(v["gamma_infeasible"].as_f64().unwrap() < gmin);
    assert!(ach <= g * (1.0 + 1e-6) && ach > 0.5 * g, "{ach} vs {g}");
    assert_eq!(v["closed_loop_stable"], serde_json::json!(true));
    assert_eq!(v["controller"]["ts"].as_f64(), Some(0.001));
    assert!(!v["steps"].as_array().unwrap().is_empty());
    // a level above γ_min is honoured
    let above = format!("{}", 2.0 * gmin);
    let o = sdctl(&[
        "hinfsyn", &p, "--nmeas", "1", "--ncon", "1", "--gamma", &above, "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["gamma"].as_f64().unwrap(), 2.0 * gmin);
    assert!(v["achieved_norm"].as_f64().unwrap() <= 2.0 * gmin * (1.0 + 1e-6));
}

/// γ below γ_min, a partition that leaves no exogenous channel, a D₁₂ of rank 0 and a plant no
/// controller stabilizes: exit 2, one line naming the problem.
#[test]
fn bad_problems_are_refused_with_the_reason() {
    let p = file("p2.json", PLANT);
    let o = sdctl(&[
        "hinfsyn", &p, "--nmeas", "1", "--ncon", "1", "--gamma", "0.01",
    ]);
    one_line_error(&o, 2, "below γ_min");
    let o = sdctl(&["hinfsyn", &p, "--nmeas", "3", "--ncon", "1"]);
    one_line_error(&o, 2, "nmeas = 3");
    let o = sdctl(&["hinfsyn", &p, "--nmeas", "1", "--ncon", "1", "--tol", "2"]);
    one_line_error(&o, 2, "tolerance");
    let q = file("nod12.json", NO_D12);
    let o = sdctl(&["hinfsyn", &q, "--nmeas", "1", "--ncon", "1"]);
    one_line_error(&o, 2, "D₁₂ has rank 0");
    let u = file("unstab.json", UNSTABILIZABLE);
    let o = sdctl(&["hinfsyn", &u, "--nmeas", "1", "--ncon", "1"]);
    one_line_error(&o, 2, "stabilizable");
}

/// `sdctl h2syn`: a finite achieved norm, a stable loop, the controller at the plant's rate; a
/// partition without exogenous channels refused.
#[test]
fn h2syn_json_and_a_bad_partition() {
    let p = file("p3.json", PLANT);
    let o = sdctl(&["h2syn", &p, "--nmeas", "1", "--ncon", "1", "--json"]);
    succeeded(&o);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["achieved_norm"].as_f64().unwrap().is_finite());
    assert_eq!(v["closed_loop_stable"], serde_json::json!(true));
    assert_eq!(v["controller"]["ts"].as_f64(), Some(0.001));
    let o = sdctl(&["h2syn", &p, "--nmeas", "1", "--ncon", "3"]);
    one_line_error(&o, 2, "ncon = 3");
}

/// `sdctl reduce --controller K --plant P --order 3 [--method M] --json`, which must succeed.
fn reduce_json(k: &str, p: &str, method: Option<&str>) -> serde_json::Value {
    let mut args = vec![
        "reduce",
        "--controller",
        k,
        "--plant",
        p,
        "--order",
        "3",
        "--json",
    ];
    if let Some(m) = method {
        args.extend(["--method", m]);
    }
    let o = sdctl(&args);
    succeeded(&o);
    serde_json::from_slice(&o.stdout).unwrap()
}

/// `sdctl reduce --controller`: a loopshaping controller (6 states) of a damped double
/// integrator reduced to 3 states keeps the loop within 0.1 dB (JSON: orders, the band, |ΔS|,
/// |ΔT|, the loop before and after, the controller); to 1 state it loses the loop: exit 1, one
/// line; to 0 states (below its integrator) it is refused: exit 2.
#[test]
fn reduce_controller_keeps_the_loop_or_says_it_cannot() {
    let ct = file(
        "mass.json",
        r#"{"type":"ss","ts":null,"a":[[0,1],[0,-0.1]],"b":[[0],[1]],"c":[[1,0]],"d":[[0]]}"#,
    );
    let dir = std::path::Path::new(&ct).parent().unwrap().to_path_buf();
    let path = |n: &str| dir.join(n).to_string_lossy().into_owned();
    let (p, w, k) = (
        path("mass_p.json"),
        path("mass_w.json"),
        path("mass_k.json"),
    );
    for args in [
        vec!["c2d", &ct, "--ts", "0.001", "-o", &p],
        vec![
            "weight",
            "pid",
            "--bandwidth-hz",
            "20",
            "--mass",
            "1",
            "--ts",
            "0.001",
            "-o",
            &w,
        ],
        vec!["loopshape", &p, "--w1", &w, "-o", &k],
    ] {
        let o = sdctl(&args);
        succeeded(&o);
    }
    // the default for a SISO discrete loop: the loop-weighted fit
    let v = reduce_json(&k, &p, None);
    assert_eq!(v["order_before"].as_u64(), Some(6));
    assert_eq!(v["order_after"].as_u64(), Some(3));
    assert_eq!(v["method"], serde_json::json!("loop_fit"));
    assert_eq!(v["controller"]["a"].as_array().unwrap().len(), 3);
    for (method, name, within) in [
        ("weighted", "closed_loop_weighted", 0.1),
        ("coprime", "coprime_factor", 0.5),
        ("fit", "loop_fit", 0.1),
    ] {
        let v = reduce_json(&k, &p, Some(method));
        assert_eq!(v["method"], serde_json::json!(name));
        assert_eq!(v["after"]["stable"], serde_json::json!(true), "{method}");
        assert!(v["max_delta_s_db"].as_f64().unwrap() <= within, "{v}");
        assert!(v["max_delta_t_db"].as_f64().unwrap() <= within, "{v}");
    }
    let o = sdctl(&[
        "reduce",
        "--controller",
        &k,
        "--plant",
        &p,
        "--order",
        "3",
        "--method",
        "optimal",
    ]);
    one_line_error(&o, 2, "coprime");
    let o = sdctl(&["reduce", "--controller", &k, "--plant", &p, "--order", "1"]);
    one_line_error(&o, 1, "does not stabilize the loop");
    let o = sdctl(&["reduce", "--controller", &k, "--plant", &p, "--order", "0"]);
    one_line_error(&o, 2, "unstable/marginal");
}

/// `sdctl weight makeweight` and `sdctl mixsyn` on a damped double integrator at 1 kHz with an
/// input disturbance: a stable loop, the achieved norm within γ, the controller at the plant's
/// rate; no weight on S, KS or T is refused (exit 2).
#[test]
fn mixsyn_designs_a_stable_loop() {
    let ct = file(
        "mix_mass.json",
        r#"{"type":"ss","ts":null,"a":[[0,1],[0,-0.1]],"b":[[0],[1]],"c":[[1,0]],"d":[[0]]}"#,
    );
    let dir = std::path::Path::new(&ct).parent().unwrap().to_path_buf();
    let path = |n: &str| dir.join(n).to_string_lossy().into_owned();
    let (p, w1) = (path("mix_p.json"), path("mix_w1.json"));
    let w2 = file(
        "mix_w2.json",
        r#"{"type":"ss","ts":0.001,"a":[],"b":[],"c":[[]],"d":[[0.01]]}"#,
    );
    let wd = file(
        "mix_wd.json",
        r#"{"type":"ss","ts":0.001,"a":[],"b":[],"c":[[]],"d":[[1]]}"#,
    );
    for args in [
        vec!["c2d", &ct, "--ts", "0.001", "-o", &p],
        vec![
            "weight",
            "makeweight",
            "--dc",
            "1000",
            "--freq-hz",
            "5",
            "--hf",
            "0.5",
            "--order",
            "2",
            "--ts",
            "0.001",
            "-o",
            &w1,
        ],
    ] {
        let o = sdctl(&args);
        succeeded(&o);
    }
    let o = sdctl(&[
        "mixsyn", &p, "--w1", &w1, "--w2", &w2, "--wd", &wd, "--json",
    ]);
    succeeded(&o);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let g = v["gamma"].as_f64().unwrap();
    assert!(
        v["achieved_norm"].as_f64().unwrap() <= g * (1.0 + 1e-6),
        "{v}"
    );
    assert_eq!(v["closed_loop_stable"], serde_json::json!(true));
    assert_eq!(v["controller"]["ts"].as_f64(), Some(0.001));
    let o = sdctl(&["mixsyn", &p, "--wd", &wd]);
    one_line_error(&o, 2, "at least one of W1");
    // multirate: the same plant and weights as the fast model at 1 kHz, the controller at
    // 4 ms, sensor noise at its samples
    let o = sdctl(&[
        "mixsyn", &p, "--w1", &w1, "--w2", &w2, "--wd", &wd, "--factor", "4", "--wn", "1e-3",
        "--json",
    ]);
    succeeded(&o);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["factor"].as_u64(), Some(4), "{v}");
    // the stationary rms of z = [W₁e; W₂u] at each of the 4 fast phases, all finite
    let phases = v["predicted_rms"]["phases"].as_array().unwrap();
    assert_eq!(phases.len(), 4, "{v}");
    assert!(phases
        .iter()
        .all(|p| p.as_array().unwrap().len() == 2 && p[0].as_f64().unwrap() > 0.0));
    assert_eq!(v["controller"]["ts"].as_f64(), Some(0.004), "{v}");
    assert_eq!(v["closed_loop_stable"], serde_json::json!(true));
    assert!(v["achieved_norm"].as_f64().unwrap() <= v["gamma"].as_f64().unwrap() * (1.0 + 1e-6));
    // the error weighted twice at the sample instants: every loop's norm can only grow, so
    // γ_min does too
    let o = sdctl(&[
        "mixsyn",
        &p,
        "--w1",
        &w1,
        "--w2",
        &w2,
        "--wd",
        &wd,
        "--factor",
        "4",
        "--wn",
        "1e-3",
        "--at-samples",
        "2",
        "--json",
    ]);
    succeeded(&o);
    let v2: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let (g1, g2) = (
        v["gamma_min"].as_f64().unwrap(),
        v2["gamma_min"].as_f64().unwrap(),
    );
    assert!(g2 >= g1 * (1.0 - 1e-3), "{g2} < {g1}");
    let multirate = |extra: &[&str]| -> std::process::Output {
        let mut args = vec![
            "mixsyn", &p, "--w1", &w1, "--wd", &wd, "--factor", "4", "--wn", "1e-3",
        ];
        args.extend_from_slice(extra);
        sdctl(&args)
    };
    for bad in ["0", "-1", "nan"] {
        one_line_error(&multirate(&["--at-samples", bad]), 2, "positive finite");
    }
    let o = sdctl(&["mixsyn", &p, "--w1", &w1, "--wd", &wd, "--at-samples", "2"]);
    one_line_error(&o, 2, "--factor");
    let o = sdctl(&["mixsyn", &p, "--w1", &w1, "--wd", &wd, "--wn", "1e-3"]);
    one_line_error(&o, 2, "--factor");
    let o = sdctl(&["mixsyn", &p, "--w1", &w1, "--wd", &wd, "--factor", "0"]);
    one_line_error(&o, 2, "at least 1");
    // an effort weight at the fast period where the slow one is meant
    one_line_error(&multirate(&["--w2-slow", &w2]), 2, "slow effort weight");
}
