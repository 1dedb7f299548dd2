//! The native half of the Python package `sdtoolkit` (pyo3, abi3): thin functions over numpy
//! arrays that call the toolkit's crates. The package's Python half (`python/sdtoolkit`) gives
//! them python-control's names and conventions, the `StateSpace` and `Frd` types and the result
//! objects; nothing here is meant to be called directly.
//!
//! Conventions at the boundary: a model is the tuple `(A, B, C, D, dt)` of float64 arrays with
//! `dt = None` for continuous time; results that the CLI writes as JSON (diagnosis, analysis,
//! loopshaping) cross as JSON text of the same serde types and become Python objects on the
//! other side, so their fields are those of the files documented in `docs/`. Errors: input the
//! caller must fix raises `ValueError`, a numerical failure on valid input raises
//! `sdtoolkit.NumericalError` (an `ArithmeticError`), each with the library's one-line message
//! (each error type's `is_numerical` decides, as for `sdctl`'s exit codes 2 and 1). Long calls
//! (frequency responses, fits, loopshaping, diagnosis, the testbed) release the interpreter
//! lock.

mod data;
mod design;
mod model;
mod ops;
mod physical;
mod signals;
mod synthesis;
mod uncertainty;

use nalgebra::DMatrix;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use sd_model::{SampleTime, StateSpace};

pyo3::create_exception!(
    _native,
    NumericalError,
    pyo3::exceptions::PyArithmeticError,
    "A numerical failure on valid input (an iteration that did not converge, a factorisation \
     that broke down); the message says which step."
);

/// An error type of the toolkit that knows whether it is a numerical failure.
pub(crate) trait Classified: std::fmt::Display {
    /// A numerical failure on valid input (else: input the caller must fix).
    fn numerical(&self) -> bool;
}

macro_rules! classified {
    ($($t:ty),*) => {$(
        impl Classified for $t {
            fn numerical(&self) -> bool {
                self.is_numerical()
            }
        }
    )*};
}
classified!(
    sd_model::ModelError,
    sd_multirate::MultirateError,
    sd_hinf::HinfError,
    sd_ident::IdentError,
    sd_analysis::AnalysisError,
    sd_testbed::TestbedError,
    sd_diagnose::DiagnoseError,
    sd_uncertainty::UncertaintyError
);

/// `ValueError` or `NumericalError` with the error's message.
pub(crate) fn py_err<E: Classified>(e: E) -> PyErr {
    if e.numerical() {
        NumericalError::new_err(e.to_string())
    } else {
        PyValueError::new_err(e.to_string())
    }
}

/// `ValueError` with `msg`.
pub(crate) fn value_err(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// A numpy matrix as a nalgebra one (one copy: nalgebra is column-major, numpy row-major).
pub(crate) fn mat(a: &PyReadonlyArray2<'_, f64>) -> DMatrix<f64> {
    let v = a.as_array();
    DMatrix::from_fn(v.nrows(), v.ncols(), |i, j| v[[i, j]])
}

/// A nalgebra matrix as a new numpy array.
pub(crate) fn np<'py>(py: Python<'py>, m: &DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn(m.shape(), |(i, j)| m[(i, j)]).into_pyarray(py)
}

/// A model as it crosses the boundary: `(A, B, C, D, dt)`, `dt = None` for continuous time.
pub(crate) type SysIn<'py> = (
    PyReadonlyArray2<'py, f64>,
    PyReadonlyArray2<'py, f64>,
    PyReadonlyArray2<'py, f64>,
    PyReadonlyArray2<'py, f64>,
    Option<f64>,
);

/// The model going back to Python.
pub(crate) type SysOut<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<f64>>,
    Option<f64>,
);

/// The toolkit's model of a boundary tuple (shapes and finiteness checked).
pub(crate) fn sys_in(s: &SysIn<'_>) -> PyResult<StateSpace> {
    let time = SampleTime::from_option(s.4).map_err(py_err)?;
    StateSpace::new(mat(&s.0), mat(&s.1), mat(&s.2), mat(&s.3), time).map_err(py_err)
}

/// A model as a boundary tuple.
pub(crate) fn sys_out<'py>(py: Python<'py>, s: &StateSpace) -> SysOut<'py> {
    (
        np(py, s.a()),
        np(py, s.b()),
        np(py, s.c()),
        np(py, s.d()),
        s.ts(),
    )
}

/// JSON text of a serde value, for the Python side to load.
pub(crate) fn json_text(v: &impl serde::Serialize) -> PyResult<String> {
    serde_json::to_string(v).map_err(|e| NumericalError::new_err(format!("result JSON: {e}")))
}

/// The module `sdtoolkit._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("NumericalError", m.py().get_type::<NumericalError>())?;
    m.add("DEFAULT_TESTBED_CONFIG", sd_testbed::DEFAULT_CONFIG)?;
    model::register(m)?;
    ops::register(m)?;
    design::register(m)?;
    synthesis::register(m)?;
    data::register(m)?;
    physical::register(m)?;
    uncertainty::register(m)?;
    signals::register(m)?;
    Ok(())
}
