//! `cargo xtask bench`: our operations against python-control/scipy on the same inputs.

use sd_model::{c2d, grid, Discretization, StateSpace};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The median time of `repeats` calls of `f` after an untimed warm-up, and the last result.
/// Warm-up: calls until [`WARM_UP_S`] has passed (at least one). The first calls of a 2 ms
/// operation take up to 4× as long here (the cores' clock and the worker threads' wake-up
/// settle over ~30 ms), and the Python peers get the same warm-up. A first call of over 1 s
/// counts as the first timed one (those effects are then below 1 %).
pub(crate) fn time_it<T>(repeats: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let t0 = Instant::now();
    let mut out = f();
    let first = t0.elapsed().as_secs_f64();
    let mut ts = Vec::with_capacity(repeats.max(1));
    if first > 1.0 {
        ts.push(first);
    }
    while t0.elapsed().as_secs_f64() < WARM_UP_S {
        out = f();
    }
    while ts.len() < repeats.max(1) {
        let t0 = Instant::now();
        out = f();
        ts.push(t0.elapsed().as_secs_f64());
    }
    (sd_model::median(&ts), out)
}

/// Untimed warm-up before every timed series (ours and the peers', tools/bench_python.py).
const WARM_UP_S: f64 = 0.1;

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn python_peers_available() -> bool {
    Command::new("python3")
        .args(["-c", "import control, slycot, scipy"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false)
}

/// A `String` error from anything displayable.
pub(crate) fn err<E: std::fmt::Display>(x: E) -> String {
    x.to_string()
}

/// Writes a model as JSON.
pub(crate) fn write_model(path: &Path, m: &StateSpace) -> Result<(), String> {
    std::fs::write(path, sd_model::model_to_json_string(m).map_err(err)?).map_err(err)
}

/// What every benchmark shares: the output folder, repeats, and the 60-state stage
/// (continuous and at 5 kHz) with its JSON files.
struct Ctx {
    dir: PathBuf,
    quick: bool,
    reps: usize,
    stage: StateSpace,
    pd: StateSpace,
    ct_path: PathBuf,
    dt_path: PathBuf,
}

impl Ctx {
    /// Repeats of the slowest operations (the fit, the testbed, the peer's frequency
    /// response).
    fn few(&self) -> usize {
        if self.quick {
            1
        } else {
            3
        }
    }
}

/// The benchmark entries (JSON) and, per entry, what the Python peers compare it with.
struct Entries {
    c2d: Value,
    freqresp: Value,
    downsample: Value,
    dare: Value,
    loopshape: Value,
    loopshape60: Value,
    frf: Value,
    fit: Value,
    testbed: Value,
    diagnose: Value,
}

/// Results the peers' comparison needs.
struct Ours {
    t_c2d: f64,
    t_fr_lib: f64,
    t_fr_proc: f64,
    t_ds: f64,
    t_dare: f64,
    t_ls: f64,
    t_ls60: f64,
    gamma_min60: f64,
    p60_path: PathBuf,
    t_frf: f64,
    gamma_min: f64,
    frd: sd_model::Frd,
    direct_1khz: StateSpace,
    fmin: f64,
    fmax: f64,
    nfreq: usize,
    p1k_path: PathBuf,
    w1_path: PathBuf,
    u_path: PathBuf,
    y_path: PathBuf,
}

/// Builds `sdctl` (release) and returns its path.
fn build_sdctl(root: &Path) -> Result<PathBuf, String> {
    eprintln!("[bench] building sdctl (release)...");
    let st = Command::new(env!("CARGO"))
        .args(["build", "--quiet", "--release", "-p", "sd-cli"])
        .current_dir(root)
        .status()
        .map_err(err)?;
    if !st.success() {
        return Err("cargo build -p sd-cli failed".into());
    }
    Ok(root.join("target/release/sdctl"))
}

/// c2d: exact ZOH of the 60-state stage at 5 kHz; returns the discrete stage too.
fn bench_c2d(
    dir: &Path,
    reps: usize,
    stage: &StateSpace,
) -> Result<(f64, StateSpace, PathBuf, PathBuf), String> {
    let ct_path = dir.join("stage60_ct.json");
    write_model(&ct_path, stage)?;
    eprintln!("[bench] c2d (ZOH) of the 60-state stage at 5 kHz, {reps} repeats...");
    let (t_c2d, pd) = time_it(reps * 10, || c2d(stage, 2e-4, Discretization::Zoh));
    let pd: StateSpace = pd.map_err(err)?;
    let dt_path = dir.join("stage60_5khz.json");
    write_model(&dt_path, &pd)?;
    Ok((t_c2d, pd, ct_path, dt_path))
}

/// The DARE and loopshaping entries, their times, γ_min and the files the peer reads.
struct DareLoopshape {
    dare: Value,
    loopshape: Value,
    t_dare: f64,
    t_ls: f64,
    gamma_min: f64,
    p1k_path: PathBuf,
    w1_path: PathBuf,
}

/// DARE of the 60-state stage at 5 kHz (Q = CᵀC, R = 1; timed before the large frequency
/// response, whose many small allocations slow every later allocation-heavy timing in this
/// process) and a loopshaping design of the paper stage at 1 kHz.
fn bench_dare_loopshape(ctx: &Ctx) -> Result<DareLoopshape, String> {
    eprintln!(
        "[bench] DARE of the 60-state stage at 5 kHz, loopshaping of the paper stage at 1 kHz..."
    );
    let pd = &ctx.pd;
    let q = pd.c().transpose() * pd.c();
    let r1 = nalgebra::DMatrix::from_element(1, 1, 1.0);
    let (t_dare, sol) = time_it(ctx.reps * 4, || {
        sd_hinf::dare(pd.a(), pd.b(), &q, &r1, None)
    });
    let sol = sol.map_err(err)?;
    let dare = json!({"name": "dare", "size": "60-state stage at 5 kHz, Q = C'C, R = 1",
        "ours_s": t_dare, "ours_rel_residual": sol.residual, "ours_closed_loop_radius": sol.closed_loop,
        "ours_condition_estimate": sol.condition, "ours_doubling_steps": sol.doubling_steps,
        "ours_refinement_steps": sol.refinement_steps});
    let p1k = c2d(
        &sd_model::stage::paper_stage(0.01).map_err(err)?,
        1e-3,
        Discretization::Zoh,
    )
    .map_err(err)?;
    let w1 = sd_hinf::weights::pid(65.0, 20.0, Some(1e-3), &Default::default()).map_err(err)?;
    let (t_ls, design) = time_it(ctx.reps * 4, || {
        sd_hinf::loopshape(&p1k, Some(&w1), None, &Default::default())
    });
    let design = design.map_err(err)?;
    let p1k_path = ctx.dir.join("paper_stage_1khz.json");
    let w1_path = ctx.dir.join("w1_pid65.json");
    write_model(&p1k_path, &p1k)?;
    write_model(&w1_path, &w1)?;
    let ls = json!({"name": "loopshape", "size": "paper stage at 1 kHz (4 states) with a PID-like W1 (3 states)",
        "ours_full_design_s": t_ls, "ours_gamma_min": design.gamma_min, "ours_achieved": design.achieved});
    Ok(DareLoopshape {
        dare,
        loopshape: ls,
        t_dare,
        t_ls,
        gamma_min: design.gamma_min,
        p1k_path,
        w1_path,
    })
}

/// Loopshaping of the 60-state stage at 1 kHz (Lemma 6 of the 5 kHz stage) with the PID-like
/// W1 of the 4-state entry: the library call and the whole `sdctl loopshape` process (reading
/// both models, the design, its checks, the controller written as JSON). Returns the entry, the
/// process time, γ_min and the plant's file for the peer.
fn bench_loopshape60(
    ctx: &Ctx,
    sdctl: &Path,
    w1_path: &Path,
) -> Result<(Value, f64, f64, PathBuf), String> {
    eprintln!("[bench] loopshaping of the 60-state stage at 1 kHz (library and sdctl process)...");
    let slow = sd_multirate::downsample(&ctx.pd, 5).map_err(err)?;
    let w1 = sd_hinf::weights::pid(65.0, 20.0, Some(1e-3), &Default::default()).map_err(err)?;
    let (t_lib, design) = time_it(ctx.reps, || {
        sd_hinf::loopshape(&slow, Some(&w1), None, &Default::default())
    });
    let design = design.map_err(err)?;
    // what the design's time goes to: its two DAREs (γ_min) and its achieved-norm check
    let (t_dares, r) = time_it(ctx.reps, || sd_hinf::gamma_min(&design.shaped_plant));
    r.map_err(err)?;
    let fb = sd_hinf::loopshape::four_block(&design.shaped_plant, &design.shaped_controller)
        .map_err(err)?;
    let (t_norm, r) = time_it(ctx.reps, || fb.hinf_norm());
    r.map_err(err)?;
    let plant_path = ctx.dir.join("stage60_1khz.json");
    write_model(&plant_path, &slow)?;
    let out_path = ctx.dir.join("loopshape60_k.json");
    let (t_proc, ok) = time_it(ctx.reps, || {
        Command::new(sdctl)
            .args(["loopshape", &plant_path.to_string_lossy(), "--w1"])
            .arg(w1_path)
            .args(["-o", &out_path.to_string_lossy()])
            .status()
            .map(|s| s.success())
            .unwrap_or(false)
    });
    if !ok {
        return Err("sdctl loopshape of the 60-state stage failed".into());
    }
    let entry = json!({"name": "loopshape_stage60",
        "size": "60-state stage at 1 kHz (Lemma 6 of the 5 kHz stage) with a PID-like W1 (3 states)",
        "ours_library_s": t_lib, "ours_sdctl_process_s": t_proc,
        "ours_parts_s": {"two_dares_gamma_min": t_dares, "achieved_norm_four_block": t_norm},
        "ours_gamma_min": design.gamma_min,
        "ours_achieved": design.achieved, "ours_gamma": design.gamma,
        "ours_closed_loop_stable": design.closed_loop_stable});
    Ok((entry, t_proc, design.gamma_min, plant_path))
}

/// Periodic FRF estimation: the 5 kHz stage driven by a multisine, 21 periods of 10 000
/// samples (the signals written for the peer).
fn bench_frf(ctx: &Ctx) -> Result<(Value, f64, PathBuf, PathBuf), String> {
    eprintln!("[bench] FRF estimation (210 000 samples) and an order-60 fit (2500 lines)...");
    let ms = sd_ident::design(&sd_ident::MultisineSpec {
        fs: 5000.0,
        period: 10_000,
        f_min: 0.5,
        f_max: 2400.0,
        lines: sd_ident::Lines::Full,
        phases: sd_ident::Phases::Random { seed: 1 },
        rms: 1.0,
        fold_rate_hz: Some(1000.0),
    })
    .map_err(err)?;
    let u = ms.repeat(21);
    let y: Vec<f64> = ctx
        .pd
        .simulate(&nalgebra::DMatrix::from_column_slice(u.len(), 1, &u), None)
        .map_err(err)?
        .y
        .iter()
        .cloned()
        .collect();
    let popt = sd_ident::PeriodicOptions::new(10_000, 1);
    let (t_frf, est) = time_it(ctx.reps, || {
        sd_ident::frf_periodic(5000.0, None, &u, &y, &popt)
    });
    let est = est.map_err(err)?;
    let to_bytes = |v: &[f64]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let (u_path, y_path) = (ctx.dir.join("frf_u.f64"), ctx.dir.join("frf_y.f64"));
    std::fs::write(&u_path, to_bytes(&u)).map_err(err)?;
    std::fs::write(&y_path, to_bytes(&y)).map_err(err)?;
    let entry = json!({"name": "frf_periodic", "size": "210 000 samples, period 10 000, 20 periods averaged",
        "ours_s": t_frf, "lines": est.lines.len()});
    Ok((entry, t_frf, u_path, y_path))
}

/// 2500 lines (0.999 Hz apart) of a model's response with complex Gaussian noise of 1 % of
/// each entry's magnitude (40 dB SNR) and that variance: the fit benchmarks' data.
pub(crate) fn noisy_frd(pd: &StateSpace, seed: u64) -> Result<sd_model::Frd, String> {
    let f: Vec<f64> = (1..=2500).map(|k| k as f64 * 0.999).collect();
    let truth = pd.freqresp(&f).map_err(err)?;
    let mut rng = sd_ident::rng::SplitMix::new(seed);
    let (mut resp, mut var) = (Vec::new(), Vec::new());
    for g in truth.response() {
        let sd = g.map(|v| 0.01 * v.norm());
        let noisy = nalgebra::DMatrix::from_fn(g.nrows(), g.ncols(), |a, b| {
            g[(a, b)]
                + num_complex::Complex64::new(rng.normal(), rng.normal())
                    * (sd[(a, b)] / 2f64.sqrt())
        });
        resp.push(noisy);
        var.push(sd.map(|s| s * s));
    }
    sd_model::Frd::new(f, resp, Some(var), truth.time()).map_err(err)
}

/// An order-60 fit of 2500 lines of the 5 kHz stage at 40 dB SNR (no peer).
fn bench_fit(ctx: &Ctx) -> Result<Value, String> {
    let frd60 = noisy_frd(&ctx.pd, 60)?;
    let fopt = sd_ident::FitOptions {
        order: 60,
        rigid_body: 2,
        feedthrough: false,
        ..Default::default()
    };
    // the same data for the peer (scipy's AAA)
    let text = sd_model::frd_to_json_string(&frd60).map_err(err)?;
    std::fs::write(ctx.dir.join(FIT_FRD), text).map_err(err)?;
    let (t_fit, fit60) = time_it(ctx.few(), || sd_ident::fit(&frd60, &fopt));
    let fit60 = fit60.map_err(err)?;
    let stable = fit60.poles.iter().all(|p| p.norm() <= 1.0);
    Ok(
        json!({"name": "fit_order60", "size": "2500 lines of the 60-state stage at 5 kHz, 40 dB SNR",
        "ours_s": t_fit, "median_rel_error": fit60.median_rel_error, "cost": fit60.cost,
        "stable": stable, "poles": 60}),
    )
}

/// The order-60 fit's data for the peer (in the bench folder).
const FIT_FRD: &str = "fit60_frd.json";

/// An order-60 common-pole fit of the two-axis stage (2×2 × 2500 lines at 40 dB SNR; no
/// peer).
fn bench_fit_mimo(ctx: &Ctx) -> Result<Value, String> {
    let pc = sd_model::stage::two_axis_stage60().map_err(err)?;
    let pd = sd_model::c2d(&pc, 2e-4, sd_model::Discretization::Zoh).map_err(err)?;
    let frd = noisy_frd(&pd, 61)?;
    let opt = sd_ident::MimoFitOptions {
        fit: sd_ident::FitOptions {
            order: 60,
            rigid_body: 2,
            feedthrough: false,
            ..Default::default()
        },
        ..Default::default()
    };
    let (t, r) = time_it(ctx.few(), || sd_ident::fit_common_poles(&frd, &opt));
    let r = r.map_err(err)?;
    Ok(json!({"name": "fit_common_poles_2x2_order60",
        "size": "2x2 x 2500 lines of the two-axis 60-state stage at 5 kHz, 40 dB SNR",
        "ours_s": t, "median_rel_error": r.median_rel_error, "cost": r.cost, "states": r.model.n(),
        "peer": "none: python-control and scipy have no rational FRF fitting"}))
}

/// An identification experiment of about `samples` samples on the virtual stage at `rate`
/// (PID-like controller, full multisine, input injection).
pub(crate) fn identification(
    rate: f64,
    period: usize,
    seed: u64,
    ni: sd_testbed::NonIdealities,
    role: sd_ident::Role,
    samples: usize,
) -> Result<sd_testbed::Identification, String> {
    let opt = sd_hinf::weights::PidOptions {
        lowpass_ratio: if rate > 2000.0 { 1000.0 / 30.0 } else { 0.0 },
        ..Default::default()
    };
    let bw = if rate > 2000.0 { 30.0 } else { 20.0 };
    let k = sd_hinf::weights::pid(bw, 20.0, Some(1.0 / rate), &opt).map_err(err)?;
    let excitation = sd_ident::design(&sd_ident::MultisineSpec {
        fs: rate,
        period,
        f_min: 0.5,
        f_max: 0.5 * rate - 0.5,
        lines: sd_ident::Lines::Full,
        phases: sd_ident::Phases::Random { seed },
        rms: 2.0,
        fold_rate_hz: Some(1000.0),
    })
    .map_err(err)?;
    Ok(sd_testbed::Identification {
        name: format!("e{seed}"),
        controller: k,
        excitation,
        periods: samples / period,
        transient_periods: 1,
        injection: sd_testbed::Injection::Input,
        noise: sd_testbed::Noise {
            force_rms: 0.05,
            sensor_rms: 3e-10,
            sensor_drift: 0.0,
            seed,
        },
        nonideal: ni,
        role,
        substeps: None,
        fine_steps: None,
    })
}

/// Virtual stage experiments of 70 000 samples (LTI and nonlinear) and a diagnosis of three.
fn bench_testbed_diagnose(ctx: &Ctx) -> Result<(Value, Value), String> {
    eprintln!("[bench] virtual stage experiments (70 000 samples) and a diagnosis of three...");
    let few = ctx.few();
    let avg = sd_testbed::NonIdealities {
        averaging: 0.6,
        ..Default::default()
    };
    let truth = sd_testbed::Truth::default();
    let id_fast = identification(5000.0, 10_000, 1, avg, sd_ident::Role::Model, 70_000)?;
    let (t_tb, data_fast) = time_it(ctx.reps, || {
        sd_testbed::run_identification(&truth, &id_fast)
    });
    let data_fast = data_fast.map_err(err)?;
    let mut nl = truth.clone();
    nl.modes[0].cubic = 4e12;
    nl.coulomb = 0.5;
    nl.coulomb_velocity = 1e-4;
    let (t_nl, _) = time_it(few, || sd_testbed::run_identification(&nl, &id_fast));
    let run = |rate, period, seed| -> Result<sd_testbed::ExperimentData, String> {
        let id = identification(rate, period, seed, avg, sd_ident::Role::Validation, 70_000)?;
        sd_testbed::run_identification(&truth, &id).map_err(err)
    };
    let exps = vec![
        data_fast.to_experiment(),
        run(5000.0, 10_000, 2)?.to_experiment(),
        run(1000.0, 2_000, 3)?.to_experiment(),
    ];
    let (t_diag, diag) = time_it(few, || sd_diagnose::diagnose(&exps, &Default::default()));
    let diag = diag.map_err(err)?;
    let tb = json!({"name": "virtual_stage", "size": "70 000 samples at 5 kHz (LTI, averaging sensor) / nonlinear (cubic + Coulomb)",
        "ours_lti_s": t_tb, "ours_nonlinear_s": t_nl, "peer": "none (no virtual stage in python-control or scipy)"});
    let d = json!({"name": "diagnose", "size": "three experiments of 70 000 samples (5 kHz model, 5 kHz, 1 kHz)",
        "ours_s": t_diag, "cause": diag.cause, "parameters": diag.parameters, "gain_ratio": diag.gain_ratio(),
        "model": diag.model_source(), "peer": "none (no such tool elsewhere)"});
    Ok((tb, d))
}

/// freqresp of the 5 kHz stage on `nfreq` log-spaced frequencies: the library call and the
/// whole `sdctl` process.
fn bench_freqresp(
    ctx: &Ctx,
    sdctl: &Path,
    (fmin, fmax, nfreq): (f64, f64, usize),
) -> Result<((f64, f64), f64, sd_model::Frd), String> {
    let f = grid(fmin, fmax, nfreq, true).map_err(err)?;
    eprintln!("[bench] freqresp of the 5 kHz stage on {nfreq} frequencies...");
    let (t_fr_lib, frd) = time_it(ctx.reps, || ctx.pd.freqresp(&f));
    let frd = frd.map_err(err)?;
    // the evaluation alone (what the flop count counts): a prepared evaluator into one buffer
    let ev = sd_model::FreqRespEvaluator::new(&ctx.pd).map_err(err)?;
    let (t_fr_eval, _) = time_it(ctx.reps, || ev.eval_many_flat(&f));
    let grid_arg = format!("{fmin}:{fmax}:{nfreq}:log");
    let out_path = ctx.dir.join("freqresp_out.json");
    let (t_fr_proc, ok) = time_it(ctx.reps, || {
        Command::new(sdctl)
            .args([
                "freqresp",
                &ctx.dt_path.to_string_lossy(),
                "--grid",
                &grid_arg,
                "-o",
                &out_path.to_string_lossy(),
            ])
            .status()
            .map(|s| s.success())
            .unwrap_or(false)
    });
    if !ok {
        return Err("sdctl freqresp failed".into());
    }
    Ok(((t_fr_lib, t_fr_eval), t_fr_proc, frd))
}

/// Lemma 6 downsampling of the 5 kHz stage by F = 5, checked against ZOH at 1 kHz.
fn bench_downsample(ctx: &Ctx) -> Result<(Value, f64, StateSpace), String> {
    eprintln!("[bench] downsample (Lemma 6) of the 5 kHz stage, F = 5...");
    let (t_ds, slow) = time_it(ctx.reps * 10, || sd_multirate::downsample(&ctx.pd, 5));
    let slow = slow.map_err(err)?;
    let direct = c2d(&ctx.stage, 1e-3, Discretization::Zoh).map_err(err)?;
    let entry = json!({"name": "downsample_lemma6", "size": "60 states, F = 5 (5 kHz -> 1 kHz)",
        "ours_s": t_ds, "ours_rel_error_vs_zoh_1khz": {"a": rel(slow.a(), direct.a()), "b": rel(slow.b(), direct.b())}});
    Ok((entry, t_ds, direct))
}

/// `‖x − y‖/‖y‖` (Frobenius).
fn rel(x: &nalgebra::DMatrix<f64>, y: &nalgebra::DMatrix<f64>) -> f64 {
    (x - y).norm() / y.norm()
}

/// A JSON number (NaN when absent).
fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

/// Runs `tools/bench_python.py` on the same inputs; its JSON answer.
fn run_peers(root: &Path, ctx: &Ctx, o: &Ours) -> Result<Value, String> {
    eprintln!("[bench] python-control / scipy on the same inputs...");
    let reps = ctx.reps;
    let cases = json!({
        "c2d": {"model": ctx.ct_path, "ts": 2e-4, "repeats": reps * 10},
        "freqresp": {"model": ctx.dt_path, "fmin": o.fmin, "fmax": o.fmax, "n": o.nfreq, "log": true, "repeats": ctx.few()},
        "downsample": {"model": ctx.dt_path, "factor": 5, "repeats": reps * 10},
        "dare": {"model": ctx.dt_path, "repeats": reps},
        "loopshape": {"plant": o.p1k_path, "w1": o.w1_path, "repeats": reps * 4},
        "loopshape60": {"plant": o.p60_path, "w1": o.w1_path, "repeats": reps},
        "frf": {"u": o.u_path, "y": o.y_path, "period": 10_000, "skip": 1, "repeats": reps},
        "fit": {"frd": ctx.dir.join(FIT_FRD), "poles": 60, "repeats": ctx.few()},
    });
    let cases_path = ctx.dir.join("python_cases.json");
    std::fs::write(&cases_path, cases.to_string()).map_err(err)?;
    let out = Command::new("python3")
        .arg(root.join("tools/bench_python.py"))
        .arg(&cases_path)
        .output()
        .map_err(err)?;
    if !out.status.success() {
        return Err(format!(
            "python peer failed: {}",
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    serde_json::from_slice(&out.stdout).map_err(err)
}

/// The c2d and freqresp peers: times, ratios and the agreement of the results.
fn compare_c2d_freqresp(py: &Value, ctx: &Ctx, o: &Ours, e: &mut Entries) {
    let (t_pc, t_sc) = (
        num(&py["c2d_python_control"]["median_s"]),
        num(&py["c2d_scipy"]["median_s"]),
    );
    let ad: Vec<Vec<f64>> =
        serde_json::from_value(py["c2d_python_control"]["ad"].clone()).unwrap_or_default();
    let mut dev: f64 = 0.0;
    for (i, row) in ad.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            dev = dev.max((v - ctx.pd.a()[(i, j)]).abs());
        }
    }
    e.c2d["peer"] = json!({"python_control_sample_system_s": t_pc, "scipy_cont2discrete_s": t_sc});
    e.c2d["ratio_python_control_over_ours"] = json!(t_pc / o.t_c2d);
    e.c2d["ratio_scipy_over_ours"] = json!(t_sc / o.t_c2d);
    e.c2d["max_rel_difference_ad"] = json!(dev / ctx.pd.a().abs().max());
    let pf = &py["freqresp_python_control"];
    let t_pf = num(&pf["median_s"]);
    let stride = pf["stride"].as_u64().unwrap_or(1) as usize;
    let re: Vec<f64> = serde_json::from_value(pf["re_sample"].clone()).unwrap_or_default();
    let im: Vec<f64> = serde_json::from_value(pf["im_sample"].clone()).unwrap_or_default();
    let mut worst: f64 = 0.0;
    for (k, (r, i)) in re.iter().zip(im.iter()).enumerate() {
        let ours = o.frd.response()[k * stride][(0, 0)];
        let theirs = num_complex::Complex64::new(*r, *i);
        worst = worst.max((ours - theirs).norm() / theirs.norm());
    }
    e.freqresp["peer"] = json!({"python_control_frequency_response_s": t_pf});
    e.freqresp["ratio_python_control_over_sdctl_process"] = json!(t_pf / o.t_fr_proc);
    e.freqresp["ratio_python_control_over_library"] = json!(t_pf / o.t_fr_lib);
    e.freqresp["max_rel_difference_sampled"] = json!(worst);
    // the same calls through our Python package: its overhead over the library call
    let sdt = &py["sdtoolkit"];
    if let (Some(tc), Some(tf)) = (sdt["c2d_s"].as_f64(), sdt["freqresp_s"].as_f64()) {
        e.c2d["python_sdtoolkit_s"] = json!(tc);
        e.c2d["ratio_python_call_over_library"] = json!(tc / o.t_c2d);
        e.freqresp["python_sdtoolkit_s"] = json!(tf);
        e.freqresp["ratio_python_call_over_library"] = json!(tf / o.t_fr_lib);
        e.freqresp["ratio_python_control_over_sdtoolkit"] = json!(t_pf / tf);
    } else {
        e.c2d["python_sdtoolkit"] = sdt.clone();
    }
}

/// The downsample, DARE, loopshaping and FRF peers.
fn compare_others(py: &Value, o: &Ours, e: &mut Entries) {
    let np_ds = &py["downsample_numpy_matrix_power"];
    let t_np = num(&np_ds["median_s"]);
    let to_mat = |v: &Value| -> Option<nalgebra::DMatrix<f64>> {
        let rows: Vec<Vec<f64>> = serde_json::from_value(v.clone()).ok()?;
        let (r, c) = (rows.len(), rows.first()?.len());
        Some(nalgebra::DMatrix::from_fn(r, c, |i, j| rows[i][j]))
    };
    if let (Some(a), Some(b)) = (to_mat(&np_ds["ad"]), to_mat(&np_ds["bd"])) {
        let d = &o.direct_1khz;
        e.downsample["peer"] = json!({"numpy_matrix_power_s": t_np,
            "numpy_rel_error_vs_zoh_1khz": {"a": rel(&a, d.a()), "b": rel(&b, d.b())}});
        e.downsample["ratio_numpy_over_ours"] = json!(t_np / o.t_ds);
    }
    let sc = &py["dare_scipy"];
    e.dare["peer"] = json!({"scipy_solve_discrete_are": sc, "python_control_dare_slycot_sb02od": py["dare_python_control"]});
    e.dare["ratio_scipy_over_ours"] = json!(num(&sc["median_s"]) / o.t_dare);
    let pl = &py["loopshape_scipy_gamma_min"];
    e.loopshape["peer"] = json!({"scipy_gamma_min_only": pl});
    e.loopshape["ratio_scipy_gamma_min_only_over_our_full_design"] =
        json!(num(&pl["median_s"]) / o.t_ls);
    e.loopshape["gamma_min_rel_difference"] =
        json!((num(&pl["gamma_min"]) - o.gamma_min).abs() / o.gamma_min);
    let pl = &py["loopshape60_scipy_two_dares"];
    e.loopshape60["peer"] = json!({"scipy_two_dares_and_gamma_min_only": pl});
    e.loopshape60["ratio_scipy_two_dares_over_our_sdctl_process"] =
        json!(num(&pl["median_s"]) / o.t_ls60);
    e.loopshape60["gamma_min_rel_difference"] =
        json!((num(&pl["gamma_min"]) - o.gamma_min60).abs() / o.gamma_min60);
    let pf = &py["frf_numpy_periodic_average"];
    e.frf["peer"] = json!({"numpy_fft_period_average": pf});
    e.frf["ratio_numpy_over_ours"] = json!(num(&pf["median_s"]) / o.t_frf);
    let aaa = &py["fit_scipy_aaa"];
    if aaa.get("median_s").is_some() {
        let (ours_t, ours_cost) = (num(&e.fit["ours_s"]), num(&e.fit["cost"]));
        e.fit["peer"] = json!({"scipy_interpolate_aaa": aaa});
        e.fit["ratio_aaa_over_ours"] = json!(num(&aaa["median_s"]) / ours_t);
        e.fit["cost_ratio_aaa_over_ours"] = json!(num(&aaa["cost"]) / ours_cost);
    } else {
        e.fit["peer"] = json!({"scipy_interpolate_aaa": aaa});
    }
}

/// Every benchmark, then the Python peers when importable; writes
/// `target/bench/results.json`.
pub fn run(quick: bool) -> Result<(), String> {
    let root = workspace_root();
    let dir = root.join("target/bench");
    std::fs::create_dir_all(&dir).map_err(err)?;
    let nfreq = if quick { 20_000 } else { 200_000 };
    let sdctl = build_sdctl(&root)?;
    let stage = sd_model::stage::stage60().map_err(err)?;
    let reps = if quick { 3 } else { 15 };
    let (t_c2d, pd, ct_path, dt_path) = bench_c2d(&dir, reps, &stage)?;
    let ctx = Ctx {
        dir,
        quick,
        reps,
        stage,
        pd,
        ct_path,
        dt_path,
    };
    let DareLoopshape {
        dare,
        loopshape,
        t_dare,
        t_ls,
        gamma_min,
        p1k_path,
        w1_path,
    } = bench_dare_loopshape(&ctx)?;
    let (loopshape60, t_ls60, gamma_min60, p60_path) = bench_loopshape60(&ctx, &sdctl, &w1_path)?;
    let slow60 = sd_multirate::downsample(&ctx.pd, 5).map_err(err)?;
    let hinf60 = crate::bench_hinf::entry(&root, &ctx.dir, &slow60, ctx.reps)?;
    let (frf, t_frf, u_path, y_path) = bench_frf(&ctx)?;
    let fit = bench_fit(&ctx)?;
    eprintln!("[bench] an order-60 common-pole fit of the two-axis stage (2x2 x 2500 lines)...");
    let fit_mimo = bench_fit_mimo(&ctx)?;
    let (testbed, diagnose) = bench_testbed_diagnose(&ctx)?;
    let (fmin, fmax) = (0.1, 2500.0);
    let ((t_fr_lib, t_fr_eval), t_fr_proc, frd) =
        bench_freqresp(&ctx, &sdctl, (fmin, fmax, nfreq))?;
    let (downsample, t_ds, direct_1khz) = bench_downsample(&ctx)?;
    let peak = crate::physical::peak();
    let memory = crate::physical::memory(&sdctl, &ctx.dir)?;
    let mut e = Entries {
        c2d: json!({"name": "c2d_zoh", "size": "60 states, 1 input, h = 0.2 ms", "ours_s": t_c2d}),
        freqresp: json!({"name": "freqresp", "size": format!("60 states, {nfreq} frequencies"),
                         "ours_library_s": t_fr_lib, "ours_evaluation_s": t_fr_eval,
                         "ours_sdctl_process_s": t_fr_proc}),

        downsample,
        dare,
        loopshape,
        loopshape60,
        frf,
        fit,
        testbed,
        diagnose,
    };
    let ours = Ours {
        t_c2d,
        t_fr_lib,
        t_fr_proc,
        t_ds,
        t_dare,
        t_ls,
        t_ls60,
        gamma_min60,
        p60_path,
        t_frf,
        gamma_min,
        frd,
        direct_1khz,
        fmin,
        fmax,
        nfreq,
        p1k_path,
        w1_path,
        u_path,
        y_path,
    };
    let python = if python_peers_available() {
        let py = run_peers(&root, &ctx, &ours)?;
        compare_c2d_freqresp(&py, &ctx, &ours, &mut e);
        compare_others(&py, &ours, &mut e);
        py["versions"].clone()
    } else {
        eprintln!("[bench] python-control/slycot not importable: peers skipped (pip install control slycot scipy)");
        Value::Null
    };
    physical_bounds(&mut e, &ctx, &peak, ((t_fr_lib, t_fr_eval), nfreq, t_dare))?;
    let entries = vec![
        peak,
        memory,
        e.c2d,
        e.freqresp,
        e.downsample,
        e.dare,
        e.loopshape,
        e.loopshape60,
        hinf60,
        e.frf,
        e.fit,
        fit_mimo,
        e.testbed,
        e.diagnose,
    ];
    let scaling = crate::scaling::table(&root, &ctx.dir, quick, !python.is_null())?;
    finish(
        &ctx.dir,
        json!({"quick": quick, "python": python, "entries": entries, "scaling": scaling}),
    )
}

/// The H∞ synthesis entry alone (`cargo xtask bench --only hinfsyn`), written to
/// `target/bench/hinfsyn.json`.
pub fn run_hinfsyn(quick: bool) -> Result<(), String> {
    let root = workspace_root();
    let dir = root.join("target/bench");
    std::fs::create_dir_all(&dir).map_err(err)?;
    let reps = if quick { 3 } else { 15 };
    let stage = sd_model::stage::stage60().map_err(err)?;
    let pd = c2d(&stage, 2e-4, Discretization::Zoh).map_err(err)?;
    let slow60 = sd_multirate::downsample(&pd, 5).map_err(err)?;
    let entry = crate::bench_hinf::entry(&root, &dir, &slow60, reps)?;
    let p = dir.join("hinfsyn.json");
    let text = serde_json::to_string_pretty(&entry).map_err(err)?;
    std::fs::write(&p, text).map_err(err)?;
    println!("{}", serde_json::to_string(&entry).map_err(err)?);
    println!("written {}", p.display());
    Ok(())
}

/// The flops of the freqresp and DARE algorithms next to their times, and the fraction of the
/// measured peak they reach (freqresp runs on every core, the doubling on one). The freqresp
/// fraction is of the evaluation on a prepared evaluator (`eval_many_flat`, the work the flop
/// count counts), and also given for the whole library call (set-up, one matrix per point).
fn physical_bounds(
    e: &mut Entries,
    ctx: &Ctx,
    peak: &Value,
    ((t_fr_lib, t_fr_eval), nfreq, t_dare): ((f64, f64), usize, f64),
) -> Result<(), String> {
    let num = |v: &Value| v.as_f64().unwrap_or(f64::NAN);
    let ev = sd_model::FreqRespEvaluator::new(&ctx.pd).map_err(err)?;
    let fpp = crate::physical::freqresp_flops_per_point(
        &ev.block_sizes(),
        ev.pole_counts(),
        ctx.pd.ny(),
        ctx.pd.nu(),
    );
    let all = num(&peak["all_cores_gflops"]);
    let rate = fpp * nfreq as f64 / t_fr_eval;
    e.freqresp["flops_per_point"] = json!(fpp);
    e.freqresp["achieved_gflops"] = json!(rate / 1e9);
    e.freqresp["fraction_of_all_cores_peak"] = json!(rate / 1e9 / all);
    e.freqresp["fraction_of_all_cores_peak_library_call"] =
        json!(fpp * nfreq as f64 / t_fr_lib / 1e9 / all);
    let n = ctx.pd.n();
    let steps = e.dare["ours_doubling_steps"].as_u64().unwrap_or(0) as f64;
    let per = crate::physical::dare_flops_per_step(n);
    let rate = steps * per / t_dare;
    e.dare["flops_per_doubling_step"] = json!(per);
    e.dare["achieved_gflops_doubling_only"] = json!(rate / 1e9);
    e.dare["fraction_of_one_core_peak"] = json!(rate / 1e9 / num(&peak["one_core_gflops"]));
    Ok(())
}

fn finish(dir: &Path, res: Value) -> Result<(), String> {
    let p = dir.join("results.json");
    std::fs::write(
        &p,
        serde_json::to_string_pretty(&res).map_err(|x| x.to_string())?,
    )
    .map_err(|x| x.to_string())?;
    for e in res["entries"].as_array().into_iter().flatten() {
        println!("{}", serde_json::to_string(e).unwrap_or_default());
    }
    println!("written {}", p.display());
    Ok(())
}
