//! Nonlinearity as a model: modal frequencies and dampings as functions of the amplitude each
//! mode is driven at.
//!
//! **Per level.** Every experiment at the model experiment's rate is one level. Its FRF is
//! fitted with the linear model's continuous modal basis ([`crate::modal`]) whose in-band pole
//! pairs are free: Gauss–Newton on residues and pole parameters `(σ, ω)` together (variable
//! projection for the line search: the residues are re-solved by weighted least squares at
//! every trial), from the linear poles. The covariance of the poles is the Gauss–Newton
//! `(JᵀWJ)⁻¹`, widened for estimated weights (`ν/(ν − 2)`, line correlation) and by the
//! level's misfit when above 1. Each pair gives a natural frequency `f = |s|/2π` and damping
//! `ζ = −σ/|s|` with standard errors (first-order propagation).
//!
//! **Amplitude.** A mode's amplitude in an experiment is the rms of the measured output in the
//! mode's band (`f(1 ± max(3ζ, 2 %))`), from the DFT of the steady record; a friction-damped
//! rigid body's corner's is the output's rms velocity below `B` = three times the linear
//! corner, over the square root of the share `(2/π)·atan(B/f_c)` a first-order velocity
//! spectrum keeps below `B` at the level's corner `f_c` ([`mode_amplitude`]); the trend uses
//! it relative to the model experiment's, `ρ = a/a_ref`. A level fit measures it around its
//! fitted pole; a level the trends predict is measured self-consistently around the pole
//! predicted at that amplitude ([`AmplitudeModel::amplitudes`]).
//!
//! **Trend.** Per mode and quantity `p(ρ) = p_ref + c·(ρ^k − 1)` by weighted least squares over
//! the levels, with `k ∈ {2, 1, −1}` chosen by the weighted residual (with two levels, where
//! every `k` fits exactly, `k = 2`: the backbone of a cubic stiffness, `ω² ≈ ω₀²(1 + ¾κA²)`).
//! A friction-damped corner `f_c = a + b·ρ^k` has `a, b ≥ 0` (non-negative least squares,
//! [`trend_fit`]) and `k = −1` by default: Coulomb friction under a Gaussian-like velocity of
//! rms σ acts as the viscous `c_eq = √(2/π)F_c/σ` (Bussgang). A mode *moves* when its
//! frequencies (or dampings) over the levels differ beyond their errors (χ² with
//! `levels − 1` degrees of freedom at the verdict's α, Bonferroni over the modes); modes that
//! do not move keep their linear poles.
//!
//! **Prediction of a level** from the trend at that level's measured amplitudes: the moving
//! poles from the trend, the others linear, the residues fitted jointly to the training levels
//! (each with its own poles). Its variance carries the residues' covariance and the trend's.

use crate::data::Estimate;
use crate::lemma6::{compare, Pred};
use crate::modal::{ModalBasis, Residues};
use crate::stats::{statistic, threshold, Line};
use crate::{
    CornerTrend, DampingTrend, DiagnoseError, FreqTrend, ModePoint, MovingMode, PoleKind, Result,
    Trend,
};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64 as C;
use sd_ident::Experiment;
use sd_model::linalg::lstsq;
use sd_model::normal_quantile;
use sd_model::StateSpace;
use sd_multirate::NonIdeal;
use std::f64::consts::TAU;

/// Exponents tried for a trend, the default first.
const EXPONENTS: [i32; 3] = [2, 1, -1];
/// Largest relative frequency shift an amplitude is sought at
/// ([`AmplitudeModel::amplitudes`]).
const MAX_SHIFT: f64 = 0.25;
/// Largest ratio between a self-consistent amplitude and the force's estimate of it for the
/// former to be taken ([`AmplitudeModel::amplitudes`]).
const FORCE_AGREEMENT: f64 = 1.5;
/// Gauss–Newton iterations of a level fit.
const GN_ITERATIONS: usize = 20;

/// One excitation level at the model experiment's rate.
pub(crate) struct Level<'a> {
    pub(crate) name: String,
    pub(crate) exp: &'a Experiment,
    pub(crate) est: &'a Estimate,
}

/// One level's modal fit.
#[derive(Clone, Debug)]
pub(crate) struct LevelFit {
    /// Natural frequency (Hz) and damping of each candidate with their standard errors.
    modal: Vec<(f64, f64, f64, f64)>,
    /// Mode amplitudes (rms of the output in each candidate's band).
    amplitude: Vec<f64>,
    /// The linear basis's frequency and damping of each candidate.
    linear: Vec<(f64, f64, f64, f64)>,
}

impl LevelFit {
    /// Whether this fit determines candidate `m` (in the order of the candidates).
    pub(crate) fn determines(&self, m: usize) -> bool {
        self.modal
            .get(m)
            .zip(self.linear.get(m))
            .is_some_and(|(f, l)| determined(*f, *l))
    }

    /// Whether this fit — of the model experiment, the data the linear model was fitted to —
    /// finds pair `m` where the linear model has it: its frequency within its half-power
    /// half-width `ζf` and its damping within a factor 2 (or within three standard errors). A
    /// pair the free fit moves further on the very data it came from is not determined by
    /// them (a spurious pair of an order chosen for the whole band), and its trend over the
    /// levels would be noise. A friction corner is not held to this: the damped rigid body
    /// ([`ModalBasis::with_damped_rigid_body`]) is not the fit's own pole, and the reference
    /// level's fit places it.
    pub(crate) fn agrees_with_linear(&self, m: usize) -> bool {
        let (Some(&(f, z, sf, sz)), Some(&(fl, zl, _, _))) =
            (self.modal.get(m), self.linear.get(m))
        else {
            return false;
        };
        let near = |x: f64, lin: f64, sd: f64| {
            (x / lin).ln().abs() <= 2f64.ln() || (x - lin).abs() <= 3.0 * sd
        };
        is_real_pole(zl)
            || (((f - fl).abs() <= zl * fl || (f - fl).abs() <= 3.0 * sf) && near(z, zl, sz))
    }
}

/// The fitted amplitude-dependent model.
#[derive(Clone, Debug)]
pub(crate) struct AmplitudeModel {
    pub(crate) basis: ModalBasis,
    pub(crate) h: f64,
    /// Candidate pair indices.
    pub(crate) cand: Vec<usize>,
    /// Per candidate: frequency and damping trends, and whether each moves.
    pub(crate) trends: Vec<(Trend, Trend, bool, bool)>,
    /// Reference amplitude per candidate (the model experiment's).
    pub(crate) reference: Vec<f64>,
    /// The reference experiment's input rms in each candidate's linear band.
    pub(crate) reference_force: Vec<f64>,
    /// Per candidate, every fitted level's (force ratio, amplitude ratio): how much the mode
    /// responds per force at each level.
    pub(crate) per_force: Vec<Vec<(f64, f64)>>,
    /// Per candidate, the lowest and highest relative amplitude of the fitted levels.
    pub(crate) range: Vec<(f64, f64)>,
    /// Residues common to the levels (set by [`AmplitudeModel::fit`]).
    pub(crate) residues: Option<Residues>,
}

/// Weighted rows of a modal fit: `(line, 1/σ)` for lines with a variance.
fn rows(est: &Estimate) -> Vec<(usize, f64)> {
    est.frd.variance().map_or_else(Vec::new, |v| {
        (0..est.frd.len())
            .filter(|&i| v[i][(0, 0)] > 0.0)
            .map(|i| (i, 1.0 / v[i][(0, 0)].sqrt()))
            .collect()
    })
}

/// Weighted cost `Σ |G − Φ r|²/σ²` and the residues of a basis on an estimate.
fn project(basis: &ModalBasis, h: f64, est: &Estimate) -> Result<(f64, Residues)> {
    let f = est.frd.freq_hz();
    let phi = basis.responses(h, NonIdeal::ideal(), f)?;
    let res = Residues::fit(&est.frd, &phi)?;
    let cost = rows(est)
        .iter()
        .map(|&(i, w)| {
            let p: C = phi[i].iter().zip(&res.r).map(|(a, b)| a * *b).sum();
            (w * (est.frd.response()[i][(0, 0)] - p)).norm_sqr()
        })
        .sum();
    Ok((cost, res))
}

/// How well `basis` (its poles fixed, its residues fitted to the level) describes a level:
/// the verdict's statistic on the level's lines at `alpha`.
pub(crate) fn describes(
    basis: &ModalBasis,
    h: f64,
    lv: &Level<'_>,
    alpha: f64,
) -> Result<crate::stats::Statistic> {
    let phi = basis.responses(h, NonIdeal::ideal(), lv.est.frd.freq_hz())?;
    let res = Residues::fit(&lv.est.frd, &phi)?;
    let lines = predicted_lines(lv.est, &phi, &res);
    Ok(statistic([(lines.as_slice(), lv.est.inflation)], alpha))
}

/// The statistic of a level's own modal fit on its lines inside `bands` (all lines when
/// there are none): the candidates at the poles `fit` found on this level, the residues
/// fitted to it. What the amplitude model's class reaches with the level's own data — the
/// floor a prediction of the level from the others can approach (a fit has seen the lines it
/// is judged on, so the floor is optimistic).
pub(crate) fn level_floor(
    (basis, cand): (&ModalBasis, &[usize]),
    fit: &LevelFit,
    h: f64,
    lv: &Level<'_>,
    bands: &[(f64, f64)],
    alpha: f64,
) -> Result<f64> {
    let mut poles = basis.poles();
    for (m, &pm) in cand.iter().enumerate() {
        let (f, z, _, _) = fit.modal[m];
        poles[pm] = if basis.is_real(pm) {
            C::new(-TAU * f, 0.0)
        } else {
            pair_of(f, z)
        };
    }
    let b = basis.with_poles(&poles)?;
    let phi = b.responses(h, NonIdeal::ideal(), lv.est.frd.freq_hz())?;
    let res = Residues::fit(&lv.est.frd, &phi)?;
    let lines: Vec<Line> = predicted_lines(lv.est, &phi, &res)
        .into_iter()
        .filter(|l| bands.is_empty() || bands.iter().any(|(lo, hi)| l.f >= *lo && l.f <= *hi))
        .collect();
    Ok(statistic([(lines.as_slice(), lv.est.inflation)], alpha).value)
}

/// An estimate's lines against the prediction `Σ r_j φ_j` with the residues' variance.
fn predicted_lines(est: &Estimate, phi: &[Vec<C>], res: &Residues) -> Vec<Line> {
    let np = res.n_params();
    compare(&est.frd, est.dof, |i, _| {
        let (value, var) = res.predict(&phi[i]);
        Some(Pred {
            value,
            var,
            dof: f64::INFINITY,
            params: np,
        })
    })
}

/// Natural frequency (Hz), damping and their standard errors from a pair and the covariance
/// of its `(σ, ω)`.
fn natural(s: C, cov: [[f64; 2]; 2]) -> (f64, f64, f64, f64) {
    let m = s.norm();
    let (sg, w) = (s.re, s.im);
    let df = [sg / (TAU * m), w / (TAU * m)];
    let dz = [-w * w / m.powi(3), sg * w / m.powi(3)];
    let q = |g: [f64; 2]| {
        (g[0] * g[0] * cov[0][0] + 2.0 * g[0] * g[1] * cov[0][1] + g[1] * g[1] * cov[1][1])
            .max(0.0)
            .sqrt()
    };
    (m / TAU, -sg / m, q(df), q(dz))
}

/// The pair of natural frequency `f` (Hz) and damping `z`.
fn pair_of(f: f64, z: f64) -> C {
    let w = TAU * f;
    C::new(-z * w, w * (1.0 - z * z).max(0.0).sqrt())
}

/// Rms of `x` sampled at `fs` in the band `[lo, hi]` Hz ([`Spectrum::band_rms`]).
#[cfg(test)]
fn band_rms(x: &[f64], fs: f64, lo: f64, hi: f64) -> f64 {
    Spectrum::of(x, fs).band_rms((lo, hi), false)
}

/// The one-sided power spectrum of a record, computed once for many band rms.
pub(crate) struct Spectrum {
    /// `|X_k|²` of the windowed DFT, `k = 0..=N/2`.
    power: Vec<f64>,
    df: f64,
    n: f64,
}

impl Spectrum {
    /// The power of the Hann-windowed DFT of `x` sampled at `fs` (window normalised to unit
    /// mean square, `Σw²/N = 3/8`) after the mean and the linear trend are removed. The
    /// window matters for non-periodic records: a rectangular one leaks the large
    /// low-frequency motion of a stage (whose record does not end where it starts) over
    /// every band with a level set by chance, which the Hann window's `1/f³` side-lobes
    /// suppress; whole periods of a periodic record lose nothing but the band edges' half
    /// bins.
    pub(crate) fn of(x: &[f64], fs: f64) -> Self {
        let n = x.len();
        if n < 4 {
            return Spectrum {
                power: Vec::new(),
                df: 1.0,
                n: 1.0,
            };
        }
        let nf = n as f64;
        let mean = x.iter().sum::<f64>() / nf;
        let tc = (nf - 1.0) / 2.0;
        let slope = x
            .iter()
            .enumerate()
            .map(|(i, v)| (i as f64 - tc) * (v - mean))
            .sum::<f64>()
            / (0..n).map(|i| (i as f64 - tc).powi(2)).sum::<f64>();
        let norm = (8.0f64 / 3.0).sqrt();
        let mut buf: Vec<C> = x
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let w = norm * (1.0 - (TAU * i as f64 / nf).cos()) / 2.0;
                C::new(w * (v - mean - slope * (i as f64 - tc)), 0.0)
            })
            .collect();
        rustfft::FftPlanner::new()
            .plan_fft_forward(n)
            .process(&mut buf);
        Spectrum {
            power: buf[..=n / 2].iter().map(|c| c.norm_sqr()).collect(),
            df: fs / nf,
            n: nf,
        }
    }

    /// Rms in the band `[lo, hi]` Hz, or with `derivative` the rms of the time derivative
    /// (each line's power times `(2πf)²`: the velocity of a position record).
    pub(crate) fn band_rms(&self, (lo, hi): (f64, f64), derivative: bool) -> f64 {
        if self.power.is_empty() || hi.is_nan() || lo.is_nan() || hi < lo {
            return 0.0;
        }
        let k0 = (lo / self.df).ceil().max(1.0) as usize;
        let k1 = ((hi / self.df).floor().max(0.0) as usize).min(self.power.len() - 1);
        let power: f64 = (k0..=k1)
            .map(|k| {
                let w = if derivative {
                    (TAU * k as f64 * self.df).powi(2)
                } else {
                    1.0
                };
                w * self.power[k]
            })
            .sum();
        (2.0 * power).sqrt() / self.n
    }
}

/// The spectra of an experiment's steady input and output.
pub(crate) struct Records {
    u: Spectrum,
    y: Spectrum,
}

impl Records {
    pub(crate) fn of(e: &Experiment) -> Self {
        let start = e.spec.skip_periods * e.spec.period_samples.unwrap_or(0);
        let fs = e.spec.sample_rate_hz;
        Records {
            u: Spectrum::of(&e.u[start.min(e.u.len())..], fs),
            y: Spectrum::of(&e.y[start.min(e.y.len())..], fs),
        }
    }
}

/// The band of a pole ([`band`]).
fn band_of(s: C) -> (f64, f64) {
    let n = natural(s, [[0.0; 2]; 2]);
    band(n.0, n.1)
}

/// The band of a mode: `f(1 ± max(3ζ, 2 %))`; of a real pole (a corner `f`), `[f/3, 3f]`.
fn band(f: f64, z: f64) -> (f64, f64) {
    if is_real_pole(z) {
        return (f / 3.0, 3.0 * f);
    }
    let w = (3.0 * z).max(0.02);
    (f * (1.0 - w), f * (1.0 + w))
}

/// The amplitude a candidate is driven at in output record `y`: for a pair, the rms of `y`
/// in the band of the pair `at` (its frequency at this level); for a friction-damped rigid
/// body's corner, the rms *velocity* of `y` from its lowest line up to three times the linear
/// corner (at most half the lowest pair's frequency), over the square root of the share of
/// the velocity's power the band holds at the corner `at`: Coulomb friction `F·sign(v)` acts
/// on a Gaussian velocity as the viscous damping `√(2/π)·F/σ_v` (Bussgang), and the velocity
/// of a damped rigid body is flat to its corner and falls as `1/f` above (`1/(1 + (f/f_c)²)`
/// in power, whose share below `B` is `(2/π)·atan(B/f_c)`).
fn mode_amplitude(basis: &ModalBasis, pm: usize, at: C, y: &Spectrum) -> f64 {
    if !basis.is_rigid_damping(pm) {
        return y.band_rms(band_of(at), false);
    }
    let top = corner_top(basis, pm);
    y.band_rms((0.0, top), true) / corner_share(top, at).sqrt()
}

/// The top of a friction corner's velocity band: three times the linear corner, at most half
/// the lowest pair's frequency (Hz).
fn corner_top(basis: &ModalBasis, pm: usize) -> f64 {
    let poles = basis.poles();
    let corner = natural(poles[pm], [[0.0; 2]; 2]).0;
    let lowest_pair = (0..poles.len())
        .filter(|&j| !basis.is_real(j))
        .map(|j| natural(poles[j], [[0.0; 2]; 2]).0)
        .fold(f64::INFINITY, f64::min);
    (3.0 * corner).min(0.5 * lowest_pair)
}

/// The share `(2/π)·atan(top/f_c)` of a first-order velocity spectrum `1/(1 + (f/f_c)²)`
/// below `top` at the corner `at` of a level: the band's power over it is the whole
/// velocity's.
fn corner_share(top: f64, at: C) -> f64 {
    let fc = natural(at, [[0.0; 2]; 2]).0.max(f64::MIN_POSITIVE);
    (std::f64::consts::FRAC_2_PI * (top / fc).atan()).max(1e-3)
}

/// One level's modal fit (module documentation): the candidates' pole pairs free, from the
/// linear basis.
pub(crate) fn fit_level(
    basis: &ModalBasis,
    cand: &[usize],
    h: f64,
    lv: &Level<'_>,
) -> Result<LevelFit> {
    let thin = lv.est.thinned()?;
    let est = &thin;
    let f = est.frd.freq_hz();
    let rw = rows(est);
    let mut b = basis.clone();
    let (mut cost, mut res) = project(&b, h, est)?;
    // each candidate's first parameter in the pole block: one for a real pole, two for a pair
    let width = |pm: usize| if basis.is_real(pm) { 1 } else { 2 };
    let offs: Vec<usize> = cand
        .iter()
        .scan(0, |o, &pm| {
            let at = *o;
            *o += width(pm);
            Some(at)
        })
        .collect();
    let np: usize = cand.iter().map(|&pm| width(pm)).sum();
    let mut jac_cov: Option<(DMatrix<f64>, Vec<usize>)> = None;
    for it in 0..=GN_ITERATIONS {
        let phi = b.responses(h, NonIdeal::ideal(), f)?;
        let dphi = b.pole_sensitivities(&res.r, h, NonIdeal::ideal(), f)?;
        let nb = res.r.len();
        let mut j = DMatrix::zeros(2 * rw.len(), nb + np);
        let mut e = DVector::zeros(2 * rw.len());
        for (k, &(i, w)) in rw.iter().enumerate() {
            let p: C = phi[i].iter().zip(&res.r).map(|(a, r)| a * *r).sum();
            let d = w * (est.frd.response()[i][(0, 0)] - p);
            e[2 * k] = d.re;
            e[2 * k + 1] = d.im;
            for c in 0..nb {
                j[(2 * k, c)] = w * phi[i][c].re;
                j[(2 * k + 1, c)] = w * phi[i][c].im;
            }
            for (m, &pm) in cand.iter().enumerate() {
                let col = b.sensitivity_column(pm);
                for t in 0..width(pm) {
                    j[(2 * k, nb + offs[m] + t)] = w * dphi[i][col + t].re;
                    j[(2 * k + 1, nb + offs[m] + t)] = w * dphi[i][col + t].im;
                }
            }
        }
        let Ok(ls) = lstsq(&j, &e) else {
            break;
        };
        jac_cov = Some((ls.cov.view((nb, nb), (np, np)).into_owned(), offs.clone()));
        if it == GN_ITERATIONS {
            break;
        }
        // halving line search on the poles, residues re-solved (variable projection)
        let mut improved = false;
        for step in (0..8).map(|k| 0.5f64.powi(k)) {
            let mut poles = b.poles();
            for (m, &pm) in cand.iter().enumerate() {
                let old = poles[pm];
                let d_im = if basis.is_real(pm) {
                    0.0
                } else {
                    ls.x[nb + offs[m] + 1]
                };
                let new = old + C::new(ls.x[nb + offs[m]], d_im) * step;
                // a step may not leave the stable (upper half) plane: at most halfway to it
                poles[pm] = C::new(new.re.min(0.5 * old.re), new.im.max(0.5 * old.im));
            }
            let trial = b.with_poles(&poles)?;
            let Ok((c2, r2)) = project(&trial, h, est) else {
                continue;
            };
            if c2 < cost {
                let rel = (cost - c2) / cost.max(f64::MIN_POSITIVE);
                (b, cost, res) = (trial, c2, r2);
                improved = rel > 1e-9;
                break;
            }
        }
        if !improved {
            // one more pass computes the covariance at the final point
            let cov = jac_cov.take();
            return finish((b, basis), cand, (cost, rw.len()), est, lv, cov);
        }
    }
    finish((b, basis), cand, (cost, rw.len()), est, lv, jac_cov)
}

/// The level fit's frequencies and dampings with errors, and its amplitudes; `cov` is the
/// pole block's covariance with each candidate's first column.
fn finish(
    (b, linear_basis): (ModalBasis, &ModalBasis),
    cand: &[usize],
    (cost, lines): (f64, usize),
    est: &Estimate,
    lv: &Level<'_>,
    cov: Option<(DMatrix<f64>, Vec<usize>)>,
) -> Result<LevelFit> {
    let (cov, offs) = cov.ok_or_else(|| {
        DiagnoseError::Numerical(format!("the modal fit of `{}` is singular", lv.name))
    })?;
    let nu = est.dof;
    let weights = if nu.is_finite() && nu > 2.0 {
        nu / (nu - 2.0)
    } else {
        1.0
    };
    let misfit = (cost / lines.max(1) as f64).max(1.0);
    let k = weights * est.inflation.max(1.0) * misfit;
    let poles = b.poles();
    let y = Records::of(lv.exp).y;
    let mut modal = Vec::new();
    let mut amplitude = Vec::new();
    for (m, &pm) in cand.iter().enumerate() {
        let real = b.is_real(pm);
        let c = |r: usize, s: usize| {
            if real && (r > 0 || s > 0) {
                0.0
            } else {
                k * cov[(offs[m] + r, offs[m] + s)]
            }
        };
        let nat = natural(poles[pm], [[c(0, 0), c(0, 1)], [c(1, 0), c(1, 1)]]);
        amplitude.push(mode_amplitude(linear_basis, pm, poles[pm], &y));
        modal.push(nat);
    }
    let linear = cand
        .iter()
        .map(|&pm| natural(linear_basis.poles()[pm], [[0.0; 2]; 2]))
        .collect();
    Ok(LevelFit {
        modal,
        amplitude,
        linear,
    })
}

/// Whether a level's fit determines a mode: its frequency within 30 % of the linear one and
/// known to better than half the linear half-power half-width `ζf` (a weak or band-edge mode
/// wanders off in a level fit; such points are left out of the trends).
fn determined(fit: (f64, f64, f64, f64), lin: (f64, f64, f64, f64)) -> bool {
    let (f, z, sf, sz) = fit;
    let finite = f.is_finite() && z.is_finite() && sf.is_finite() && sz.is_finite();
    if is_real_pole(lin.1) {
        // a real pole (a corner, ζ = 1) may move by two decades down (a friction corner
        // falls as 1/amplitude) and one up, known to half its value
        finite && f > 0.01 * lin.0 && f < 10.0 * lin.0 && sf < 0.5 * f
    } else {
        finite && (f / lin.0 - 1.0).abs() < 0.3 && sf < 0.5 * lin.1 * lin.0
    }
}

/// Whether a damping ratio is a real pole's (`natural` gives ζ = 1 for `s = −a + 0j`).
fn is_real_pole(z: f64) -> bool {
    z >= 1.0 - 1e-12
}

/// Weighted least squares of `p(ρ) = a + b·ρ^k` over points `(ρ, p, σ)`, written as the
/// trend `p_ref + c(ρ^k − 1)` (`p_ref = a + b`, `c = b`), and its weighted residual.
///
/// `nonneg` constrains `a, b ≥ 0` (non-negative least squares over the two columns: the
/// unconstrained solution when feasible, else the better feasible one-column fit). That is a
/// friction-damped corner's physics: `2πm·f = c_v + c_eq(ρ)`, a viscous part and an
/// amplitude-dependent part that are both non-negative (Coulomb friction under a
/// Gaussian-like velocity of rms σ has the equivalent damping `c_eq = √(2/π)·F_c/σ`, Bussgang;
/// k = −1), so a corner can neither cross zero nor fall under a law that rises.
fn trend_fit(pts: &[(f64, f64, f64)], k: i32, nonneg: bool) -> Option<(Trend, f64)> {
    let n = pts.len();
    if n < 2 {
        return None;
    }
    let w = |i: usize| 1.0 / pts[i].2.max(f64::MIN_POSITIVE);
    let g = DVector::from_fn(n, |i, _| pts[i].1 * w(i));
    // columns: 0 the constant a, 1 the amplitude term b·ρ^k
    let solve = |cols: &[usize]| -> Option<([f64; 2], [[f64; 2]; 2], f64)> {
        let x = DMatrix::from_fn(n, cols.len(), |i, j| {
            w(i) * if cols[j] == 0 { 1.0 } else { pts[i].0.powi(k) }
        });
        let ls = lstsq(&x, &g).ok()?;
        let chi2 = (&g - &x * &ls.x).norm_squared();
        let (mut c, mut cov) = ([0.0; 2], [[0.0; 2]; 2]);
        for (j, &cj) in cols.iter().enumerate() {
            c[cj] = ls.x[j];
            for (l, &cl) in cols.iter().enumerate() {
                cov[cj][cl] = ls.cov[(j, l)];
            }
        }
        Some((c, cov, chi2))
    };
    let (c, cov, chi2) = match solve(&[0, 1])? {
        full if !nonneg || (full.0[0] >= 0.0 && full.0[1] >= 0.0) => full,
        _ => [solve(&[1]), solve(&[0])]
            .into_iter()
            .flatten()
            .filter(|(c, _, _)| c[0] >= 0.0 && c[1] >= 0.0)
            .min_by(|x, y| x.2.total_cmp(&y.2))?,
    };
    let free = if nonneg {
        c.iter().filter(|v| **v != 0.0).count().max(1)
    } else {
        2
    };
    // the points' scatter beyond their errors widens the trend's
    let scale = if n > free {
        (chi2 / (n - free) as f64).max(1.0)
    } else {
        1.0
    };
    Some((
        Trend {
            exponent: k,
            at_reference: c[0] + c[1],
            at_reference_std: ((cov[0][0] + 2.0 * cov[0][1] + cov[1][1]) * scale)
                .max(0.0)
                .sqrt(),
            slope: c[1],
            slope_std: (cov[1][1] * scale).sqrt(),
            covariance: (cov[0][1] + cov[1][1]) * scale,
        },
        chi2,
    ))
}

/// The trend: exponent `default` (2 for a mode, the cubic-stiffness backbone; −1 for a
/// friction-damped rigid body's corner, `c_eq ∝ 1/amplitude`) unless another exponent of
/// [`EXPONENTS`] lowers the weighted residual by more than the `1 − alpha` quantile of χ²₁
/// (the data must insist on a different law; with two points every exponent fits exactly and
/// the default stays). `nonneg`: the corner's constrained form ([`trend_fit`]).
fn best_trend(pts: &[(f64, f64, f64)], alpha: f64, default: i32, nonneg: bool) -> Option<Trend> {
    let (first, c0) = trend_fit(pts, default, nonneg)?;
    let margin = normal_quantile(1.0 - alpha / 2.0).powi(2);
    let mut best = (first, c0);
    if pts.len() > 2 {
        for k in EXPONENTS.iter().filter(|k| **k != default) {
            if let Some((t, c)) = trend_fit(pts, *k, nonneg) {
                if c < best.1 && c0 - c > margin {
                    best = (t, c);
                }
            }
        }
    }
    Some(best.0)
}

/// Largest ratio between the highest and the lowest response per force of a moving pair over
/// the levels ([`proportional`]).
const RESPONSE_SPREAD: f64 = 2.0;

/// Whether a pair's amplitude ratios follow its force ratios (`(force, amplitude)` per level,
/// each relative to the model experiment): the response per force in the mode's band (around
/// its fitted pole) stays within [`RESPONSE_SPREAD`] over the levels. A stiffness
/// nonlinearity moves the resonance a few per cent and keeps its peak, so its response per
/// force hardly changes; a level fit that wandered to another feature, or a band the noise
/// dominates, breaks the proportion, and its "trend" is no amplitude law. The factor 2 was set
/// on development seeds (`diagnose_levels` header); the level tests check its outcome.
fn proportional(per_force: &[(f64, f64)]) -> bool {
    let (lo, hi) = per_force
        .iter()
        .map(|(f, a)| a / f)
        .fold((f64::INFINITY, 0.0f64), |(l, h), x| (l.min(x), h.max(x)));
    per_force.len() < 2 || hi <= RESPONSE_SPREAD * lo
}

/// Whether values `(p, σ)` differ beyond their errors (χ² against the weighted mean).
fn moves(vals: &[(f64, f64)], alpha: f64) -> bool {
    let w: Vec<f64> = vals
        .iter()
        .map(|v| 1.0 / v.1.max(f64::MIN_POSITIVE).powi(2))
        .collect();
    let sw: f64 = w.iter().sum();
    let mean = vals.iter().zip(&w).map(|(v, w)| v.0 * w).sum::<f64>() / sw;
    let chi2: f64 = vals
        .iter()
        .zip(&w)
        .map(|(v, w)| (v.0 - mean).powi(2) * w)
        .sum();
    let dof = vals.len().saturating_sub(1);
    // χ²_ν/ν is Gamma(ν/2, 1)/(ν/2)
    dof > 0 && chi2 / dof as f64 > threshold(dof as f64 / 2.0, alpha)
}

impl Trend {
    /// The value at relative amplitude `rho` and its standard error.
    pub fn at(&self, rho: f64) -> (f64, f64) {
        let g = rho.powi(self.exponent) - 1.0;
        let v = self.at_reference_std.powi(2)
            + 2.0 * g * self.covariance
            + g * g * self.slope_std.powi(2);
        (self.at_reference + self.slope * g, v.max(0.0).sqrt())
    }

    /// The sign of `dp/dρ` when the slope differs from zero beyond `z` standard errors.
    fn direction(&self, z: f64) -> i32 {
        if self.slope.abs() <= z * self.slope_std {
            0
        } else if (self.slope * self.exponent as f64) > 0.0 {
            1
        } else {
            -1
        }
    }
}

/// Candidates, as indices of [`ModalBasis::poles`]. Pairs: inside the estimate's band with at
/// least a few lines around them, apart from every other pair by more than twice their
/// half-power half-widths together (two modes closer than that trade frequency and damping
/// in a fit; they keep their linear poles). Of the real poles only a damped rigid body's
/// corner `a/2π` ([`ModalBasis::with_damped_rigid_body`], whose residues do not change when
/// friction moves it): below the band's top with at least three lines under ten times the
/// corner (where it turns the phase by more than 6°), and a factor 3 from any other real
/// pole. Other real poles keep their linear values (their residues would have to move with
/// them).
pub(crate) fn candidates(basis: &ModalBasis, est: &Estimate) -> Vec<usize> {
    let f = est.frd.freq_hz();
    let (lo, hi) = (
        f.first().copied().unwrap_or(0.0),
        f.last().copied().unwrap_or(0.0),
    );
    let poles = basis.poles();
    let nat: Vec<(f64, f64)> = poles
        .iter()
        .map(|p| {
            let n = natural(*p, [[0.0; 2]; 2]);
            (n.0, n.1)
        })
        .collect();
    let pair_ok = |i: usize| {
        let (fi, zi) = nat[i];
        let lines = f.iter().filter(|x| (**x - fi).abs() < 0.05 * fi).count();
        let apart = (0..nat.len())
            .filter(|&j| j != i && !basis.is_real(j))
            .all(|j| (fi - nat[j].0).abs() > 2.0 * (zi * fi + nat[j].1 * nat[j].0));
        fi > lo && fi < hi && lines >= 3 && apart
    };
    let real_ok = |i: usize| {
        let fi = nat[i].0;
        let lines = f.iter().filter(|x| **x < 10.0 * fi).count();
        let apart = (0..nat.len())
            .filter(|&j| j != i && basis.is_real(j))
            .all(|j| (nat[j].0 / fi).ln().abs() > 3f64.ln());
        fi > 0.0 && fi < hi && lines >= 3 && apart
    };
    (0..nat.len())
        .filter(|&i| {
            if basis.is_rigid_damping(i) {
                real_ok(i)
            } else {
                !basis.is_real(i) && pair_ok(i)
            }
        })
        .collect()
}

impl AmplitudeModel {
    /// Fits the trends and the shared residues on `fits` (level fits of `levels`; the first
    /// level is the reference).
    pub(crate) fn fit(
        basis: &ModalBasis,
        h: f64,
        cand: &[usize],
        levels: &[&Level<'_>],
        fits: &[&LevelFit],
        alpha: f64,
    ) -> Result<Self> {
        let reference: Vec<f64> = fits
            .first()
            .map(|f| f.amplitude.clone())
            .ok_or_else(|| DiagnoseError::Setup("no level to fit".into()))?;
        let a_mode = alpha / (2.0 * cand.len().max(1) as f64);
        let mut trends = Vec::new();
        for m in 0..cand.len() {
            let rho = |f: &LevelFit| f.amplitude[m] / reference[m].max(f64::MIN_POSITIVE);
            let lin = natural(basis.poles()[cand[m]], [[0.0; 2]; 2]);
            // levels where the fit determines the mode (module documentation)
            // (and whose amplitude was measured: a positive finite ratio)
            let good: Vec<&&LevelFit> = fits
                .iter()
                .filter(|f| determined(f.modal[m], lin) && rho(f).is_finite() && rho(f) > 0.0)
                .collect();
            let fp: Vec<(f64, f64, f64)> = good
                .iter()
                .map(|f| (rho(f), f.modal[m].0, f.modal[m].2))
                .collect();
            let zp: Vec<(f64, f64, f64)> = good
                .iter()
                .map(|f| (rho(f), f.modal[m].1, f.modal[m].3))
                .collect();
            let fallback = Trend {
                exponent: EXPONENTS[0],
                at_reference: lin.0,
                at_reference_std: f64::INFINITY,
                slope: 0.0,
                slope_std: f64::INFINITY,
                covariance: 0.0,
            };
            // the pole keeps its linear value
            let linear = || {
                let zfall = Trend {
                    at_reference: lin.1,
                    ..fallback.clone()
                };
                (fallback.clone(), zfall, false, false)
            };
            if fp.len() < 2 {
                trends.push(linear());
                continue;
            }
            let default = if basis.is_rigid_damping(cand[m]) {
                -1
            } else {
                EXPONENTS[0]
            };
            // points the weighted fit cannot use (equal amplitudes, a zero error): the pole
            // keeps its linear value
            let Some(ft) = best_trend(&fp, alpha, default, basis.is_rigid_damping(cand[m])) else {
                trends.push(linear());
                continue;
            };
            let zt = if basis.is_real(cand[m]) {
                // a real pole's damping is 1 at every amplitude
                Trend {
                    at_reference: 1.0,
                    at_reference_std: 0.0,
                    slope_std: 0.0,
                    ..fallback.clone()
                }
            } else {
                best_trend(&zp, alpha, EXPONENTS[0], false).unwrap_or_else(|| Trend {
                    at_reference: lin.1,
                    ..fallback.clone()
                })
            };
            let fm = moves(&fp.iter().map(|p| (p.1, p.2)).collect::<Vec<_>>(), a_mode);
            // a real pole has no damping of its own (ζ = 1); a damping without a trend does
            // not move
            let zm = !basis.is_real(cand[m])
                && zt.slope_std.is_finite()
                && moves(&zp.iter().map(|p| (p.1, p.2)).collect::<Vec<_>>(), a_mode);
            trends.push((ft, zt, fm, zm));
        }
        let force_rec = Records::of(
            levels
                .first()
                .ok_or_else(|| DiagnoseError::Setup("no level to fit".into()))?
                .exp,
        );
        let force = |rec: &Records, pm: usize| rec.u.band_rms(band_of(basis.poles()[pm]), false);
        let reference_force: Vec<f64> = cand
            .iter()
            .map(|&pm| force(&force_rec, pm).max(f64::MIN_POSITIVE))
            .collect();
        let recs: Vec<Records> = levels.iter().map(|lv| Records::of(lv.exp)).collect();
        let per_force: Vec<Vec<(f64, f64)>> = cand
            .iter()
            .enumerate()
            .map(|(m, &pm)| {
                recs.iter()
                    .zip(fits)
                    .map(|(r, f)| {
                        (
                            force(r, pm) / reference_force[m],
                            f.amplitude[m] / reference[m].max(f64::MIN_POSITIVE),
                        )
                    })
                    .filter(|(x, y)| x.is_finite() && *x > 0.0 && y.is_finite() && *y > 0.0)
                    .collect()
            })
            .collect();
        // a pair whose response per force is not proportional over the levels is not a mode
        // moving with amplitude ([`proportional`]): it keeps its linear pole
        for (m, t) in trends.iter_mut().enumerate() {
            if !basis.is_real(cand[m]) && !proportional(&per_force[m]) {
                (t.2, t.3) = (false, false);
            }
        }
        let range = (0..cand.len())
            .map(|m| {
                fits.iter()
                    .map(|f| f.amplitude[m] / reference[m].max(f64::MIN_POSITIVE))
                    .filter(|r| r.is_finite() && *r > 0.0)
                    .fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
                        (lo.min(r), hi.max(r))
                    })
            })
            .collect();
        let mut me = AmplitudeModel {
            range,
            basis: basis.clone(),
            h,
            cand: cand.to_vec(),
            trends,
            reference,
            reference_force,
            per_force,
            residues: None,
        };
        me.residues = Some(me.reference_residues(levels)?);
        Ok(me)
    }

    fn res(&self) -> Result<&Residues> {
        self.residues
            .as_ref()
            .ok_or_else(|| DiagnoseError::Numerical("amplitude model without residues".into()))
    }

    /// The poles ([`ModalBasis::poles`]) at amplitudes `amp` (one per candidate): moving ones
    /// from their trends, the others linear.
    fn pairs_at(&self, amp: &[f64]) -> Vec<C> {
        let mut pairs = self.basis.poles().to_vec();
        for (m, &pm) in self.cand.iter().enumerate() {
            let rho = amp[m] / self.reference[m].max(f64::MIN_POSITIVE);
            pairs[pm] = self.pole_at(m, rho);
        }
        pairs
    }

    /// Candidate `m`'s pole at relative amplitude `rho`: from its trends when it moves, else
    /// linear.
    fn pole_at(&self, m: usize, rho: f64) -> C {
        let pm = self.cand[m];
        let lin_pole = self.basis.poles()[pm];
        let (ft, zt, fm, zm) = &self.trends[m];
        if !(*fm || *zm) {
            return lin_pole;
        }
        let lin = natural(lin_pole, [[0.0; 2]; 2]);
        let f = if *fm { ft.at(rho).0 } else { lin.0 };
        if self.basis.is_real(pm) {
            // a corner stays a stable real pole
            C::new(-TAU * f.max(1e-3 * lin.0), 0.0)
        } else {
            let z = zt.at(rho).0;
            pair_of(f.max(1e-3 * lin.0), z.clamp(1e-6, 0.999))
        }
    }

    /// Candidate `m`'s amplitude in an experiment: self-consistent, the rms of the output in
    /// the band of the pole the trend predicts at that very amplitude. With `g(ρ)` the rms in
    /// the band of the pole at `ρ` over the reference amplitude, the stable solutions of
    /// `ρ = g(ρ)` (where `g(ρ) − ρ` turns from positive to negative) are sought on a 2 % grid
    /// of `ρ` from 1/16 to 64 while the pole stays within ±[`MAX_SHIFT`] of its linear
    /// frequency, each refined by bisection. Several solutions are usual once a mode has left
    /// its linear band: a band on the skirt of the response measures a smaller amplitude,
    /// which predicts a smaller shift, and a band far off may catch another mode. They are
    /// told apart by the force: the input's rms in the linear band over the reference
    /// experiment's (measured without the model), times the response per force of the fitted
    /// level nearest in force, estimates the amplitude; the solution nearest it (in `ln ρ`)
    /// is taken when within a factor [`FORCE_AGREEMENT`], else the force's estimate itself.
    /// A pole that does not move is measured directly; a moving friction corner's band is
    /// fixed, and only its share of the velocity ([`mode_amplitude`]) follows the corner
    /// predicted at that amplitude (a fixed point).
    fn amplitude_of(&self, m: usize, rec: &Records) -> f64 {
        let pm = self.cand[m];
        let (fm, zm) = (self.trends[m].2, self.trends[m].3);
        let lin_pole = self.basis.poles()[pm];
        let direct = mode_amplitude(&self.basis, pm, lin_pole, &rec.y);
        let a_ref = self.reference[m].max(f64::MIN_POSITIVE);
        if self.basis.is_rigid_damping(pm) && fm && direct > 0.0 {
            // the corner's band share depends on the corner at this amplitude: a fixed point
            // on the band's rms, measured once (the share changes slowly with the corner, so
            // a few steps settle it)
            let top = corner_top(&self.basis, pm);
            let band = rec.y.band_rms((0.0, top), true);
            let mut a = direct;
            for _ in 0..20 {
                let next = band / corner_share(top, self.pole_at(m, a / a_ref)).sqrt();
                let done = (next / a - 1.0).abs() < 1e-6;
                a = next;
                if done {
                    break;
                }
            }
            return a;
        }
        if !(fm || zm) || self.basis.is_real(pm) || direct <= 0.0 {
            return direct;
        }
        let f_lin = natural(lin_pole, [[0.0; 2]; 2]).0;
        // ln(g(ρ)/ρ) at ln ρ, where the pole stays within MAX_SHIFT of the linear one
        let d = |ln_rho: f64| -> Option<f64> {
            let p = self.pole_at(m, ln_rho.exp());
            let f = natural(p, [[0.0; 2]; 2]).0;
            let g = mode_amplitude(&self.basis, pm, p, &rec.y) / a_ref;
            ((f / f_lin - 1.0).abs() <= MAX_SHIFT && g > 0.0).then(|| g.ln() - ln_rho)
        };
        // the amplitude the force predicts: its ratio times the response per force of the
        // fitted level nearest in force
        let phi = rec.u.band_rms(band_of(lin_pole), false) / self.reference_force[m];
        let from_force = self.per_force[m]
            .iter()
            .min_by(|a, b| (a.0 / phi).ln().abs().total_cmp(&(b.0 / phi).ln().abs()))
            .map(|(f, r)| phi * r / f)
            .filter(|r| r.is_finite() && *r > 0.0);
        let Some(target) = from_force.map(f64::ln) else {
            return direct;
        };
        let step = 0.02f64.ln_1p();
        let (lo, hi) = ((1.0f64 / 16.0).ln(), 64f64.ln());
        let n = ((hi - lo) / step).ceil() as usize;
        let grid: Vec<(f64, Option<f64>)> = (0..=n)
            .map(|k| {
                let x = lo + step * k as f64;
                (x, d(x))
            })
            .collect();
        let mut best: Option<f64> = None;
        for w in grid.windows(2) {
            let (Some(d0), Some(d1)) = (w[0].1, w[1].1) else {
                continue;
            };
            if !(d0 >= 0.0 && d1 < 0.0) {
                continue;
            }
            let (mut a, mut b) = (w[0].0, w[1].0);
            for _ in 0..30 {
                let c = 0.5 * (a + b);
                match d(c) {
                    Some(dc) if dc >= 0.0 => a = c,
                    _ => b = c,
                }
            }
            let x = 0.5 * (a + b);
            if best.is_none_or(|bx| (x - target).abs() < (bx - target).abs()) {
                best = Some(x);
            }
        }
        // a solution far from what the force says is another mode's or the skirt's: the
        // force's amplitude then stands
        let x = best
            .filter(|x| (x - target).abs() <= FORCE_AGREEMENT.ln())
            .unwrap_or(target);
        x.exp() * a_ref
    }

    /// Residues fitted to the reference level (the model experiment) at its trend poles: the
    /// modes' strengths do not depend on amplitude in a stiffness or damping nonlinearity,
    /// and the reference is the level the linear model was made for.
    fn reference_residues(&self, levels: &[&Level<'_>]) -> Result<Residues> {
        let lv = levels
            .first()
            .ok_or_else(|| DiagnoseError::Setup("no level to fit".into()))?;
        let amp = self.amplitudes(lv);
        let b = self.basis.with_poles(&self.pairs_at(&amp))?;
        let phi = b.responses(self.h, NonIdeal::ideal(), lv.est.frd.freq_hz())?;
        Residues::fit(&lv.est.frd, &phi)
    }

    /// A level's mode amplitudes, each self-consistent with its predicted pole
    /// ([`AmplitudeModel::amplitude_of`]), as the level fits measure them.
    pub(crate) fn amplitudes(&self, lv: &Level<'_>) -> Vec<f64> {
        self.amplitudes_of(lv.exp)
    }

    /// [`AmplitudeModel::amplitudes`] of any experiment at the model's rate.
    pub(crate) fn amplitudes_of(&self, e: &Experiment) -> Vec<f64> {
        let rec = Records::of(e);
        (0..self.cand.len())
            .map(|m| self.amplitude_of(m, &rec))
            .collect()
    }

    /// The prediction of a level's FRF lines, with the residues' variance (the trend's poles
    /// enter through their propagated errors).
    pub(crate) fn lines(&self, lv: &Level<'_>) -> Result<Vec<Line>> {
        let amp = self.amplitudes(lv);
        let b = self.basis.with_poles(&self.pairs_at(&amp))?;
        let f = lv.est.frd.freq_hz();
        let phi = b.responses(self.h, NonIdeal::ideal(), f)?;
        Ok(predicted_lines(lv.est, &phi, self.res()?))
    }

    /// The moving candidates: `(candidate, linear frequency (Hz), the top of the band its
    /// amplitude is measured in (Hz))`.
    pub(crate) fn moving(&self) -> Vec<(usize, f64, f64)> {
        self.cand
            .iter()
            .enumerate()
            .filter(|(m, _)| self.trends[*m].2 || self.trends[*m].3)
            .map(|(m, &pm)| {
                let p = self.basis.poles()[pm];
                let f = natural(p, [[0.0; 2]; 2]).0;
                let top = if self.basis.is_rigid_damping(pm) {
                    corner_top(&self.basis, pm)
                } else {
                    band_of(p).1
                };
                (m, f, top)
            })
            .collect()
    }

    /// Whether any mode moves with amplitude in this model.
    pub(crate) fn moves_any(&self) -> bool {
        self.trends.iter().any(|t| t.2 || t.3)
    }

    /// Whether a level's amplitude lies outside the range of the levels the model was
    /// fitted on (for any moving mode).
    pub(crate) fn extrapolates(&self, lv: &Level<'_>, fits: &[&LevelFit]) -> bool {
        let amp = self.amplitudes(lv);
        self.cand.iter().enumerate().any(|(m, _)| {
            let (fm, zm) = (self.trends[m].2, self.trends[m].3);
            let (lo, hi) = fits.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), f| {
                (lo.min(f.amplitude[m]), hi.max(f.amplitude[m]))
            });
            (fm || zm) && (amp[m] < lo * 0.999 || amp[m] > hi * 1.001)
        })
    }

    /// The bands of the moving modes at a level: from the lower to the higher of the linear
    /// and the predicted frequency, widened by `max(5ζ, 2 %)` (empty when nothing moves).
    pub(crate) fn moving_bands(&self, lv: &Level<'_>) -> Vec<(f64, f64)> {
        self.moving_bands_with(&self.amplitudes(lv))
    }

    /// [`AmplitudeModel::moving_bands`] at the mode amplitudes `amp`.
    pub(crate) fn moving_bands_with(&self, amp: &[f64]) -> Vec<(f64, f64)> {
        let pred = self.predicted_with(amp);
        self.cand
            .iter()
            .enumerate()
            .filter(|(m, _)| self.trends[*m].2 || self.trends[*m].3)
            .map(|(m, &pm)| {
                let lin = natural(self.basis.poles()[pm], [[0.0; 2]; 2]);
                let (f, z) = pred[m];
                if self.basis.is_real(pm) {
                    // a corner acts on every line below ten times itself
                    return (0.0, 10.0 * lin.0.max(f));
                }
                let w = (5.0 * lin.1.max(z)).max(0.02);
                (lin.0.min(f) * (1.0 - w), lin.0.max(f) * (1.0 + w))
            })
            .collect()
    }

    /// The discrete model at a level.
    pub(crate) fn model_at(&self, lv: &Level<'_>) -> Result<StateSpace> {
        self.model_with(&self.amplitudes(lv))
    }

    /// The discrete model at the mode amplitudes `amp` (one per candidate).
    pub(crate) fn model_with(&self, amp: &[f64]) -> Result<StateSpace> {
        self.basis
            .with_poles(&self.pairs_at(amp))?
            .model(&self.res()?.r, self.h, NonIdeal::ideal())
    }

    /// Natural frequency (Hz) and damping of every candidate predicted at a level's
    /// amplitudes.
    pub(crate) fn predicted(&self, lv: &Level<'_>) -> Vec<(f64, f64)> {
        self.predicted_with(&self.amplitudes(lv))
    }

    /// Natural frequency (Hz) and damping of every candidate at the mode amplitudes `amp`.
    pub(crate) fn predicted_with(&self, amp: &[f64]) -> Vec<(f64, f64)> {
        let pairs = self.pairs_at(amp);
        self.cand
            .iter()
            .map(|&pm| {
                let n = natural(pairs[pm], [[0.0; 2]; 2]);
                (n.0, n.1)
            })
            .collect()
    }

    /// The moving modes as reported, with every level's points (and, where given, what the
    /// model fitted without that level predicted for it: `loo[level][candidate]`).
    pub(crate) fn report(
        &self,
        levels: &[&Level<'_>],
        fits: &[&LevelFit],
        loo: &[Option<Vec<(f64, f64)>>],
    ) -> Vec<MovingMode> {
        let mut out = Vec::new();
        for (m, &pm) in self.cand.iter().enumerate() {
            let (ft, zt, fm, zm) = &self.trends[m];
            if !(*fm || *zm) {
                continue;
            }
            let lin = natural(self.basis.poles()[pm], [[0.0; 2]; 2]);
            let points = levels
                .iter()
                .zip(fits)
                .enumerate()
                .map(|(l, (lv, f))| ModePoint {
                    held_out_prediction: loo.get(l).and_then(|p| p.as_ref()).map(|p| p[m]),
                    experiment: lv.name.clone(),
                    amplitude: f.amplitude[m],
                    relative_amplitude: f.amplitude[m] / self.reference[m].max(f64::MIN_POSITIVE),
                    freq_hz: f.modal[m].0,
                    freq_hz_std: f.modal[m].2,
                    damping: f.modal[m].1,
                    damping_std: f.modal[m].3,
                })
                .collect();
            out.push(MovingMode {
                pole: if self.basis.is_real(pm) {
                    PoleKind::Real
                } else {
                    PoleKind::Pair
                },
                linear_freq_hz: lin.0,
                linear_damping: lin.1,
                frequency_moves: *fm,
                damping_moves: *zm,
                frequency: ft.clone(),
                damping: zt.clone(),
                points,
            });
        }
        out
    }
}

/// `kind` and `damping_trend` of the moving pairs: the dominant one (the largest frequency
/// or damping slope relative to its error) decides, at `z` standard errors; `corner_trend`
/// likewise of the moving real poles' corners.
pub(crate) fn kinds(modes: &[MovingMode], z: f64) -> (FreqTrend, DampingTrend, CornerTrend) {
    let dominant = |pole: PoleKind,
                    moves: &dyn Fn(&MovingMode) -> bool,
                    t: &dyn Fn(&MovingMode) -> Trend| {
        modes
            .iter()
            .filter(|m| m.pole == pole && moves(m))
            .max_by(|a, b| {
                let k = |m: &MovingMode| t(m).slope.abs() / t(m).slope_std.max(f64::MIN_POSITIVE);
                k(a).total_cmp(&k(b))
            })
            .map_or(0, |m| t(m).direction(z))
    };
    let f = match dominant(PoleKind::Pair, &|m| m.frequency_moves, &|m| {
        m.frequency.clone()
    }) {
        1 => FreqTrend::Hardening,
        -1 => FreqTrend::Softening,
        _ => FreqTrend::None,
    };
    let d = match dominant(PoleKind::Pair, &|m| m.damping_moves, &|m| m.damping.clone()) {
        1 => DampingTrend::Increasing,
        -1 => DampingTrend::Decreasing,
        _ => DampingTrend::None,
    };
    let c = match dominant(PoleKind::Real, &|m| m.frequency_moves, &|m| {
        m.frequency.clone()
    }) {
        1 => CornerTrend::Rising,
        -1 => CornerTrend::Falling,
        _ => CornerTrend::None,
    };
    (f, d, c)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn band_rms_of_a_sine() {
        let fs = 1000.0;
        let x: Vec<f64> = (0..1000)
            .map(|k| {
                2.0 * (TAU * 50.0 * k as f64 / fs).sin() + 0.5 * (TAU * 200.0 * k as f64 / fs).sin()
            })
            .collect();
        // whole periods: exact but for the removed trend's share of the sines (≤ 1e-3)
        assert!((band_rms(&x, fs, 45.0, 55.0) / (2.0 / 2f64.sqrt()) - 1.0).abs() < 1e-3);
        assert!((band_rms(&x, fs, 190.0, 210.0) / (0.5 / 2f64.sqrt()) - 1.0).abs() < 1e-3);
        // the derivative's rms: 2πf times the amplitude over √2, both sines together
        let v = ((TAU * 50.0 * 2.0).powi(2) + (TAU * 200.0 * 0.5).powi(2)).sqrt() / 2f64.sqrt();
        let got = Spectrum::of(&x, fs).band_rms((0.0, 300.0), true);
        assert!((got / v - 1.0).abs() < 1e-3, "{got} {v}");
    }

    /// A record that does not end where it starts (a slow drift 1000× the sine's amplitude,
    /// not a whole number of its periods): the band around the sine still reads the sine.
    #[test]
    fn band_rms_ignores_the_leakage_of_slow_motion() {
        let fs = 1000.0;
        let x: Vec<f64> = (0..3000)
            .map(|k| {
                let t = k as f64 / fs;
                1e-3 * (TAU * 150.0 * t).sin() + (TAU * 0.13 * t).sin() + 0.3 * t * t
            })
            .collect();
        let b = band_rms(&x, fs, 140.0, 160.0);
        assert!((b / (1e-3 / 2f64.sqrt()) - 1.0).abs() < 0.01, "{b}");
    }

    #[test]
    fn trend_recovers_a_quadratic_backbone() {
        let pts: Vec<(f64, f64, f64)> = [1.0, 2.0, 4.0, 8.0]
            .iter()
            .map(|&r: &f64| (r, 100.0 + 0.05 * (r * r - 1.0), 0.01))
            .collect();
        let t = best_trend(&pts, 0.01, 2, false).unwrap();
        assert_eq!(t.exponent, 2);
        assert!((t.slope - 0.05).abs() < 1e-9 && (t.at_reference - 100.0).abs() < 1e-9);
        assert_eq!(t.direction(3.0), 1);
        let (v, _) = t.at(3.0);
        assert!((v - 100.4).abs() < 1e-9);
    }

    #[test]
    fn natural_frequency_and_damping_of_a_pair() {
        let s = pair_of(100.0, 0.02);
        let (f, z, _, _) = natural(s, [[0.0; 2]; 2]);
        assert!((f - 100.0).abs() < 1e-9 && (z - 0.02).abs() < 1e-12);
    }
}
