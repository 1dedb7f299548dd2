//! `cargo xtask bench`: our operations against python-control/scipy on the same inputs.

use sd_model::{c2d, grid, Discretization, StateSpace};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time_it<T>(repeats: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let t0 = Instant::now();
    let mut out = f();
    let mut ts = vec![t0.elapsed().as_secs_f64()];
    for _ in 1..repeats {
        let t0 = Instant::now();
        out = f();
        ts.push(t0.elapsed().as_secs_f64());
    }
    (median(ts), out)
}

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

pub fn run(quick: bool) -> Result<(), String> {
    let root = workspace_root();
    let dir = root.join("target/bench");
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let reps = if quick { 3 } else { 15 };
    let nfreq = if quick { 20_000 } else { 200_000 };
    let e = |x: sd_model::ModelError| x.to_string();

    eprintln!("[bench] building sdctl (release)...");
    let st = Command::new(env!("CARGO"))
        .args(["build", "--quiet", "--release", "-p", "sd-cli"])
        .current_dir(&root)
        .status()
        .map_err(|x| x.to_string())?;
    if !st.success() {
        return Err("cargo build -p sd-cli failed".into());
    }
    let sdctl = root.join("target/release/sdctl");

    let stage = sd_model::stage::stage60().map_err(e)?;
    let ct_path = dir.join("stage60_ct.json");
    std::fs::write(&ct_path, sd_model::model_to_json_string(&stage).map_err(e)?)
        .map_err(|x| x.to_string())?;
    let mut entries: Vec<Value> = Vec::new();

    // c2d: exact ZOH of the 60-state stage at 5 kHz
    eprintln!("[bench] c2d (ZOH) of the 60-state stage at 5 kHz, {reps} repeats...");
    let (t_c2d, pd) = time_it(reps * 10, || c2d(&stage, 2e-4, Discretization::Zoh));
    let pd: StateSpace = pd.map_err(e)?;
    let dt_path = dir.join("stage60_5khz.json");
    std::fs::write(&dt_path, sd_model::model_to_json_string(&pd).map_err(e)?)
        .map_err(|x| x.to_string())?;

    // DARE of the 60-state stage at 5 kHz (timed before the 200 000-point frequency response,
    // whose many small allocations slow every later allocation-heavy timing in this process) (Q = CᵀC, R = 1) and a loopshaping design at 1 kHz
    eprintln!(
        "[bench] DARE of the 60-state stage at 5 kHz, loopshaping of the paper stage at 1 kHz..."
    );
    let q = pd.c().transpose() * pd.c();
    let r1 = nalgebra::DMatrix::from_element(1, 1, 1.0);
    let (t_dare, sol) = time_it(reps * 4, || sd_hinf::dare(pd.a(), pd.b(), &q, &r1, None));
    let sol = sol.map_err(|x| x.to_string())?;
    let mut dare_entry = json!({"name": "dare", "size": "60-state stage at 5 kHz, Q = C'C, R = 1",
        "ours_s": t_dare, "ours_rel_residual": sol.residual, "ours_closed_loop_radius": sol.closed_loop,
        "ours_condition_estimate": sol.condition});
    let p1k = c2d(
        &sd_model::stage::paper_stage(0.01).map_err(e)?,
        1e-3,
        Discretization::Zoh,
    )
    .map_err(e)?;
    let w1 = sd_hinf::weights::pid(65.0, 20.0, Some(1e-3), &Default::default())
        .map_err(|x| x.to_string())?;
    let (t_ls, design) = time_it(reps * 4, || {
        sd_hinf::loopshape(&p1k, Some(&w1), None, &Default::default())
    });
    let design = design.map_err(|x| x.to_string())?;
    let p1k_path = dir.join("paper_stage_1khz.json");
    let w1_path = dir.join("w1_pid65.json");
    std::fs::write(&p1k_path, sd_model::model_to_json_string(&p1k).map_err(e)?)
        .map_err(|x| x.to_string())?;
    std::fs::write(&w1_path, sd_model::model_to_json_string(&w1).map_err(e)?)
        .map_err(|x| x.to_string())?;
    let mut ls_entry = json!({"name": "loopshape", "size": "paper stage at 1 kHz (4 states) with a PID-like W1 (3 states)",
        "ours_full_design_s": t_ls, "ours_gamma_min": design.gamma_min});

    // FRF estimation: the 5 kHz stage driven by a multisine, 21 periods of 10 000 samples
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
    .map_err(|x| x.to_string())?;
    let u = ms.repeat(21);
    let y: Vec<f64> = pd
        .simulate(&nalgebra::DMatrix::from_column_slice(u.len(), 1, &u), None)
        .map_err(e)?
        .y
        .iter()
        .cloned()
        .collect();
    let popt = sd_ident::PeriodicOptions::new(10_000, 1);
    let (t_frf, est) = time_it(reps, || sd_ident::frf_periodic(5000.0, None, &u, &y, &popt));
    let est = est.map_err(|x| x.to_string())?;
    let to_bytes = |v: &[f64]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let (u_path, y_path) = (dir.join("frf_u.f64"), dir.join("frf_y.f64"));
    std::fs::write(&u_path, to_bytes(&u)).map_err(|x| x.to_string())?;
    std::fs::write(&y_path, to_bytes(&y)).map_err(|x| x.to_string())?;
    let mut frf_entry = json!({"name": "frf_periodic", "size": "210 000 samples, period 10 000, 20 periods averaged",
        "ours_s": t_frf, "lines": est.lines.len()});
    // order-60 fit of 2500 lines at 40 dB SNR
    let f60: Vec<f64> = (1..=2500).map(|k| k as f64 * 0.999).collect();
    let truth = pd.freqresp(&f60).map_err(e)?;
    let mut seed: u64 = 60;
    let mut normal = || {
        // SplitMix64 + Box–Muller, enough for bench noise
        let mut next = || {
            seed = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = seed;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        let (a, b) = (next().max(1e-300), next());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    };
    let (mut resp, mut var) = (Vec::new(), Vec::new());
    for g in truth.response() {
        let g = g[(0, 0)];
        let s = 0.01 * g.norm();
        let n = num_complex::Complex64::new(normal(), normal()) * (s / 2f64.sqrt());
        resp.push(nalgebra::DMatrix::from_element(1, 1, g + n));
        var.push(nalgebra::DMatrix::from_element(1, 1, s * s));
    }
    let frd60 = sd_model::Frd::new(f60, resp, Some(var), truth.time()).map_err(e)?;
    let fopt = sd_ident::FitOptions {
        order: 60,
        rigid_body: 2,
        feedthrough: false,
        ..Default::default()
    };
    let (t_fit, fit60) = time_it(if quick { 1 } else { 3 }, || sd_ident::fit(&frd60, &fopt));
    let fit60 = fit60.map_err(|x| x.to_string())?;
    let fit_entry = json!({"name": "fit_order60", "size": "2500 lines of the 60-state stage at 5 kHz, 40 dB SNR",
        "ours_s": t_fit, "median_rel_error": fit60.median_rel_error, "cost": fit60.cost,
        "peer": "none: python-control and scipy have no rational FRF fitting"});

    // virtual stage: 70 000-sample experiments (LTI and nonlinear) and a diagnosis of three
    eprintln!("[bench] virtual stage experiments (70 000 samples) and a diagnosis of three...");
    let mk_id = |rate: f64,
                 period: usize,
                 rms: f64,
                 seed: u64,
                 ni: sd_testbed::NonIdealities,
                 role: sd_ident::Role|
     -> Result<sd_testbed::Identification, String> {
        let opt = sd_hinf::weights::PidOptions {
            lowpass_ratio: if rate > 2000.0 { 1000.0 / 30.0 } else { 0.0 },
            ..Default::default()
        };
        let k = sd_hinf::weights::pid(
            if rate > 2000.0 { 30.0 } else { 20.0 },
            20.0,
            Some(1.0 / rate),
            &opt,
        )
        .map_err(|x| x.to_string())?;
        let excitation = sd_ident::design(&sd_ident::MultisineSpec {
            fs: rate,
            period,
            f_min: 0.5,
            f_max: 0.5 * rate - 0.5,
            lines: sd_ident::Lines::Full,
            phases: sd_ident::Phases::Random { seed },
            rms,
            fold_rate_hz: Some(1000.0),
        })
        .map_err(|x| x.to_string())?;
        Ok(sd_testbed::Identification {
            name: format!("e{seed}"),
            controller: k,
            excitation,
            periods: 70_000 / period,
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
    };
    let avg = sd_testbed::NonIdealities {
        averaging: 0.6,
        ..Default::default()
    };
    let truth = sd_testbed::Truth::default();
    let id_fast = mk_id(5000.0, 10_000, 2.0, 1, avg, sd_ident::Role::Model)?;
    let (t_tb, data_fast) = time_it(reps, || sd_testbed::run_identification(&truth, &id_fast));
    let data_fast = data_fast.map_err(|x| x.to_string())?;
    let mut nl = truth.clone();
    nl.modes[0].cubic = 4e12;
    nl.coulomb = 0.5;
    nl.coulomb_velocity = 1e-4;
    let (t_nl, _) = time_it(if quick { 1 } else { 3 }, || {
        sd_testbed::run_identification(&nl, &id_fast)
    });
    let data_fast2 = sd_testbed::run_identification(
        &truth,
        &mk_id(5000.0, 10_000, 2.0, 2, avg, sd_ident::Role::Validation)?,
    )
    .map_err(|x| x.to_string())?;
    let data_slow = sd_testbed::run_identification(
        &truth,
        &mk_id(1000.0, 2_000, 2.0, 3, avg, sd_ident::Role::Validation)?,
    )
    .map_err(|x| x.to_string())?;
    let exps = vec![
        data_fast.to_experiment(),
        data_fast2.to_experiment(),
        data_slow.to_experiment(),
    ];
    let (t_diag, diag) = time_it(if quick { 1 } else { 3 }, || {
        sd_diagnose::diagnose(&exps, &Default::default())
    });
    let diag = diag.map_err(|x| x.to_string())?;
    let tb_entry = json!({"name": "virtual_stage", "size": "70 000 samples at 5 kHz (LTI, averaging sensor) / nonlinear (cubic + Coulomb)",
        "ours_lti_s": t_tb, "ours_nonlinear_s": t_nl, "peer": "none (no virtual stage in python-control or scipy)"});
    let diag_entry = json!({"name": "diagnose", "size": "three experiments of 70 000 samples (5 kHz model, 5 kHz, 1 kHz)",
        "ours_s": t_diag, "cause": diag.cause, "parameters": diag.parameters, "gain_ratio": diag.gain_ratio(),
        "model": diag.model_source(), "peer": "none (no such tool elsewhere)"});

    // freqresp: library call and the whole sdctl process
    let (fmin, fmax) = (0.1, 2500.0);
    let f = grid(fmin, fmax, nfreq, true).map_err(e)?;
    eprintln!("[bench] freqresp of the 5 kHz stage on {nfreq} frequencies...");
    let (t_fr_lib, frd) = time_it(reps, || pd.freqresp(&f));
    let frd = frd.map_err(e)?;
    let grid_arg = format!("{fmin}:{fmax}:{nfreq}:log");
    let out_path = dir.join("freqresp_out.json");
    let (t_fr_proc, ok) = time_it(reps, || {
        Command::new(&sdctl)
            .args([
                "freqresp",
                &dt_path.to_string_lossy(),
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

    // downsample (Lemma 6) of the 5 kHz stage by F = 5, checked against ZOH at 1 kHz
    eprintln!("[bench] downsample (Lemma 6) of the 5 kHz stage, F = 5...");
    let (t_ds, slow) = time_it(reps * 10, || sd_multirate::downsample(&pd, 5));
    let slow = slow.map_err(|x| x.to_string())?;
    let direct = c2d(&stage, 1e-3, Discretization::Zoh).map_err(e)?;
    let rel = |x: &nalgebra::DMatrix<f64>, y: &nalgebra::DMatrix<f64>| (x - y).norm() / y.norm();
    let mut ds_entry = json!({"name": "downsample_lemma6", "size": "60 states, F = 5 (5 kHz -> 1 kHz)",
        "ours_s": t_ds, "ours_rel_error_vs_zoh_1khz": {"a": rel(slow.a(), direct.a()), "b": rel(slow.b(), direct.b())}});

    let mut c2d_entry =
        json!({"name": "c2d_zoh", "size": "60 states, 1 input, h = 0.2 ms", "ours_s": t_c2d});
    let mut fr_entry = json!({"name": "freqresp", "size": format!("60 states, {nfreq} frequencies"),
                              "ours_library_s": t_fr_lib, "ours_sdctl_process_s": t_fr_proc});

    let python = if python_peers_available() {
        eprintln!("[bench] python-control / scipy on the same inputs...");
        let cases = json!({
            "c2d": {"model": ct_path, "ts": 2e-4, "repeats": reps * 10},
            "freqresp": {"model": dt_path, "fmin": fmin, "fmax": fmax, "n": nfreq, "log": true, "repeats": if quick { 1 } else { 3 }},
            "downsample": {"model": dt_path, "factor": 5, "repeats": reps * 10},
            "dare": {"model": dt_path, "repeats": reps},
            "loopshape": {"plant": p1k_path, "w1": w1_path, "repeats": reps * 4},
            "frf": {"u": u_path, "y": y_path, "period": 10_000, "skip": 1, "repeats": reps},
        });
        let cases_path = dir.join("python_cases.json");
        std::fs::write(&cases_path, cases.to_string()).map_err(|x| x.to_string())?;
        let o = Command::new("python3")
            .arg(root.join("tools/bench_python.py"))
            .arg(&cases_path)
            .output()
            .map_err(|x| x.to_string())?;
        if !o.status.success() {
            return Err(format!(
                "python peer failed: {}",
                String::from_utf8_lossy(&o.stderr)
            ));
        }
        let py: Value = serde_json::from_slice(&o.stdout).map_err(|x| x.to_string())?;
        let t_pc = py["c2d_python_control"]["median_s"]
            .as_f64()
            .unwrap_or(f64::NAN);
        let t_sc = py["c2d_scipy"]["median_s"].as_f64().unwrap_or(f64::NAN);
        // agreement of the results
        let ad: Vec<Vec<f64>> =
            serde_json::from_value(py["c2d_python_control"]["ad"].clone()).unwrap_or_default();
        let mut dev: f64 = 0.0;
        for (i, row) in ad.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                dev = dev.max((v - pd.a()[(i, j)]).abs());
            }
        }
        let rel_ad = dev / pd.a().abs().max();
        c2d_entry["peer"] =
            json!({"python_control_sample_system_s": t_pc, "scipy_cont2discrete_s": t_sc});
        c2d_entry["ratio_python_control_over_ours"] = json!(t_pc / t_c2d);
        c2d_entry["ratio_scipy_over_ours"] = json!(t_sc / t_c2d);
        c2d_entry["max_rel_difference_ad"] = json!(rel_ad);
        let t_pf = py["freqresp_python_control"]["median_s"]
            .as_f64()
            .unwrap_or(f64::NAN);
        let stride = py["freqresp_python_control"]["stride"]
            .as_u64()
            .unwrap_or(1) as usize;
        let re: Vec<f64> =
            serde_json::from_value(py["freqresp_python_control"]["re_sample"].clone())
                .unwrap_or_default();
        let im: Vec<f64> =
            serde_json::from_value(py["freqresp_python_control"]["im_sample"].clone())
                .unwrap_or_default();
        let mut worst: f64 = 0.0;
        for (k, (r, i)) in re.iter().zip(im.iter()).enumerate() {
            let ours = frd.response()[k * stride][(0, 0)];
            let theirs = num_complex::Complex64::new(*r, *i);
            worst = worst.max((ours - theirs).norm() / theirs.norm());
        }
        fr_entry["peer"] = json!({"python_control_frequency_response_s": t_pf});
        fr_entry["ratio_python_control_over_sdctl_process"] = json!(t_pf / t_fr_proc);
        fr_entry["ratio_python_control_over_library"] = json!(t_pf / t_fr_lib);
        fr_entry["max_rel_difference_sampled"] = json!(worst);
        let np_ds = &py["downsample_numpy_matrix_power"];
        let t_np = np_ds["median_s"].as_f64().unwrap_or(f64::NAN);
        let to_mat = |v: &Value| -> Option<nalgebra::DMatrix<f64>> {
            let rows: Vec<Vec<f64>> = serde_json::from_value(v.clone()).ok()?;
            let (r, c) = (rows.len(), rows.first()?.len());
            Some(nalgebra::DMatrix::from_fn(r, c, |i, j| rows[i][j]))
        };
        if let (Some(a), Some(b)) = (to_mat(&np_ds["ad"]), to_mat(&np_ds["bd"])) {
            ds_entry["peer"] = json!({"numpy_matrix_power_s": t_np,
                "numpy_rel_error_vs_zoh_1khz": {"a": rel(&a, direct.a()), "b": rel(&b, direct.b())}});
            ds_entry["ratio_numpy_over_ours"] = json!(t_np / t_ds);
        }
        let sc = &py["dare_scipy"];
        dare_entry["peer"] = json!({"scipy_solve_discrete_are": sc, "python_control_dare_slycot_sb02od": py["dare_python_control"]});
        dare_entry["ratio_scipy_over_ours"] =
            json!(sc["median_s"].as_f64().unwrap_or(f64::NAN) / t_dare);
        let pl = &py["loopshape_scipy_gamma_min"];
        ls_entry["peer"] = json!({"scipy_gamma_min_only": pl});
        ls_entry["ratio_scipy_gamma_min_only_over_our_full_design"] =
            json!(pl["median_s"].as_f64().unwrap_or(f64::NAN) / t_ls);
        ls_entry["gamma_min_rel_difference"] = json!(
            (pl["gamma_min"].as_f64().unwrap_or(f64::NAN) - design.gamma_min).abs()
                / design.gamma_min
        );
        let pf = &py["frf_numpy_periodic_average"];
        frf_entry["peer"] = json!({"numpy_fft_period_average": pf});
        frf_entry["ratio_numpy_over_ours"] =
            json!(pf["median_s"].as_f64().unwrap_or(f64::NAN) / t_frf);
        py["versions"].clone()
    } else {
        eprintln!("[bench] python-control/slycot not importable: peers skipped (pip install control slycot scipy)");
        Value::Null
    };
    entries.extend([
        c2d_entry, fr_entry, ds_entry, dare_entry, ls_entry, frf_entry, fit_entry, tb_entry,
        diag_entry,
    ]);
    finish(
        &dir,
        json!({"quick": quick, "python": python, "entries": entries}),
    )
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
