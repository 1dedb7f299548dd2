//! Dense linear-algebra kernels used by the model operations.
//!
//! Conversions between nalgebra (the public currency) and faer (used where it has the
//! decomposition: eigenvalues, generalized eigenvalues, SVD) live in [`convert`].

pub mod convert;
pub mod expm;
pub mod golden;
pub mod lyap;
pub mod schur;

pub use expm::expm;
pub use golden::golden_min;
