//! Time-domain simulation of discrete models, and of continuous models under a ZOH input.
//!
//! `x_{k+1} = A x_k + B u_k`, `y_k = C x_k + D u_k`, inputs as an N×nu matrix (one row per
//! sample), outputs N×ny. A continuous model is discretised exactly (Lemma 5) first, so the
//! result is exact at the sample instants for a piecewise-constant input.

use crate::c2d::{c2d, Discretization};
use crate::error::{ModelError, Result};
use crate::ss::StateSpace;
use nalgebra::{DMatrix, DVector};

/// Outputs and final state of a simulation.
#[derive(Debug, Clone)]
pub struct Simulation {
    /// Outputs, N×ny.
    pub y: DMatrix<f64>,
    /// State after the last sample, `x_N`.
    pub x_final: DVector<f64>,
}

impl StateSpace {
    /// Simulates a discrete model from `x0` (zero if `None`).
    pub fn simulate(&self, u: &DMatrix<f64>, x0: Option<&DVector<f64>>) -> Result<Simulation> {
        if self.time().is_continuous() {
            return Err(ModelError::WrongDomain {
                operation: "simulate (use simulate_zoh for continuous models)".into(),
                expected: "discrete-time".into(),
                found: "continuous-time".into(),
            });
        }
        if u.ncols() != self.nu() {
            return Err(ModelError::dim(
                "input signal columns (one per model input)",
                self.nu(),
                u.ncols(),
            ));
        }
        crate::ss::check_finite(u, "input signal")?;
        let n = self.n();
        let mut x = match x0 {
            Some(x) if x.len() != n => return Err(ModelError::dim("initial state", n, x.len())),
            Some(x) => x.clone(),
            None => DVector::zeros(n),
        };
        let steps = u.nrows();
        let mut y = DMatrix::zeros(steps, self.ny());
        let (a, b, c, d) = (self.a(), self.b(), self.c(), self.d());
        let mut xn = DVector::zeros(n);
        for k in 0..steps {
            let uk = u.row(k).transpose();
            let yk = c * &x + d * &uk;
            y.row_mut(k).copy_from(&yk.transpose());
            xn.gemv(1.0, a, &x, 0.0);
            xn.gemv(1.0, b, &uk, 1.0);
            std::mem::swap(&mut x, &mut xn);
        }
        Ok(Simulation { y, x_final: x })
    }

    /// Simulates a continuous model driven through a zero-order hold with period `ts`.
    pub fn simulate_zoh(
        &self,
        u: &DMatrix<f64>,
        ts: f64,
        x0: Option<&DVector<f64>>,
    ) -> Result<Simulation> {
        c2d(self, ts, Discretization::Zoh)?.simulate(u, x0)
    }
}

/// Root mean square of a signal, `sqrt(Σ x²/N)` (0 for an empty one). The one `rms` of the
/// workspace.
pub fn rms(x: &[f64]) -> f64 {
    rms_of(x.iter().copied())
}

/// Median of the non-NaN values: the upper middle one, `v[⌊N/2⌋]` of the sorted values (NaN
/// when there is none). The one `median` of the workspace.
pub fn median(x: &[f64]) -> f64 {
    let mut v: Vec<f64> = x.iter().copied().filter(|v| !v.is_nan()).collect();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// [`rms`] of the values of an iterator.
pub fn rms_of(x: impl IntoIterator<Item = f64>) -> f64 {
    let (s, n) = x
        .into_iter()
        .fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    (s / n.max(1) as f64).sqrt()
}
