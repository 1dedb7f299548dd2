//! The one error type of `sd-testbed`.

/// Everything that can go wrong in `sd-testbed`. Each message says what to fix.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TestbedError {
    /// Model operations.
    #[error(transparent)]
    Model(#[from] sd_model::ModelError),
    /// Non-ideal discretisation.
    #[error(transparent)]
    Multirate(#[from] sd_multirate::MultirateError),
    /// Excitation design.
    #[error(transparent)]
    Ident(#[from] sd_ident::IdentError),
    /// Controller weights.
    #[error(transparent)]
    Hinf(#[from] sd_hinf::HinfError),
    /// A configuration value that is not usable (message says which and why).
    #[error("configuration: {0}")]
    Config(String),
    /// The identification loop is unstable.
    #[error("{0}")]
    Unstable(String),
}

impl TestbedError {
    /// A numerical failure on valid input; everything else (configuration, an unstable loop)
    /// is input to fix.
    pub fn is_numerical(&self) -> bool {
        match self {
            TestbedError::Model(m) => m.is_numerical(),
            TestbedError::Multirate(m) => m.is_numerical(),
            TestbedError::Ident(m) => m.is_numerical(),
            TestbedError::Hinf(m) => m.is_numerical(),
            _ => false,
        }
    }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, TestbedError>;
