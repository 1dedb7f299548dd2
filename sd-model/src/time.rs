//! Sample time of a model: continuous or discrete with a checked period.

use crate::error::{ModelError, Result};
use std::fmt;

/// Whether a model lives in continuous time or in discrete time with period `ts` seconds.
///
/// Invariant: `ts` is finite and strictly positive (checked by [`SampleTime::discrete`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SampleTime {
    /// Continuous time (Laplace variable `s`).
    Continuous,
    /// Discrete time (variable `z`) with sampling period `ts` seconds.
    Discrete {
        /// Sampling period in seconds.
        ts: f64,
    },
}

impl SampleTime {
    /// A discrete sample time; `ts` must be finite and > 0.
    pub fn discrete(ts: f64) -> Result<Self> {
        if ts.is_finite() && ts > 0.0 {
            Ok(SampleTime::Discrete { ts })
        } else {
            Err(ModelError::InvalidSampleTime { ts })
        }
    }
    /// From the JSON convention: `None` is continuous.
    pub fn from_option(ts: Option<f64>) -> Result<Self> {
        match ts {
            None => Ok(SampleTime::Continuous),
            Some(t) => Self::discrete(t),
        }
    }
    /// `None` for continuous time, `Some(ts)` otherwise.
    pub fn ts(&self) -> Option<f64> {
        match self {
            SampleTime::Continuous => None,
            SampleTime::Discrete { ts } => Some(*ts),
        }
    }
    /// True for continuous time.
    pub fn is_continuous(&self) -> bool {
        matches!(self, SampleTime::Continuous)
    }
    /// True for discrete time.
    pub fn is_discrete(&self) -> bool {
        !self.is_continuous()
    }
    /// Two sample times are compatible when both are continuous or both discrete with periods
    /// equal to a relative 1e-9 (periods read from files carry rounding).
    pub fn compatible(&self, other: &SampleTime) -> bool {
        match (self, other) {
            (SampleTime::Continuous, SampleTime::Continuous) => true,
            (SampleTime::Discrete { ts: a }, SampleTime::Discrete { ts: b }) => {
                (a - b).abs() <= 1e-9 * a.abs().max(b.abs())
            }
            _ => false,
        }
    }
    /// Error unless compatible.
    pub(crate) fn check_same(&self, other: &SampleTime, operation: &str) -> Result<()> {
        if self.compatible(other) {
            Ok(())
        } else {
            Err(ModelError::SampleTimeMismatch {
                operation: operation.to_string(),
                left: self.to_string(),
                right: other.to_string(),
            })
        }
    }
    /// The point of the complex plane where a response is evaluated at `f_hz`: `s = j2πf`
    /// (continuous) or `z = e^{j2πf·ts}` (discrete).
    pub fn point(&self, f_hz: f64) -> num_complex::Complex64 {
        let w = 2.0 * std::f64::consts::PI * f_hz;
        match self {
            SampleTime::Continuous => num_complex::Complex64::new(0.0, w),
            SampleTime::Discrete { ts } => num_complex::Complex64::from_polar(1.0, w * ts),
        }
    }

    /// Nyquist frequency in Hz for discrete time.
    pub fn nyquist_hz(&self) -> Option<f64> {
        self.ts().map(|t| 0.5 / t)
    }
    pub(crate) fn domain_name(&self) -> &'static str {
        if self.is_continuous() {
            "continuous-time"
        } else {
            "discrete-time"
        }
    }
}

impl fmt::Display for SampleTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SampleTime::Continuous => write!(f, "continuous"),
            SampleTime::Discrete { ts } => write!(f, "ts = {ts} s"),
        }
    }
}
