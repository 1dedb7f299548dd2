//! Data: `frf`, `frf_from_arrays`, `fit`, `diagnose`, `testbed`.

use crate::{json_text, py_err, sys_in, sys_out, value_err, SysIn, SysOut};
use nalgebra::DMatrix;
use numpy::ndarray::Array3;
use numpy::{Complex64, IntoPyArray, PyArray1, PyArray3};
use numpy::{PyReadonlyArray1, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use sd_model::{Frd, SampleTime};
use std::path::Path;

/// An FRD as it crosses the boundary: frequencies (Hz), responses `(ny, nu, nf)`, variances
/// `(ny, nu, nf)` or None, `dt` (None: continuous).
pub(crate) type FrdOut<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray3<Complex64>>,
    Option<Bound<'py, PyArray3<f64>>>,
    Option<f64>,
);

pub(crate) fn frd_out<'py>(py: Python<'py>, frd: &Frd) -> FrdOut<'py> {
    let (ny, nu) = frd.shape();
    let nf = frd.len();
    let r = frd.response();
    let resp = Array3::from_shape_fn((ny, nu, nf), |(i, j, k)| r[k][(i, j)]);
    let var = frd
        .variance()
        .map(|v| Array3::from_shape_fn((ny, nu, nf), |(i, j, k)| v[k][(i, j)]).into_pyarray(py));
    (
        frd.freq_hz().to_vec().into_pyarray(py),
        resp.into_pyarray(py),
        var,
        frd.time().ts(),
    )
}

pub(crate) fn frd_in(
    freq_hz: &PyReadonlyArray1<'_, f64>,
    resp: &PyReadonlyArray3<'_, Complex64>,
    var: Option<&PyReadonlyArray3<'_, f64>>,
    dt: Option<f64>,
) -> PyResult<Frd> {
    let f = freq_hz.as_array().to_vec();
    let r = resp.as_array();
    let (ny, nu, nf) = r.dim();
    if nf != f.len() {
        return Err(value_err(format!(
            "the response has {nf} frequencies (its last axis), the frequency vector {}",
            f.len()
        )));
    }
    let response = (0..nf)
        .map(|k| DMatrix::from_fn(ny, nu, |i, j| r[[i, j, k]]))
        .collect();
    let variance = match var {
        Some(v) => {
            let v = v.as_array();
            if v.dim() != (ny, nu, nf) {
                return Err(value_err(format!(
                    "the variance has shape {:?}, the response ({ny}, {nu}, {nf})",
                    v.dim()
                )));
            }
            Some(
                (0..nf)
                    .map(|k| DMatrix::from_fn(ny, nu, |i, j| v[[i, j, k]]))
                    .collect(),
            )
        }
        None => None,
    };
    let time = SampleTime::from_option(dt).map_err(py_err)?;
    Frd::new(f, response, variance, time).map_err(py_err)
}

/// The FRF of experiment `experiment` of the manifest file `manifest` (periodic or LPM, closed
/// loop through the reference), with its data-quality warnings.
#[pyfunction]
#[pyo3(signature = (manifest, experiment, excited_fraction, keep_low_snr))]
fn frf<'py>(
    py: Python<'py>,
    manifest: &str,
    experiment: &str,
    excited_fraction: Option<f64>,
    keep_low_snr: bool,
) -> PyResult<(FrdOut<'py>, Vec<String>)> {
    let req = sd_ident::FrfRequest {
        excited_fraction,
        keep_low_snr,
    };
    let (frd, warnings) = py
        .detach(|| {
            let exp = sd_ident::load_experiment(Path::new(manifest), experiment)?;
            sd_ident::frf_of_experiment(&exp, &req)
        })
        .map_err(py_err)?;
    let w = warnings.iter().map(|w| w.to_string()).collect();
    Ok((frd_out(py, &frd), w))
}

/// The FRF of recorded arrays: `period` samples per period (None: non-periodic, LPM),
/// `skip_periods` transient periods, `r` the reference (None: open loop `Y/U`).
#[pyfunction]
#[pyo3(signature = (r, u, y, fs, period, skip_periods, excited_fraction, keep_low_snr))]
fn frf_from_arrays<'py>(
    py: Python<'py>,
    r: Option<PyReadonlyArray1<'py, f64>>,
    u: PyReadonlyArray1<'py, f64>,
    y: PyReadonlyArray1<'py, f64>,
    fs: f64,
    period: Option<usize>,
    skip_periods: usize,
    excited_fraction: Option<f64>,
    keep_low_snr: bool,
) -> PyResult<(FrdOut<'py>, Vec<String>)> {
    let exp = sd_ident::Experiment::from_arrays(
        "arrays",
        fs,
        period,
        skip_periods,
        r.map(|r| r.as_array().to_vec()),
        u.as_array().to_vec(),
        y.as_array().to_vec(),
    )
    .map_err(py_err)?;
    let req = sd_ident::FrfRequest {
        excited_fraction,
        keep_low_snr,
    };
    let (frd, warnings) = py
        .detach(|| sd_ident::frf_of_experiment(&exp, &req))
        .map_err(py_err)?;
    let w = warnings.iter().map(|w| w.to_string()).collect();
    Ok((frd_out(py, &frd), w))
}

/// A discrete-time rational fit of a SISO FRD (`sd_ident::fit`): the model, its cost, the
/// median relative error, the cost per line, the poles and the fit's warnings. A MIMO FRD gets
/// one set of poles for every entry (`sd_ident::fit_common_poles`, residue ranks `rank`:
/// "select", "full" or a number): the model, cost, full-rank cost, entry costs, median
/// relative error, poles and per-mode ranks and singular values.
#[pyfunction]
#[pyo3(signature = (freq_hz, response, variance, dt, order, rigid_body, strictly_proper, weighting, min_damping, rank, input_delay))]
fn fit<'py>(
    py: Python<'py>,
    freq_hz: PyReadonlyArray1<'py, f64>,
    response: PyReadonlyArray3<'py, Complex64>,
    variance: Option<PyReadonlyArray3<'py, f64>>,
    dt: Option<f64>,
    order: usize,
    rigid_body: usize,
    strictly_proper: bool,
    weighting: &str,
    min_damping: f64,
    rank: &str,
    input_delay: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let input_delay: sd_ident::InputDelay = input_delay
        .parse()
        .map_err(|e: String| value_err(format!("input_delay: {e}")))?;
    let frd = frd_in(&freq_hz, &response, variance.as_ref(), dt)?;
    let weighting = match weighting {
        "variance" => sd_ident::Weighting::Variance,
        "relative" => sd_ident::Weighting::Relative,
        "uniform" => sd_ident::Weighting::Uniform,
        other => {
            return Err(value_err(format!(
                "weighting {other:?}: use \"variance\", \"relative\" or \"uniform\""
            )))
        }
    };
    let opt = sd_ident::FitOptions {
        order,
        rigid_body,
        feedthrough: !strictly_proper,
        weighting,
        min_damping,
        ..Default::default()
    };
    if frd.shape() != (1, 1) {
        return fit_mimo(py, &frd, opt, rank, input_delay);
    }
    if input_delay != sd_ident::InputDelay::None {
        return Err(value_err(
            "input_delay applies to a MIMO FRD; a SISO fit absorbs a delay with its poles",
        ));
    }
    let r = py.detach(|| sd_ident::fit(&frd, &opt)).map_err(py_err)?;
    let d = PyDict::new(py);
    d.set_item("model", sys_out(py, &r.model))?;
    d.set_item("cost", r.cost)?;
    d.set_item("median_rel_error", r.median_rel_error)?;
    d.set_item("line_cost", r.line_cost.clone().into_pyarray(py))?;
    let poles: Vec<Complex64> = r.poles.iter().map(|p| Complex64::new(p.re, p.im)).collect();
    d.set_item("poles", poles.into_pyarray(py))?;
    let w: Vec<String> = r.warnings.iter().map(|w| w.to_string()).collect();
    d.set_item("warnings", w)?;
    Ok(d)
}

/// [`fit`] of a MIMO FRD.
fn fit_mimo<'py>(
    py: Python<'py>,
    frd: &sd_model::Frd,
    fit: sd_ident::FitOptions,
    rank: &str,
    input_delay: sd_ident::InputDelay,
) -> PyResult<Bound<'py, PyDict>> {
    let rank: sd_ident::ResidueRank = rank
        .parse()
        .map_err(|e: String| value_err(format!("rank: {e}")))?;
    let opt = sd_ident::MimoFitOptions {
        fit,
        rank,
        input_delay,
        ..Default::default()
    };
    let r = py
        .detach(|| sd_ident::fit_common_poles(frd, &opt))
        .map_err(py_err)?;
    let d = PyDict::new(py);
    d.set_item("model", sys_out(py, &r.model))?;
    d.set_item("cost", r.cost)?;
    d.set_item("full_rank_cost", r.full_rank_cost)?;
    let ec: Vec<Vec<f64>> = (0..r.entry_cost.nrows())
        .map(|a| r.entry_cost.row(a).iter().copied().collect())
        .collect();
    d.set_item("entry_cost", ec)?;
    d.set_item("median_rel_error", r.median_rel_error)?;
    let poles: Vec<Complex64> = r.poles.iter().map(|p| Complex64::new(p.re, p.im)).collect();
    d.set_item("poles", poles.into_pyarray(py))?;
    let ranks: Vec<usize> = r.modes.iter().map(|m| m.rank).collect();
    d.set_item("ranks", ranks)?;
    let sv: Vec<Vec<f64>> = r.modes.iter().map(|m| m.singular_values.clone()).collect();
    d.set_item("singular_values", sv)?;
    d.set_item("states", r.model.n())?;
    d.set_item("input_delay", r.input_delay.clone())?;
    let scans = PyList::empty(py);
    for s in &r.delay_scans {
        let e = PyDict::new(py);
        e.set_item("input", s.input)?;
        e.set_item("delay", s.delay)?;
        e.set_item("cost", s.cost.clone())?;
        e.set_item("threshold", s.threshold)?;
        scans.append(e)?;
    }
    d.set_item("delay_scans", scans)?;
    Ok(d)
}

/// The diagnosis of the experiments of `manifest` (`sdctl diagnose`): `diagnosis.json`'s text;
/// with `out`, also the whole report folder (report.md, figures, models).
#[pyfunction]
#[pyo3(signature = (manifest, model, alpha, max_order, out))]
fn diagnose(
    py: Python<'_>,
    manifest: &str,
    model: Option<SysIn<'_>>,
    alpha: f64,
    max_order: usize,
    out: Option<&str>,
) -> PyResult<String> {
    let model = model.as_ref().map(sys_in).transpose()?;
    let exps = py
        .detach(|| sd_ident::load_experiments(Path::new(manifest), |_| true))
        .map_err(py_err)?;
    if exps.iter().any(|e| e.spec.is_mimo()) {
        if model.is_some() {
            return Err(value_err(
                "model= is for SISO experiments: the MIMO diagnosis fits its common-pole model",
            ));
        }
        let opt = sd_diagnose::MimoDiagnoseOptions {
            alpha,
            order: None,
            max_order,
        };
        let d = py
            .detach(|| sd_diagnose::diagnose_mimo(&exps, &opt, &mut |_| {}))
            .map_err(py_err)?;
        if let Some(dir) = out {
            py.detach(|| sd_report::mimo::write_mimo(Path::new(dir), &d, manifest))
                .map_err(|e| value_err(e.to_string()))?;
        }
        return json_text(&d.to_json());
    }
    let d = py
        .detach(|| {
            let opt = sd_diagnose::DiagnoseOptions {
                model,
                alpha,
                max_order,
            };
            sd_diagnose::diagnose(&exps, &opt)
        })
        .map_err(py_err)?;
    if let Some(dir) = out {
        py.detach(|| sd_report::diagnosis::write_all(Path::new(dir), &d, manifest))
            .map_err(|e| value_err(e.to_string()))?;
    }
    json_text(&d.to_json())
}

/// What the diagnosis in `diagnosis_dir` (its `predictor.json`) predicts on the experiments of
/// `manifest` (`sdctl predict`): `prediction.json`'s text; with `out`, also the report folder.
/// An error when no experiment can be predicted (each one's reason in the message).
#[pyfunction]
#[pyo3(signature = (diagnosis_dir, manifest, alpha, out))]
fn predict(
    py: Python<'_>,
    diagnosis_dir: &str,
    manifest: &str,
    alpha: f64,
    out: Option<&str>,
) -> PyResult<String> {
    let path = Path::new(diagnosis_dir).join("predictor.json");
    let text = std::fs::read_to_string(&path).map_err(|e| {
        value_err(format!(
            "{}: {e}; give a folder written by diagnose(out=...) or `sdctl diagnose`",
            path.display()
        ))
    })?;
    let p = py
        .detach(|| {
            let predictor = sd_diagnose::Predictor::from_json_str(&text)?;
            let exps = sd_ident::load_experiments(Path::new(manifest), |_| true)
                .map_err(|e| sd_diagnose::DiagnoseError::Setup(format!("{manifest}: {e}")))?;
            sd_diagnose::predict_experiments(&predictor, &exps, alpha)
        })
        .map_err(py_err)?;
    if let Some(msg) = p.nothing_predicted() {
        return Err(value_err(msg));
    }
    if let Some(dir) = out {
        py.detach(|| {
            std::fs::create_dir_all(dir).map_err(|source| sd_report::ReportError::Io {
                path: dir.to_string(),
                source,
            })?;
            sd_report::prediction::write_prediction(Path::new(dir), &p, diagnosis_dir)
        })
        .map_err(|e| value_err(e.to_string()))?;
    }
    let v = serde_json::to_value(&p).map_err(|e| value_err(e.to_string()))?;
    json_text(&v)
}

/// Writes `files` into the folder `dir` (created), each atomically.
fn write_files(dir: &str, files: &[(String, String)]) -> PyResult<()> {
    let dir = Path::new(dir);
    std::fs::create_dir_all(dir)
        .map_err(|e| value_err(format!("cannot create {}: {e}", dir.display())))?;
    for (name, text) in files {
        sd_report::write_atomic(&dir.join(name), &format!("{text}\n"))
            .map_err(|e| value_err(e.to_string()))?;
    }
    Ok(())
}

/// [`testbed`] of a multi-axis configuration: `r`, `u`, `y` are lists of arrays (one per
/// actuator or sensor).
fn testbed_axes<'py>(
    py: Python<'py>,
    text: &str,
    out: Option<&str>,
) -> PyResult<(Vec<Bound<'py, PyDict>>, SysOut<'py>)> {
    let (cfg, data, files) = py
        .detach(|| {
            let cfg = sd_testbed::parse_axis_config(text)?;
            let (data, files) = sd_testbed::run_axis_config(&cfg)?;
            Ok::<_, sd_testbed::TestbedError>((cfg, data, files))
        })
        .map_err(py_err)?;
    if let Some(dir) = out {
        write_files(dir, &files)?;
    }
    let truth = cfg.truth.linear_model().map_err(py_err)?;
    let mut list = Vec::with_capacity(data.len());
    for e in &data {
        let d = PyDict::new(py);
        let arrays = |v: &[Vec<f64>]| -> Vec<Bound<'py, numpy::PyArray1<f64>>> {
            v.iter().map(|c| c.clone().into_pyarray(py)).collect()
        };
        d.set_item("name", &e.name)?;
        d.set_item("rate_hz", e.rate_hz)?;
        d.set_item("period", e.period)?;
        d.set_item("skip_periods", e.skip_periods)?;
        d.set_item("role", e.role.as_str())?;
        d.set_item("r", arrays(&e.r))?;
        d.set_item("u", arrays(&e.u))?;
        d.set_item("y", arrays(&e.y))?;
        list.push(d);
    }
    Ok((list, sys_out(py, &truth)))
}

/// The virtual stage (`sdctl testbed`): runs the configuration `config` (TOML text; None: the
/// default two-rate identification), returns the experiments' arrays and the continuous truth,
/// and with `out` writes the manifest, the CSVs and truth.json there.
#[pyfunction]
#[pyo3(signature = (config, out))]
fn testbed<'py>(
    py: Python<'py>,
    config: Option<&str>,
    out: Option<&str>,
) -> PyResult<(Vec<Bound<'py, PyDict>>, SysOut<'py>)> {
    let text = config.unwrap_or(sd_testbed::DEFAULT_CONFIG);
    if sd_testbed::is_multiaxis(text) {
        return testbed_axes(py, text, out);
    }
    let (data, truth) = py
        .detach(|| {
            let cfg = sd_testbed::parse_config(text)?;
            let data = sd_testbed::run_config(&cfg)?;
            let truth = sd_testbed::truth_model(&cfg.truth)?;
            Ok::<_, sd_testbed::TestbedError>((data, truth))
        })
        .map_err(py_err)?;
    if let Some(dir) = out {
        let files = sd_testbed::output_files(&data, &truth).map_err(py_err)?;
        write_files(dir, &files)?;
    }
    let mut list = Vec::with_capacity(data.len());
    for e in &data {
        let d = PyDict::new(py);
        d.set_item("name", &e.name)?;
        d.set_item("rate_hz", e.rate_hz)?;
        d.set_item("period", e.period)?;
        d.set_item("skip_periods", e.skip_periods)?;
        d.set_item("role", e.role.as_str())?;
        d.set_item("r", e.r.clone().map(|r| r.into_pyarray(py)))?;
        d.set_item("u", e.u.clone().into_pyarray(py))?;
        d.set_item("y", e.y.clone().into_pyarray(py))?;
        list.push(d);
    }
    Ok((list, sys_out(py, &truth)))
}

/// An FRD from the toolkit's FRD JSON text (docs/formats.md).
#[pyfunction]
fn frd_from_json<'py>(py: Python<'py>, text: &str) -> PyResult<FrdOut<'py>> {
    let f = sd_model::frd_from_json_str(text).map_err(py_err)?;
    Ok(frd_out(py, &f))
}

/// The toolkit's FRD JSON text of an FRD.
#[pyfunction]
#[pyo3(signature = (freq_hz, response, variance, dt))]
fn frd_to_json(
    freq_hz: PyReadonlyArray1<'_, f64>,
    response: PyReadonlyArray3<'_, Complex64>,
    variance: Option<PyReadonlyArray3<'_, f64>>,
    dt: Option<f64>,
) -> PyResult<String> {
    let f = frd_in(&freq_hz, &response, variance.as_ref(), dt)?;
    sd_model::frd_to_json_string(&f).map_err(py_err)
}

/// Registers this file's functions.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(frf, m)?)?;
    m.add_function(wrap_pyfunction!(frf_from_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(predict, m)?)?;
    m.add_function(wrap_pyfunction!(testbed, m)?)?;
    m.add_function(wrap_pyfunction!(frd_from_json, m)?)?;
    m.add_function(wrap_pyfunction!(frd_to_json, m)?)?;
    Ok(())
}
