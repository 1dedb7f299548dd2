//! Transfer functions, norms and balanced truncation: `tf`, `norm`, `balred`.

use crate::{py_err, sys_in, sys_out, value_err, SysIn, SysOut};
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use sd_model::{SampleTime, TransferFunction};

/// A SISO transfer function `num(s)/den(s)` (descending powers; `dt` the sample time, `None`
/// continuous) as a state-space model (controllable canonical form); improper or zero
/// denominators raise `ValueError`.
#[pyfunction]
#[pyo3(signature = (num, den, dt=None))]
fn tf<'py>(
    py: Python<'py>,
    num: PyReadonlyArray1<'py, f64>,
    den: PyReadonlyArray1<'py, f64>,
    dt: Option<f64>,
) -> PyResult<SysOut<'py>> {
    let time = SampleTime::from_option(dt).map_err(py_err)?;
    let t = TransferFunction::new(num.as_array().to_vec(), den.as_array().to_vec(), time)
        .map_err(py_err)?;
    Ok(sys_out(py, &t.to_ss().map_err(py_err)?))
}

/// The H2 norm (`p = 2`; stable models, a continuous one with D = 0) or the H∞ norm
/// (`p = inf`, with the peak frequency in Hz; the L∞ norm of an unstable model, which the
/// third element says).
#[pyfunction]
fn norm(py: Python<'_>, sys: SysIn<'_>, p: f64) -> PyResult<(f64, Option<f64>, bool)> {
    let s = sys_in(&sys)?;
    if p == 2.0 {
        let v = py.detach(|| s.h2_norm()).map_err(py_err)?;
        Ok((v, None, true))
    } else if p.is_infinite() && p > 0.0 {
        let h = py.detach(|| s.hinf_norm()).map_err(py_err)?;
        Ok((h.value, Some(h.peak_hz), h.stable))
    } else {
        Err(value_err(format!("p = {p}: the norm is 2 or inf")))
    }
}

/// Balanced truncation to `order` states (the stable part; unstable and marginal poles kept):
/// the reduced model, the Hankel singular values of the stable part and the a-priori bound
/// `2Σ` of the discarded ones on `‖G − G_r‖∞`.
#[pyfunction]
fn balred<'py>(
    py: Python<'py>,
    sys: SysIn<'py>,
    order: usize,
) -> PyResult<(SysOut<'py>, Vec<f64>, f64)> {
    let s = sys_in(&sys)?;
    let r = py.detach(|| s.balanced_truncation(order)).map_err(py_err)?;
    Ok((sys_out(py, &r.model), r.hankel_sv, r.error_bound))
}

/// Registers this file's functions.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(tf, m)?)?;
    m.add_function(wrap_pyfunction!(norm, m)?)?;
    m.add_function(wrap_pyfunction!(balred, m)?)?;
    Ok(())
}
