//! Uncertainty and the intersample error: `uncertainty`, `coverage`, `downsample_uncertainty`,
//! `robust_stability`, `intersample` — the library calls behind `sdctl uncertainty`,
//! `coverage`, `downsample --uncertainty`, `analyze --uncertainty` and `intersample`. An
//! uncertainty crosses the boundary as its JSON text (docs/formats.md), exactly as the CLI
//! writes and reads it.

use crate::data::frd_in;
use crate::{json_text, py_err, sys_in, value_err, SysIn};
use numpy::{Complex64, PyReadonlyArray1, PyReadonlyArray3};
use pyo3::prelude::*;
use sd_uncertainty::Form;

/// The FRD arrays as they cross the boundary.
type FrdIn<'py> = (
    PyReadonlyArray1<'py, f64>,
    PyReadonlyArray3<'py, Complex64>,
    Option<PyReadonlyArray3<'py, f64>>,
    Option<f64>,
);

fn form_of(form: &str) -> PyResult<Form> {
    match form {
        "additive" => Ok(Form::Additive),
        "multiplicative" => Ok(Form::Multiplicative),
        other => Err(value_err(format!(
            "form must be \"additive\" or \"multiplicative\", not {other:?}"
        ))),
    }
}

/// The bound and weight of an uncertainty JSON text; a weight fitted of `weight_order` when
/// the text has none and an order is given.
fn bound_and_weight(
    text: &str,
    weight_order: Option<usize>,
) -> PyResult<(sd_uncertainty::Bound, Option<sd_model::StateSpace>)> {
    let b = sd_uncertainty::from_json_str(text).map_err(py_err)?;
    let mut w = sd_uncertainty::weight_from_json_str(text).map_err(py_err)?;
    if w.is_none() {
        if let Some(n) = weight_order {
            w = Some(sd_uncertainty::overbound(&b, n).map_err(py_err)?.model);
        }
    }
    Ok((b, w))
}

/// The model's error bound from measured data with variances, as `sdctl uncertainty`: the
/// uncertainty JSON text (with the overbounding weight when `weight_order` is given).
#[pyfunction]
#[pyo3(signature = (model, frd, form, confidence, simultaneous, weight_order))]
fn uncertainty(
    py: Python<'_>,
    model: SysIn<'_>,
    frd: FrdIn<'_>,
    form: &str,
    confidence: f64,
    simultaneous: bool,
    weight_order: Option<usize>,
) -> PyResult<String> {
    let m = sys_in(&model)?;
    let f = frd_in(&frd.0, &frd.1, frd.2.as_ref(), frd.3)?;
    let form = form_of(form)?;
    py.detach(|| {
        let per_line = if simultaneous {
            sd_uncertainty::per_line_confidence(confidence, f.len())?
        } else {
            confidence
        };
        let b = sd_uncertainty::from_data(&m, &f, form, per_line)?;
        let w = weight_order
            .map(|n| sd_uncertainty::overbound(&b, n))
            .transpose()?;
        sd_uncertainty::to_json_string(&b, w.as_ref())
    })
    .map_err(py_err)
}

/// How many lines of a measurement lie inside nominal ± bound, as `sdctl coverage --json`.
#[pyfunction]
fn coverage(bound: &str, frd: FrdIn<'_>) -> PyResult<String> {
    let b = sd_uncertainty::from_json_str(bound).map_err(py_err)?;
    let f = frd_in(&frd.0, &frd.1, frd.2.as_ref(), frd.3)?;
    json_text(&sd_uncertainty::coverage(&b, &f).map_err(py_err)?)
}

/// A fast bound taken to the slow rate `factor·h` through Lemma 6 (with the rate-tied
/// non-idealities), as `sdctl downsample --uncertainty`: the slow uncertainty JSON text and
/// the slow lines left out.
#[pyfunction]
#[pyo3(signature = (bound, factor, hold_delay, averaging))]
fn downsample_uncertainty(
    bound: &str,
    factor: usize,
    hold_delay: f64,
    averaging: f64,
) -> PyResult<(String, Vec<f64>)> {
    let (b, _) = bound_and_weight(bound, None)?;
    let ni = sd_multirate::NonIdeal {
        hold_delay,
        averaging,
    };
    let d = sd_uncertainty::downsample_nonideal_all(&b, factor, ni).map_err(py_err)?;
    let text = sd_uncertainty::to_json_string(&d.bound, None).map_err(py_err)?;
    Ok((text, d.missing_hz))
}

/// Robust stability of the loop `(p, k)` against an uncertainty, as `sdctl analyze
/// --uncertainty --json`'s `robust`.
#[pyfunction]
#[pyo3(signature = (p, k, bound, weight_order))]
fn robust_stability(
    py: Python<'_>,
    p: SysIn<'_>,
    k: SysIn<'_>,
    bound: &str,
    weight_order: Option<usize>,
) -> PyResult<String> {
    let (p, k) = (sys_in(&p)?, sys_in(&k)?);
    let (b, w) = bound_and_weight(bound, weight_order)?;
    let r = py
        .detach(|| sd_uncertainty::robust_stability(&p, &k, &b, w.as_ref()))
        .map_err(py_err)?;
    json_text(&r)
}

/// The predicted fast- and slow-rate error of a slow controller on a fast plant under white
/// force and sensor disturbances, as `sdctl intersample --json`; with an uncertainty, the
/// fast error bounded over every plant inside its weight (`robust`) and the slow margin on
/// the bound's lines (`robust_lines`).
#[pyfunction]
#[pyo3(signature = (p, k, factor, force_rms, sensor_rms, points, bound, weight_order))]
#[allow(clippy::too_many_arguments)]
fn intersample(
    py: Python<'_>,
    p: SysIn<'_>,
    k: SysIn<'_>,
    factor: usize,
    force_rms: f64,
    sensor_rms: f64,
    points: usize,
    bound: Option<&str>,
    weight_order: Option<usize>,
) -> PyResult<String> {
    let (p, k) = (sys_in(&p)?, sys_in(&k)?);
    let h = p
        .ts()
        .ok_or_else(|| value_err("intersample needs a discrete fast plant"))?;
    for (v, what) in [(force_rms, "force_rms"), (sensor_rms, "sensor_rms")] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(value_err(format!("{what} {v} must be finite and >= 0")));
        }
    }
    let (pd, pn) = (2.0 * h * force_rms.powi(2), 2.0 * h * sensor_rms.powi(2));
    let bw = bound
        .map(|b| bound_and_weight(b, weight_order))
        .transpose()?;
    let weight = match &bw {
        Some((_, None)) => {
            return Err(value_err(
                "the uncertainty carries no overbounding weight, which the intersample bound \
                 needs between the lines: give weight_order (4 to 8 is typical)",
            ))
        }
        Some((b, Some(w))) => Some((b, w)),
        None => None,
    };
    let (r, robust, lines) = py.detach(|| {
        let r =
            sd_analysis::intersample(&p, &k, factor, &|_| pd, &|_| pn, points).map_err(py_err)?;
        let (robust, lines) = match weight {
            Some((b, w)) => (
                Some(
                    sd_uncertainty::robust_intersample(
                        &p,
                        &k,
                        factor,
                        (w, b.form),
                        &|_| pd,
                        &|_| pn,
                        points,
                    )
                    .map_err(py_err)?,
                ),
                sd_uncertainty::slow_margin_on_lines(&p, &k, factor, b, w).ok(),
            ),
            None => (None, None),
        };
        Ok::<_, PyErr>((r, robust, lines))
    })?;
    let v = serde_json::json!({
        "factor": factor,
        "rms_fast": r.rms_fast, "rms_slow": r.rms_slow,
        "fast_hz": r.fast_hz, "fast_psd": r.fast_psd,
        "slow_hz": r.slow_hz, "slow_psd": r.slow_psd,
        "control_sensitivity": r.control_sensitivity,
        "robust": robust,
        "robust_lines": lines,
    });
    Ok(v.to_string())
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(uncertainty, m)?)?;
    m.add_function(wrap_pyfunction!(coverage, m)?)?;
    m.add_function(wrap_pyfunction!(downsample_uncertainty, m)?)?;
    m.add_function(wrap_pyfunction!(robust_stability, m)?)?;
    m.add_function(wrap_pyfunction!(intersample, m)?)?;
    Ok(())
}
