//! Synthesis and controller reduction: `hinfsyn`, `h2syn`, `mixsyn`, `reduce_controller`. Each
//! returns the controller as a model tuple and the toolkit's JSON report as text (the Python
//! side loads it), as `sdctl … --json` prints it.

use crate::{json_text, py_err, sys_in, sys_out, value_err, SysIn};
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn part(nmeas: usize, ncon: usize) -> sd_hinf::Partition {
    sd_hinf::Partition { nmeas, ncon }
}

fn options(gamma: Option<f64>, tol: f64) -> sd_hinf::HinfOptions {
    sd_hinf::HinfOptions {
        gamma,
        tolerance: tol,
        ..Default::default()
    }
}

/// A synthesis result as Python sees it: `controller` (model tuple) and `report_json`.
fn report<'py>(
    py: Python<'py>,
    controller: &sd_model::StateSpace,
    r: &impl serde::Serialize,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("controller", sys_out(py, controller))?;
    out.set_item("report_json", json_text(r)?)?;
    Ok(out)
}

/// H∞ synthesis on a generalized plant (`sd_hinf::hinfsyn`): `controller`, `report_json`.
#[pyfunction]
#[pyo3(signature = (plant, nmeas, ncon, gamma, tol))]
fn hinfsyn<'py>(
    py: Python<'py>,
    plant: SysIn<'py>,
    nmeas: usize,
    ncon: usize,
    gamma: Option<f64>,
    tol: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let p = sys_in(&plant)?;
    let r = py
        .detach(|| sd_hinf::hinfsyn(&p, part(nmeas, ncon), &options(gamma, tol)))
        .map_err(py_err)?;
    report(py, &r.controller, &r)
}

/// H2 synthesis on a generalized plant (`sd_hinf::h2syn`): `controller`, `report_json`.
#[pyfunction]
fn h2syn<'py>(
    py: Python<'py>,
    plant: SysIn<'py>,
    nmeas: usize,
    ncon: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let p = sys_in(&plant)?;
    let r = py
        .detach(|| sd_hinf::h2syn(&p, part(nmeas, ncon)))
        .map_err(py_err)?;
    report(py, &r.controller, &r)
}

/// Mixed-sensitivity synthesis (`sd_hinf::mixsyn`): `controller` (negative feedback),
/// `report_json`, `generalized_plant`. With `factor` the multirate design
/// (`sd_hinf::multirate_hinfsyn`: the plant at the fast rate, the controller at `factor` times
/// its period, `wr`, `wn`, `w2_slow`, `at_samples` as `sdctl mixsyn --factor`).
#[pyfunction]
#[pyo3(signature = (plant, w1, w2, w3, wd, gamma, tol, factor=None, wr=None, wn=None, w2_slow=None, at_samples=None))]
#[allow(clippy::too_many_arguments)]
fn mixsyn<'py>(
    py: Python<'py>,
    plant: SysIn<'py>,
    w1: Option<SysIn<'py>>,
    w2: Option<SysIn<'py>>,
    w3: Option<SysIn<'py>>,
    wd: Option<SysIn<'py>>,
    gamma: Option<f64>,
    tol: f64,
    factor: Option<usize>,
    wr: Option<SysIn<'py>>,
    wn: Option<f64>,
    w2_slow: Option<SysIn<'py>>,
    at_samples: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let g = sys_in(&plant)?;
    let conv = |w: &Option<SysIn<'py>>| w.as_ref().map(sys_in).transpose();
    let (w1, w2, w3, wd) = (conv(&w1)?, conv(&w2)?, conv(&w3)?, conv(&wd)?);
    let (wr, w2s) = (conv(&wr)?, conv(&w2_slow)?);
    let w = sd_hinf::MixsynWeights {
        w1: w1.as_ref(),
        w2: w2.as_ref(),
        w3: w3.as_ref(),
        wd: wd.as_ref(),
    };
    let opt = options(gamma, tol);
    let (r, gp) = match factor {
        None => {
            if wr.is_some() || wn.is_some() || w2s.is_some() || at_samples.is_some() {
                return Err(value_err(
                    "wr, wn, w2_slow and at_samples belong to a multirate design: give factor",
                ));
            }
            py.detach(|| sd_hinf::mixsyn(&g, &w, &opt))
                .map_err(py_err)?
        }
        Some(f) => {
            if wn.is_some_and(|v| !v.is_finite()) {
                return Err(value_err("wn must be a finite number"));
            }
            let wn = wn.map(|v| nalgebra::DMatrix::identity(g.ny(), g.ny()) * v);
            let mw = sd_hinf::MultirateWeights {
                mix: w,
                wr: wr.as_ref(),
                wn: wn.as_ref(),
                w2_slow: w2s.as_ref(),
                at_samples,
            };
            let m = py
                .detach(|| sd_hinf::multirate_hinfsyn(&g, f, &mw, &opt))
                .map_err(py_err)?;
            (m.synthesis, m.plant)
        }
    };
    let out = report(py, &r.controller, &r)?;
    out.set_item("generalized_plant", sys_out(py, &gp))?;
    Ok(out)
}

/// Controller reduction keeping the loop (`sd_analysis::reduce_controller`): `controller`,
/// the orders, `hankel_sv`, `band_hz`, `max_delta_s_db`, `max_delta_t_db`, and the loop's
/// stability and margins `before` / `after` (dicts).
#[pyfunction]
fn reduce_controller<'py>(
    py: Python<'py>,
    plant: SysIn<'py>,
    controller: SysIn<'py>,
    order: usize,
    method: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let method: sd_analysis::ReductionMethod = method
        .parse()
        .map_err(|e: sd_analysis::AnalysisError| value_err(e.to_string()))?;
    let (p, k) = (sys_in(&plant)?, sys_in(&controller)?);
    let r = py
        .detach(|| sd_analysis::reduce_controller(&p, &k, order, method))
        .map_err(py_err)?;
    let side = |s: &sd_analysis::Summary| -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        crate::design::summary_into(&d, s)?;
        Ok(d)
    };
    let out = PyDict::new(py);
    out.set_item("controller", sys_out(py, &r.controller))?;
    let method = serde_json::to_value(r.method)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default();
    out.set_item("method", method)?;
    out.set_item("order_before", r.orders.0)?;
    out.set_item("order_after", r.orders.1)?;
    out.set_item("hankel_sv", r.hankel_sv.clone())?;
    out.set_item("band_hz", r.band_hz)?;
    out.set_item("max_delta_s_db", r.max_delta_s_db)?;
    out.set_item("max_delta_t_db", r.max_delta_t_db)?;
    out.set_item("before", side(&r.before)?)?;
    out.set_item("after", side(&r.after)?)?;
    Ok(out)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(hinfsyn, m)?)?;
    m.add_function(wrap_pyfunction!(h2syn, m)?)?;
    m.add_function(wrap_pyfunction!(mixsyn, m)?)?;
    m.add_function(wrap_pyfunction!(reduce_controller, m)?)?;
    Ok(())
}
