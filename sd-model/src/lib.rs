//! `sd-model`: linear models for sampled-data control design.
//!
//! State space ([`StateSpace`]), SISO transfer functions ([`TransferFunction`]) and frequency
//! response data ([`Frd`]) with JSON in the project's file formats; exact discretisation
//! ([`c2d()`], Lemma 5 of Oomen et al. 2007) and its principal inverse with alias candidates
//! ([`d2c()`], [`d2c_with_aliases`]); frequency response after one block-diagonal reduction;
//! interconnection; poles and invariant zeros; minimal realisation; balanced truncation; H2 and
//! H∞ norms; simulation. Every numerical routine documents its method, reference and accuracy.
//!
//! ```
//! use sd_model::{c2d, alias, Discretization, stage::paper_stage};
//! let p = paper_stage(0.01)?;                       // 653 Hz mode, m = 20 kg
//! let pd = c2d(&p, 1e-3, Discretization::Zoh)?;      // exact ZOH at 1 kHz
//! assert!((alias(653.0, 1000.0)?.alias_hz - 347.0).abs() < 1e-9);
//! let g = pd.freqresp(&[347.0])?;
//! assert!(g.response()[0][(0, 0)].norm() > 0.0);
//! # Ok::<(), sd_model::ModelError>(())
//! ```

pub mod alias;
pub mod c2d;
mod c2d_mapped;
pub mod connect;
pub mod d2c;
pub mod delay;
pub mod error;
pub mod frd;
pub mod freqresp;
pub mod json;
pub mod keys;
pub mod linalg;
pub mod norms;
mod pole_guard;
mod pole_sum;
pub mod poles;
pub mod quantile;
pub mod reduce;
pub mod sim;
pub mod ss;
pub mod stage;
pub mod tf;
pub mod time;
pub mod zeros;

pub use alias::{alias, fold, folded_line, folding_frequencies, line_index, Alias};
pub use c2d::{c2d, Discretization};
pub use connect::{append, feedback, parallel, series};
pub use d2c::{d2c, d2c_near, d2c_with_aliases, BranchPick, ModeAliases};
pub use delay::{input_delay, phase_error_deg, thiran, whole_input_delay};
pub use error::{ModelError, Result};
pub use frd::Frd;
pub use freqresp::{grid, EvalPath, FreqRespEvaluator};
pub use json::{
    frd_from_json_str, frd_json_chunks, frd_to_json_string, model_from_json_str,
    model_to_json_string, read_model, write_model,
};
pub use norms::HinfNorm;
pub use num_complex::Complex64;
pub use quantile::{chi2_quantile, f_quantile, normal_cdf, normal_quantile};
pub use reduce::BalancedTruncation;
pub use sim::{median, rms, rms_of, Simulation};
pub use ss::StateSpace;
pub use tf::TransferFunction;
pub use time::SampleTime;

/// The crate README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;

/// The workspace README's Rust example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
pub struct WorkspaceReadmeDoctest;
