//! Dense linear-algebra kernels used by the model operations.
//!
//! Conversions between nalgebra (the public currency) and faer (used where it has the
//! decomposition: eigenvalues, generalized eigenvalues, SVD) live in [`convert`]; the one
//! least-squares solver of the toolkit (column-scaled QR + SVD, with covariance) is [`lstsq()`](fn@lstsq).

pub mod blocks;
pub mod convert;
pub mod expm;
pub mod golden;
pub mod hamiltonian;
pub mod lstsq;
pub mod lyap;
pub mod qr;
pub mod schur;

pub use expm::expm;
pub use golden::golden_min;
pub use lstsq::{lstsq, lstsq_faer, LstSq};
pub use qr::qr_r;
