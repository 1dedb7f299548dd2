//! Time-domain comparison: the measured input through the model against the measured output.
//!
//! For a periodic experiment the steady periods are averaged (noise down by √P), and the model's
//! periodic steady-state response to the averaged input period is computed exactly by the DFT:
//! `ŷ = IDFT(P(k f₀) U_k)` for every bin `0 < k ≤ N/2` (conjugate symmetric). The DC bin is the
//! measured mean (a rigid-body plant has no finite DC gain, and a periodic record fixes no
//! absolute position). No initial state is needed: both signals are steady periodic. The noise
//! floor of the averaged output is `sqrt(mean_n var_p(y)/P)`, from the spread between periods.

use crate::{DiagnoseError, Result};
use num_complex::Complex64 as C;
use rustfft::FftPlanner;
use sd_ident::Experiment;

/// One averaged steady period of an experiment.
#[derive(Debug, Clone)]
pub struct AveragedPeriod {
    /// Sample rate (Hz).
    pub rate_hz: f64,
    /// Averaged input period.
    pub u: Vec<f64>,
    /// Averaged output period.
    pub y: Vec<f64>,
    /// Rms noise of the averaged output.
    pub noise_rms: f64,
}

impl AveragedPeriod {
    /// The steady periods of a periodic experiment, averaged; `None` for a non-periodic one or
    /// one with fewer than two steady periods.
    pub fn of(e: &Experiment) -> Option<Self> {
        let n = e.spec.period_samples?;
        let total = e.u.len() / n.max(1);
        let skip = e.spec.skip_periods;
        let p = total.checked_sub(skip)?;
        if n == 0 || p < 2 {
            return None;
        }
        let mean = |x: &[f64]| -> Vec<f64> {
            (0..n)
                .map(|i| (skip..total).map(|q| x[q * n + i]).sum::<f64>() / p as f64)
                .collect()
        };
        let u = mean(&e.u);
        let y = mean(&e.y);
        let var: f64 = (0..n)
            .map(|i| {
                (skip..total)
                    .map(|q| (e.y[q * n + i] - y[i]).powi(2))
                    .sum::<f64>()
                    / (p - 1) as f64
            })
            .sum::<f64>()
            / n as f64;
        Some(AveragedPeriod {
            rate_hz: e.spec.sample_rate_hz,
            u,
            y,
            noise_rms: (var / p as f64).sqrt(),
        })
    }

    /// The DFT bin frequencies `k f₀`, `0 < k ≤ N/2`.
    pub fn bins_hz(&self) -> Vec<f64> {
        let n = self.u.len();
        (1..=n / 2)
            .map(|k| k as f64 * self.rate_hz / n as f64)
            .collect()
    }

    /// The periodic response to the averaged input of a model given by its response at
    /// [`Self::bins_hz`].
    ///
    /// # Errors
    /// A response of the wrong length.
    pub fn simulate(&self, response: &[C]) -> Result<Vec<f64>> {
        let n = self.u.len();
        if response.len() != n / 2 {
            return Err(DiagnoseError::Setup(format!(
                "{} responses for {} DFT bins",
                response.len(),
                n / 2
            )));
        }
        let mut planner = FftPlanner::<f64>::new();
        let mut buf: Vec<C> = self.u.iter().map(|&x| C::new(x, 0.0)).collect();
        planner.plan_fft_forward(n).process(&mut buf);
        let mut out = vec![C::new(0.0, 0.0); n];
        out[0] = C::new(self.y.iter().sum::<f64>(), 0.0);
        for k in 1..=n / 2 {
            let v = response[k - 1] * buf[k];
            if 2 * k == n {
                out[k] = C::new(v.re, 0.0);
            } else {
                out[k] = v;
                out[n - k] = v.conj();
            }
        }
        planner.plan_fft_inverse(n).process(&mut out);
        Ok(out.iter().map(|c| c.re / n as f64).collect())
    }

    /// Rms of the output around its mean.
    pub fn output_rms(&self) -> f64 {
        let m = self.y.iter().sum::<f64>() / self.y.len().max(1) as f64;
        rms(self.y.iter().map(|y| y - m))
    }

    /// Rms of `y − ŷ`.
    pub fn error_rms(&self, sim: &[f64]) -> f64 {
        rms(self.y.iter().zip(sim).map(|(a, b)| a - b))
    }
}

fn rms(x: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = x.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    (s / n.max(1) as f64).sqrt()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A periodic input through a first-order filter: the DFT simulation equals the steady
    /// state of the recursion (run long enough that the transient is gone).
    #[test]
    fn equals_the_steady_state_of_the_recursion() {
        let n = 64;
        let u: Vec<f64> = (0..n).map(|i| ((i * 7 % 13) as f64 - 6.0) / 6.0).collect();
        let a = 0.8;
        let mut x = 0.0;
        let mut y = vec![0.0; n];
        for rep in 0..200 {
            for i in 0..n {
                // y_k = x_k, x_{k+1} = a x_k + u_k: P(z) = 1/(z − a)
                if rep == 199 {
                    y[i] = x;
                }
                x = a * x + u[i];
            }
        }
        let per = AveragedPeriod {
            rate_hz: 1.0,
            u: u.clone(),
            y: y.clone(),
            noise_rms: 0.0,
        };
        let resp: Vec<C> = per
            .bins_hz()
            .iter()
            .map(|f| 1.0 / (C::from_polar(1.0, 2.0 * std::f64::consts::PI * f) - a))
            .collect();
        let sim = per.simulate(&resp).unwrap();
        let err = per.error_rms(&sim);
        assert!(err < 1e-12 * per.output_rms().max(1.0), "{err}");
    }
}
