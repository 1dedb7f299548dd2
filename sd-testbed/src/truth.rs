//! The continuous-time truth of the virtual stage, in modal coordinates.
//!
//! States `[x, v, q₁, q̇₁, …, q_m, q̇_m, a?, f…]`: rigid-body position and velocity, one pair
//! per flexible mode, an optional amplifier state and the states of continuous sensor filters.
//!
//! ```text
//! m v̇ = F − c_v v − F_c tanh(v/v_s)                      (Coulomb friction, smoothed)
//! q̈_i + 2ζ_iω_i q̇_i + ω_i² (q_i + κ_i q_i³) = (r_i/m) F    (cubic stiffness κ_i)
//! ȧ = ω_a (u − a),  F = a                                  (amplifier pole; F = u without it)
//! y = filters(x + Σ q_i)                                   (position, through sensor filters)
//! ```
//!
//! With `F_c = 0` and every `κ_i = 0` the truth is LTI (`linear_model`), and its transfer
//! function is the virtual stage's (docs/stage.md) `1/(m s²) + Σ r_i/(m(s² + 2ζ_iω_is + ω_i²))` (with viscous friction
//! `c_v` the rigid body becomes `1/(s(ms + c_v))`). The Coulomb term is smoothed by `tanh` with a
//! velocity scale `v_s`, so the right-hand side is smooth and the fine-step integrator's error
//! can be checked by halving its step.

use crate::error::{Result, TestbedError};
use nalgebra::{DMatrix, DVector};
use sd_model::{SampleTime, StateSpace};
use std::f64::consts::PI;

/// A flexible mode.
#[derive(Debug, Clone, PartialEq)]
pub struct ModeSpec {
    /// Natural frequency (Hz).
    pub freq_hz: f64,
    /// Damping ratio.
    pub zeta: f64,
    /// Residue r (dimensionless, relative to the rigid-body line 1/(m s²)).
    pub residue: f64,
    /// Cubic stiffness coefficient κ (1/position²); 0 for a linear mode.
    pub cubic: f64,
}

/// The virtual stage.
#[derive(Debug, Clone, PartialEq)]
pub struct Truth {
    /// Moving mass (kg).
    pub mass: f64,
    /// Flexible modes.
    pub modes: Vec<ModeSpec>,
    /// Amplifier pole (Hz), if any.
    pub amplifier_hz: Option<f64>,
    /// Viscous friction (N·s/m).
    pub viscous: f64,
    /// Coulomb friction force (N).
    pub coulomb: f64,
    /// Velocity scale of the smoothed Coulomb term (m/s).
    pub coulomb_velocity: f64,
    /// Continuous sensor filters (SISO, continuous time), applied in series to the position.
    pub sensor_filters: Vec<StateSpace>,
}

impl Default for Truth {
    /// docs/stage.md: m = 20 kg, 653 Hz (ζ 0.01, r 2) and 1.65 kHz (ζ 0.005, r 0.3) modes.
    fn default() -> Self {
        Truth {
            mass: 20.0,
            modes: vec![
                ModeSpec {
                    freq_hz: 653.0,
                    zeta: 0.01,
                    residue: 2.0,
                    cubic: 0.0,
                },
                ModeSpec {
                    freq_hz: 1650.0,
                    zeta: 0.005,
                    residue: 0.3,
                    cubic: 0.0,
                },
            ],
            amplifier_hz: None,
            viscous: 0.0,
            coulomb: 0.0,
            coulomb_velocity: 1e-6,
            sensor_filters: Vec::new(),
        }
    }
}

/// Layout of the state vector.
#[derive(Debug, Clone)]
pub(crate) struct Layout {
    pub n: usize,
    pub v: usize,
    pub modes: Vec<usize>,
}

impl Truth {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(TestbedError::Config(m));
        if !(self.mass.is_finite() && self.mass > 0.0) {
            return bad(format!("mass {} must be > 0", self.mass));
        }
        for (i, m) in self.modes.iter().enumerate() {
            let ok = m.freq_hz.is_finite()
                && m.freq_hz > 0.0
                && m.zeta.is_finite()
                && m.zeta >= 0.0
                && m.residue.is_finite()
                && m.cubic.is_finite();
            if !ok {
                return bad(format!(
                    "mode {}: frequency must be > 0, damping ≥ 0, residue and cubic finite",
                    i + 1
                ));
            }
        }
        if let Some(f) = self.amplifier_hz {
            if !(f.is_finite() && f > 0.0) {
                return bad(format!("amplifier pole {f} Hz must be > 0"));
            }
        }
        if !(self.viscous.is_finite()
            && self.viscous >= 0.0
            && self.coulomb.is_finite()
            && self.coulomb >= 0.0)
        {
            return bad("friction coefficients must be finite and ≥ 0".into());
        }
        if !(self.coulomb_velocity.is_finite() && self.coulomb_velocity > 0.0) {
            return bad("coulomb_velocity must be > 0".into());
        }
        for f in &self.sensor_filters {
            if !f.time().is_continuous() || f.nu() != 1 || f.ny() != 1 {
                return bad("sensor filters must be continuous SISO models".into());
            }
        }
        Ok(())
    }

    /// True when the nonlinear terms are active.
    pub fn is_nonlinear(&self) -> bool {
        self.coulomb != 0.0 || self.modes.iter().any(|m| m.cubic != 0.0)
    }

    pub(crate) fn layout(&self) -> Layout {
        let mut modes = Vec::new();
        let mut i = 2;
        for _ in &self.modes {
            modes.push(i);
            i += 2;
        }
        if self.amplifier_hz.is_some() {
            i += 1;
        }
        for f in &self.sensor_filters {
            i += f.n();
        }
        Layout { n: i, v: 1, modes }
    }

    /// The linear part `(A, B, C, D)` (force command in, measured position out); the nonlinear
    /// terms are added by `Truth::nonlinear_term`.
    ///
    /// # Errors
    /// Invalid parameters.
    pub fn linear_model(&self) -> Result<StateSpace> {
        self.validate()?;
        let lay = self.layout();
        let n = lay.n;
        let m = self.mass;
        let mut a = DMatrix::<f64>::zeros(n, n);
        let mut b = DMatrix::<f64>::zeros(n, 1);
        // force input column: directly, or through the amplifier state
        let mut force = DVector::<f64>::zeros(n);
        force[1] = 1.0 / m;
        a[(0, 1)] = 1.0;
        a[(1, 1)] = -self.viscous / m;
        for (k, md) in self.modes.iter().enumerate() {
            let i = lay.modes[k];
            let w = 2.0 * PI * md.freq_hz;
            a[(i, i + 1)] = 1.0;
            a[(i + 1, i)] = -w * w;
            a[(i + 1, i + 1)] = -2.0 * md.zeta * w;
            force[i + 1] = md.residue / m;
        }
        let mut next = 2 + 2 * self.modes.len();
        if let Some(fa) = self.amplifier_hz {
            let wa = 2.0 * PI * fa;
            let ia = next;
            next += 1;
            a[(ia, ia)] = -wa;
            b[(ia, 0)] = wa;
            for r in 0..n {
                a[(r, ia)] += force[r];
            }
        } else {
            for r in 0..n {
                b[(r, 0)] = force[r];
            }
        }
        // position row, then through the filters in series
        let mut c = DMatrix::<f64>::zeros(1, n);
        c[(0, 0)] = 1.0;
        for &i in &lay.modes {
            c[(0, i)] = 1.0;
        }
        let mut d = 0.0;
        for f in &self.sensor_filters {
            let nf = f.n();
            let j = next;
            next += nf;
            // filter input = current output row c·x + d·u
            let fa = f.a();
            let fb = f.b();
            for r in 0..nf {
                for cc in 0..nf {
                    a[(j + r, j + cc)] = fa[(r, cc)];
                }
                for cc in 0..n {
                    a[(j + r, cc)] += fb[(r, 0)] * c[(0, cc)];
                }
                b[(j + r, 0)] += fb[(r, 0)] * d;
            }
            let mut c2 = DMatrix::<f64>::zeros(1, n);
            for cc in 0..n {
                c2[(0, cc)] = f.d()[(0, 0)] * c[(0, cc)];
            }
            for r in 0..nf {
                c2[(0, j + r)] += f.c()[(0, r)];
            }
            d *= f.d()[(0, 0)];
            c = c2;
        }
        Ok(StateSpace::new(
            a,
            b,
            c,
            DMatrix::from_element(1, 1, d),
            SampleTime::Continuous,
        )?)
    }

    /// The nonlinear part `g(x)` of `ẋ = A x + B u + g(x)` (zero for a linear truth).
    pub(crate) fn nonlinear_term(&self, lay: &Layout, x: &[f64], out: &mut [f64]) {
        out.iter_mut().for_each(|v| *v = 0.0);
        if self.coulomb != 0.0 {
            out[lay.v] = -self.coulomb * (x[lay.v] / self.coulomb_velocity).tanh() / self.mass;
        }
        for (k, md) in self.modes.iter().enumerate() {
            if md.cubic != 0.0 {
                let i = lay.modes[k];
                let w = 2.0 * PI * md.freq_hz;
                out[i + 1] = -w * w * md.cubic * x[i] * x[i] * x[i];
            }
        }
    }
}
