//! `sd-hinf`: Riccati solvers and discrete-time McFarlane–Glover H∞ loopshaping.
//!
//! - [`dare`], [`care`]: the stabilizing solution (cross term S allowed), its residual, closed
//!   loop and condition estimate, or an error saying why there is none.

pub mod error;
pub mod riccati;
pub mod tol;

pub use error::{HinfError, Result};
pub use riccati::{care, dare, RiccatiSolution};
