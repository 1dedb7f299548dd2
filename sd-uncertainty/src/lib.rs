//! Model uncertainty from measured data, as a first-class object that travels between rates.
//!
//! The reference paper (Oomen, van de Wal, Bosgra, ACC 2007) leaves open how model uncertainty
//! behaves under downsampling. This crate answers it for the frequency-domain bound:
//!
//! - [`from_data`]: the pointwise bound on a model's error from a measured FRF with variances,
//!   `|P − P̂| ≤ |G − P̂| + κσ` at a stated per-line confidence, additive or multiplicative
//!   ([`bound`] has the math).
//! - [`overbound`]: a low-order stable weight `W(z)` with `|W| ≥ b` on every line (checked),
//!   and how conservative it is ([`weight`]).
//! - [`downsample()`]: the slow-rate bound the fast one implies through Lemma 6: each slow line
//!   collects its `F` fold frequencies weighted by the slow hold,
//!   `|Δ_T(f)| ≤ Σ_k |H_F(f_k)/F|·|Δ_h(f_k)|` ([`mod@downsample`] has the structure and when it
//!   is tight).
//! - [`robust_stability`]: the largest scaling of the bound a loop tolerates (small gain on
//!   the lines and, with the weight, between them), the worst-case sensitivity, and a
//!   destabilising plant inside the bound when there is one ([`robust`]).
//! - [`robust_intersample`]: the fast-rate (intersample) error of a slow loop around the fast
//!   plant, bounded over every plant inside the fast-rate weight ([`mod@intersample`]).
//! - [`chordal_gap`]: the largest chordal distance between a model and a measured FRF (the
//!   ν-gap to the measured plant when the winding condition holds, [`gap`]), against which a
//!   loopshaping design's margin `ε = 1/γ` is read.
//! - [`coverage`]: the fraction of a measurement's lines inside nominal ± bound, the check of a
//!   bound on data it was not made from.
//!
//! SISO; a bound lives on the lines of the data it came from.

pub mod bound;
pub mod downsample;
pub mod error;
pub mod gap;
pub mod intersample;
pub mod json;
pub mod robust;
pub mod weight;

pub use bound::{coverage, from_data, per_line_confidence, sigma_factor, Bound, Coverage, Form};
pub use downsample::{downsample, downsample_nonideal, downsample_nonideal_all, Downsampled};
pub use error::{Result, UncertaintyError};
pub use gap::{chordal, chordal_gap, ChordalGap};
pub use intersample::{robust_intersample, slow_margin_on_lines, LinesMargin, RobustIntersample};
pub use json::{carries, embed, from_json_str, to_json_string, weight_from_json_str};
pub use robust::{
    destabilising, loading_per_line, robust_stability, worst_case_plant, Destabilising, Robust,
};
pub use weight::{overbound, Weight};

/// The crate README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;
