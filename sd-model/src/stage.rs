//! Motion-stage models: a rigid body plus lightly damped flexible modes (force in, position out).
//!
//! `P(s) = 1/(m s²) + Σ_i r_i / (m (s² + 2ζ_iω_i s + ω_i²))` (docs/stage.md). Realised in physical
//! (position, velocity) coordinates per mode — `[[0, 1], [−ω², −2ζω]]` blocks — which is how
//! such models arrive from modal analysis, and which makes ‖A‖ ≈ ω_max² large: a realistic
//! numerical stress test.

use crate::error::{ModelError, Result};
use crate::ss::StateSpace;
use crate::time::SampleTime;
use nalgebra::DMatrix;
use std::f64::consts::PI;

/// A flexible mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Natural frequency in Hz.
    pub freq_hz: f64,
    /// Damping ratio.
    pub zeta: f64,
    /// Residue relative to the rigid body (gain of the mode's `1/m` term).
    pub residue: f64,
}

/// Builds the continuous stage model with mass `mass` (kg), optional rigid body, and modes.
pub fn stage_model(mass: f64, rigid_body: bool, modes: &[Mode]) -> Result<StateSpace> {
    if !(mass.is_finite() && mass > 0.0) {
        return Err(ModelError::InvalidArgument(format!(
            "mass {mass} must be finite and > 0"
        )));
    }
    for m in modes {
        if !(m.freq_hz.is_finite()
            && m.freq_hz > 0.0
            && m.zeta.is_finite()
            && m.zeta >= 0.0
            && m.residue.is_finite())
        {
            return Err(ModelError::InvalidArgument(format!(
                "invalid mode {m:?}: frequency > 0, damping >= 0, finite residue"
            )));
        }
    }
    let n = 2 * modes.len() + if rigid_body { 2 } else { 0 };
    let mut a = DMatrix::zeros(n, n);
    let mut b = DMatrix::zeros(n, 1);
    let mut c = DMatrix::zeros(1, n);
    let mut k = 0;
    if rigid_body {
        a[(0, 1)] = 1.0;
        b[(1, 0)] = 1.0 / mass;
        c[(0, 0)] = 1.0;
        k = 2;
    }
    for m in modes {
        let w = 2.0 * PI * m.freq_hz;
        a[(k, k + 1)] = 1.0;
        a[(k + 1, k)] = -w * w;
        a[(k + 1, k + 1)] = -2.0 * m.zeta * w;
        b[(k + 1, 0)] = m.residue / mass;
        c[(0, k)] = 1.0;
        k += 2;
    }
    StateSpace::new(a, b, c, DMatrix::zeros(1, 1), SampleTime::Continuous)
}

/// The 29 modes of the project's 60-state reference stage: log-spaced from 300 Hz to 6 kHz,
/// damping ratios spread over 0.002–0.03, residues of alternating sign decaying with frequency.
pub fn stage60_modes() -> Vec<Mode> {
    (0..29)
        .map(|i| {
            let t = i as f64 / 28.0;
            let f = 300.0 * (20f64).powf(t);
            // deterministic scatter of the damping over [0.002, 0.03] (log scale)
            let u = ((i * 7) % 29) as f64 / 28.0;
            let zeta = 0.002 * (15f64).powf(u);
            let r = if i % 2 == 0 { 1.0 } else { -0.6 } * (1.0 - 0.8 * t) * 2.0;
            Mode {
                freq_hz: f,
                zeta,
                residue: r,
            }
        })
        .collect()
}

/// The 60-state reference stage: m = 20 kg, rigid body + [`stage60_modes`].
pub fn stage60() -> Result<StateSpace> {
    stage_model(20.0, true, &stage60_modes())
}

/// The paper's stage (docs/stage.md): m = 20 kg, rigid body, 653 Hz mode with ζ and r = 2.
pub fn paper_stage(zeta: f64) -> Result<StateSpace> {
    stage_model(
        20.0,
        true,
        &[Mode {
            freq_hz: 653.0,
            zeta,
            residue: 2.0,
        }],
    )
}

/// The paper's stage with the optional second mode of docs/stage.md: rigid body, 653 Hz (ζ = 0.01,
/// r = 2) and 1.65 kHz (ζ = 0.005, r = 0.3), m = 20 kg.
pub fn paper_stage_two_modes() -> Result<StateSpace> {
    stage_model(
        20.0,
        true,
        &[
            Mode {
                freq_hz: 653.0,
                zeta: 0.01,
                residue: 2.0,
            },
            Mode {
                freq_hz: 1650.0,
                zeta: 0.005,
                residue: 0.3,
            },
        ],
    )
}

/// One mode of a two-axis stage: its frequency, the sensors' and the actuators' participation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoAxisMode {
    /// The mode (frequency, damping, residue magnitude relative to the rigid body).
    pub mode: Mode,
    /// Participation of each of the two sensors (the output shape).
    pub output_shape: [f64; 2],
    /// Participation of each of the two actuators (the input shape).
    pub input_shape: [f64; 2],
}

/// The modes of the two-axis variant of the 60-state stage: [`stage60_modes`]' frequencies,
/// dampings and residue magnitudes, each with its own sensor and actuator shapes
/// (`[cos θ, sin θ]`-like, θ stepping by irrational fractions of a turn so that no two
/// neighbouring modes share a direction).
pub fn two_axis_modes() -> Vec<TwoAxisMode> {
    stage60_modes()
        .into_iter()
        .enumerate()
        .map(|(i, m)| {
            let (t, p) = (0.3 + 1.9 * i as f64, 0.5 + 1.3 * i as f64);
            TwoAxisMode {
                mode: Mode {
                    residue: m.residue.abs(),
                    ..m
                },
                output_shape: [0.4 + 0.6 * t.cos().abs(), t.sin()],
                input_shape: [0.4 + 0.6 * p.cos().abs(), p.sin()],
            }
        })
        .collect()
}

/// The two-axis stage (two actuators, two sensors, force in, position out, 20 kg): a rigid
/// body both actuators push (the second at 0.8) and both sensors see (the second at 0.7),
/// and the [`two_axis_modes`], each mode's residue matrix the rank-one
/// `r·c bᵀ/m` of its output shape `c` and input shape `b`. 60 states.
pub fn two_axis_stage60() -> Result<StateSpace> {
    let modes = two_axis_modes();
    let mass = 20.0;
    let n = 2 + 2 * modes.len();
    let (mut a, mut b, mut c) = (
        DMatrix::zeros(n, n),
        DMatrix::zeros(n, 2),
        DMatrix::zeros(2, n),
    );
    a[(0, 1)] = 1.0;
    b[(1, 0)] = 1.0 / mass;
    b[(1, 1)] = 0.8 / mass;
    c[(0, 0)] = 1.0;
    c[(1, 0)] = 0.7;
    for (i, m) in modes.iter().enumerate() {
        let k = 2 + 2 * i;
        let w = 2.0 * PI * m.mode.freq_hz;
        a[(k, k + 1)] = 1.0;
        a[(k + 1, k)] = -w * w;
        a[(k + 1, k + 1)] = -2.0 * m.mode.zeta * w;
        for j in 0..2 {
            b[(k + 1, j)] = m.mode.residue / mass * m.input_shape[j];
            c[(j, k)] = m.output_shape[j];
        }
    }
    StateSpace::new(a, b, c, DMatrix::zeros(2, 2), SampleTime::Continuous)
}
