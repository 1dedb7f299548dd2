//! `sd-analysis`: closed-loop analysis of sampled-data motion systems.
//!
//! - [`ClosedLoop`]: internal stability, S, T, PS, KS, |S| peak, margins (python-control's
//!   definitions), the gain crossover and the closed-loop −3 dB bandwidth, the `sdctl analyze` summary.
//! - [`generalized_nyquist()`]: the generalised Nyquist criterion of a MIMO loop (encirclements
//!   of `det(I + L)`, checked against the closed-loop eigenvalues), [`characteristic_loci()`].
//! - [`analyze_measured()`]: a controller model on a *measured* plant FRF — L, S, T on the
//!   lines, margins between lines, the Nyquist test closed by the physics at both ends.
//! - [`reduce_controller()`]: controller reduction with the closed-loop weight, judged on the
//!   loop (|ΔS|, |ΔT| below twice the crossover, margins before and after).
//! - [`spectra`]: Welch and periodogram PSDs with windows, cumulative power spectrum, rms,
//!   dominant frequency.
//! - [`standstill()`]: disturbance simulation of a single-rate loop, and of a slow controller on a
//!   fast plant (errors at both rates).
//! - [`intersample()`]: predicted fast- and slow-rate error spectra of a multirate loop and the
//!   control sensitivity `K_d S_d`.

pub mod closed_loop;
pub mod error;
pub mod intersample;
pub mod measured;
pub mod measured_nyquist;
pub mod mimo;
pub mod mu;
pub mod nyquist;
pub mod reduce_controller;
pub mod reduce_fit;
pub mod spectra;
pub mod standstill;
pub mod tol;

pub use closed_loop::{ClosedLoop, Margins, Responses, Summary};
pub use error::{AnalysisError, Result};
pub use intersample::{intersample, rms_of_density, Intersample};
pub use measured::{analyze_measured, MeasuredAnalysis, MeasuredPlant, MeasuredResponses};
pub use measured_nyquist::MeasuredNyquist;
pub use mimo::{mimo_margins, singular_values, ChannelMargins, MimoMargins, Side, SingularValues};
pub use mu::{mu_diagonal, mu_upper, structured_disk_margins, MuBounds, StructuredDiskMargin};
pub use nyquist::{characteristic_loci, generalized_nyquist, Nyquist};
pub use reduce_controller::{reduce_controller, ControllerReduction, ReductionMethod};
pub use sd_multirate::MultirateSimulation;
pub use spectra::{cps, periodogram, rms, welch, Spectrum, Window};
pub use standstill::{standstill, standstill_multirate, Standstill};

/// The crate README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;
