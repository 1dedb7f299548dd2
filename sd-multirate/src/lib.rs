//! `sd-multirate`: the multirate side of sampled-data control (Oomen, van de Wal & Bosgra,
//! ACC 2007, Lemmas 6 and 7).
//!
//! - [`downsample()`]: Lemma 6, a fast model seen through a slow hold and sampler, in the same
//!   state coordinates (binary powering of `[A B; 0 I]`, never a companion form).
//! - [`c2d_nonideal`], [`downsample_nonideal`]: rate-tied non-idealities — a hold that switches a
//!   fraction α of the period late, a sampler that averages over the last fraction β — exactly,
//!   from a continuous model (block exponentials) or from a fast discrete one (lifted).
//! - [`downsample_frd`]: Lemma 6 on a measured fast FRF (the fold sum), no model needed.
//! - [`fold_map`], [`appears_at()`]: which frequencies alias onto which, with the slow hold's
//!   weights `|H_F|/F`.
//! - [`lift()`], [`PeriodicSystem`]: lifting a fast model to an F-input/F-output slow LTI model
//!   and back.
//! - [`MultirateLoop`]: a slow controller around a fast plant — lifted closed loop (Lemma 7),
//!   fast-rate simulation, harmonic transfer function, fast and slow error spectra,
//!   performance frequency gain.
//!
//! ```
//! use sd_model::{c2d, Discretization, stage::paper_stage};
//! use sd_multirate::downsample;
//! let p = paper_stage(0.01)?;                               // 653 Hz mode
//! let fast = c2d(&p, 2e-4, Discretization::Zoh)?;           // 5 kHz
//! let slow = downsample(&fast, 5)?;                         // Lemma 6 → 1 kHz
//! let direct = c2d(&p, 1e-3, Discretization::Zoh)?;         // Lemma 5 at 1 kHz
//! assert!((slow.a() - direct.a()).norm() < 1e-12 * direct.a().norm());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod alias_map;
pub mod closed_loop;
pub mod downsample;
pub mod error;
pub mod frd_fold;
pub mod lift;
pub mod nonideal;
pub mod tol;

pub use alias_map::{appears_at, fold_map, hold_weight, FoldTerm};
pub use closed_loop::{HarmonicTransfer, MultirateLoop, MultirateSimulation};
pub use downsample::downsample;
pub use error::{MultirateError, Result};
pub use frd_fold::{downsample_frd, DownsampledFrd};
pub use lift::{lift, stack, unstack, PeriodicSystem, Phase};
pub use nonideal::{c2d_nonideal, downsample_nonideal, NonIdeal, MAX_HOLD_DELAY};

/// The crate README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;
