//! Signals and weights: `multisine` (as `sdctl multisine`, the design without the files) and
//! the notch, low-pass and `makeweight` weights (as `sdctl weight notch|lowpass|makeweight`).

use crate::{py_err, sys_out, value_err, SysOut};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// One period of a multisine (random phases from `seed`; `lines` "full" or "random_odd" —
/// odd lines with one random detection line left out per group of three) and, with `inputs`
/// > 1, the orthogonal set of one experiment per input: `signals[e][j]` is input `j` in
/// experiment `e`.
#[pyfunction]
#[pyo3(signature = (fs, period, f_min, f_max, lines, seed, rms, inputs))]
#[allow(clippy::too_many_arguments)]
fn multisine<'py>(
    py: Python<'py>,
    fs: f64,
    period: usize,
    f_min: f64,
    f_max: f64,
    lines: &str,
    seed: u64,
    rms: f64,
    inputs: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let lines = match lines {
        "full" => sd_ident::Lines::Full,
        "random_odd" => sd_ident::Lines::RandomOdd { group: 3, seed },
        other => {
            return Err(value_err(format!(
                "lines must be \"full\" or \"random_odd\", not {other:?}"
            )))
        }
    };
    let spec = sd_ident::MultisineSpec {
        fs,
        period,
        f_min,
        f_max,
        lines,
        phases: sd_ident::Phases::Random { seed },
        rms,
        fold_rate_hz: None,
    };
    let ms = sd_ident::design(&spec).map_err(py_err)?;
    let sets = sd_ident::orthogonal(&ms, inputs).map_err(py_err)?;
    let d = PyDict::new(py);
    d.set_item("signal", ms.signal.clone().into_pyarray(py))?;
    let sets: Vec<Vec<Bound<'py, numpy::PyArray1<f64>>>> = sets
        .into_iter()
        .map(|e| e.into_iter().map(|x| x.into_pyarray(py)).collect())
        .collect();
    d.set_item("signals", sets)?;
    d.set_item("excited_bins", ms.excited.clone())?;
    let f: Vec<f64> = ms.excited.iter().map(|&k| k as f64 * ms.f0).collect();
    d.set_item("excited_hz", f.into_pyarray(py))?;
    d.set_item("detection_odd_bins", ms.detection_odd.clone())?;
    d.set_item("detection_even_bins", ms.detection_even.clone())?;
    d.set_item("f0", ms.f0)?;
    d.set_item("fs", ms.fs)?;
    d.set_item("crest_factor", ms.crest_factor)?;
    Ok(d)
}

/// The notch `(s² + 2ζz ω s + ω²)/(s² + 2ζp ω s + ω²)` (Tustin, prewarped at its frequency,
/// when `dt` is given).
#[pyfunction]
fn weight_notch<'py>(
    py: Python<'py>,
    freq_hz: f64,
    zeta_zero: f64,
    zeta_pole: f64,
    dt: Option<f64>,
) -> PyResult<SysOut<'py>> {
    let w = sd_hinf::weights::notch(freq_hz, zeta_zero, zeta_pole, dt).map_err(py_err)?;
    Ok(sys_out(py, &w))
}

/// The second-order low-pass `ω²/(s² + 2ζω s + ω²)` (Tustin, prewarped, when `dt` is given).
#[pyfunction]
fn weight_lowpass<'py>(
    py: Python<'py>,
    freq_hz: f64,
    zeta: f64,
    dt: Option<f64>,
) -> PyResult<SysOut<'py>> {
    let w = sd_hinf::weights::lowpass(freq_hz, zeta, dt).map_err(py_err)?;
    Ok(sys_out(py, &w))
}

/// MATLAB-like `makeweight`: gain `dc` at low frequency, `mag` at `freq_hz`, `hf` at high
/// frequency, of order 1 or 2.
#[pyfunction]
#[pyo3(signature = (dc, freq_hz, mag, hf, order, dt))]
fn makeweight<'py>(
    py: Python<'py>,
    dc: f64,
    freq_hz: f64,
    mag: f64,
    hf: f64,
    order: usize,
    dt: Option<f64>,
) -> PyResult<SysOut<'py>> {
    let w = sd_hinf::weights::makeweight(dc, freq_hz, mag, hf, order, dt).map_err(py_err)?;
    Ok(sys_out(py, &w))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(multisine, m)?)?;
    m.add_function(wrap_pyfunction!(weight_notch, m)?)?;
    m.add_function(wrap_pyfunction!(weight_lowpass, m)?)?;
    m.add_function(wrap_pyfunction!(makeweight, m)?)?;
    Ok(())
}
