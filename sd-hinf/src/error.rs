//! The one error type of `sd-hinf`.

use sd_model::ModelError;

/// Everything that can go wrong in `sd-hinf`. Each message says what to fix.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum HinfError {
    /// An error of the underlying model operations (shapes, NaN, domains, ...).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The Riccati equation has no stabilizing solution; `reason` says which condition fails.
    #[error("no stabilizing solution of the {equation}: {reason}")]
    NoStabilizingSolution {
        /// "CARE" or "DARE" (and which one, in loopshaping).
        equation: String,
        /// Eigenvalues on the axis/circle, not stabilizable, not detectable, ...
        reason: String,
    },
    /// A matrix that must be symmetric (Q, R) is not.
    #[error("{what} must be symmetric (relative asymmetry {asymmetry:.1e})")]
    NotSymmetric {
        /// Which matrix.
        what: &'static str,
        /// ‖M − Mᵀ‖/‖M‖.
        asymmetry: f64,
    },
    /// An argument that is not usable (message says which and why).
    #[error("{0}")]
    InvalidArgument(String),
    /// A numerical failure that is not the input's fault.
    #[error("numerical failure: {0}")]
    Numerical(String),
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, HinfError>;

impl HinfError {
    /// A numerical failure on valid input; "no stabilizing solution" is a property of the
    /// problem given, not a numerical failure.
    pub fn is_numerical(&self) -> bool {
        match self {
            HinfError::Model(m) => m.is_numerical(),
            HinfError::Numerical(_) => true,
            _ => false,
        }
    }
}
