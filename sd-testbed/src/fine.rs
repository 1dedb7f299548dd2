//! The fine-step route (another numerical form than the exact discretisation, for held-out
//! tests of the diagnosis), for any number of inputs and outputs.
//!
//! Each period of the *true* length `h` is cut into `N` sub-steps; the continuous model is
//! ZOH-discretised once at the sub-step `h/N`. Actuator `j`'s hold switches on the sub-step
//! grid, `round(α_j N)` sub-steps late (any α up to [`sd_multirate::MAX_HOLD_DELAY`]
//! periods: the command issued `⌈(d − s)/N⌉` periods ago is in force on sub-step `s` while
//! `d > s`); sensor `i` averages its output by the trapezoidal rule over the last
//! `round(β_i N)` sub-steps of the period (0: it samples at the period's end). The error
//! against the exact route is O(1/N) in each switching instant and O(1/N²) in the averages.

use crate::error::{Result, TestbedError};
use nalgebra::{DMatrix, DVector};
use sd_model::StateSpace;
use std::collections::VecDeque;

/// A running fine-step simulation (module documentation).
#[derive(Debug, Clone)]
pub(crate) struct FineStep {
    ad: DMatrix<f64>,
    bd: DMatrix<f64>,
    c: DMatrix<f64>,
    x: DVector<f64>,
    subs: usize,
    dt: f64,
    /// Per actuator: its hold delay in sub-steps.
    delay_subs: Vec<usize>,
    /// Per sensor: its averaging window in sub-steps.
    window_subs: Vec<usize>,
    /// Past commands (one vector per period), the newest first.
    history: VecDeque<DVector<f64>>,
    /// Per sensor: the last period's average.
    avg: DVector<f64>,
    u_sub: DVector<f64>,
    tmp: DVector<f64>,
}

impl FineStep {
    /// The fine-step simulation of the continuous, strictly proper `model` at the true
    /// period `h` with `subs` sub-steps, per-actuator hold delays and per-sensor averaging
    /// windows (fractions of the period).
    ///
    /// # Errors
    /// `subs` < 2, a non-positive period, lists of the wrong length, negative or non-finite
    /// fractions, the discretisation's failure.
    pub(crate) fn new(
        model: &StateSpace,
        h: f64,
        subs: usize,
        delays: &[f64],
        windows: &[f64],
    ) -> Result<Self> {
        if subs < 2 || !(h.is_finite() && h > 0.0) {
            return Err(TestbedError::Config(format!(
                "fine-step simulation needs ≥ 2 sub-steps (got {subs}) and a period > 0 (got \
                 {h})"
            )));
        }
        if delays.len() != model.nu() || windows.len() != model.ny() {
            return Err(TestbedError::Config(format!(
                "{} hold delays and {} averaging windows given for {} actuators and {} sensors",
                delays.len(),
                windows.len(),
                model.nu(),
                model.ny()
            )));
        }
        let bad = |v: &f64| !(v.is_finite() && *v >= 0.0);
        if delays.iter().any(bad) || windows.iter().any(|w| bad(w) || *w > 1.0) {
            return Err(TestbedError::Config(
                "hold delays must be ≥ 0 and averaging windows within [0, 1] periods".into(),
            ));
        }
        let dt = h / subs as f64;
        let d = sd_model::c2d(model, dt, sd_model::Discretization::Zoh)?;
        let round = |f: f64| (f * subs as f64).round() as usize;
        Ok(FineStep {
            ad: d.a().clone(),
            bd: d.b().clone(),
            c: d.c().clone(),
            x: DVector::zeros(d.n()),
            subs,
            dt,
            delay_subs: delays.iter().map(|a| round(*a)).collect(),
            window_subs: windows.iter().map(|b| round(*b)).collect(),
            history: VecDeque::new(),
            avg: DVector::zeros(model.ny()),
            u_sub: DVector::zeros(model.nu()),
            tmp: DVector::zeros(d.n()),
        })
    }

    /// Advances one period with the commands `u` (one per actuator).
    pub(crate) fn step(&mut self, u: &[f64]) {
        self.history.push_front(DVector::from_column_slice(u));
        let keep = self.delay_subs.iter().copied().max().unwrap_or(0) / self.subs + 2;
        self.history.truncate(keep);
        let ny = self.c.nrows();
        let mut integral = vec![0.0; ny];
        let mut y0 = &self.c * &self.x;
        for s in 0..self.subs {
            for (j, &d) in self.delay_subs.iter().enumerate() {
                // the command issued `lag` periods ago is in force on this sub-step
                let lag = if d > s {
                    (d - s).div_ceil(self.subs)
                } else {
                    0
                };
                self.u_sub[j] = self.history.get(lag).map_or(0.0, |v| v[j]);
            }
            self.tmp.gemv(1.0, &self.ad, &self.x, 0.0);
            self.tmp.gemv(1.0, &self.bd, &self.u_sub, 1.0);
            std::mem::swap(&mut self.tmp, &mut self.x);
            let y1 = &self.c * &self.x;
            for (i, w) in self.window_subs.iter().enumerate() {
                if *w > 0 && s + w >= self.subs {
                    integral[i] += 0.5 * (y0[i] + y1[i]) * self.dt;
                }
            }
            y0 = y1;
        }
        for (i, w) in self.window_subs.iter().enumerate() {
            if *w > 0 {
                self.avg[i] = integral[i] / (*w as f64 * self.dt);
            }
        }
    }

    /// The measurements at the current sample instant (one per sensor).
    pub(crate) fn measure(&self) -> DVector<f64> {
        let now = &self.c * &self.x;
        DVector::from_fn(self.c.nrows(), |i, _| {
            if self.window_subs[i] > 0 {
                self.avg[i]
            } else {
                now[i]
            }
        })
    }
}
