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
//! Every basis function is one output of a small continuous block (rigid body as a 1/s² chain
//! whose two states give 1/s² and 1/s, a real pole as 1/(s − p), a pair as
//! `[[σ, ω], [−ω, σ]]`, whose two states span `{(s − σ), ω}/((s − σ)² + ω²)`, and a constant).
//! Under a hypothesis θ (hold delay α or window β) each experiment's basis responses are the
//! blocks discretised exactly at the experiment's own
//! period with [`sd_multirate::c2d_nonideal`], so the plant `P = Σ r_j φ_j` is linear in the
//! real residues `r`. They are fitted to the fast FRF by weighted least squares
//! (`min Σ |G − Σ r_j φ_j^h|²/σ²`, columns scaled to unit norm, SVD with rank cut at
//! `1e-10·σ_max`), which gives their covariance `(JᵀWJ)⁻¹` and so the variance of every
//! prediction `Σ r_j φ_j^T(f)`. A hypothesis is judged by how well the fast data, discretised
//! its way, predict the slow data.

use crate::{DiagnoseError, Result};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64 as C;
use rayon::prelude::*;
use sd_model::{Frd, SampleTime, StateSpace};
use sd_multirate::{c2d_nonideal, NonIdeal};

/// Poles with `|s·h|` below this are rigid-body poles.
const RIGID_SH: f64 = 1e-4;
/// Poles with `|z|` below this are dropped (delay-like).
const MIN_ABS_Z: f64 = 0.05;

/// The continuous basis: small blocks (1 input, one output per basis function each), kept
/// apart so that every discretisation is of a 1- or 2-state model (O(n) per hypothesis instead
/// of one exponential of the whole augmented model).
#[derive(Debug, Clone)]
pub(crate) struct ModalBasis {
    blocks: Vec<StateSpace>,
    rigid: usize,
    /// Damping `a ≥ 0` of the two-state rigid body `ẋ = v, v̇ = −a v + u` (outputs `x` and
    /// `v`: `1/(s(s + a))` and `1/(s + a)`); 0 but in [`ModalBasis::with_damped_rigid_body`].
    rigid_damping: f64,
    real: Vec<f64>,
    pairs: Vec<C>,
}

/// `(|s|, ζ = −Re s/|s|)` of a continuous pole (rad/s; ζ = 0 at the origin).
fn natural(p: &C) -> (f64, f64) {
    let m = p.norm();
    (m, if m > 0.0 { -p.re / m } else { 0.0 })
}

impl ModalBasis {
    /// From the poles of a model at period `h` (`None`: continuous poles).
    pub(crate) fn from_model(model: &StateSpace) -> Result<Self> {
        Self::from_poles_of(model, false)
    }

    /// [`ModalBasis::from_model`] of one entry of a MIMO model with several rigid-body modes:
    /// rigid-body poles beyond two are dropped (one double integrator spans them all in a
    /// single entry) instead of read as real poles at the origin.
    pub(crate) fn from_model_entry(model: &StateSpace) -> Result<Self> {
        Self::from_poles_of(model, true)
    }

    fn from_poles_of(model: &StateSpace, drop_extra_rigid: bool) -> Result<Self> {
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
            let at_origin = (s * scale).norm() < RIGID_SH;
            if at_origin && rigid < 2 {
                rigid += 1;
            } else if at_origin && drop_extra_rigid {
                continue;
            } else if s.im.abs() <= 1e-9 * s.norm().max(1e-300) {
                real.push(s.re);
            } else if s.im > 0.0 {
                pairs.push(s);
            }
        }
        Self::build((rigid, 0.0), &real, &pairs)
    }

    /// The basis with a friction-damped rigid body where the model has none: a model fitted
    /// to data of a stage whose rigid body is damped (Coulomb friction at a small amplitude
    /// acts as a viscous `c_eq`) shows it as an integrator (a rigid-body pole, or real poles
    /// or a pole pair below `near_zero` rad/s: integrators for the data, dropped, the block's
    /// integrator stands for them) and a real corner `−c/m` below the modes (the first real
    /// pole above `near_zero`). They become one block `1/(s(s + a))`,
    /// `1/(s + a)` (the same span as `1/s`, `1/(s + a)`), whose residue on `1/(s(s + a))` is
    /// `1/m` whatever `a`: friction then moves one pole and leaves the residues alone, as
    /// the amplitude model assumes. Unchanged when the model has rigid-body poles or no such
    /// pair of real poles.
    pub(crate) fn with_damped_rigid_body(&self, near_zero: f64) -> Result<Self> {
        Ok(self
            .with_damped_rigid_body_at(near_zero, 0)?
            .unwrap_or_else(|| self.clone()))
    }

    /// The number of real poles [`ModalBasis::with_damped_rigid_body_at`] may take as the
    /// corner: at or above `near_zero`, below the lowest pair (0 where the model has two
    /// rigid-body poles or no integrator).
    pub(crate) fn corner_choices(&self, near_zero: f64) -> usize {
        (0..4)
            .take_while(|&n| {
                self.with_damped_rigid_body_at(near_zero, n)
                    .is_ok_and(|b| b.is_some())
            })
            .count()
    }

    /// [`ModalBasis::with_damped_rigid_body`] with the `nth` real pole at or above
    /// `near_zero` (slowest first) as the corner, the others kept as real poles; `None` where
    /// there is no such pole below the lowest pair, or no block to make.
    pub(crate) fn with_damped_rigid_body_at(
        &self,
        near_zero: f64,
        nth: usize,
    ) -> Result<Option<Self>> {
        let mut real = self.real.clone();
        real.sort_by(|a, b| b.total_cmp(a));
        // pole pairs below `near_zero` are integrators for the data too
        let (low, pairs): (Vec<C>, Vec<C>) = self.pairs.iter().partition(|p| p.norm() < near_zero);
        let lowest_pair = pairs.iter().map(|p| p.norm()).fold(f64::INFINITY, f64::min);
        let near: Vec<usize> = (0..real.len())
            .filter(|&k| real[k].abs() < near_zero)
            .collect();
        // an undamped rigid body already (two poles at z = 1), or no integrator at all
        if self.rigid >= 2 || (self.rigid == 0 && near.is_empty() && low.is_empty()) {
            return Ok(None);
        }
        // the corner: the nth real pole at or above `near_zero`, below the modes
        let first = (0..real.len()).find(|&k| real[k].abs() >= near_zero);
        let Some(k) = first.map(|f| f + nth).filter(|&k| k < real.len()) else {
            return Ok(None);
        };
        if real[k].abs() >= lowest_pair {
            return Ok(None);
        }
        let rest: Vec<f64> = (first.unwrap_or(k)..real.len())
            .filter(|&q| q != k)
            .map(|q| real[q])
            .collect();
        Self::build((2, real[k].abs()), &rest, &pairs).map(Some)
    }

    /// The basis with a friction-damped rigid body where a fit of the model experiment shows
    /// none at all: at the lowest level, where friction acts as a large viscous `c_eq`, a fit
    /// may spend two real poles below the modes on `1/(s(ms + c))` (the integrator then reads
    /// as the slower one). The slowest real pole becomes the integrator and the next the
    /// corner of the block `1/(s(s + a))`, `1/(s + a)` ([`ModalBasis::with_damped_rigid_body`]).
    /// `None` when the model has a rigid body or fewer than two real poles below its lowest
    /// pair. Whether the model experiment is still described is the caller's check.
    pub(crate) fn with_slow_poles_as_damped_rigid_body(&self) -> Result<Option<Self>> {
        if self.rigid > 0 {
            return Ok(None);
        }
        let lowest_pair = self
            .pairs
            .iter()
            .map(|p| p.norm())
            .fold(f64::INFINITY, f64::min);
        let mut real = self.real.clone();
        real.sort_by(|a, b| b.total_cmp(a));
        if real.len() < 2 || real[1].abs() >= lowest_pair {
            return Ok(None);
        }
        Self::build((2, real[1].abs()), &real[2..], &self.pairs).map(Some)
    }

    /// The basis with one integrator where the model has two rigid-body poles (a fit with one
    /// fixed rigid-body pole may put a free pole so near z = 1 that it reads as a second one,
    /// [`ModalBasis::from_model`]), so that a real corner below the modes can be read as a
    /// friction-damped rigid body ([`ModalBasis::with_damped_rigid_body`]); `None` unless the
    /// model has two undamped rigid-body poles. Whether the model experiment is still described
    /// is the caller's check.
    pub(crate) fn with_one_integrator(&self) -> Result<Option<Self>> {
        if self.rigid != 2 || self.rigid_damping != 0.0 {
            return Ok(None);
        }
        Self::build((1, 0.0), &self.real, &self.pairs).map(Some)
    }

    /// The basis with each group of pole pairs closer than twice their half-power
    /// half-widths together reduced to its least damped pair (a fit of a mode whose
    /// frequency wanders with amplitude, or of a distorted resonance, may split it into two
    /// close pairs, which then trade frequency and damping in a level fit); `None` when no
    /// pair is that close to another.
    pub(crate) fn without_close_pairs(&self) -> Result<Option<Self>> {
        let nat = natural;
        let close = |a: &C, b: &C| {
            let ((fa, za), (fb, zb)) = (nat(a), nat(b));
            (fa - fb).abs() <= 2.0 * (za * fa + zb * fb)
        };
        let keep: Vec<C> = self
            .pairs
            .iter()
            .filter(|p| {
                // dropped when a close neighbour is less damped (ties: the later one goes)
                !self.pairs.iter().any(|q| {
                    !std::ptr::eq(*p, q)
                        && close(p, q)
                        && (nat(q).1 < nat(p).1
                            || (nat(q).1 == nat(p).1 && (q as *const C) < (*p as *const C)))
                })
            })
            .copied()
            .collect();
        if keep.len() == self.pairs.len() {
            return Ok(None);
        }
        Self::build((self.rigid, self.rigid_damping), &self.real, &keep).map(Some)
    }

    /// A friction-damped rigid body's basis' ([`ModalBasis::with_damped_rigid_body`]) real
    /// poles and overdamped pairs (`ζ > 0.5`) below its lowest lightly damped pair, slowest
    /// first (real poles as `s + 0j`): a fit of a stage at the friction's level may spend
    /// them on the nonlinear low-frequency response, where they stay put while the corner
    /// moves. Empty when the rigid body is not damped.
    pub(crate) fn slow_extras(&self) -> Vec<C> {
        if !self.is_damped() {
            return Vec::new();
        }
        let zeta = |p: &C| natural(p).1;
        let lowest = self
            .pairs
            .iter()
            .filter(|p| zeta(p) <= 0.5)
            .map(|p| p.norm())
            .fold(f64::INFINITY, f64::min);
        let mut out: Vec<C> = self
            .real
            .iter()
            .map(|r| C::new(*r, 0.0))
            .chain(self.pairs.iter().copied().filter(|p| zeta(p) > 0.5))
            .filter(|p| p.norm() < lowest)
            .collect();
        out.sort_by(|a, b| a.norm().total_cmp(&b.norm()));
        out
    }

    /// The basis without the real poles and pairs in `drop` (as [`ModalBasis::slow_extras`]
    /// gives them).
    pub(crate) fn without_poles(&self, drop: &[C]) -> Result<Self> {
        let real: Vec<f64> = self
            .real
            .iter()
            .copied()
            .filter(|r| !drop.contains(&C::new(*r, 0.0)))
            .collect();
        let pairs: Vec<C> = self
            .pairs
            .iter()
            .copied()
            .filter(|p| !drop.contains(p))
            .collect();
        Self::build((self.rigid, self.rigid_damping), &real, &pairs)
    }

    /// What the basis is made of: (rigid-body poles, the rigid body's damping), the real
    /// poles and the pairs (upper half plane), all continuous (rad/s): what
    /// [`ModalBasis::build`] takes back.
    pub(crate) fn parts(&self) -> ((usize, f64), &[f64], &[C]) {
        ((self.rigid, self.rigid_damping), &self.real, &self.pairs)
    }

    /// The basis of [`ModalBasis::parts`].
    pub(crate) fn build((rigid, damping): (usize, f64), real: &[f64], pairs: &[C]) -> Result<Self> {
        Ok(ModalBasis {
            blocks: Self::blocks((rigid, damping), real, pairs)?,
            rigid,
            rigid_damping: damping,
            real: real.to_vec(),
            pairs: pairs.to_vec(),
        })
    }

    fn blocks(
        (rigid, damping): (usize, f64),
        real: &[f64],
        pairs: &[C],
    ) -> Result<Vec<StateSpace>> {
        let ct = SampleTime::Continuous;
        let block = |a: DMatrix<f64>, b: DMatrix<f64>| -> Result<StateSpace> {
            let n = a.nrows();
            Ok(StateSpace::new(
                a,
                b,
                DMatrix::identity(n, n),
                DMatrix::zeros(n, 1),
                ct,
            )?)
        };
        let mut blocks = Vec::new();
        match rigid {
            1 => blocks.push(block(
                DMatrix::zeros(1, 1),
                DMatrix::from_element(1, 1, 1.0),
            )?),
            2 => blocks.push(block(
                DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 0.0, -damping]),
                DMatrix::from_column_slice(2, 1, &[0.0, 1.0]),
            )?),
            _ => {}
        }
        for &p in real {
            blocks.push(block(
                DMatrix::from_element(1, 1, p),
                DMatrix::from_element(1, 1, 1.0),
            )?);
        }
        for p in pairs {
            blocks.push(block(
                DMatrix::from_row_slice(2, 2, &[p.re, p.im, -p.im, p.re]),
                DMatrix::from_column_slice(2, 1, &[1.0, 0.0]),
            )?);
        }
        // the feedthrough: a constant
        blocks.push(StateSpace::new(
            DMatrix::zeros(0, 0),
            DMatrix::zeros(0, 1),
            DMatrix::zeros(1, 0),
            DMatrix::from_element(1, 1, 1.0),
            ct,
        )?);
        Ok(blocks)
    }

    /// Whether the rigid body is damped ([`ModalBasis::with_damped_rigid_body`]).
    pub(crate) fn is_damped(&self) -> bool {
        self.damped() == 1
    }

    /// Whether the rigid body's damping is a movable pole (a damped rigid body).
    fn damped(&self) -> usize {
        usize::from(self.rigid == 2 && self.rigid_damping > 0.0)
    }

    /// The column of pair `m`'s σ in [`ModalBasis::pole_sensitivities`] (ω is the next).
    pub(crate) fn pair_sensitivity_column(&self, m: usize) -> usize {
        self.damped() + self.real.len() + 2 * m
    }

    /// Every movable pole, the real ones first (as `p + 0j`: a damped rigid body's `−a`,
    /// then the others), then the pairs (upper half plane): the index space of
    /// [`ModalBasis::with_poles`] and [`ModalBasis::sensitivity_column`].
    pub(crate) fn poles(&self) -> Vec<C> {
        let rigid = (self.damped() == 1).then_some(-self.rigid_damping);
        rigid
            .into_iter()
            .chain(self.real.iter().copied())
            .map(|p| C::new(p, 0.0))
            .chain(self.pairs.iter().copied())
            .collect()
    }

    /// Whether pole `u` of [`ModalBasis::poles`] is the damped rigid body's `−a`.
    pub(crate) fn is_rigid_damping(&self, u: usize) -> bool {
        u < self.damped()
    }

    /// Whether pole `u` of [`ModalBasis::poles`] is real.
    pub(crate) fn is_real(&self, u: usize) -> bool {
        u < self.damped() + self.real.len()
    }

    /// The first column of pole `u`'s parameters in [`ModalBasis::pole_sensitivities`] (one
    /// for a real pole, σ and ω for a pair).
    pub(crate) fn sensitivity_column(&self, u: usize) -> usize {
        if self.is_real(u) {
            u
        } else {
            self.pair_sensitivity_column(u - self.damped() - self.real.len())
        }
    }

    /// The same basis with every movable pole replaced (the order of [`ModalBasis::poles`]).
    pub(crate) fn with_poles(&self, poles: &[C]) -> Result<Self> {
        let (d, nr) = (self.damped(), self.real.len());
        if poles.len() != d + nr + self.pairs.len() {
            return Err(DiagnoseError::Numerical(format!(
                "{} poles given for a basis of {}",
                poles.len(),
                d + nr + self.pairs.len()
            )));
        }
        let damping = if d == 1 {
            -poles[0].re
        } else {
            self.rigid_damping
        };
        let real: Vec<f64> = poles[d..d + nr].iter().map(|p| p.re).collect();
        Self::build((self.rigid, damping), &real, &poles[d + nr..])
    }

    /// Columns of the residue vector that belong to the rigid-body block.
    fn rigid_columns(&self) -> usize {
        match self.rigid {
            0 => 0,
            1 => 1,
            _ => 2,
        }
    }

    /// Sensitivities of `Σ r_j φ_j` to the pole parameters (each real pole; σ and ω of each
    /// pair), at period `ts` under `ni`: one row per frequency, one column per parameter.
    /// Central differences with a step of 1e-6·|s| (the blocks are 1×1 or 2×2, so this is
    /// cheap and accurate to ~1e-10 relative).
    pub(crate) fn pole_sensitivities(
        &self,
        r: &[f64],
        ts: f64,
        ni: NonIdeal,
        freq_hz: &[f64],
    ) -> Result<Vec<Vec<C>>> {
        let mut cols: Vec<Vec<C>> = Vec::new();
        let mut j = self.rigid_columns();
        let eval = |blk: &StateSpace| -> Result<Vec<Vec<C>>> {
            let d = c2d_nonideal(blk, ts, ni).map_err(|e| DiagnoseError::Setup(e.to_string()))?;
            let ev = sd_model::FreqRespEvaluator::new(&d)?;
            Ok(freq_hz
                .iter()
                .map(|&f| ev.eval_hz(f).column(0).iter().copied().collect())
                .collect())
        };
        let diff =
            |plus: &StateSpace, minus: &StateSpace, step: f64, w: &[f64]| -> Result<Vec<C>> {
                let (a, b) = (eval(plus)?, eval(minus)?);
                Ok(a.iter()
                    .zip(&b)
                    .map(|(x, y)| {
                        x.iter()
                            .zip(y)
                            .zip(w)
                            .map(|((p, m), wk)| (p - m) * (*wk / (2.0 * step)))
                            .sum()
                    })
                    .collect())
            };
        if self.damped() == 1 {
            let a = self.rigid_damping;
            let step = 1e-6 * a.max(1.0);
            let rb = |x: f64| Self::blocks((2, x), &[], &[]).map(|mut b| b.remove(0));
            // the pole is −a: d/dp = −d/da
            let mut col = diff(&rb(a + step)?, &rb(a - step)?, step, &r[0..2])?;
            col.iter_mut().for_each(|c| *c = -*c);
            cols.push(col);
        }
        for &p in &self.real {
            let step = 1e-6 * p.abs().max(1.0);
            let one = |x: f64| Self::blocks((0, 0.0), &[x], &[]).map(|mut b| b.remove(0));
            cols.push(diff(&one(p + step)?, &one(p - step)?, step, &r[j..j + 1])?);
            j += 1;
        }
        for &p in &self.pairs {
            let step = 1e-6 * p.norm().max(1.0);
            let two = |x: C| Self::blocks((0, 0.0), &[], &[x]).map(|mut b| b.remove(0));
            let w = &r[j..j + 2];
            cols.push(diff(&two(p + step)?, &two(p - step)?, step, w)?);
            let di = C::new(0.0, step);
            cols.push(diff(&two(p + di)?, &two(p - di)?, step, w)?);
            j += 2;
        }
        // transpose to one row per frequency
        Ok((0..freq_hz.len())
            .map(|i| cols.iter().map(|c| c[i]).collect())
            .collect())
    }

    fn discretised(&self, ts: f64, ni: NonIdeal) -> Result<Vec<StateSpace>> {
        self.blocks
            .iter()
            .map(|b| c2d_nonideal(b, ts, ni).map_err(|e| DiagnoseError::Setup(e.to_string())))
            .collect()
    }

    /// The basis responses at period `ts` under `ni`, at `freq_hz`: one row per frequency.
    pub(crate) fn responses(&self, ts: f64, ni: NonIdeal, freq_hz: &[f64]) -> Result<Vec<Vec<C>>> {
        let evs = self
            .discretised(ts, ni)?
            .iter()
            .map(sd_model::FreqRespEvaluator::new)
            .collect::<std::result::Result<Vec<_>, _>>()?;
        let widths: Vec<usize> = self.blocks.iter().map(StateSpace::ny).collect();
        let total: usize = widths.iter().sum();
        Ok(freq_hz
            .par_iter()
            .with_min_len(256)
            .map(|&f| {
                let mut row = vec![C::new(0.0, 0.0); total];
                let mut at = 0;
                for (ev, w) in evs.iter().zip(&widths) {
                    ev.eval_hz_into(f, &mut row[at..at + w]);
                    at += w;
                }
                row
            })
            .collect())
    }

    /// The discrete model `Σ r_j φ_j` at period `ts` under `ni` (the blocks in parallel).
    pub(crate) fn model(&self, r: &[f64], ts: f64, ni: NonIdeal) -> Result<StateSpace> {
        stacked(&self.discretised(ts, ni)?, r, SampleTime::discrete(ts)?)
    }

    /// The continuous model `Σ r_j φ_j(s)` (the blocks in parallel, before any hold or
    /// sampler): what `sdctl c2d` discretises with the named non-idealities.
    pub(crate) fn continuous(&self, r: &[f64]) -> Result<StateSpace> {
        stacked(&self.blocks, r, SampleTime::Continuous)
    }
}

/// The blocks in parallel, each block's outputs weighted by its residues: one input, one output.
fn stacked(blocks: &[StateSpace], r: &[f64], time: SampleTime) -> Result<StateSpace> {
    let n: usize = blocks.iter().map(StateSpace::n).sum();
    let mut a = DMatrix::zeros(n, n);
    let mut b = DMatrix::zeros(n, 1);
    let mut c = DMatrix::zeros(1, n);
    let mut d = DMatrix::zeros(1, 1);
    let (mut i, mut j) = (0, 0);
    for blk in blocks {
        let (k, m) = (blk.n(), blk.ny());
        let row = DMatrix::from_row_slice(1, m, &r[j..j + m]);
        a.view_mut((i, i), (k, k)).copy_from(blk.a());
        b.view_mut((i, 0), (k, 1)).copy_from(blk.b());
        c.view_mut((0, i), (1, k)).copy_from(&(&row * blk.c()));
        d += &row * blk.d();
        i += k;
        j += m;
    }
    Ok(StateSpace::new(a, b, c, d, time)?)
}

/// Residues fitted to an FRF, with their covariance (and, after [`Residues::with_poles`], the
/// covariance of residues and pole parameters together).
#[derive(Debug, Clone)]
pub(crate) struct Residues {
    pub(crate) r: Vec<f64>,
    cov: DMatrix<f64>,
    full: Option<DMatrix<f64>>,
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
        let mut phis = Vec::with_capacity(rows.len());
        let mut g = Vec::with_capacity(rows.len());
        for &i in &rows {
            let w = 1.0 / var[i][(0, 0)].sqrt();
            phis.push(phi[i].iter().map(|v| v * w).collect::<Vec<C>>());
            g.push(frd.response()[i][(0, 0)] * w);
        }
        Self::fit_weighted(&phis, &g)
    }

    /// Least squares of `g ≈ Σ r_j φ_j` over rows already weighted by `1/σ` (real and
    /// imaginary parts as separate equations).
    pub(crate) fn fit_weighted(phi: &[Vec<C>], g: &[C]) -> Result<Self> {
        let nb = phi.first().map(|p| p.len()).unwrap_or(0);
        let m = 2 * phi.len();
        let mut j = DMatrix::zeros(m, nb);
        let mut y = DVector::zeros(m);
        for (k, (row, gk)) in phi.iter().zip(g).enumerate() {
            y[2 * k] = gk.re;
            y[2 * k + 1] = gk.im;
            for c in 0..nb.min(row.len()) {
                j[(2 * k, c)] = row[c].re;
                j[(2 * k + 1, c)] = row[c].im;
            }
        }
        let Ok(ls) = sd_model::linalg::lstsq(&j, &y) else {
            return Err(DiagnoseError::Setup(
                "the modal basis has no finite response on the model experiment's lines".into(),
            ));
        };
        Ok(Residues {
            r: ls.x.iter().copied().collect(),
            cov: ls.cov,
            full: None,
        })
    }

    /// Adds the Gauss–Newton covariance of residues and pole parameters together,
    /// `(JᵀWJ)⁻¹` with `J = [φ, ∂G/∂θ]` on the fast lines (`dphi` from
    /// [`ModalBasis::pole_sensitivities`]): the prediction variance of a model whose poles were
    /// fitted to the same data (a pole the data hardly determine shows as a wide prediction).
    pub(crate) fn with_poles(mut self, frd: &Frd, phi: &[Vec<C>], dphi: &[Vec<C>]) -> Result<Self> {
        let Some(var) = frd.variance() else {
            return Ok(self);
        };
        let (nb, np) = (self.r.len(), dphi.first().map(Vec::len).unwrap_or(0));
        if np == 0 {
            return Ok(self);
        }
        let rows: Vec<usize> = (0..frd.len()).filter(|&i| var[i][(0, 0)] > 0.0).collect();
        let mut j = DMatrix::zeros(2 * rows.len(), nb + np);
        for (k, &i) in rows.iter().enumerate() {
            let w = 1.0 / var[i][(0, 0)].sqrt();
            for c in 0..nb + np {
                let v = if c < nb { phi[i][c] } else { dphi[i][c - nb] };
                j[(2 * k, c)] = w * v.re;
                j[(2 * k + 1, c)] = w * v.im;
            }
        }
        let g = DVector::zeros(2 * rows.len());
        if let Ok(ls) = sd_model::linalg::lstsq(&j, &g) {
            self.full = Some(ls.cov);
        }
        Ok(self)
    }

    /// Scales the covariances: the weights `1/σ̂²` of the fit come from variances estimated
    /// with ν degrees of freedom, and `E[σ²/σ̂²] = ν/(ν − 2)`, so the nominal `(JᵀŴJ)⁻¹`
    /// understates the covariance by that factor.
    ///
    /// With correlated lines (LPM: inflation c, about c lines per independent datum) the
    /// nominal covariance understates the estimate's by c as well.
    pub(crate) fn for_estimated_weights(mut self, dof: f64, inflation: f64) -> Self {
        let k = inflation.max(1.0)
            * if dof.is_finite() && dof > 2.0 {
                dof / (dof - 2.0)
            } else {
                1.0
            };
        if k != 1.0 {
            self.cov *= k;
            if let Some(f) = &mut self.full {
                *f *= k;
            }
        }
        self
    }

    /// Parameters behind a prediction: the residues and, when their covariance is known, the
    /// pole parameters.
    pub(crate) fn n_params(&self) -> usize {
        self.full.as_ref().map_or(self.r.len(), |f| f.nrows())
    }

    /// The joint covariance of residues and pole parameters (after [`Residues::with_poles`]),
    /// ordered as the gradient `[φ, ∂φ/∂poles]` of [`Residues::predict_full`].
    pub(crate) fn joint_covariance(&self) -> Option<&DMatrix<f64>> {
        self.full.as_ref()
    }

    /// Residues with a saved covariance: `cov` is the residues' own (`r.len()` square) or the
    /// joint covariance of residues and pole parameters (larger), as [`Residues::with_poles`]
    /// orders it.
    pub(crate) fn with_covariance(r: Vec<f64>, cov: DMatrix<f64>) -> Self {
        let n = r.len();
        if cov.nrows() > n {
            Residues {
                r,
                cov: cov.view((0, 0), (n, n)).into_owned(),
                full: Some(cov),
            }
        } else {
            Residues { r, cov, full: None }
        }
    }

    /// The covariance to save: the joint one where the poles' is known, else the residues'.
    pub(crate) fn saved_covariance(&self) -> &DMatrix<f64> {
        self.full.as_ref().unwrap_or(&self.cov)
    }

    /// The prediction variance at `freq_hz` of the model `Σ r_j φ_j` on `basis` at period
    /// `ts` under `ni`: `gᴴΣg` with `g = [φ, ∂φ/∂poles]` where the poles' covariance is
    /// known ([`Residues::predict_full`]), `φᴴΣ_rφ` otherwise.
    ///
    /// # Errors
    /// A basis that cannot be discretised at `ts`.
    pub(crate) fn variances(
        &self,
        basis: &ModalBasis,
        ts: f64,
        ni: NonIdeal,
        freq_hz: &[f64],
    ) -> Result<Vec<f64>> {
        let phi = basis.responses(ts, ni, freq_hz)?;
        if self.full.is_none() {
            return Ok(phi.iter().map(|p| self.predict(p).1).collect());
        }
        let dphi = basis.pole_sensitivities(&self.r, ts, ni, freq_hz)?;
        Ok(phi
            .iter()
            .zip(&dphi)
            .map(|(p, d)| self.predict_full(p, d).1)
            .collect())
    }

    /// Residues taken as known (no covariance): a saved model's.
    pub(crate) fn known(r: Vec<f64>) -> Self {
        let n = r.len();
        Residues {
            r,
            cov: DMatrix::zeros(n, n),
            full: None,
        }
    }

    /// The covariances times `k`.
    pub(crate) fn scaled(mut self, k: f64) -> Self {
        self.cov *= k;
        if let Some(f) = &mut self.full {
            *f *= k;
        }
        self
    }

    /// The prediction `Σ r_j φ_j` and its variance (residues only).
    pub(crate) fn predict(&self, phi: &[C]) -> (C, f64) {
        let p = phi.iter().zip(&self.r).map(|(f, r)| f * *r).sum();
        (p, quad(&self.cov, phi))
    }

    /// The prediction and its variance with the poles' uncertainty (`dphi` the pole
    /// sensitivities at this line); residues only without [`Residues::with_poles`].
    pub(crate) fn predict_full(&self, phi: &[C], dphi: &[C]) -> (C, f64) {
        let p = phi.iter().zip(&self.r).map(|(f, r)| f * *r).sum();
        match &self.full {
            Some(cov) => {
                let g: Vec<C> = phi.iter().chain(dphi).copied().collect();
                (p, quad(cov, &g))
            }
            None => (p, quad(&self.cov, phi)),
        }
    }
}

/// `Re(g)ᵀ Σ Re(g) + Im(g)ᵀ Σ Im(g)` (≥ 0).
fn quad(cov: &DMatrix<f64>, g: &[C]) -> f64 {
    let n = g.len().min(cov.nrows());
    let re = DVector::from_iterator(n, g.iter().take(n).map(|f| f.re));
    let im = DVector::from_iterator(n, g.iter().take(n).map(|f| f.im));
    let v = (re.transpose() * cov.view((0, 0), (n, n)) * &re)[(0, 0)]
        + (im.transpose() * cov.view((0, 0), (n, n)) * &im)[(0, 0)];
    v.max(0.0)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A friction-damped rigid body `1/(s(ms + c))` (m = 2, c/m = 200 rad/s) with a mode, as
    /// a fit shows it (one integrator, a real corner): the damped block spans it exactly with
    /// the residue `1/m` on `1/(s(s + a))` and none on `1/(s + a)`, and with those residues
    /// unchanged it is exact again after friction halves the corner (`a` = 100) — the
    /// property the amplitude model relies on. In the plain basis `1/s`, `1/(s + a)` the
    /// residues would have to change (`±1/(m a)`).
    #[test]
    fn damped_rigid_body_keeps_its_residues_when_the_corner_moves() {
        let pair = C::new(-20.0, 2000.0);
        let plain = ModalBasis::build((1, 0.0), &[-200.0], &[pair]).unwrap();
        let damped = plain.with_damped_rigid_body(10.0).unwrap();
        assert_eq!(damped.poles().len(), 2);
        assert!(damped.is_rigid_damping(0) && (damped.poles()[0].re + 200.0).abs() < 1e-12);
        let ts = 2e-4;
        let ff: Vec<f64> = (1..400).map(|k| k as f64 * 2.0).collect();
        let truth = |a: f64| {
            // 1/(m s (s + a)) + 3/(s² − 2σ s + |p|²), exactly discretised through the blocks
            let b = ModalBasis::build((2, a), &[], &[pair]).unwrap();
            let d = b
                .model(&[0.5, 0.0, 0.0, 3.0, 0.0], ts, NonIdeal::ideal())
                .unwrap();
            d.freqresp(&ff).unwrap()
        };
        let g: Vec<C> = truth(200.0).response().iter().map(|r| r[(0, 0)]).collect();
        let phi = damped.responses(ts, NonIdeal::ideal(), &ff).unwrap();
        let res = Residues::fit_weighted(&phi, &g).unwrap();
        assert!(
            (res.r[0] - 0.5).abs() < 1e-8 && res.r[1].abs() < 1e-8,
            "{:?}",
            res.r
        );
        let moved = damped.with_poles(&[C::new(-100.0, 0.0), pair]).unwrap();
        let phi2 = moved.responses(ts, NonIdeal::ideal(), &ff).unwrap();
        let want = truth(100.0);
        let worst = phi2
            .iter()
            .zip(want.response())
            .map(|(ph, w)| ((res.predict(ph).0 - w[(0, 0)]) / w[(0, 0)]).norm())
            .fold(0.0, f64::max);
        assert!(worst < 1e-8, "{worst}");
        // an undamped rigid body (two poles at z = 1) is left alone
        let undamped = ModalBasis::build((2, 0.0), &[-200.0], &[pair]).unwrap();
        assert_eq!(
            undamped.with_damped_rigid_body(10.0).unwrap().poles().len(),
            2
        );
        assert!(!undamped
            .with_damped_rigid_body(10.0)
            .unwrap()
            .is_rigid_damping(0));
    }

    /// The slow extras of a damped rigid body's basis are the real poles and overdamped
    /// pairs below the lowest lightly damped pair, slowest first; an undamped basis has none.
    #[test]
    fn slow_extras_are_the_poles_below_the_first_mode() {
        let mode = C::new(-20.0, 2000.0);
        let over = C::new(-900.0, 300.0);
        let b = ModalBasis::build((2, 50.0), &[-5000.0, -400.0], &[mode, over]).unwrap();
        let extras = b.slow_extras();
        assert_eq!(extras, vec![C::new(-400.0, 0.0), over], "{extras:?}");
        let slim = b.without_poles(&extras).unwrap();
        assert!(slim.is_damped());
        let left: Vec<C> = slim.poles();
        assert_eq!(left.len(), 3, "{left:?}");
        assert!(left.contains(&C::new(-5000.0, 0.0)) && left.contains(&mode));
        let undamped = ModalBasis::build((2, 0.0), &[-400.0], &[mode]).unwrap();
        assert!(undamped.slow_extras().is_empty());
    }

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
    }
}
