//! `fit_physical`: the physical modal model of a SISO FRD (`sdctl fit --stabilization`).

use crate::data::frd_in;
use crate::{py_err, sys_out, value_err, SysOut};
use numpy::{Complex64, PyReadonlyArray1, PyReadonlyArray3};
use pyo3::prelude::*;

/// The physical modal model of a SISO discrete FRD (`sd_ident::physical_fit`): the model with
/// its input delay (whole samples exact, a fraction by Thiran's allpass) and the text of
/// `modes.json` (`sdctl fit --stabilization`; the warnings as their messages).
#[pyfunction]
#[pyo3(signature = (freq_hz, response, variance, dt, max_order, rigid_body, max_delay, strictly_proper))]
#[allow(clippy::too_many_arguments)]
fn fit_physical<'py>(
    py: Python<'py>,
    freq_hz: PyReadonlyArray1<'py, f64>,
    response: PyReadonlyArray3<'py, Complex64>,
    variance: Option<PyReadonlyArray3<'py, f64>>,
    dt: Option<f64>,
    max_order: usize,
    rigid_body: Option<usize>,
    max_delay: usize,
    strictly_proper: bool,
) -> PyResult<(SysOut<'py>, String)> {
    let frd = frd_in(&freq_hz, &response, variance.as_ref(), dt)?;
    let opt = sd_ident::StabilizationOptions {
        max_order,
        rigid_body,
        feedthrough: !strictly_proper,
        max_delay,
    };
    let r = py
        .detach(|| sd_ident::physical_fit(&frd, &opt, &mut |_| {}))
        .map_err(py_err)?;
    let (model, phase_err) = r.model_with_delay(frd.freq_hz()).map_err(py_err)?;
    let mut v = serde_json::to_value(r.summary(phase_err))
        .map_err(|e| value_err(format!("modes JSON: {e}")))?;
    v["warnings"] = r
        .fit
        .warnings
        .iter()
        .map(|w| serde_json::Value::from(w.to_string()))
        .collect::<Vec<_>>()
        .into();
    Ok((sys_out(py, &model), v.to_string()))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fit_physical, m)?)?;
    Ok(())
}
