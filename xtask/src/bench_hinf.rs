//! `cargo xtask bench`'s H∞ synthesis entry (#41 item 6): the γ-optimal mixed-sensitivity
//! synthesis of the 60-state stage at 1 kHz with the paper's mixsyn weights, and SLICOT's
//! SB10DD (through slycot, `tools/bench_sb10dd.py`) at the same γ on the same generalized plant.

use crate::bench::{err, time_it, write_model};
use sd_hinf::weights::{makeweight, notch};
use sd_hinf::{augw, hinfsyn, HinfOptions, MixsynWeights};
use sd_model::StateSpace;
use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;

/// The entry; `slow60` is the 60-state stage at 1 kHz.
pub(crate) fn entry(
    root: &Path,
    dir: &Path,
    slow60: &StateSpace,
    reps: usize,
) -> Result<Value, String> {
    eprintln!(
        "[bench] H∞ synthesis of the 60-state stage's mixed-sensitivity plant (and SB10DD)..."
    );
    use crate::mixsyn_design::{W1, W1_PEAK, W2, WD};
    let ts = slow60.ts();
    let shape = makeweight(W1.0, W1.1, 1.0, W1.2, 2, ts).map_err(err)?;
    let peak = notch(W1_PEAK.0, W1_PEAK.1, W1_PEAK.2, ts).map_err(err)?;
    let w1 = sd_model::series(&shape, &peak).map_err(err)?;
    let gain = |v: f64| StateSpace::gain(nalgebra::DMatrix::from_element(1, 1, v), slow60.time());
    let (w2, wd) = (gain(W2).map_err(err)?, gain(WD).map_err(err)?);
    let w = MixsynWeights {
        w1: Some(&w1),
        w2: Some(&w2),
        w3: None,
        wd: Some(&wd),
    };
    let (p, part) = augw(slow60, &w).map_err(err)?;
    let (t, r) = time_it(reps, || hinfsyn(&p, part, &HinfOptions::default()));
    let r = r.map_err(err)?;
    // the final independent check alone: the closed loop's H∞ norm
    let cl = sd_hinf::lft_lower(&p, &r.controller, part).map_err(err)?;
    let (t_norm, nr) = time_it(reps, || cl.hinf_norm());
    nr.map_err(err)?;
    let steps = r.steps.len();
    let per_step = t / steps as f64;
    let plant_path = dir.join("hinfsyn_stage60_plant.json");
    write_model(&plant_path, &p)?;
    let mut e = json!({"name": "hinfsyn_stage60_mixsyn",
        "size": format!("generalized plant of {} states (the 60-state stage at 1 kHz, W1 with a 347 Hz peak, W2, Wd)", p.n()),
        "ours_gamma_optimal_s": t, "ours_gamma_min": r.gamma_min, "ours_achieved": r.achieved_norm,
        "ours_gamma_steps": steps, "ours_per_gamma_step_s": per_step,
        "ours_closed_loop_stable": r.closed_loop_stable, "target_s": 0.5,
        "ours_parts_s": {"final_check_hinf_norm": t_norm, "closed_loop_states": cl.n()}});
    match peer(root, &plant_path, r.gamma, reps) {
        Ok(py) => {
            let t_peer = py["median_s"].as_f64().unwrap_or(f64::NAN);
            e["peer"] = json!({"slycot_sb10dd_at_our_gamma": py});
            e["ratio_sb10dd_over_our_gamma_step"] = json!(t_peer / per_step);
        }
        Err(msg) => e["peer"] = json!({"error": msg}),
    }
    e["random_plant_64"] = random_entry(root, dir, reps)?;
    Ok(e)
}

/// The per-γ-step comparison on a plant SB10DD solves (it refuses the stage's mixed-sensitivity
/// plant at every γ, its X-Riccati equation "not solved"): a seeded random stable discrete
/// generalized plant of 64 states (two disturbances, one control; two errors, one
/// measurement; `D₁₂ = [0; 1]`, `D₂₁ = [0 1]`). Ours: the γ-optimal synthesis, and its time per
/// level tried (the bisection, the final independent check included); SB10DD: one call at
/// 1.1·our γ_min (where both return a controller).
fn random_entry(root: &Path, dir: &Path, reps: usize) -> Result<Value, String> {
    let p = random_plant(64, 41)?;
    let part = sd_hinf::Partition { nmeas: 1, ncon: 1 };
    let (t, r) = time_it(reps, || hinfsyn(&p, part, &HinfOptions::default()));
    let r = r.map_err(err)?;
    let per_step = t / r.steps.len() as f64;
    let path = dir.join("hinfsyn_random64_plant.json");
    write_model(&path, &p)?;
    let gamma = 1.1 * r.gamma_min;
    let mut e = json!({"size": "random stable discrete generalized plant, 64 states, seed 41",
        "ours_gamma_optimal_s": t, "ours_gamma_min": r.gamma_min, "ours_gamma_steps": r.steps.len(),
        "ours_per_gamma_step_s": per_step, "sb10dd_gamma": gamma});
    match peer(root, &path, gamma, reps) {
        Ok(py) => {
            let t_peer = py["median_s"].as_f64().unwrap_or(f64::NAN);
            e["ratio_sb10dd_over_our_gamma_step"] = json!(t_peer / per_step);
            e["peer"] = json!({"slycot_sb10dd": py});
        }
        Err(msg) => e["peer"] = json!({"error": msg}),
    }
    Ok(e)
}

/// The seeded random plant of [`random_entry`]: A with entries uniform in ±1 scaled to
/// `‖A‖_F = 0.9` (so ρ(A) < 1), B and C uniform in ±1.
fn random_plant(n: usize, seed: u64) -> Result<StateSpace, String> {
    let mut rng = sd_ident::rng::SplitMix::new(seed);
    let mut u = || 2.0 * rng.uniform() - 1.0;
    let a = nalgebra::DMatrix::from_fn(n, n, |_, _| u());
    let a = &a * (0.9 / a.norm());
    let b = nalgebra::DMatrix::from_fn(n, 3, |_, _| u());
    let c = nalgebra::DMatrix::from_fn(3, n, |_, _| u());
    let mut d = nalgebra::DMatrix::zeros(3, 3);
    d[(1, 2)] = 1.0;
    d[(2, 1)] = 1.0;
    StateSpace::new(
        a,
        b,
        c,
        d,
        sd_model::SampleTime::discrete(1e-3).map_err(err)?,
    )
    .map_err(err)
}

fn peer(root: &Path, plant: &Path, gamma: f64, reps: usize) -> Result<Value, String> {
    let out = Command::new("python3")
        .arg(root.join("tools/bench_sb10dd.py"))
        .arg(plant)
        .arg(format!("{gamma:.17e}"))
        .arg(reps.to_string())
        .output()
        .map_err(err)?;
    if !out.status.success() {
        let msg = String::from_utf8_lossy(&out.stderr);
        return Err(msg.lines().last().unwrap_or("python failed").to_string());
    }
    serde_json::from_slice(&out.stdout).map_err(err)
}
