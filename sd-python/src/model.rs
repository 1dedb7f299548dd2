//! Models: `c2d`, `d2c`, `alias`, `downsample`, `freqresp`, `poles`, `zeros`, `lsim`.

use crate::{py_err, sys_in, sys_out, value_err, SysIn, SysOut};
use numpy::ndarray::Array3;
use numpy::{Complex64, IntoPyArray, PyArray1, PyArray3, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Exact discretisation of a continuous model (`method` "zoh", "foh" or "tustin"); with
/// `hold_delay` or `averaging` (fractions of the period) the rate-tied non-ideal ZOH of
/// `sd_multirate::c2d_nonideal`.
#[pyfunction]
#[pyo3(signature = (sys, dt, method, hold_delay, averaging, prewarp_hz))]
fn c2d<'py>(
    py: Python<'py>,
    sys: SysIn<'py>,
    dt: f64,
    method: &str,
    hold_delay: f64,
    averaging: f64,
    prewarp_hz: Option<f64>,
) -> PyResult<SysOut<'py>> {
    let s = sys_in(&sys)?;
    let nonideal = hold_delay != 0.0 || averaging != 0.0;
    let m = match method {
        "zoh" => sd_model::Discretization::Zoh,
        "foh" => sd_model::Discretization::Foh,
        "tustin" | "bilinear" => sd_model::Discretization::Tustin { prewarp_hz },
        "matched" => sd_model::Discretization::Matched,
        "impulse" => sd_model::Discretization::Impulse,
        other => {
            return Err(value_err(format!(
                "method {other:?}: use \"zoh\", \"foh\", \"tustin\", \"matched\" or \"impulse\""
            )))
        }
    };
    if prewarp_hz.is_some() && !matches!(m, sd_model::Discretization::Tustin { .. }) {
        return Err(value_err("prewarp_hz only applies to method=\"tustin\""));
    }
    let d = if nonideal {
        if !matches!(m, sd_model::Discretization::Zoh) {
            return Err(value_err(
                "hold_delay and averaging apply to method=\"zoh\" (the default)",
            ));
        }
        let ni = sd_multirate::NonIdeal {
            hold_delay,
            averaging,
        };
        sd_multirate::c2d_nonideal(&s, dt, ni).map_err(py_err)?
    } else {
        sd_model::c2d(&s, dt, m).map_err(py_err)?
    };
    Ok(sys_out(py, &d))
}

/// A list of Python dicts.
type Dicts<'py> = Vec<Bound<'py, PyDict>>;

/// The continuous model of a discrete one (principal logarithm, or the branch nearest each of
/// `near_hz`) and, per mode, its alias candidates up to `max_hz`.
#[pyfunction]
#[pyo3(signature = (sys, near_hz, max_hz))]
fn d2c<'py>(
    py: Python<'py>,
    sys: SysIn<'py>,
    near_hz: Vec<f64>,
    max_hz: Option<f64>,
) -> PyResult<(SysOut<'py>, Dicts<'py>, Dicts<'py>)> {
    let s = sys_in(&sys)?;
    let ts = s
        .ts()
        .ok_or_else(|| value_err("d2c takes a discrete model (dt is None)"))?;
    let max_hz = max_hz.unwrap_or(3.0 / ts);
    if !(max_hz.is_finite() && max_hz > 0.0) {
        return Err(value_err(format!("max_hz {max_hz} must be positive")));
    }
    let (principal, modes) = sd_model::d2c_with_aliases(&s, max_hz).map_err(py_err)?;
    let (c, picks) = if near_hz.is_empty() {
        (principal, Vec::new())
    } else {
        sd_model::d2c_near(&s, &near_hz).map_err(py_err)?
    };
    let mut mode_list = Vec::with_capacity(modes.len());
    for m in modes {
        let d = PyDict::new(py);
        d.set_item("z", Complex64::new(m.z.re, m.z.im))?;
        d.set_item("freq_hz", m.freq_hz)?;
        d.set_item("damping", m.damping)?;
        d.set_item("candidates", m.candidates)?;
        mode_list.push(d);
    }
    let mut pick_list = Vec::with_capacity(picks.len());
    for p in picks {
        let d = PyDict::new(py);
        d.set_item("requested_hz", p.requested_hz)?;
        d.set_item("z", Complex64::new(p.z.re, p.z.im))?;
        d.set_item("branch", p.branch)?;
        d.set_item("freq_hz", p.freq_hz)?;
        d.set_item("damping", p.damping)?;
        d.set_item("principal_hz", p.principal_hz)?;
        pick_list.push(d);
    }
    Ok((sys_out(py, &c), mode_list, pick_list))
}

/// Where `freq_hz` appears when sampled at `rate_hz`, the continuous frequencies up to
/// `max_hz` that appear there, and with `factor` the fast frequencies folding onto it through
/// the slow hold with their weights.
#[pyfunction]
#[pyo3(signature = (freq_hz, rate_hz, max_hz, factor))]
fn alias<'py>(
    py: Python<'py>,
    freq_hz: f64,
    rate_hz: f64,
    max_hz: Option<f64>,
    factor: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let a = sd_model::alias(freq_hz, rate_hz).map_err(py_err)?;
    let max_hz = max_hz.unwrap_or(5.0 * rate_hz);
    let folds = sd_model::folding_frequencies(a.alias_hz, rate_hz, max_hz).map_err(py_err)?;
    let d = PyDict::new(py);
    d.set_item("freq_hz", a.freq_hz)?;
    d.set_item("rate_hz", a.rate_hz)?;
    d.set_item("alias_hz", a.alias_hz)?;
    d.set_item("fold_index", a.fold_index)?;
    d.set_item("mirrored", a.mirrored)?;
    d.set_item("nyquist_hz", rate_hz / 2.0)?;
    d.set_item("folding_frequencies_hz", folds)?;
    if let Some(f) = factor {
        let terms = sd_multirate::fold_map(a.alias_hz, rate_hz, f).map_err(py_err)?;
        let list: Vec<(i64, f64, f64)> = terms
            .iter()
            .map(|t| (t.k as i64, t.fast_hz, t.weight))
            .collect();
        d.set_item("fast_folds", list)?;
    }
    Ok(d)
}

/// Lemma 6: the exact slow model of a fast discrete one (`factor` F), optionally through a
/// slow hold delayed by `hold_delay` and a sampler averaging over `averaging` of the slow
/// period (multiples of 1/F).
#[pyfunction]
#[pyo3(signature = (sys, factor, hold_delay, averaging))]
fn downsample<'py>(
    py: Python<'py>,
    sys: SysIn<'py>,
    factor: usize,
    hold_delay: f64,
    averaging: f64,
) -> PyResult<SysOut<'py>> {
    let s = sys_in(&sys)?;
    if s.ts().is_none() {
        return Err(value_err(
            "downsample takes a discrete model at the fast rate (Lemma 6); this one is \
             continuous (dt is None): use c2d with the slow period instead",
        ));
    }
    let ni = sd_multirate::NonIdeal {
        hold_delay,
        averaging,
    };
    let d = sd_multirate::downsample_nonideal(&s, factor, ni).map_err(py_err)?;
    Ok(sys_out(py, &d))
}

/// The frequency response at `f_hz` (Hz) as a complex array `(ny, nu, nf)`, and the path the
/// evaluator took ("block_diagonal", "hessenberg" or "dense"). The interpreter lock is
/// released during the evaluation; the frequencies are read in place.
#[pyfunction]
fn freqresp<'py>(
    py: Python<'py>,
    sys: SysIn<'py>,
    f_hz: PyReadonlyArray1<'py, f64>,
) -> PyResult<(Bound<'py, PyArray3<Complex64>>, &'static str)> {
    let s = sys_in(&sys)?;
    let owned;
    let f: &[f64] = match f_hz.as_slice() {
        Ok(v) => v,
        Err(_) => {
            owned = f_hz.as_array().to_vec();
            &owned
        }
    };
    if let Some(bad) = f.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
        return Err(value_err(format!(
            "frequency {bad} Hz: frequencies must be finite and non-negative"
        )));
    }
    if let (Some(ny), Some(fm)) = (s.time().nyquist_hz(), f.iter().cloned().reduce(f64::max)) {
        if fm > ny * (1.0 + 1e-12) {
            return Err(value_err(format!(
                "frequency {fm} Hz is above the model's Nyquist frequency {ny} Hz"
            )));
        }
    }
    let ev = sd_model::FreqRespEvaluator::new(&s).map_err(py_err)?;
    let path = match ev.path() {
        sd_model::EvalPath::BlockDiagonal => "block_diagonal",
        sd_model::EvalPath::Hessenberg => "hessenberg",
        sd_model::EvalPath::Dense => "dense",
    };
    let (ny, nu, nf) = (s.ny(), s.nu(), f.len());
    let out = py.detach(|| {
        // the library's own (parallel) evaluation, then one copy into numpy's layout
        // an entry at a pole is inf (`mark_poles`), not what rounding makes of it
        let mut g = ev.eval_many_flat(f);
        ev.mark_poles(f, &mut g);
        Array3::from_shape_fn((ny, nu, nf), |(i, j, k)| g[(k * nu + j) * ny + i])
    });
    Ok((out.into_pyarray(py), path))
}

/// The poles (eigenvalues of A) of a model, sorted by modulus then argument.
#[pyfunction]
fn poles<'py>(py: Python<'py>, sys: SysIn<'py>) -> PyResult<Bound<'py, PyArray1<Complex64>>> {
    let s = sys_in(&sys)?;
    let p = py.detach(|| s.poles()).map_err(py_err)?;
    Ok(p.into_pyarray(py))
}

/// The invariant zeros of a model (finite values where the system pencil loses rank; the
/// Emami-Naeini–Van Dooren reduction), sorted by modulus.
#[pyfunction]
fn zeros<'py>(py: Python<'py>, sys: SysIn<'py>) -> PyResult<Bound<'py, PyArray1<Complex64>>> {
    let s = sys_in(&sys)?;
    let z = py.detach(|| s.zeros()).map_err(py_err)?;
    Ok(z.into_pyarray(py))
}

/// A model from the toolkit's model JSON text (docs/formats.md; also `{"type": "tf", ...}`).
#[pyfunction]
fn model_from_json<'py>(py: Python<'py>, text: &str) -> PyResult<SysOut<'py>> {
    let s = sd_model::model_from_json_str(text).map_err(py_err)?;
    Ok(sys_out(py, &s))
}

/// The toolkit's model JSON text of a model (what `sdctl` reads and writes).
#[pyfunction]
fn model_to_json(sys: SysIn<'_>) -> PyResult<String> {
    sd_model::model_to_json_string(&sys_in(&sys)?).map_err(py_err)
}

/// `lsim`'s result: the outputs (N × ny) and the final state.
type Simulated<'py> = (Bound<'py, numpy::PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

/// Simulation of a discrete model (`x₀` zero when `None`), or of a continuous one under a
/// zero-order hold of period `dt_hold` (exact at the samples, Lemma 5): the outputs (N × ny,
/// one row per sample) and the final state.
#[pyfunction]
#[pyo3(signature = (sys, u, x0, dt_hold))]
fn lsim<'py>(
    py: Python<'py>,
    sys: SysIn<'py>,
    u: numpy::PyReadonlyArray2<'py, f64>,
    x0: Option<PyReadonlyArray1<'py, f64>>,
    dt_hold: Option<f64>,
) -> PyResult<Simulated<'py>> {
    let s = sys_in(&sys)?;
    let u = crate::mat(&u);
    let x0 = x0.map(|x| nalgebra::DVector::from_column_slice(&x.as_array().to_vec()));
    let sim = py
        .detach(|| match dt_hold {
            Some(h) => s.simulate_zoh(&u, h, x0.as_ref()),
            None => s.simulate(&u, x0.as_ref()),
        })
        .map_err(py_err)?;
    Ok((
        crate::np(py, &sim.y),
        sim.x_final.as_slice().to_vec().into_pyarray(py),
    ))
}

/// Registers this file's functions.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(c2d, m)?)?;
    m.add_function(wrap_pyfunction!(d2c, m)?)?;
    m.add_function(wrap_pyfunction!(alias, m)?)?;
    m.add_function(wrap_pyfunction!(downsample, m)?)?;
    m.add_function(wrap_pyfunction!(freqresp, m)?)?;
    m.add_function(wrap_pyfunction!(poles, m)?)?;
    m.add_function(wrap_pyfunction!(zeros, m)?)?;
    m.add_function(wrap_pyfunction!(lsim, m)?)?;
    m.add_function(wrap_pyfunction!(model_from_json, m)?)?;
    m.add_function(wrap_pyfunction!(model_to_json, m)?)?;
    Ok(())
}
