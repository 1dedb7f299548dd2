//! Design and analysis: `dare`, `care`, `loopshape`, `weight_pid`, `analyze`.

use crate::{mat, np, py_err, sys_in, sys_out, value_err, SysIn, SysOut};
use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A Riccati solution as a dict: `X`, `K` (the gain, `u = −K x`), the relative `residual`, the
/// closed loop's spectral radius (DARE) or abscissa (CARE), the relative `condition` estimate.
fn riccati<'py>(py: Python<'py>, r: &sd_hinf::RiccatiSolution) -> PyResult<Bound<'py, PyDict>> {
    riccati_dict(
        py,
        (np(py, &r.x), np(py, &r.gain)),
        [r.residual, r.closed_loop, r.condition],
    )
}

/// The dict of a Riccati solution, real or complex: `X`, `K` and its three figures.
fn riccati_dict<'py, T: IntoPyObject<'py>>(
    py: Python<'py>,
    (x, k): (T, T),
    [residual, closed_loop, condition]: [f64; 3],
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("X", x)?;
    d.set_item("K", k)?;
    d.set_item("residual", residual)?;
    d.set_item("closed_loop", closed_loop)?;
    d.set_item("condition", condition)?;
    Ok(d)
}

type Mat<'py> = PyReadonlyArray2<'py, f64>;
type M = nalgebra::DMatrix<f64>;

/// The standard solver and its descriptor (`E ≠ I`) form.
type Solver = fn(&M, &M, &M, &M, Option<&M>) -> sd_hinf::Result<sd_hinf::RiccatiSolution>;
type GenSolver = fn(&M, &M, &M, &M, &M, Option<&M>) -> sd_hinf::Result<sd_hinf::RiccatiSolution>;

/// One Riccati solver on the boundary's matrices, with the interpreter lock released; with
/// `e`, the generalized equation ([`sd_hinf::gcare`], [`sd_hinf::gdare`]).
fn solve<'py>(
    py: Python<'py>,
    (solver, generalized): (Solver, GenSolver),
    [a, b, q, r]: [Mat<'py>; 4],
    (s, e): (Option<Mat<'py>>, Option<Mat<'py>>),
) -> PyResult<Bound<'py, PyDict>> {
    let (a, b, q, r) = (mat(&a), mat(&b), mat(&q), mat(&r));
    let s = s.as_ref().map(mat);
    let e = e.as_ref().map(mat);
    let sol = py
        .detach(|| match &e {
            Some(e) => generalized(&a, e, &b, &q, &r, s.as_ref()),
            None => solver(&a, &b, &q, &r, s.as_ref()),
        })
        .map_err(py_err)?;
    riccati(py, &sol)
}

/// The stabilising solution of `AᵀXA − X − (AᵀXB + S)(R + BᵀXB)⁻¹(BᵀXA + Sᵀ) + Q = 0`
/// (structure-preserving doubling, Newton-refined); with `e`, of
/// `AᵀXA − EᵀXE − (AᵀXB + S)(R + BᵀXB)⁻¹(BᵀXA + Sᵀ) + Q = 0`. No solution raises
/// `ValueError` with the reason.
#[pyfunction]
#[pyo3(signature = (a, b, q, r, s=None, e=None))]
fn dare<'py>(
    py: Python<'py>,
    a: Mat<'py>,
    b: Mat<'py>,
    q: Mat<'py>,
    r: Mat<'py>,
    s: Option<Mat<'py>>,
    e: Option<Mat<'py>>,
) -> PyResult<Bound<'py, PyDict>> {
    solve(py, (sd_hinf::dare, sd_hinf::gdare), [a, b, q, r], (s, e))
}

/// The stabilising solution of `AᵀX + XA − (XB + S)R⁻¹(BᵀX + Sᵀ) + Q = 0` (ordered
/// Hamiltonian Schur, Newton-refined); with `e`, of
/// `AᵀXE + EᵀXA − (EᵀXB + S)R⁻¹(BᵀXE + Sᵀ) + Q = 0`.
#[pyfunction]
#[pyo3(signature = (a, b, q, r, s=None, e=None))]
fn care<'py>(
    py: Python<'py>,
    a: Mat<'py>,
    b: Mat<'py>,
    q: Mat<'py>,
    r: Mat<'py>,
    s: Option<Mat<'py>>,
    e: Option<Mat<'py>>,
) -> PyResult<Bound<'py, PyDict>> {
    solve(py, (sd_hinf::care, sd_hinf::gcare), [a, b, q, r], (s, e))
}

type CMat<'py> = PyReadonlyArray2<'py, numpy::Complex64>;

/// A complex numpy matrix as the solver's complex matrix (copied once).
fn cmat(a: &CMat<'_>) -> sd_hinf::CMatrix {
    let v = a.as_array();
    sd_hinf::CMatrix::from_fn(v.nrows(), v.ncols(), |i, j| v[[i, j]])
}

/// A complex Riccati solution as the dict of [`riccati`], `X` and `K` complex.
fn complex_riccati<'py>(
    py: Python<'py>,
    r: &sd_hinf::ComplexRiccatiSolution,
) -> PyResult<Bound<'py, PyDict>> {
    let arr = |m: &sd_hinf::CMatrix| {
        numpy::ndarray::Array2::from_shape_fn(m.shape(), |(i, j)| m[(i, j)]).into_pyarray(py)
    };
    riccati_dict(
        py,
        (arr(&r.x), arr(&r.gain)),
        [r.residual, r.closed_loop, r.condition],
    )
}

/// `care` / `dare` on complex data (`continuous` chooses), the interpreter lock released
/// ([`sd_hinf::care_complex`], [`sd_hinf::dare_complex`]: conjugate transposes in place of
/// transposes; the imaginary parts are solved for, never dropped).
#[pyfunction]
#[pyo3(signature = (continuous, a, b, q, r, s=None, e=None))]
#[allow(clippy::too_many_arguments)]
fn riccati_complex<'py>(
    py: Python<'py>,
    continuous: bool,
    a: CMat<'py>,
    b: CMat<'py>,
    q: CMat<'py>,
    r: CMat<'py>,
    s: Option<CMat<'py>>,
    e: Option<CMat<'py>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (a, b, q, r) = (cmat(&a), cmat(&b), cmat(&q), cmat(&r));
    let (s, e) = (s.as_ref().map(cmat), e.as_ref().map(cmat));
    let data = sd_hinf::ComplexRiccatiData {
        a: &a,
        b: &b,
        q: &q,
        r: &r,
        s: s.as_ref(),
        e: e.as_ref(),
    };
    let sol = py
        .detach(|| {
            if continuous {
                sd_hinf::care_complex(&data)
            } else {
                sd_hinf::dare_complex(&data)
            }
        })
        .map_err(py_err)?;
    complex_riccati(py, &sol)
}

/// McFarlane–Glover loopshaping of `plant` with pre-weight `w1` and post-weight `w2`: the
/// controller to implement (`K = W1 K∞ W2`), the shaped controller and the figures of the
/// design (γ_min, γ, achieved norm, closed-loop stability, Riccati residuals).
#[pyfunction]
#[pyo3(signature = (plant, w1, w2, factor, strictly_proper))]
fn loopshape<'py>(
    py: Python<'py>,
    plant: SysIn<'py>,
    w1: Option<SysIn<'py>>,
    w2: Option<SysIn<'py>>,
    factor: f64,
    strictly_proper: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let p = sys_in(&plant)?;
    let w1 = w1.as_ref().map(sys_in).transpose()?;
    let w2 = w2.as_ref().map(sys_in).transpose()?;
    let opt = sd_hinf::LoopshapeOptions {
        factor,
        strictly_proper,
    };
    let d = py
        .detach(|| sd_hinf::loopshape(&p, w1.as_ref(), w2.as_ref(), &opt))
        .map_err(py_err)?;
    let out = PyDict::new(py);
    out.set_item("controller", sys_out(py, &d.controller))?;
    out.set_item("shaped_controller", sys_out(py, &d.shaped_controller))?;
    out.set_item("shaped_plant", sys_out(py, &d.shaped_plant))?;
    out.set_item("gamma_min", d.gamma_min)?;
    out.set_item("gamma", d.gamma)?;
    out.set_item("achieved", d.achieved)?;
    out.set_item("stability_margin", 1.0 / d.achieved)?;
    out.set_item("closed_loop_stable", d.closed_loop_stable)?;
    out.set_item("closed_loop_radius", d.closed_loop_radius)?;
    let ric: Vec<(String, f64, f64)> = d
        .riccati
        .iter()
        .map(|r| (r.name.clone(), r.residual, r.condition))
        .collect();
    out.set_item("riccati", ric)?;
    Ok(out)
}

/// The PID-like loopshaping weight of `sd_hinf::weights::pid` (crossover `bandwidth_hz`, a
/// rigid body of `mass`; continuous when `dt` is None).
#[pyfunction]
#[pyo3(signature = (bandwidth_hz, mass, dt, integrator_ratio, lead_ratio, lowpass_ratio, lowpass_zeta))]
fn weight_pid<'py>(
    py: Python<'py>,
    bandwidth_hz: f64,
    mass: f64,
    dt: Option<f64>,
    integrator_ratio: f64,
    lead_ratio: f64,
    lowpass_ratio: f64,
    lowpass_zeta: f64,
) -> PyResult<SysOut<'py>> {
    let opt = sd_hinf::weights::PidOptions {
        integrator_ratio,
        lead_ratio,
        lowpass_ratio,
        lowpass_zeta,
    };
    let w = sd_hinf::weights::pid(bandwidth_hz, mass, dt, &opt).map_err(py_err)?;
    Ok(sys_out(py, &w))
}

/// The loop of plant `p` and controller `k` (negative feedback) as `sdctl analyze --json`
/// reports it: stability, closed-loop radius, bandwidth, crossover, |S| peak, margins, the
/// generalised Nyquist criterion.
#[pyfunction]
fn analyze<'py>(py: Python<'py>, p: SysIn<'py>, k: SysIn<'py>) -> PyResult<Bound<'py, PyDict>> {
    let (p, k) = (sys_in(&p)?, sys_in(&k)?);
    let (s, lat, nyq) = py
        .detach(|| {
            let cl = sd_analysis::ClosedLoop::new(&p, &k)?;
            let s = cl.summary()?;
            // loop-at-a-time and disk margins of a stable loop, as `sdctl analyze --json`
            let lat = if s.stable {
                Some(sd_analysis::mimo_margins(&cl)?)
            } else {
                None
            };
            let nyq = sd_analysis::generalized_nyquist(&cl)?;
            Ok::<_, sd_analysis::AnalysisError>((s, lat, nyq))
        })
        .map_err(py_err)?;
    let d = PyDict::new(py);
    let text = serde_json::to_string(&nyq).map_err(|e| value_err(e.to_string()))?;
    d.set_item("nyquist_json", text)?;
    if let Some(m) = lat {
        let text = serde_json::to_string(&m).map_err(|e| value_err(e.to_string()))?;
        d.set_item("loop_at_a_time_json", text)?;
    }
    summary_into(&d, &s)?;
    Ok(d)
}

/// A controller on a measured plant, as `sdctl analyze --plant-frd --json`: the FRD's arrays,
/// the controller, the plant's integrators (None: read from the lowest lines) and unstable
/// poles, and a Lemma 6 factor to fold a fast FRF to the controller's rate first. Returns the
/// analysis as JSON text and `S`, `T` on the lines as FRD arrays.
#[pyfunction]
#[pyo3(signature = (freq_hz, response, variance, dt, k, integrators, unstable_poles, factor))]
#[allow(clippy::too_many_arguments)]
fn analyze_measured<'py>(
    py: Python<'py>,
    freq_hz: numpy::PyReadonlyArray1<'py, f64>,
    response: numpy::PyReadonlyArray3<'py, numpy::Complex64>,
    variance: Option<numpy::PyReadonlyArray3<'py, f64>>,
    dt: Option<f64>,
    k: SysIn<'py>,
    integrators: Option<usize>,
    unstable_poles: usize,
    factor: Option<usize>,
) -> PyResult<(String, crate::data::FrdOut<'py>, crate::data::FrdOut<'py>)> {
    let frd = crate::data::frd_in(&freq_hz, &response, variance.as_ref(), dt)?;
    let k = sys_in(&k)?;
    let plant = sd_analysis::MeasuredPlant {
        integrators,
        unstable_poles,
    };
    let (a, resp) = py
        .detach(|| {
            let frd = match factor {
                Some(f) => sd_multirate::downsample_frd(&frd, f, None)?.frd,
                None => frd,
            };
            sd_analysis::analyze_measured(&frd, &k, plant)
        })
        .map_err(py_err)?;
    let text = serde_json::to_string(&a).map_err(|e| value_err(e.to_string()))?;
    Ok((
        text,
        crate::data::frd_out(py, &resp.s),
        crate::data::frd_out(py, &resp.t),
    ))
}

/// A loop's summary (`sd_analysis::Summary`) as items of `d`: the keys of `sdctl analyze
/// --json` (analyze, reduce_controller's `before` and `after`).
pub(crate) fn summary_into(d: &Bound<'_, PyDict>, s: &sd_analysis::Summary) -> PyResult<()> {
    d.set_item("stable", s.stable)?;
    d.set_item("closed_loop_radius", s.closed_loop_radius)?;
    d.set_item("bandwidth_hz", s.bandwidth_hz)?;
    d.set_item("crossover_hz", s.crossover_hz)?;
    d.set_item("sensitivity_peak_db", s.sensitivity_peak_db)?;
    d.set_item("sensitivity_peak_hz", s.sensitivity_peak_hz)?;
    d.set_item("gain_margin_db", s.gain_margin_db)?;
    d.set_item("gain_margin_hz", s.gain_margin_hz)?;
    d.set_item("phase_margin_deg", s.phase_margin_deg)?;
    d.set_item("phase_margin_hz", s.phase_margin_hz)?;
    d.set_item("modulus_margin", s.modulus_margin)
}

/// Registers this file's functions.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(dare, m)?)?;
    m.add_function(wrap_pyfunction!(care, m)?)?;
    m.add_function(wrap_pyfunction!(riccati_complex, m)?)?;
    m.add_function(wrap_pyfunction!(loopshape, m)?)?;
    m.add_function(wrap_pyfunction!(weight_pid, m)?)?;
    m.add_function(wrap_pyfunction!(analyze, m)?)?;
    m.add_function(wrap_pyfunction!(analyze_measured, m)?)?;
    Ok(())
}
