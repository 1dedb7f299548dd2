//! The crate's one error type.

use thiserror::Error;

/// What can go wrong.
#[derive(Debug, Error)]
pub enum UncertaintyError {
    /// A model operation failed.
    #[error(transparent)]
    Model(#[from] sd_model::ModelError),
    /// A multirate operation failed.
    #[error(transparent)]
    Multirate(#[from] sd_multirate::MultirateError),
    /// A closed-loop computation failed.
    #[error(transparent)]
    Analysis(#[from] sd_analysis::AnalysisError),
    /// The weight's fit failed.
    #[error(transparent)]
    Ident(#[from] sd_ident::IdentError),
    /// An argument or a data set that cannot be used, and what to change.
    #[error("{0}")]
    Input(String),
}

/// Result with [`UncertaintyError`].
pub type Result<T> = std::result::Result<T, UncertaintyError>;

impl UncertaintyError {
    /// A numerical failure on valid input (else: input the caller must fix), by the wrapped
    /// crate's own classification.
    pub fn is_numerical(&self) -> bool {
        match self {
            UncertaintyError::Model(e) => e.is_numerical(),
            UncertaintyError::Multirate(e) => e.is_numerical(),
            UncertaintyError::Analysis(e) => e.is_numerical(),
            UncertaintyError::Ident(e) => e.is_numerical(),
            UncertaintyError::Input(_) => false,
        }
    }
}
