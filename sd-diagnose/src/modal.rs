//! The continuous-time modal model behind the rate-tied extensions.
//!
//! A delayed hold or an averaging sampler acts between the samples, so its exact effect on a
//! slower experiment needs the plant between the fast samples: a continuous model. The fast
//! discrete model's poles give it: a pole `z` maps to `s = ln(z)/h` (the principal branch;
//! the fast data cannot see modes above their own Nyquist frequency), poles at `z = 1` to the
//! rigid-body basis `{1/s, 1/s²}`, and a feedthrough is kept as a constant. Negative real poles
//! and poles near the origin (`|z| < 0.05`, what a fit uses to mimic a fractional delay) have
//! no continuous counterpart and are dropped: under the right hypothesis the delay is part of
//! the discretisation instead.
//!
//! Every basis function is one output of one continuous model
//! `ẋ = blockdiag(…) x + b u`, `φ = [I; 0] x + [0; 1] u` (rigid body as a 1/s² chain, a real
//! pole as 1/(s − p), a pair as `[[σ, ω], [−ω, σ]]`, whose two states span
//! `{(s − σ), ω}/((s − σ)² + ω²)`). Under a hypothesis θ (hold delay α or window β) each
//! experiment's basis responses are that model discretised exactly at the experiment's own
//! period with [`sd_multirate::c2d_nonideal`], so the plant `P = Σ r_j φ_j` is linear in the
//! real residues `r`. They are fitted to the fast FRF by weighted least squares
//! (`min Σ |G − Σ r_j φ_j^h|²/σ²`, columns scaled to unit norm, SVD with rank cut at
//! `1e-10·σ_max`), which gives their covariance `(JᵀWJ)⁻¹` and so the variance of every
//! prediction `Σ r_j φ_j^T(f)`. A hypothesis is judged by how well the fast data, discretised
//! its way, predict the slow data.

use crate::{DiagnoseError, Result};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64 as C;
use sd_model::{Frd, SampleTime, StateSpace};
use sd_multirate::{c2d_nonideal, NonIdeal};

/// Poles with `|s·h|` below this are rigid-body poles.
const RIGID_SH: f64 = 1e-4;
/// Poles with `|z|` below this are dropped (delay-like).
const MIN_ABS_Z: f64 = 0.05;

/// The continuous basis model (1 input, one output per basis function).
#[derive(Debug, Clone)]
pub(crate) struct ModalBasis {
    sys: StateSpace,
}

impl ModalBasis {
    /// From the poles of a model at period `h` (`None`: continuous poles).
    pub(crate) fn from_model(model: &StateSpace) -> Result<Self> {
        let poles = model.poles()?;
        let ct: Vec<C> = match model.ts() {
            Some(h) => poles
                .iter()
                .filter(|z| z.norm() >= MIN_ABS_Z)
                .filter(|z| !(z.re < 0.0 && z.im.abs() <= 1e-9 * z.norm()))
                .map(|z| z.ln() / h)
                .collect(),
            None => poles,
        };
        let scale = model.ts().unwrap_or(1.0);
        let mut rigid = 0usize;
        let mut real = Vec::new();
        let mut pairs = Vec::new();
        for s in ct {
            if (s * scale).norm() < RIGID_SH && rigid < 2 {
                rigid += 1;
            } else if s.im.abs() <= 1e-9 * s.norm().max(1e-300) {
                real.push(s.re);
            } else if s.im > 0.0 {
                pairs.push(s);
            }
        }
        Self::build(rigid, &real, &pairs)
    }

    fn build(rigid: usize, real: &[f64], pairs: &[C]) -> Result<Self> {
        let n = rigid + real.len() + 2 * pairs.len();
        let mut a = DMatrix::zeros(n, n);
        let mut b = DMatrix::zeros(n, 1);
        let mut i = 0;
        match rigid {
            1 => {
                b[(0, 0)] = 1.0;
                i = 1;
            }
            2 => {
                a[(0, 1)] = 1.0;
                b[(1, 0)] = 1.0;
                i = 2;
            }
            _ => {}
        }
        for &p in real {
            a[(i, i)] = p;
            b[(i, 0)] = 1.0;
            i += 1;
        }
        for p in pairs {
            a[(i, i)] = p.re;
            a[(i + 1, i + 1)] = p.re;
            a[(i, i + 1)] = p.im;
            a[(i + 1, i)] = -p.im;
            b[(i, 0)] = 1.0;
            i += 2;
        }
        let mut c = DMatrix::zeros(n + 1, n);
        for k in 0..n {
            c[(k, k)] = 1.0;
        }
        let mut d = DMatrix::zeros(n + 1, 1);
        d[(n, 0)] = 1.0;
        Ok(ModalBasis {
            sys: StateSpace::new(a, b, c, d, SampleTime::Continuous)?,
        })
    }

    /// The basis responses at period `ts` under `ni`, at `freq_hz`: one row per frequency.
    pub(crate) fn responses(&self, ts: f64, ni: NonIdeal, freq_hz: &[f64]) -> Result<Vec<Vec<C>>> {
        let d = c2d_nonideal(&self.sys, ts, ni).map_err(|e| DiagnoseError::Setup(e.to_string()))?;
        let ev = sd_model::FreqRespEvaluator::new(&d)?;
        Ok(freq_hz
            .iter()
            .map(|&f| ev.eval_hz(f).column(0).iter().copied().collect())
            .collect())
    }

    /// The discrete model `Σ r_j φ_j` at period `ts` under `ni`.
    pub(crate) fn model(&self, r: &[f64], ts: f64, ni: NonIdeal) -> Result<StateSpace> {
        let d = c2d_nonideal(&self.sys, ts, ni).map_err(|e| DiagnoseError::Setup(e.to_string()))?;
        let row = DMatrix::from_row_slice(1, r.len(), r);
        Ok(StateSpace::new(
            d.a().clone(),
            d.b().clone(),
            &row * d.c(),
            &row * d.d(),
            d.time(),
        )?)
    }
}

/// Residues fitted to an FRF, with their covariance.
#[derive(Debug, Clone)]
pub(crate) struct Residues {
    pub(crate) r: Vec<f64>,
    cov: DMatrix<f64>,
    /// Mean normalized squared residual of the fit on its own data.
    pub(crate) chi2: f64,
}

impl Residues {
    /// Weighted least squares of `frd ≈ Σ r_j φ_j` (rows of `phi` per line of `frd`); lines
    /// without a positive variance are skipped.
    pub(crate) fn fit(frd: &Frd, phi: &[Vec<C>]) -> Result<Self> {
        let var = frd.variance().ok_or_else(|| {
            DiagnoseError::Setup("the model experiment's FRF has no variance".into())
        })?;
        let nb = phi.first().map(|p| p.len()).unwrap_or(0);
        let rows: Vec<usize> = (0..frd.len()).filter(|&i| var[i][(0, 0)] > 0.0).collect();
        if rows.len() < nb || nb == 0 {
            return Err(DiagnoseError::Setup(format!(
                "{} lines with variance for {nb} modal residues",
                rows.len()
            )));
        }
        let m = 2 * rows.len();
        let mut j = DMatrix::zeros(m, nb);
        let mut g = DVector::zeros(m);
        for (k, &i) in rows.iter().enumerate() {
            let w = 1.0 / var[i][(0, 0)].sqrt();
            let y = frd.response()[i][(0, 0)];
            g[2 * k] = w * y.re;
            g[2 * k + 1] = w * y.im;
            for c in 0..nb {
                j[(2 * k, c)] = w * phi[i][c].re;
                j[(2 * k + 1, c)] = w * phi[i][c].im;
            }
        }
        let scale: Vec<f64> = (0..nb)
            .map(|c| {
                let s = j.column(c).norm();
                if s > 0.0 && s.is_finite() {
                    s
                } else {
                    1.0
                }
            })
            .collect();
        for c in 0..nb {
            let s = scale[c];
            j.column_mut(c).scale_mut(1.0 / s);
        }
        let svd = j.clone().svd(true, true);
        let (Some(u), Some(vt)) = (svd.u.as_ref(), svd.v_t.as_ref()) else {
            return Err(DiagnoseError::Setup("SVD of the residue fit failed".into()));
        };
        let smax = svd.singular_values.max();
        if !(smax.is_finite() && smax > 0.0) {
            return Err(DiagnoseError::Setup(
                "the modal basis has no finite response on the model experiment's lines".into(),
            ));
        }
        let mut x = DVector::zeros(nb);
        let mut cov = DMatrix::zeros(nb, nb);
        for (k, &sv) in svd.singular_values.iter().enumerate() {
            if sv > 1e-10 * smax {
                let v = vt.row(k).transpose();
                x += &v * (u.column(k).dot(&g) / sv);
                cov += &v * v.transpose() / (sv * sv);
            }
        }
        let res = &g - &j * &x;
        let r: Vec<f64> = (0..nb).map(|c| x[c] / scale[c]).collect();
        for a in 0..nb {
            for b in 0..nb {
                cov[(a, b)] /= scale[a] * scale[b];
            }
        }
        Ok(Residues {
            r,
            cov,
            chi2: res.norm_squared() / rows.len() as f64,
        })
    }

    /// The prediction `Σ r_j φ_j` and its variance.
    pub(crate) fn predict(&self, phi: &[C]) -> (C, f64) {
        let p = phi.iter().zip(&self.r).map(|(f, r)| f * *r).sum();
        let nb = self.r.len();
        let re = DVector::from_iterator(nb, phi.iter().map(|f| f.re));
        let im = DVector::from_iterator(nb, phi.iter().map(|f| f.im));
        let var =
            (re.transpose() * &self.cov * &re)[(0, 0)] + (im.transpose() * &self.cov * &im)[(0, 0)];
        (p, var.max(0.0))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// The basis spans the paper's two-mode stage exactly: its residue fit on noise-free
    /// delayed-hold data at 5 kHz predicts the 1 kHz delayed-hold FRF to rounding.
    #[test]
    fn exact_on_a_modal_plant_under_a_delayed_hold() {
        let p = sd_model::stage::paper_stage_two_modes().unwrap();
        let ni = NonIdeal::hold_delay(0.37);
        let fast = c2d_nonideal(&p, 2e-4, ni).unwrap();
        let slow = c2d_nonideal(&p, 1e-3, ni).unwrap();
        let basis = ModalBasis::from_model(
            &sd_model::c2d(&p, 2e-4, sd_model::Discretization::Zoh).unwrap(),
        )
        .unwrap();
        let ff: Vec<f64> = (1..2500).map(|k| k as f64).collect();
        let fs: Vec<f64> = (1..500).map(|k| k as f64 + 0.5).collect();
        let g = fast.freqresp(&ff).unwrap();
        let var = g
            .response()
            .iter()
            .map(|r| DMatrix::from_element(1, 1, 1e-6 * r[(0, 0)].norm_sqr()))
            .collect();
        let g = Frd::new(ff.clone(), g.response().to_vec(), Some(var), g.time()).unwrap();
        let res = Residues::fit(&g, &basis.responses(2e-4, ni, &ff).unwrap()).unwrap();
        let phi = basis.responses(1e-3, ni, &fs).unwrap();
        let want = slow.freqresp(&fs).unwrap();
        let worst = phi
            .iter()
            .zip(want.response())
            .map(|(ph, w)| ((res.predict(ph).0 - w[(0, 0)]) / w[(0, 0)]).norm())
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{worst}");
        assert!(res.chi2 < 1e-6, "{}", res.chi2);
    }
}
