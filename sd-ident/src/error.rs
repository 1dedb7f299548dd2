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

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, IdentError>;
