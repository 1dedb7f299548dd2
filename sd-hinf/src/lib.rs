//! `sd-hinf`: Riccati solvers, H∞ loopshaping, H∞/H2 synthesis on a generalized plant, mixed
//! sensitivity, LQR/LQE and weights — continuous or discrete time.
//!
//! - [`dare`], [`care`]: the stabilizing solution (cross term S allowed), its residual, closed
//!   loop and condition estimate, or an error saying why there is none.
//! - [`loopshape()`]: `G_s = W₂PW₁`, γ_min, the central controller for γ = factor·γ_min (or the
//!   strictly proper one), `K = W₁K_sW₂` for negative feedback, the achieved 4-block norm.
//! - [`hinfsyn()`]: H∞ synthesis on a generalized plant ([`Partition`], `u = K y`): γ_min by
//!   bisection to a stated tolerance, the central controller, the achieved norm checked by
//!   [`sd_model::StateSpace::hinf_norm`]; [`lft_lower`] closes any such loop.
//! - [`h2syn`], [`dlqr`], [`dlqe`]: H2 synthesis and the discrete LQ regulator and Kalman filter.
//! - [`mixsyn()`], [`augw`]: mixed sensitivity `[W₁S; W₂KS; W₃T]`, optionally with an input
//!   force disturbance (process sensitivity).
//! - [`weights`]: PID-like, notch, low-pass and `makeweight` weights, discrete by prewarped
//!   Tustin.
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
//!
//! // mixed sensitivity on the same plant: |S| below 1/|W1|, the force per metre below 1e7
//! let w1 = weights::makeweight(1e4, 40.0, 1.0, 0.7, 2, Some(1e-3))?;
//! let w2 = sd_model::StateSpace::gain(nalgebra::DMatrix::from_element(1, 1, 1e-7), p.time())?;
//! let wd = sd_model::StateSpace::gain(nalgebra::DMatrix::from_element(1, 1, 1.0), p.time())?;
//! let w = sd_hinf::MixsynWeights { w1: Some(&w1), w2: Some(&w2), w3: None, wd: Some(&wd) };
//! let (r, _plant) = sd_hinf::mixsyn(&p, &w, &Default::default())?;
//! assert!(r.closed_loop_stable && r.achieved_norm <= r.gamma * (1.0 + 1e-6));
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
pub mod multirate;
pub mod multirate_rms;
pub mod ncf;
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
pub use multirate::{
    multirate_h2syn, multirate_hinfsyn, multirate_norm, multirate_plant, MultirateSynthesis,
    MultirateWeights,
};
pub use multirate_rms::{multirate_rms, MultirateRms};
pub use ncf::{coprime_reduce, normalized_lcf, CoprimeReduction};
pub use riccati::complex::{
    care_complex, dare_complex, CMatrix, ComplexRiccatiData, ComplexRiccatiSolution,
};
pub use riccati::descriptor::{gcare, gdare, MAX_E_CONDITION};
pub use riccati::{care, care_residual_of, dare, RiccatiSolution};

/// The crate README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;
