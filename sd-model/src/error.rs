//! The one error type of `sd-model`.

use num_complex::Complex64;

/// Everything that can go wrong in `sd-model`. Each message says what to fix.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// A matrix or vector has the wrong shape.
    #[error("dimension mismatch in {what}: expected {expected}, found {found}")]
    DimensionMismatch {
        /// Which argument or matrix.
        what: String,
        /// The shape that was required.
        expected: String,
        /// The shape that was given.
        found: String,
    },
    /// A NaN or infinite value where a finite number is required.
    #[error("{what} contains a NaN or infinite value; all entries must be finite")]
    NonFinite {
        /// Which argument or matrix.
        what: String,
    },
    /// A sampling period that is not finite and positive.
    #[error("invalid sampling period {ts}: it must be finite and > 0 seconds")]
    InvalidSampleTime {
        /// The offending value.
        ts: f64,
    },
    /// An operation was applied to a model of the wrong time domain.
    #[error("{operation} needs a {expected} model, got a {found} one")]
    WrongDomain {
        /// The operation.
        operation: String,
        /// The required domain.
        expected: String,
        /// The domain of the model given.
        found: String,
    },
    /// Two models with different sample times were combined.
    #[error("sample time mismatch in {operation}: {left} vs {right}; resample one model first")]
    SampleTimeMismatch {
        /// The operation.
        operation: String,
        /// The left model's sample time.
        left: String,
        /// The right model's sample time.
        right: String,
    },
    /// A discrete pole with no real matrix logarithm (zero or on the negative real axis).
    #[error(
        "d2c: discrete pole {re:.6}{im:+.6}i has no real logarithm ({why}); \
         no continuous-time model with this sample time produces it"
    )]
    NoRealLogarithm {
        /// Real part of the pole.
        re: f64,
        /// Imaginary part of the pole.
        im: f64,
        /// Why: on the negative real axis, or zero.
        why: String,
    },
    /// A matrix that must be invertible is (numerically) singular.
    #[error("{what} is singular to working precision")]
    Singular {
        /// What was singular and what that means for the user.
        what: String,
    },
    /// An iterative algorithm did not converge.
    #[error("{what} did not converge")]
    NotConverged {
        /// The algorithm.
        what: String,
    },
    /// The model must be stable for this operation.
    #[error("{operation} needs a stable model: {detail}")]
    Unstable {
        /// The operation.
        operation: String,
        /// Which pole violates stability.
        detail: String,
    },
    /// An argument outside its valid range.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// A model or FRD file could not be parsed.
    #[error("cannot read {what}: {detail}")]
    Parse {
        /// What was being read.
        what: String,
        /// Where and why it failed.
        detail: String,
    },
}

impl ModelError {
    /// A numerical failure on valid input (an iteration that did not converge), as opposed to
    /// input that must be fixed: the CLI exits 1 for these and 2 for the rest, the Python
    /// package raises `sdtoolkit.NumericalError` and `ValueError`.
    pub fn is_numerical(&self) -> bool {
        matches!(self, ModelError::NotConverged { .. })
    }
    /// A [`ModelError::DimensionMismatch`] from anything printable.
    pub fn dim(what: impl Into<String>, expected: impl ToString, found: impl ToString) -> Self {
        ModelError::DimensionMismatch {
            what: what.into(),
            expected: expected.to_string(),
            found: found.to_string(),
        }
    }
    pub(crate) fn no_log(p: Complex64, why: &str) -> Self {
        ModelError::NoRealLogarithm {
            re: p.re,
            im: p.im,
            why: why.to_string(),
        }
    }
}

/// Result alias for `sd-model`.
pub type Result<T> = std::result::Result<T, ModelError>;
