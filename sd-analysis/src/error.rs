//! The one error type of `sd-analysis`.

use sd_hinf::HinfError;
use sd_model::ModelError;
use sd_multirate::MultirateError;

/// Everything that can go wrong in `sd-analysis`. Each message says what to fix.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AnalysisError {
    /// An error of the model operations.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// An error of the multirate operations.
    #[error(transparent)]
    Multirate(#[from] MultirateError),
    /// An error of the Riccati-based operations (coprime factors).
    #[error(transparent)]
    Hinf(#[from] HinfError),
    /// An argument that is not usable (message says which and why).
    #[error("{0}")]
    InvalidArgument(String),
    /// A reduction that does not keep the loop (message says which order and why).
    #[error("{0}")]
    ReductionFailed(String),
}

impl AnalysisError {
    /// A numerical failure on valid input; everything else is input to fix.
    pub fn is_numerical(&self) -> bool {
        match self {
            AnalysisError::Model(m) => m.is_numerical(),
            AnalysisError::Multirate(m) => m.is_numerical(),
            AnalysisError::Hinf(h) => h.is_numerical(),
            AnalysisError::ReductionFailed(_) => true,
            _ => false,
        }
    }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, AnalysisError>;
