//! `sd-hinf`: Riccati solvers, discrete-time McFarlane–Glover H∞ loopshaping and weights.
//!
//! - [`dare`], [`care`]: the stabilizing solution (cross term S allowed), its residual, closed
//!   loop and condition estimate, or an error saying why there is none.
//! - [`loopshape()`]: `G_s = W₂PW₁`, γ_min, the central controller for γ = factor·γ_min (or the
//!   strictly proper one), `K = W₁K_sW₂` for negative feedback, the achieved 4-block norm.
//! - [`weights`]: PID-like, notch and low-pass weights, discrete by prewarped Tustin.
//! - `lmi` (feature `lmi`): the H∞ norm by the bounded-real lemma as an SDP (clarabel), the
//!   independent cross-check used in the tests.
//!
//! ```
//! use sd_hinf::{dare, loopshape, LoopshapeOptions, weights};
//! use sd_model::{c2d, Discretization, stage::paper_stage};
//! let p = c2d(&paper_stage(0.01)?, 1e-3, Discretization::Zoh)?;       // 1 kHz stage model
//! let w1 = weights::pid(65.0, 20.0, Some(1e-3), &Default::default())?;
//! let design = loopshape(&p, Some(&w1), None, &LoopshapeOptions::default())?;
//! assert!(design.closed_loop_stable && design.achieved <= design.gamma * (1.0 + 1e-6));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod bilinear;
mod board;
pub mod error;
pub mod h2;
pub mod hinfsyn;
pub mod lft;
#[cfg(feature = "lmi")]
pub mod lmi;
pub mod loopshape;
pub mod mixsyn;
pub mod riccati;
mod sda;
pub mod tol;
pub mod weights;

pub use error::{HinfError, Result};
pub use h2::{dlqe, dlqr, h2syn, H2Synthesis, Kalman, Lqr};
pub use hinfsyn::{hinfsyn, GammaOutcome, GammaStep, HinfOptions, HinfSynthesis};
pub use lft::{lft_lower, undo_loop_shift, Blocks, Partition};
pub use loopshape::{gamma_min, loopshape, Loopshape, LoopshapeOptions, RiccatiReport};
pub use mixsyn::{augw, mixsyn, MixsynWeights};
pub use riccati::{care, care_residual_of, dare, RiccatiSolution};

/// The crate README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;
