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
//! **On the tracks** ([`on_tracks`]): a variant of the level fits where the pairs that tracked
//! physical modes follow take the tracks' local fits; the diagnosis chooses between the
//! variants on the training levels.
//!
//! **Prediction of a level** from the trend at that level's measured amplitudes: the moving
//! poles from the trend, the others linear, the residues fitted jointly to the training levels
//! (each with its own poles). Its variance carries the residues' covariance and the trend's.

use crate::data::Estimate;
use crate::lemma6::{compare, Pred};
use crate::modal::{ModalBasis, Residues};
use crate::stats::{statistic, threshold, Line};
use crate::{
    CornerTrend, DampingTrend, DiagnoseError, FreqTrend, ModePoint, MovingMode, PointFit, PoleKind,
    Result, Trend,
};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64 as C;
use sd_ident::Experiment;
use sd_model::linalg::lstsq;
use sd_model::normal_quantile;
use sd_model::StateSpace;
use sd_multirate::NonIdeal;
use std::f64::consts::TAU;

mod level_fit;
mod on_tracks;
mod spectrum;
mod trend;

use level_fit::*;
pub(crate) use level_fit::{candidates, describes, fit_level, level_floor};
pub(crate) use on_tracks::on_tracks;
use spectrum::*;
pub(crate) use trend::kinds;
use trend::*;

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
    /// Where each candidate's `modal` comes from ([`on_tracks`]).
    fit_of: Vec<PointFit>,
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
        let mut trends = candidate_trends(basis, cand, fits, &reference, alpha);
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

    /// The prediction variance at `freq_hz` of the model at mode amplitudes `amp` and period
    /// `ts` from the common residues' covariance (the trends' own uncertainty is not in it).
    pub(crate) fn variances_with(&self, amp: &[f64], ts: f64, freq_hz: &[f64]) -> Result<Vec<f64>> {
        let basis = self.basis.with_poles(&self.pairs_at(amp))?;
        self.res()?
            .variances(&basis, ts, NonIdeal::ideal(), freq_hz)
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
                    fit: f.fit_of[m],
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

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn natural_frequency_and_damping_of_a_pair() {
        let s = pair_of(100.0, 0.02);
        let (f, z, _, _) = natural(s, [[0.0; 2]; 2]);
        assert!((f - 100.0).abs() < 1e-9 && (z - 0.02).abs() < 1e-12);
    }
}
