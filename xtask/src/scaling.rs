//! The scaling table of `cargo xtask bench`: time against state dimension (c2d, Lemma 6
//! downsampling, freqresp per point — 20 000 frequencies on a prepared evaluator — and its
//! once-per-model set-up timed apart (the peer's per point: the slope between 2000 and 20 000
//! frequencies), DARE, loopshaping, the fit) and against record length
//! (periodic FRF estimation, the diagnosis), each with the exponent of a least-squares line
//! through `log t` against `log n` and, where python-control/scipy/numpy have the operation,
//! the peer's time on the same inputs.
//!
//! The models: a rigid body and `(n − 2)/2` flexible modes log-spaced from 100 Hz to 2.4 kHz
//! (ζ 0.5–2 %, residues alternating in sign), the physical-coordinate realisation of
//! [`sd_model::stage::stage_model`], at 5 kHz after an exact ZOH.

use crate::bench::{err, identification, noisy_frd, time_it, write_model};
use sd_model::stage::{stage_model, Mode};
use sd_model::{c2d, grid, Discretization, StateSpace};
use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;

/// State dimensions of the table.
pub const SIZES: [usize; 5] = [10, 30, 60, 120, 240];
/// Record lengths (samples) of the table.
pub const LENGTHS: [usize; 3] = [10_000, 100_000, 1_000_000];
/// Frequencies of the per-point freqresp timing.
const POINTS: usize = 2000;

/// The continuous n-state stage (module documentation).
pub fn stage_n(n: usize) -> Result<StateSpace, String> {
    let k = n.saturating_sub(2) / 2;
    let modes: Vec<Mode> = (0..k)
        .map(|i| {
            let x = if k > 1 {
                i as f64 / (k - 1) as f64
            } else {
                0.0
            };
            Mode {
                freq_hz: 100.0 * 24f64.powf(x),
                zeta: 0.005 + 0.015 * ((i * 7) % 11) as f64 / 10.0,
                residue: if i % 2 == 0 { 0.6 } else { -0.4 },
            }
        })
        .collect();
    stage_model(20.0, true, &modes).map_err(err)
}

/// The exponent `e` of `log t = a + e·log x` by least squares (NaN with fewer than two
/// positive points).
pub fn exponent(x: &[f64], t: &[f64]) -> f64 {
    let pts: Vec<(f64, f64)> = x
        .iter()
        .zip(t)
        .filter(|(a, b)| **a > 0.0 && **b > 0.0 && b.is_finite())
        .map(|(a, b)| (a.ln(), b.ln()))
        .collect();
    let m = pts.len() as f64;
    if pts.len() < 2 {
        return f64::NAN;
    }
    let (sx, sy) = pts
        .iter()
        .fold((0.0, 0.0), |(sx, sy), (a, b)| (sx + a, sy + b));
    let (mx, my) = (sx / m, sy / m);
    let (sxy, sxx) = pts.iter().fold((0.0, 0.0), |(sxy, sxx), (a, b)| {
        (sxy + (a - mx) * (b - my), sxx + (a - mx) * (a - mx))
    });
    sxy / sxx
}

/// One row of the table: the operation, its sizes, our times, the peer's where given.
fn row(
    name: &str,
    unit: &str,
    sizes: &[usize],
    ours: &[f64],
    peer: Option<(&str, Vec<f64>)>,
) -> Value {
    let x: Vec<f64> = sizes.iter().map(|&n| n as f64).collect();
    let mut v = json!({"name": name, "against": unit, "sizes": sizes, "ours_s": ours,
        "ours_exponent": exponent(&x, ours)});
    if let Some((who, t)) = peer {
        let ratio: Vec<f64> = t.iter().zip(ours).map(|(p, o)| p / o).collect();
        v["peer"] = json!(who);
        v["peer_s"] = json!(t);
        v["peer_exponent"] = json!(exponent(&x, &t));
        v["ratio_peer_over_ours"] = json!(ratio);
    }
    v
}

/// Our times against n, with the model files for the peer.
struct BySize {
    c2d: Vec<f64>,
    downsample: Vec<f64>,
    freqresp_per_point: Vec<f64>,
    freqresp_setup: Vec<f64>,
    dare: Vec<f64>,
    loopshape: Vec<f64>,
    fit: Vec<f64>,
    files: Files,
}

/// Times every state-dimension operation at every size of [`SIZES`].
fn by_size(dir: &Path, quick: bool) -> Result<BySize, String> {
    let reps = if quick { 1 } else { 3 };
    let mut o = BySize {
        c2d: Vec::new(),
        downsample: Vec::new(),
        freqresp_per_point: Vec::new(),
        freqresp_setup: Vec::new(),
        dare: Vec::new(),
        loopshape: Vec::new(),
        fit: Vec::new(),
        files: Vec::new(),
    };
    let f10 = grid(0.1, 2500.0, 10 * POINTS, true).map_err(err)?;
    let w1 = sd_hinf::weights::pid(20.0, 20.0, Some(1e-3), &Default::default()).map_err(err)?;
    for n in SIZES {
        eprintln!("[bench] scaling: n = {n}");
        let ct = stage_n(n)?;
        let (t, pd) = time_it(reps, || c2d(&ct, 2e-4, Discretization::Zoh));
        let pd = pd.map_err(err)?;
        o.c2d.push(t);
        let (ct_path, dt_path) = (
            dir.join(format!("scale{n}_ct.json")),
            dir.join(format!("scale{n}_5khz.json")),
        );
        write_model(&ct_path, &ct)?;
        write_model(&dt_path, &pd)?;
        o.files.push((
            n,
            ct_path.to_string_lossy().into_owned(),
            dt_path.to_string_lossy().into_owned(),
        ));
        let (t, slow) = time_it(reps, || sd_multirate::downsample(&pd, 5));
        let slow = slow.map_err(err)?;
        o.downsample.push(t);
        // the set-up (the reduction and its accuracy check, paid once per model) and the
        // evaluation per point on the prepared evaluator (10·POINTS frequencies into one
        // buffer), timed apart: a slope between two whole calls was noisier than either
        let (t, ev) = time_it(reps, || sd_model::FreqRespEvaluator::new(&pd));
        let ev = ev.map_err(err)?;
        o.freqresp_setup.push(t);
        let (t, _) = time_it(reps, || ev.eval_many_flat(&f10));
        o.freqresp_per_point.push(t / f10.len() as f64);
        let q = pd.c().transpose() * pd.c();
        let r1 = nalgebra::DMatrix::from_element(1, 1, 1.0);
        let (t, x) = time_it(reps, || sd_hinf::dare(pd.a(), pd.b(), &q, &r1, None));
        x.map_err(err)?;
        o.dare.push(t);
        let (t, d) = time_it(reps, || {
            sd_hinf::loopshape(&slow, Some(&w1), None, &Default::default())
        });
        o.loopshape.push(if d.is_ok() { t } else { f64::NAN });
        o.fit.push(fit_time(&pd, n, quick)?);
    }
    Ok(o)
}

/// The order-n fit of 2500 lines of the n-state stage at 40 dB SNR (skipped above 120 states
/// in a quick run).
fn fit_time(pd: &StateSpace, n: usize, quick: bool) -> Result<f64, String> {
    if quick && n > 120 {
        return Ok(f64::NAN);
    }
    let frd = noisy_frd(pd, n as u64)?;
    let opt = sd_ident::FitOptions {
        order: n,
        rigid_body: 2,
        feedthrough: false,
        ..Default::default()
    };
    let (t, r) = time_it(1, || sd_ident::fit(&frd, &opt));
    Ok(if r.is_ok() { t } else { f64::NAN })
}

/// Written files of the peer: `(size, first path, second path)`.
type Files = Vec<(usize, String, String)>;

/// Our times against record length: periodic FRF estimation (period 1000) and a diagnosis of
/// three virtual-stage experiments of that length each; the signals for the peer.
fn by_length(
    dir: &Path,
    lengths: &[usize],
    quick: bool,
) -> Result<(Vec<f64>, Vec<f64>, Files), String> {
    let (mut frf, mut diag, mut files) = (Vec::new(), Vec::new(), Vec::new());
    let truth = sd_testbed::Truth::default();
    let avg = sd_testbed::NonIdealities {
        averaging: 0.6,
        ..Default::default()
    };
    for &len in lengths {
        eprintln!("[bench] scaling: {len} samples");
        let period = 1000;
        let id = identification(5000.0, period, 1, avg, sd_ident::Role::Model, len)?;
        let data = sd_testbed::run_identification(&truth, &id).map_err(err)?;
        let e = data.to_experiment();
        let popt = sd_ident::PeriodicOptions::new(period, 1);
        let (t, est) = time_it(if quick { 1 } else { 3 }, || {
            sd_ident::frf_periodic(5000.0, None, &e.u, &e.y, &popt)
        });
        est.map_err(err)?;
        frf.push(t);
        let to_bytes = |v: &[f64]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let (u_path, y_path) = (
            dir.join(format!("scale_u{len}.f64")),
            dir.join(format!("scale_y{len}.f64")),
        );
        std::fs::write(&u_path, to_bytes(&e.u)).map_err(err)?;
        std::fs::write(&y_path, to_bytes(&e.y)).map_err(err)?;
        files.push((
            len,
            u_path.to_string_lossy().into_owned(),
            y_path.to_string_lossy().into_owned(),
        ));
        let run = |rate: f64, period: usize, seed: u64| -> Result<sd_ident::Experiment, String> {
            let id = identification(rate, period, seed, avg, sd_ident::Role::Validation, len)?;
            Ok(sd_testbed::run_identification(&truth, &id)
                .map_err(err)?
                .to_experiment())
        };
        let exps = vec![e, run(5000.0, period, 2)?, run(1000.0, period / 5, 3)?];
        let (t, d) = time_it(1, || sd_diagnose::diagnose(&exps, &Default::default()));
        diag.push(if d.is_ok() { t } else { f64::NAN });
    }
    Ok((frf, diag, files))
}

/// The peers' times on the same inputs (`tools/bench_python.py --scaling`), when importable.
fn peers(root: &Path, dir: &Path, s: &BySize, lens: &Files) -> Option<Value> {
    let cases = json!({
        "models": s.files.iter().map(|(n, ct, dt)| json!({"n": n, "ct": ct, "dt": dt})).collect::<Vec<_>>(),
        "points": POINTS,
        "records": lens.iter().map(|(l, u, y)| json!({"samples": l, "u": u, "y": y, "period": 1000})).collect::<Vec<_>>(),
    });
    let path = dir.join("python_scaling.json");
    std::fs::write(&path, cases.to_string()).ok()?;
    let out = Command::new("python3")
        .arg(root.join("tools/bench_python.py"))
        .arg("--scaling")
        .arg(&path)
        .output()
        .ok()?;
    if !out.status.success() {
        eprintln!(
            "[bench] scaling peers failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        return None;
    }
    serde_json::from_slice(&out.stdout).ok()
}

/// The whole table (JSON rows), printed as it goes.
pub fn table(root: &Path, dir: &Path, quick: bool, with_peers: bool) -> Result<Value, String> {
    let s = by_size(dir, quick)?;
    // a quick run stops at 10⁵ samples
    let lengths = if quick { &LENGTHS[..2] } else { &LENGTHS[..] };
    let (frf, diag, lens) = by_length(dir, lengths, quick)?;
    let py = if with_peers {
        peers(root, dir, &s, &lens)
    } else {
        None
    };
    let p = |k: &str| -> Option<Vec<f64>> {
        py.as_ref()
            .and_then(|v| serde_json::from_value::<Vec<f64>>(v[k].clone()).ok())
    };
    let sizes = SIZES.to_vec();
    let with = |who: &'static str, k: &str| p(k).map(|t| (who, t));
    let rows = vec![
        row(
            "c2d_zoh",
            "states",
            &sizes,
            &s.c2d,
            with("scipy.signal.cont2discrete", "c2d"),
        ),
        row(
            "downsample_lemma6",
            "states",
            &sizes,
            &s.downsample,
            with("numpy.linalg.matrix_power", "downsample"),
        ),
        row(
            "freqresp_per_point",
            "states",
            &sizes,
            &s.freqresp_per_point,
            with("control.frequency_response", "freqresp_per_point"),
        ),
        row(
            "freqresp_setup",
            "states",
            &sizes,
            &s.freqresp_setup,
            with("control.frequency_response", "freqresp_setup"),
        ),
        row(
            "dare",
            "states",
            &sizes,
            &s.dare,
            with("scipy.linalg.solve_discrete_are", "dare"),
        ),
        row("loopshape", "states", &sizes, &s.loopshape, None),
        row("fit", "states (= order)", &sizes, &s.fit, None),
        row(
            "frf_periodic",
            "samples",
            lengths,
            &frf,
            with("numpy period average", "frf"),
        ),
        row("diagnose", "samples per experiment", lengths, &diag, None),
    ];
    for r in &rows {
        eprintln!(
            "[bench] scaling {:<20} ours {:?} (exponent {:.2}){}",
            r["name"].as_str().unwrap_or(""),
            r["ours_s"]
                .as_array()
                .map(|a| a
                    .iter()
                    .map(|x| format!("{:.3e}", x.as_f64().unwrap_or(f64::NAN)))
                    .collect::<Vec<_>>())
                .unwrap_or_default(),
            r["ours_exponent"].as_f64().unwrap_or(f64::NAN),
            match r["ratio_peer_over_ours"].as_array() {
                Some(x) => format!(
                    "; {} over ours {:?}",
                    r["peer"].as_str().unwrap_or(""),
                    x.iter()
                        .map(|v| format!("{:.2}", v.as_f64().unwrap_or(f64::NAN)))
                        .collect::<Vec<_>>()
                ),
                None => String::new(),
            }
        );
    }
    Ok(Value::Array(rows))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exponent_of_a_power_law() {
        let x = [10.0, 30.0, 60.0, 120.0];
        let t: Vec<f64> = x.iter().map(|v: &f64| 3e-6 * v.powf(2.5)).collect();
        assert!((exponent(&x, &t) - 2.5).abs() < 1e-12);
    }

    #[test]
    fn stage_of_n_states() {
        for n in SIZES {
            let s = stage_n(n).expect("stage");
            assert_eq!(s.n(), n);
        }
    }
}
