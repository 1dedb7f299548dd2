//! The one error type of `sd-multirate`.

use sd_model::ModelError;

/// Everything that can go wrong in `sd-multirate`. Each message says what to fix.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MultirateError {
    /// An error from the underlying model operations (shapes, NaN, domains, ...).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A rate factor F that is not usable.
    #[error("invalid rate factor {factor}: {why}")]
    InvalidFactor {
        /// The factor given.
        factor: usize,
        /// What is wrong and what to use instead.
        why: String,
    },
    /// A fraction of the sample period (hold delay α, averaging window β) out of range or not
    /// representable at the given rate.
    #[error("invalid {what} = {value}: {why}")]
    InvalidFraction {
        /// Which fraction.
        what: &'static str,
        /// The value given.
        value: f64,
        /// What is allowed.
        why: String,
    },
    /// The slow and fast models' sample times are not related by the factor F.
    #[error("sample times do not match: {detail}")]
    RateMismatch {
        /// The periods found and the relation required.
        detail: String,
    },
    /// An argument that is not usable (message says which and why).
    #[error("{0}")]
    InvalidArgument(String),
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, MultirateError>;

impl MultirateError {
    /// A numerical failure on valid input ([`ModelError::is_numerical`]); everything else is
    /// input to fix.
    pub fn is_numerical(&self) -> bool {
        matches!(self, MultirateError::Model(m) if m.is_numerical())
    }
}

pub(crate) fn require_discrete(sys: &sd_model::StateSpace, op: &str) -> Result<f64> {
    sys.ts().ok_or_else(|| {
        MultirateError::Model(ModelError::WrongDomain {
            operation: op.into(),
            expected: "discrete-time".into(),
            found: "continuous-time".into(),
        })
    })
}

pub(crate) fn check_factor(factor: usize) -> Result<()> {
    if factor == 0 {
        return Err(MultirateError::InvalidFactor {
            factor,
            why: "the factor F = T/h must be a positive integer (1 keeps the rate)".into(),
        });
    }
    if factor > crate::tol::MAX_FACTOR {
        return Err(MultirateError::InvalidFactor {
            factor,
            why: format!(
                "factors above {} are not supported (lifted models grow with F)",
                crate::tol::MAX_FACTOR
            ),
        });
    }
    Ok(())
}
