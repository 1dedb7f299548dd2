//! `sd-testbed`: a virtual wafer stage that produces measured data.
//!
//! A continuous-time truth ([`Truth`]: rigid body, lightly damped modes, optional amplifier
//! pole, sensor filters, cubic stiffness and Coulomb friction) is simulated exactly when linear
//! and by an exponential integrator when not ([`PlantSim`]), with rate-tied non-idealities
//! (hold delay, averaging sampler), sample-clock error and quantization; experiments
//! ([`run_identification`], [`run_standstill`]) give data in the docs/formats.md format, seeded and reproducible.

pub mod config;
pub mod config_axes;
pub mod error;
pub mod experiments;
mod fine;
pub mod multiaxis;
pub mod sim;
pub mod truth;

pub use config::{parse_config, run_config, TestbedConfig, DEFAULT_CONFIG};
pub use config_axes::{is_multiaxis, parse_axis_config, run_axis_config, AxisConfig};
pub use error::{Result, TestbedError};
pub use experiments::{
    manifest, output_files, run_identification, run_standstill, truth_model, ExperimentData,
    Identification, Injection, Noise, Standstill,
};
pub use multiaxis::{
    axis_manifest, decentralised_pid, run_multiaxis, AxisData, AxisIdentification, AxisMode,
    AxisNonIdealities, MultiAxisTruth,
};
pub use sim::{default_substeps, NonIdealities, PlantSim};
pub use truth::{ModeSpec, Truth};

/// The crate README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;
