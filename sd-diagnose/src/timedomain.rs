//! Time-domain comparison: the measured input through the model against the measured output.
//!
//! For a periodic experiment the steady periods are averaged (noise down by √P), and the model's
//! periodic steady-state response to the averaged input period is computed exactly by the DFT:
//! `ŷ = IDFT(P(k f₀) U_k)`. No initial state is needed: both signals are steady periodic.
//!
//! Only the bins where the measured input is known — its period average exceeds three times its
//! standard error across periods — enter, in the simulation and in the measured output alike
//! (the DC bin is the measured mean). Elsewhere the input is mostly an unmeasured disturbance
//! that the loop cancels: in closed loop `u ≈ −d` at low frequencies, and a rigid body turns
//! that into a large simulated drift the real output, driven by `u + d`, does not have.
//!
//! The noise floor of the comparison comes from the spread between periods of the residual
//! itself, `E_k = Y_k − P_k U_k` per period: `sqrt((2/N²) Σ_bins var_p(E_k)/P)`. It includes
//! the measured input's noise through the model (what an unmeasured force leaves in `u`), so a
//! right model reaches it and a wrong one stays above it.

use crate::{DiagnoseError, Result};
use num_complex::Complex64 as C;
use rustfft::FftPlanner;
use sd_ident::Experiment;
use sd_model::rms_of as rms;

/// One averaged steady period of an experiment, restricted to the bins where the input is
/// measured.
#[derive(Debug, Clone)]
pub struct AveragedPeriod {
    /// Sample rate (Hz).
    pub rate_hz: f64,
    /// Period length N.
    n: usize,
    /// Averaged input spectrum, bins 0..=N/2.
    u: Vec<C>,
    /// Per-period input and output spectra on the used bins.
    per_u: Vec<Vec<C>>,
    per_y: Vec<Vec<C>>,
    /// Bins `1..=N/2` used (input above 3 standard errors).
    used: Vec<usize>,
    /// The averaged output on the used bins (and its mean).
    pub y: Vec<f64>,
}

fn spectra(x: &[f64], n: usize, skip: usize, total: usize) -> Vec<Vec<C>> {
    let mut planner = FftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(n);
    (skip..total)
        .map(|q| {
            let mut buf: Vec<C> = x[q * n..(q + 1) * n]
                .iter()
                .map(|&v| C::new(v, 0.0))
                .collect();
            fft.process(&mut buf);
            buf.truncate(n / 2 + 1);
            buf
        })
        .collect()
}

/// Mean and variance of the mean, per bin, over periods.
fn mean_var(s: &[Vec<C>]) -> (Vec<C>, Vec<f64>) {
    let p = s.len() as f64;
    let m: Vec<C> = (0..s[0].len())
        .map(|k| s.iter().map(|x| x[k]).sum::<C>() / p)
        .collect();
    let v: Vec<f64> = (0..s[0].len())
        .map(|k| s.iter().map(|x| (x[k] - m[k]).norm_sqr()).sum::<f64>() / (p - 1.0) / p)
        .collect();
    (m, v)
}

fn inverse(n: usize, half: &[C]) -> Vec<f64> {
    let mut out = vec![C::new(0.0, 0.0); n];
    for (k, &v) in half.iter().enumerate() {
        if k == 0 || 2 * k == n {
            out[k] = C::new(v.re, 0.0);
        } else {
            out[k] = v;
            out[n - k] = v.conj();
        }
    }
    FftPlanner::<f64>::new()
        .plan_fft_inverse(n)
        .process(&mut out);
    out.iter().map(|c| c.re / n as f64).collect()
}

impl AveragedPeriod {
    /// The steady periods of a periodic experiment, averaged; `None` for a non-periodic one or
    /// one with fewer than two steady periods.
    pub fn of(e: &Experiment) -> Option<Self> {
        let n = e.spec.period_samples?;
        let total = e.u.len() / n.max(1);
        let skip = e.spec.skip_periods;
        let p = total.checked_sub(skip)?;
        if n < 2 || p < 2 {
            return None;
        }
        let su = spectra(&e.u, n, skip, total);
        let sy = spectra(&e.y, n, skip, total);
        let (u, uv) = mean_var(&su);
        let (y, _) = mean_var(&sy);
        let used: Vec<usize> = (1..=n / 2)
            .filter(|&k| u[k].norm_sqr() > 9.0 * uv[k])
            .collect();
        let mut yh = vec![C::new(0.0, 0.0); n / 2 + 1];
        yh[0] = y[0];
        for &k in &used {
            yh[k] = y[k];
        }
        let pick = |s: &[Vec<C>]| -> Vec<Vec<C>> {
            s.iter()
                .map(|x| used.iter().map(|&k| x[k]).collect())
                .collect()
        };
        Some(AveragedPeriod {
            rate_hz: e.spec.sample_rate_hz,
            n,
            u,
            per_u: pick(&su),
            per_y: pick(&sy),
            y: inverse(n, &yh),
            used,
        })
    }

    /// Rms noise of `y − ŷ` for a model given by its response at [`Self::bins_hz`], from the
    /// spread of the per-period residual spectra.
    pub fn noise_rms(&self, response: &[C]) -> f64 {
        self.band_rms(response, &|_| true).1
    }

    /// Rms of `y − ŷ` and its noise, counting only the bins whose frequency satisfies `keep`
    /// (Parseval on the averaged and per-period residual spectra).
    pub fn band_rms(&self, response: &[C], keep: &dyn Fn(f64) -> bool) -> (f64, f64) {
        let f0 = self.rate_hz / self.n as f64;
        let w = |k: usize| if 2 * k == self.n { 1.0 } else { 2.0 };
        let nn = (self.n * self.n) as f64;
        let mut err = 0.0;
        for (j, &k) in self.used.iter().enumerate() {
            if keep(k as f64 * f0) {
                let mean_y = self.per_y.iter().map(|y| y[j]).sum::<C>() / self.per_y.len() as f64;
                err += w(k) * (mean_y - response[j] * self.u[k]).norm_sqr();
            }
        }
        (err.sqrt() / nn.sqrt(), self.noise_in(response, keep))
    }

    fn noise_in(&self, response: &[C], keep: &dyn Fn(f64) -> bool) -> f64 {
        let f0 = self.rate_hz / self.n as f64;
        let per: Vec<Vec<C>> = self
            .per_u
            .iter()
            .zip(&self.per_y)
            .map(|(u, y)| {
                y.iter()
                    .zip(u)
                    .zip(response)
                    .map(|((y, u), r)| y - r * u)
                    .collect()
            })
            .collect();
        if per.len() < 2 || self.used.is_empty() {
            return 0.0;
        }
        let (_, v) = mean_var(&per);
        let ms: f64 = self
            .used
            .iter()
            .zip(&v)
            .filter(|(&k, _)| keep(k as f64 * f0))
            .map(|(&k, v)| if 2 * k == self.n { 1.0 } else { 2.0 } * v)
            .sum();
        (ms / (self.n * self.n) as f64).sqrt()
    }

    /// The frequencies of the bins used (Hz).
    pub fn bins_hz(&self) -> Vec<f64> {
        self.used
            .iter()
            .map(|&k| k as f64 * self.rate_hz / self.n as f64)
            .collect()
    }

    /// The periodic response to the averaged input of a model given by its response at
    /// [`Self::bins_hz`] (the DC bin is the measured mean).
    ///
    /// # Errors
    /// A response of the wrong length.
    pub fn simulate(&self, response: &[C]) -> Result<Vec<f64>> {
        if response.len() != self.used.len() {
            return Err(DiagnoseError::Setup(format!(
                "{} responses for {} DFT bins",
                response.len(),
                self.used.len()
            )));
        }
        let mut half = vec![C::new(0.0, 0.0); self.n / 2 + 1];
        half[0] = C::new(self.y.iter().sum::<f64>(), 0.0);
        for (&k, r) in self.used.iter().zip(response) {
            half[k] = r * self.u[k];
        }
        Ok(inverse(self.n, &half))
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

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A periodic input through a first-order filter: the DFT simulation equals the steady
    /// state of the recursion (run long enough that the transient is gone).
    #[test]
    fn equals_the_steady_state_of_the_recursion() {
        let n = 64;
        let per_u: Vec<f64> = (0..n).map(|i| ((i * 7 % 13) as f64 - 6.0) / 6.0).collect();
        let a = 0.8;
        let mut x = 0.0;
        let (mut u, mut y) = (Vec::new(), Vec::new());
        for rep in 0..200 {
            for i in 0..n {
                // y_k = x_k, x_{k+1} = a x_k + u_k: P(z) = 1/(z − a); a little noise on the
                // recorded output of the last periods
                if rep >= 196 {
                    u.push(per_u[i]);
                    y.push(x + 1e-9 * (((rep * n + i) * 2654435761usize % 1000) as f64 - 500.0));
                }
                x = a * x + per_u[i];
            }
        }
        let spec = sd_ident::ExperimentSpec {
            name: "t".into(),
            file: "t.csv".into(),
            sample_rate_hz: 1.0,
            period_samples: Some(n),
            skip_periods: 0,
            reference: None,
            input: "u".into(),
            output: "y".into(),
            role: sd_ident::Role::Validation,
            extra: Default::default(),
        };
        let e = Experiment {
            spec,
            r: None,
            u,
            y,
            extra: Default::default(),
        };
        let per = AveragedPeriod::of(&e).unwrap();
        let resp: Vec<C> = per
            .bins_hz()
            .iter()
            .map(|f| 1.0 / (C::from_polar(1.0, 2.0 * std::f64::consts::PI * f) - a))
            .collect();
        let sim = per.simulate(&resp).unwrap();
        let err = per.error_rms(&sim);
        let noise = per.noise_rms(&resp);
        assert!(
            err < 3.0 * noise && err > 0.3 * noise,
            "{err} vs noise {noise}"
        );
        assert!(noise > 0.0 && noise < 1e-6);
        // a wrong model misses
        let wrong: Vec<C> = resp.iter().map(|r| r * 1.1).collect();
        assert!(per.error_rms(&per.simulate(&wrong).unwrap()) > 0.05 * per.output_rms());
    }
}

/// Time-domain comparison of a non-periodic record: the measured input through a discrete model
/// from the least-squares initial state.
///
/// `ŷ = y_forced + O x₀` with `y_forced` the zero-state response and `O_k = C A^k`; `x₀`
/// minimizes `‖y − ŷ‖` (columns of O scaled to unit norm, SVD with rank cut `1e-10·σ_max`, so a
/// rigid body's growing rows are harmless). Returns the simulated output.
///
/// # Errors
/// A continuous model, signals of different lengths, non-finite samples.
pub fn simulate_record(model: &sd_model::StateSpace, u: &[f64], y: &[f64]) -> Result<Vec<f64>> {
    use nalgebra::{DMatrix, DVector};
    if u.len() != y.len() {
        return Err(DiagnoseError::Setup(format!(
            "input ({}) and output ({}) have different lengths",
            u.len(),
            y.len()
        )));
    }
    let forced = model.simulate(&DMatrix::from_column_slice(u.len(), 1, u), None)?;
    let n = model.n();
    let mut yf: Vec<f64> = forced.y.column(0).iter().copied().collect();
    if n == 0 || u.is_empty() {
        return Ok(yf);
    }
    let m = u.len();
    let mut o = DMatrix::zeros(m, n);
    let mut row = model.c().row(0).clone_owned();
    for k in 0..m {
        o.row_mut(k).copy_from(&row);
        row = &row * model.a();
    }
    if !o.iter().all(|v| v.is_finite()) {
        // an unstable model over a long record: no initial-state fit, zero state
        return Ok(yf);
    }
    let r = DVector::from_iterator(m, y.iter().zip(&yf).map(|(a, b)| a - b));
    if let Ok(ls) = sd_model::linalg::lstsq(&o, &r) {
        let free = &o * ls.x;
        for (a, b) in yf.iter_mut().zip(free.iter()) {
            *a += b;
        }
    }
    Ok(yf)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod record_tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// A record that starts from an unknown state (a rigid body plus two modes): the
    /// least-squares initial state makes the simulation exact; the zero state does not.
    #[test]
    fn initial_state_is_recovered() {
        let p = sd_model::stage::paper_stage_two_modes().unwrap();
        let pd = sd_model::c2d(&p, 1e-3, sd_model::Discretization::Zoh).unwrap();
        let m = 3000;
        let u: Vec<f64> = (0..m)
            .map(|k| ((k * 37 % 101) as f64 - 50.0) / 50.0)
            .collect();
        let x0 = DVector::from_iterator(pd.n(), (0..pd.n()).map(|i| 1e-4 * (i as f64 + 1.0)));
        let run = |x: Option<&DVector<f64>>| -> Vec<f64> {
            pd.simulate(&DMatrix::from_column_slice(m, 1, &u), x)
                .unwrap()
                .y
                .column(0)
                .iter()
                .copied()
                .collect()
        };
        let y = run(Some(&x0));
        let sim = simulate_record(&pd, &u, &y).unwrap();
        let scale = y.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let worst = |a: &[f64]| {
            y.iter()
                .zip(a)
                .fold(0.0f64, |w, (p, q)| w.max((p - q).abs()))
        };
        assert!(worst(&sim) < 1e-9 * scale, "{} of {scale}", worst(&sim));
        assert!(worst(&run(None)) > 1e-3 * scale);
    }
}
