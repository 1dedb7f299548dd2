//! The one error type of `sd-ident`.

use sd_model::ModelError;

/// Everything that can go wrong in `sd-ident`. Each message says what to fix.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IdentError {
    /// An error of the underlying model operations.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A malformed manifest or data file: where and what.
    #[error("{file}: {detail}")]
    Format {
        /// The file (or "manifest").
        file: String,
        /// Line, column and what is wrong.
        detail: String,
    },
    /// Data that cannot give what was asked (too short, not periodic, no excitation, ...).
    #[error("{0}")]
    Data(String),
    /// An argument out of range (message says which and why).
    #[error("{0}")]
    InvalidArgument(String),
    /// A numerical failure that is not the input's fault.
    #[error("numerical failure: {0}")]
    Numerical(String),
}

impl IdentError {
    /// A numerical failure on valid input; everything else is input to fix.
    pub fn is_numerical(&self) -> bool {
        match self {
            IdentError::Model(m) => m.is_numerical(),
            IdentError::Numerical(_) => true,
            _ => false,
        }
    }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, IdentError>;
