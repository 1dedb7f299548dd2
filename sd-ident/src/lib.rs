//! `sd-ident`: from measured data to a discrete-time model.
//!
//! - [`multisine`]: random-phase, Schroeder and random-odd multisines on fold-aware grids, crest
//!   factor, CSV output.
//! - [`experiment`]: the manifest of docs/formats.md (TOML) and robust CSV reading.
//! - [`frf`]: FRF of periodic data — closed loop `(Y/R)/(U/R)` or open loop — with variances
//!   from the spread over periods, and noise / nonlinear-distortion levels.
//! - [`frf_mimo`]: the ny×nu FRF of periodic experiments (one input per experiment, or
//!   orthogonal multisines from [`orthogonal`]), open or closed loop, with the covariance of the
//!   vectorised estimate.
//! - [`bla`]: the best linear approximation with its total variance (noise + stochastic
//!   nonlinear distortion from detection lines, realisations, or carried from a sibling).
//! - [`lpm()`]: the local polynomial method for transients and non-periodic (MIMO) data.
//! - [`fit()`]: discrete-time rational fitting up to order ~60 (SK iterations in a partial-fraction
//!   basis, then Levenberg–Marquardt on the variance-weighted cost; stability by reflection;
//!   rigid-body poles at z = 1 optionally fixed; order selection).
//! - [`physical_fit`]: the stabilisation diagram, poles no narrower than the lines resolve,
//!   order and rigid body by held-out lines, an input delay; the mode table.
//! - [`fit_common_poles`]: one set of poles for every entry of a MIMO FRD, residue matrices of
//!   the rank the data support, a minimal modal realisation.

pub mod bla;
pub mod error;
pub mod estimate;
pub mod experiment;
pub mod fit;
pub mod fit_mimo;
pub mod frf;
pub mod frf_mimo;
pub mod input_delay;
pub mod local_dft;
pub mod local_mode;
pub mod lpm;
pub mod multisine;
pub mod quality;
pub mod rng;
pub mod roughness;
pub mod stabilization;
#[cfg(test)]
mod testsim;
pub mod tol;

pub use bla::{detection_gate, same_level, BandLevel, Bla, Distortion, Unmeasurable};
pub use error::{IdentError, Result};
pub use estimate::{
    estimate_experiment, estimate_in_set, excitation_rms, frf_of_experiment, frf_of_experiments,
    ExperimentFrf, FrfRequest,
};
pub use experiment::{
    load_experiment, load_experiments, parse_manifest, read_columns, Experiment, ExperimentSpec,
    ExtraColumns, ExtraSignals, Role,
};
pub use fit::{
    check_order_determined, final_prediction_error, fit, fit_with_progress, model_cost,
    select_order, FitOptions, FitProgress, FitResult, FitWarning, ModalTerm, Weighting,
};
pub use fit_mimo::{
    fit_common_poles, fit_common_poles_with_progress, MimoFitOptions, MimoFitResult, MimoMode,
    ResidueRank,
};
pub use frf::{
    frf_periodic, DistortionReport, FrfEstimate, PeriodicOptions, MIN_INPUT_SNR, NL_NEIGHBOURS,
};
pub use frf_mimo::{frf_periodic_mimo, Channels, MimoFrfEstimate};
pub use input_delay::{advance_inputs, shift_inputs, DelayScan, InputDelay};
pub use local_dft::{local_mode_dft, local_mode_dft_beside, LineSpectra};
pub use local_mode::{
    local_mode, local_mode_beside, local_mode_with, LineNoise, LocalMode, MIN_LINES,
    MIN_POOLED_LINES,
};
pub use lpm::{
    lpm, lpm_closed_loop, lpm_closed_loop_full, lpm_closed_loop_mimo, lpm_closed_loop_snr,
    lpm_excitation_correlation, lpm_polynomial_correlation, moving_mean, ClosedLoopLpm,
    LpmEstimate, LpmOptions, EXPECTED_VAR_HALF_WIDTH,
};
pub use multisine::{
    crest_factor, design, orthogonal, write_csv, Lines, Multisine, MultisineSpec, Phases,
};
pub use quality::{
    feedback_only, input_unexplained_by_output, likely_period, snr_warnings, trusted, DataWarning,
    FEEDBACK_ONLY_RESIDUAL, NO_EXCITATION_SNR,
};
pub use roughness::{ROUGHNESS_DOF, ROUGHNESS_WINDOW};
pub use stabilization::{
    physical_fit, DiagramPole, ModeKind, OrderRow, PhysicalFit, PhysicalFitSummary, PhysicalMode,
    PoleClass, StabilizationOptions, FLOOR_RESOLUTION,
};

/// The crate README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;
