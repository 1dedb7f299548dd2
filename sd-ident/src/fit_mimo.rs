//! A common-pole fit of a MIMO FRD: one set of poles for every entry, residue matrices of the
//! rank the data support, realised in modal form with the fewest states.
//!
//! **Model** (the partial fractions of [`mod@crate::fit`], with matrix residues):
//! `Ĝ(z) = Σ_i R_i/(z − p_i) + Σ_{l=1}^{m} C_l/(z − 1)^l + D`, `R_i`, `C_l`, `D` ∈ ℂ^{ny×nu}
//! (`R_i` real for a real pole, conjugate for the pair's other pole). Every entry `(a, b)` has
//! its own weights `w_k^{ab}` (the FRD's per-entry variance, relative or uniform,
//! [`Weighting`]); the cost is `V = Σ_{ab} Σ_k (w_k^{ab})² |G_k^{ab} − Ĝ^{ab}(z_k)|²`.
//!
//! **Step 1, vector fitting with a common denominator** (Gustavsen & Semlyen 1999;
//! Deschrijver, Mrozowski, Dhaene & De Zutter, IEEE MWCL 18(6), 2008, "fast VF"): one
//! `σ(z) = 1 + Σ c̃_i φ_i(z)` for every entry, each entry with its own numerator. Per entry the
//! QR factorisation of `[Φ, −G Φ_free, G]` (weighted) leaves in its trailing block the
//! equations of `c̃` with the entry's numerator eliminated; those blocks of all entries are
//! stacked and solved together, and the zeros of σ are the new poles (reflected into the unit
//! disc, the damping floor applied, as in the SISO fit).
//!
//! **Step 2, Levenberg–Marquardt by variable projection** (Golub & Pereyra 1973; Kaufman's
//! Jacobian, BIT 15, 1975): only the poles are iterated; for given poles every entry's
//! residues are the weighted least-squares solution. The Gauss–Newton equations of the poles
//! come, per entry, from the QR factorisation of `[Φ, (∂Φ/∂θ) r, G]`: its trailing block is
//! the linearised residual with the residues eliminated. Marquardt's damping, scaled by the
//! column norms.
//!
//! **Step 3, residue ranks.** Each free pole's residue matrix `R = Σ s_l u_l v_lᴴ` (SVD). With
//! variance weights the residues' covariance is known (each entry's least squares), and the
//! smaller singular values are tested: `Σ_{l>k} s_l² / var(s_{k+1})` against the χ² quantile
//! of `2(ny − k)(nu − k)` (pairs; half that for a real pole) degrees of freedom at `alpha`.
//! The chosen ranks are then imposed by alternating least squares (outputs' factors given the
//! inputs', and back) on the weighted cost, the poles fixed. [`ResidueRank::Fixed`] imposes a
//! rank on every pole; [`ResidueRank::Full`] keeps the free residues.
//!
//! **Realisation.** A real pole of rank k: k states (`B = S Vᵀ`, `C = U`); a pair of rank k:
//! 2k states per `[[α, −β], [β, α]]` block (`B = [Re b; Im b]`, `C = [2 Re c, −2 Im c]` for
//! each rank-one term `c b/(z − p)`); the rigid body by Ho–Kalman with the rank of its
//! Markov parameters' Hankel matrix (`rigid_block`). A 2×2 structure with rank-one modes
//! has a quarter of the states of four SISO fits of the same order.

use crate::error::{IdentError, Result};
use crate::fit::{
    numerator_basis, reflect, sigma_zeros, starting_poles, weights_entry, Data, FitOptions,
    FitProgress, Weighting,
};
use crate::input_delay::{shift_inputs, DelayScan, InputDelay};
use faer::Mat;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::{Frd, SampleTime, StateSpace};
use std::f64::consts::PI;

mod rank;
mod realise;
use rank::*;
use realise::*;

/// The rank of each free pole's residue matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case", tag = "kind", content = "rank")]
pub enum ResidueRank {
    /// Free residues (the realisation still uses each residue's numerical rank).
    Full,
    /// The rank the data support (module documentation, step 3); full rank without variance
    /// weights.
    Select,
    /// This rank for every free pole (at most `min(ny, nu)`).
    Fixed(usize),
}

impl std::str::FromStr for ResidueRank {
    type Err = String;

    /// `select`, `full` or a positive number (the command line's and Python's spelling).
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "select" => Ok(ResidueRank::Select),
            "full" => Ok(ResidueRank::Full),
            n => match n.parse::<usize>() {
                Ok(k) if k > 0 => Ok(ResidueRank::Fixed(k)),
                _ => Err(format!(
                    "`{n}` is not a rank: use select, full or a positive number"
                )),
            },
        }
    }
}

/// Settings of a common-pole fit.
#[derive(Debug, Clone, PartialEq)]
pub struct MimoFitOptions {
    /// Order (free poles plus rigid-body poles, counted once for all entries), weighting,
    /// iterations, damping floor: as the SISO fit.
    pub fit: FitOptions,
    /// Residue ranks.
    pub rank: ResidueRank,
    /// False-alarm probability of each rank test ([`ResidueRank::Select`]).
    pub alpha: f64,
    /// Whole-sample input delays (leads included) fitted outside the rational part
    /// ([`crate::input_delay`]; default none).
    pub input_delay: InputDelay,
}

impl Default for MimoFitOptions {
    fn default() -> Self {
        MimoFitOptions {
            fit: FitOptions::default(),
            rank: ResidueRank::Select,
            alpha: 0.01,
            input_delay: InputDelay::None,
        }
    }
}

/// One free pole of a common-pole fit.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MimoMode {
    /// Natural frequency `|s|/2π` of `s = ln(p)/T` (Hz).
    pub freq_hz: f64,
    /// Damping ratio `−Re s/|s|` (1 for a real pole).
    pub damping: f64,
    /// Singular values of the free residue matrix, largest first.
    pub singular_values: Vec<f64>,
    /// The rank used.
    pub rank: usize,
    /// Output direction `u₁` of the largest singular value (magnitudes, unit norm).
    pub output_direction: Vec<f64>,
    /// Input direction `v₁` (magnitudes, unit norm).
    pub input_direction: Vec<f64>,
}

/// A common-pole fit.
#[derive(Debug, Clone)]
pub struct MimoFitResult {
    /// The modal realisation at the FRD's sample time (ny outputs, nu inputs) of `H`: the
    /// response to the inputs shifted by `input_delay` (none by default).
    pub model: StateSpace,
    /// Each input's delay in samples, `G(z) = H(z)·diag(z^{−δ_j})` (negative: the outputs
    /// respond before the input as recorded; [`crate::input_delay`]).
    pub input_delay: Vec<i32>,
    /// The cost of each input's column at each delay tried, when they were estimated.
    pub delay_scans: Vec<DelayScan>,
    /// Cost V with the ranks used.
    pub cost: f64,
    /// Cost with free (full-rank) residues at the same poles.
    pub full_rank_cost: f64,
    /// Each entry's part of `cost` (ny × nu).
    pub entry_cost: DMatrix<f64>,
    /// Cost after each SK and accepted LM iteration (full-rank residues).
    pub history: Vec<FitProgress>,
    /// The free poles (upper half-plane representative of each pair) and the rigid-body poles.
    pub poles: Vec<C>,
    /// Per free pole (real poles first, then pairs): frequency, damping, ranks.
    pub modes: Vec<MimoMode>,
    /// Median of `|G − Ĝ|/|G|` over every entry and line.
    pub median_rel_error: f64,
}

/// The weighted data of every entry, sharing `z`.
struct Entries {
    /// One SISO data set per entry, row-major (`a·nu + b`).
    data: Vec<Data>,
    ny: usize,
    nu: usize,
    /// The FRD has per-entry variances.
    has_variance: bool,
}

/// Residues of one entry: per free basis column, rigid, feedthrough (as
/// [`numerator_basis`] orders them), and their covariance.
struct EntryFit {
    x: Vec<f64>,
    cov: DMatrix<f64>,
}

/// The weighted least squares of every entry's numerator for given poles.
fn entry_residues(
    e: &Entries,
    real: &[f64],
    pairs: &[C],
    m: usize,
    feed: bool,
) -> Result<Vec<EntryFit>> {
    e.data
        .iter()
        .map(|d| {
            let a = weighted_basis(d, real, pairs, m, feed);
            let b: Vec<f64> =
                d.g.iter()
                    .zip(&d.w)
                    .flat_map(|(g, w)| [w * g.re, w * g.im])
                    .collect();
            let ls = sd_model::linalg::lstsq_faer(a.as_ref(), &b).map_err(|err| {
                IdentError::Numerical(format!("the residues' least squares failed: {err}"))
            })?;
            Ok(EntryFit {
                x: ls.x.iter().copied().collect(),
                cov: ls.cov,
            })
        })
        .collect()
}

/// The weighted numerator basis of one entry (2K × columns, real and imaginary rows).
fn weighted_basis(d: &Data, real: &[f64], pairs: &[C], m: usize, feed: bool) -> Mat<f64> {
    let mut row = Vec::new();
    numerator_basis(real, pairs, m, feed, d.z[0], &mut row);
    let ncol = row.len();
    let mut a = Mat::<f64>::zeros(2 * d.z.len(), ncol);
    for (i, (&z, &w)) in d.z.iter().zip(&d.w).enumerate() {
        numerator_basis(real, pairs, m, feed, z, &mut row);
        for (j, v) in row.iter().enumerate() {
            a[(2 * i, j)] = w * v.re;
            a[(2 * i + 1, j)] = w * v.im;
        }
    }
    a
}

/// Evaluates an entry's numerator coefficients `x` at `z`.
fn eval(x: &[f64], real: &[f64], pairs: &[C], m: usize, feed: bool, z: C, row: &mut Vec<C>) -> C {
    numerator_basis(real, pairs, m, feed, z, row);
    row.iter().zip(x).map(|(v, c)| v * *c).sum()
}

/// Per entry and line, the model with residues `xs` minus the data, and the data.
fn residuals(
    e: &Entries,
    xs: &[Vec<f64>],
    real: &[f64],
    pairs: &[C],
    m: usize,
    feed: bool,
) -> Vec<Vec<(C, C)>> {
    let mut row = Vec::new();
    e.data
        .iter()
        .zip(xs)
        .map(|(d, x)| {
            d.z.iter()
                .zip(&d.g)
                .map(|(&z, &g)| (eval(x, real, pairs, m, feed, z, &mut row) - g, g))
                .collect()
        })
        .collect()
}

/// Every entry's weighted cost for residues `xs`.
fn entry_costs(
    e: &Entries,
    xs: &[Vec<f64>],
    real: &[f64],
    pairs: &[C],
    m: usize,
    feed: bool,
) -> Vec<f64> {
    residuals(e, xs, real, pairs, m, feed)
        .iter()
        .zip(&e.data)
        .map(|(r, d)| {
            r.iter()
                .zip(&d.w)
                .map(|((dv, _), w)| (w * dv).norm_sqr())
                .sum()
        })
        .collect()
}

/// The trailing `rows × (cols)` block of the R factor of `[a | extra]` (columns of `a` first):
/// the equations of the `extra` columns with `a`'s unknowns eliminated.
fn trailing_block(a: &Mat<f64>, extra: &Mat<f64>) -> Mat<f64> {
    let (k, na, ne) = (a.nrows(), a.ncols(), extra.ncols());
    let mut aug = Mat::<f64>::zeros(k, na + ne);
    aug.as_mut().submatrix_mut(0, 0, k, na).copy_from(a);
    aug.as_mut().submatrix_mut(0, na, k, ne).copy_from(extra);
    let r = sd_model::linalg::qr_r(aug);
    let rows = ne.min(k.saturating_sub(na));
    Mat::from_fn(rows, ne, |i, j| r[(na + i, na + j)])
}

/// The blocks' equations stacked: the first `cols` columns of each as the matrix (with
/// `spare` zero rows below, for a damping term), its column `cols` as the right-hand side.
fn stack(blocks: &[Mat<f64>], cols: usize, spare: usize) -> (Mat<f64>, Vec<f64>) {
    let rows: usize = blocks.iter().map(|b| b.nrows()).sum();
    let mut m = Mat::<f64>::zeros(rows + spare, cols);
    let mut rhs = vec![0.0; rows + spare];
    let mut at = 0;
    for b in blocks {
        for i in 0..b.nrows() {
            for c in 0..cols {
                m[(at + i, c)] = b[(i, c)];
            }
            rhs[at + i] = b[(i, cols)];
        }
        at += b.nrows();
    }
    (m, rhs)
}

/// One common-denominator pole relocation (module documentation, step 1).
fn relocate_common(
    e: &Entries,
    real: &[f64],
    pairs: &[C],
    m: usize,
    feed: bool,
) -> Result<(Vec<f64>, Vec<C>)> {
    let nf = real.len() + 2 * pairs.len();
    let mut blocks = Vec::with_capacity(e.data.len());
    let mut row = Vec::new();
    for d in &e.data {
        let a = weighted_basis(d, real, pairs, m, feed);
        let mut extra = Mat::<f64>::zeros(2 * d.z.len(), nf + 1);
        for (i, ((&z, &g), &w)) in d.z.iter().zip(&d.g).zip(&d.w).enumerate() {
            numerator_basis(real, pairs, m, feed, z, &mut row);
            for (j, v) in row[..nf].iter().enumerate() {
                let t = -g * v * w;
                extra[(2 * i, j)] = t.re;
                extra[(2 * i + 1, j)] = t.im;
            }
            extra[(2 * i, nf)] = w * g.re;
            extra[(2 * i + 1, nf)] = w * g.im;
        }
        blocks.push(trailing_block(&a, &extra));
    }
    let (s, rhs) = stack(&blocks, nf, 0);
    let ls = sd_model::linalg::lstsq_faer(s.as_ref(), &rhs).map_err(|err| {
        IdentError::Numerical(format!("the common pole relocation failed: {err}"))
    })?;
    let ct: Vec<f64> = ls.x.iter().copied().collect();
    sigma_zeros(real, pairs, &ct, &e.data[0])
}

/// The pole parameters: real poles, then `(Re, Im)` of each pair.
fn pole_params(real: &[f64], pairs: &[C]) -> Vec<f64> {
    real.iter()
        .copied()
        .chain(pairs.iter().flat_map(|p| [p.re, p.im]))
        .collect()
}

/// The poles of parameters `v` ([`pole_params`]), made admissible.
fn poles_of(v: &[f64], nr: usize, d: &Data) -> (Vec<f64>, Vec<C>) {
    let real = v[..nr]
        .iter()
        .map(|&p| reflect(C::new(p, 0.0)).re)
        .collect();
    let pairs = v[nr..]
        .chunks(2)
        .map(|c| d.constrain(C::new(c[0], c[1])))
        .collect();
    (real, pairs)
}

/// One entry's weighted `∂(Φ x)/∂θ` (2K × poles' parameters) and its data column.
fn pole_derivatives(d: &Data, x: &[f64], real: &[f64], pairs: &[C]) -> Mat<f64> {
    let np = real.len() + 2 * pairs.len();
    let jj = C::new(0.0, 1.0);
    let mut out = Mat::<f64>::zeros(2 * d.z.len(), np + 1);
    for (i, ((&z, &g), &w)) in d.z.iter().zip(&d.g).zip(&d.w).enumerate() {
        let mut put = |c: usize, v: C| {
            out[(2 * i, c)] = w * v.re;
            out[(2 * i + 1, c)] = w * v.im;
        };
        for (q, &p) in real.iter().enumerate() {
            let u = 1.0 / (z - p);
            put(q, x[q] * u * u);
        }
        for (q, &a) in pairs.iter().enumerate() {
            let off = real.len() + 2 * q;
            let (c1, c2) = (x[off], x[off + 1]);
            let (u, v) = (1.0 / (z - a), 1.0 / (z - a.conj()));
            let (s, t) = (u * u + v * v, u * u - v * v);
            put(off, c1 * s + c2 * jj * t);
            put(off + 1, c1 * jj * t - c2 * s);
        }
        put(np, g);
    }
    out
}

/// The common poles' state during the iterations.
struct PoleFit {
    real: Vec<f64>,
    pairs: Vec<C>,
    fits: Vec<EntryFit>,
    cost: f64,
}

impl PoleFit {
    fn at(e: &Entries, real: Vec<f64>, pairs: Vec<C>, m: usize, feed: bool) -> Result<Self> {
        let fits = entry_residues(e, &real, &pairs, m, feed)?;
        let xs: Vec<Vec<f64>> = fits.iter().map(|f| f.x.clone()).collect();
        let cost = entry_costs(e, &xs, &real, &pairs, m, feed).iter().sum();
        Ok(PoleFit {
            real,
            pairs,
            fits,
            cost,
        })
    }
}

/// Levenberg–Marquardt on the poles by variable projection (module documentation, step 2).
fn lm_common(
    e: &Entries,
    mut cur: PoleFit,
    opt: &FitOptions,
    history: &mut Vec<FitProgress>,
    progress: &mut dyn FnMut(&FitProgress),
) -> Result<PoleFit> {
    let (m, feed) = (opt.rigid_body, opt.feedthrough);
    let np = cur.real.len() + 2 * cur.pairs.len();
    if np == 0 {
        return Ok(cur);
    }
    let mut lambda: f64 = 1e-3;
    let mut accepted = 0;
    for _ in 0..opt.lm_iterations {
        let mut blocks = Vec::with_capacity(e.data.len());
        for (d, f) in e.data.iter().zip(&cur.fits) {
            let a = weighted_basis(d, &cur.real, &cur.pairs, m, feed);
            blocks.push(trailing_block(
                &a,
                &pole_derivatives(d, &f.x, &cur.real, &cur.pairs),
            ));
        }
        let rows: usize = blocks.iter().map(|b| b.nrows()).sum();
        let (mut j, rhs) = stack(&blocks, np, np);
        let dn: Vec<f64> = (0..np)
            .map(|c| (0..rows).map(|r| j[(r, c)].powi(2)).sum::<f64>().sqrt())
            .collect();
        let theta = pole_params(&cur.real, &cur.pairs);
        let mut improved = false;
        for _ in 0..12 {
            for c in 0..np {
                j[(rows + c, c)] = lambda.sqrt() * dn[c].max(f64::MIN_POSITIVE);
            }
            let Ok(step) = sd_model::linalg::lstsq_faer(j.as_ref(), &rhs) else {
                lambda *= 10.0;
                continue;
            };
            let trial: Vec<f64> = theta
                .iter()
                .zip(step.x.iter())
                .map(|(t, s)| t + s)
                .collect();
            let (real, pairs) = poles_of(&trial, cur.real.len(), &e.data[0]);
            let cand = PoleFit::at(e, real, pairs, m, feed);
            match cand {
                Ok(c) if c.cost.is_finite() && c.cost < cur.cost => {
                    let rel = (cur.cost - c.cost) / cur.cost;
                    cur = c;
                    lambda = (lambda / 3.0).max(1e-12);
                    improved = true;
                    accepted += 1;
                    let p = FitProgress {
                        stage: "lm",
                        iteration: accepted,
                        cost: cur.cost,
                    };
                    progress(&p);
                    history.push(p);
                    if rel < crate::tol::LM_STOP {
                        return Ok(cur);
                    }
                    break;
                }
                _ => lambda *= 4.0,
            }
        }
        if !improved {
            break;
        }
    }
    Ok(cur)
}

/// Fits one set of poles to every entry of a MIMO FRD (module documentation).
///
/// # Errors
/// A continuous-time FRD, an order below the rigid-body count, a fixed rank above
/// `min(ny, nu)` or zero, too few lines for the parameters, NaN data, a singular
/// least-squares problem.
pub fn fit_common_poles(frd: &Frd, opt: &MimoFitOptions) -> Result<MimoFitResult> {
    fit_common_poles_with_progress(frd, opt, &mut |_| {})
}

/// [`fit_common_poles`] reporting each iteration to `progress`.
pub fn fit_common_poles_with_progress(
    frd: &Frd,
    opt: &MimoFitOptions,
    progress: &mut dyn FnMut(&FitProgress),
) -> Result<MimoFitResult> {
    let fo = &opt.fit;
    let (delay, scans) = crate::input_delay::resolve(frd, opt)?;
    let shifted;
    let frd = if delay.iter().any(|d| *d != 0) {
        shifted = shift_inputs(frd, &delay)?;
        &shifted
    } else {
        frd
    };
    let (ts, e) = entries(frd, fo)?;
    let (ny, nu) = (e.ny, e.nu);
    if let ResidueRank::Fixed(k) = opt.rank {
        if k == 0 || k > ny.min(nu) {
            return Err(IdentError::InvalidArgument(format!(
                "residue rank {k} must be between 1 and min(ny, nu) = {}",
                ny.min(nu)
            )));
        }
    }
    if !(opt.alpha > 0.0 && opt.alpha < 0.5) {
        return Err(IdentError::InvalidArgument(format!(
            "the rank test's alpha {} must be in (0, 0.5)",
            opt.alpha
        )));
    }
    let (m, feed) = (fo.rigid_body, fo.feedthrough);
    let nf = fo.order - m;
    let (mut real, mut pairs) = starting_poles(frd.freq_hz(), ts, nf);
    let mut history = Vec::new();
    let mut best: Option<PoleFit> = None;
    for it in 0..fo.sk_iterations {
        (real, pairs) = relocate_common(&e, &real, &pairs, m, feed)?;
        let pf = PoleFit::at(&e, real.clone(), pairs.clone(), m, feed)?;
        let p = FitProgress {
            stage: "sk",
            iteration: it + 1,
            cost: pf.cost,
        };
        progress(&p);
        history.push(p);
        if best.as_ref().is_none_or(|b| pf.cost < b.cost) {
            best = Some(pf);
        }
    }
    let start = match best {
        Some(b) => b,
        None => PoleFit::at(&e, real, pairs, m, feed)?,
    };
    let pf = lm_common(&e, start, fo, &mut history, progress)?;
    let mut r = finish(&e, pf, opt, history, ts)?;
    r.input_delay = delay;
    r.delay_scans = scans;
    Ok(r)
}

/// Ranks, the rank-constrained residues, the realisation and the report of a pole fit.
fn finish(
    e: &Entries,
    pf: PoleFit,
    opt: &MimoFitOptions,
    history: Vec<FitProgress>,
    ts: f64,
) -> Result<MimoFitResult> {
    let (ny, nu, m, feed) = (e.ny, e.nu, opt.fit.rigid_body, opt.fit.feedthrough);
    let nf = pf.real.len() + 2 * pf.pairs.len();
    let cols = pole_columns(pf.real.len(), pf.pairs.len());
    let xs: Vec<Vec<f64>> = pf.fits.iter().map(|f| f.x.clone()).collect();
    let variance = opt.fit.weighting == Weighting::Variance && e.has_variance;
    let numerical = |pc: (usize, bool)| {
        let s = residue_matrix(&xs, ny, nu, pc).singular_values();
        let top = s.iter().cloned().fold(0.0, f64::max);
        s.iter().filter(|v| **v > 1e-12 * top).count().max(1)
    };
    let ranks: Vec<usize> = cols
        .iter()
        .map(|&pc| match opt.rank {
            ResidueRank::Full => numerical(pc),
            ResidueRank::Fixed(k) => k,
            ResidueRank::Select if variance => supported_rank(&pf.fits, ny, nu, pc, opt.alpha),
            ResidueRank::Select => numerical(pc),
        })
        .collect();
    let f0 = factors(&xs, ny, nu, &cols, &ranks);
    let rest0: Vec<Vec<f64>> = xs.iter().map(|x| x[nf..].to_vec()).collect();
    let constrained = ranks.iter().zip(&cols).any(|(&k, &pc)| k < numerical(pc));
    let problem = Ranked {
        e,
        real: &pf.real,
        pairs: &pf.pairs,
        m,
        feed,
    };
    let (xs_final, f_final, rest_final) = if constrained {
        let mut f = f0.clone();
        let mut rest = rest0.clone();
        let (x2, _) = problem.solve_into(&mut f, &mut rest)?;
        (x2, f, rest)
    } else {
        (xs.clone(), f0, rest0)
    };
    let costs = entry_costs(e, &xs_final, &pf.real, &pf.pairs, m, feed);
    let model = realise(
        &f_final,
        &problem.poles(),
        &rest_final,
        (ny, nu, m, feed),
        ts,
    )?;
    let modes = cols
        .iter()
        .zip(&ranks)
        .zip(problem.poles())
        .map(|((&pc, &k), (p, _))| mode_report(&xs, ny, nu, pc, k, p, ts))
        .collect();
    let mut poles: Vec<C> = problem.poles().iter().map(|(p, _)| *p).collect();
    poles.extend(std::iter::repeat_n(C::new(1.0, 0.0), m));
    Ok(MimoFitResult {
        model,
        cost: costs.iter().sum(),
        full_rank_cost: pf.cost,
        entry_cost: DMatrix::from_fn(ny, nu, |a, b| costs[a * nu + b]),
        history,
        poles,
        modes,
        median_rel_error: median_rel_error(e, &xs_final, &pf.real, &pf.pairs, m, feed),
        input_delay: vec![0; nu],
        delay_scans: Vec::new(),
    })
}

/// One free pole's report.
fn mode_report(
    xs: &[Vec<f64>],
    ny: usize,
    nu: usize,
    pc: (usize, bool),
    rank: usize,
    p: C,
    ts: f64,
) -> MimoMode {
    let r = residue_matrix(xs, ny, nu, pc);
    let svd = r.svd(true, true);
    let s = (p.ln()) / ts;
    let unit = |v: Vec<f64>| {
        let n = v
            .iter()
            .map(|x| x * x)
            .sum::<f64>()
            .sqrt()
            .max(f64::MIN_POSITIVE);
        v.into_iter().map(|x| x / n).collect::<Vec<f64>>()
    };
    MimoMode {
        freq_hz: s.norm() / (2.0 * PI),
        damping: if s.norm() > 0.0 {
            -s.re / s.norm()
        } else {
            1.0
        },
        singular_values: svd.singular_values.iter().copied().collect(),
        rank,
        output_direction: svd.u.as_ref().map_or_else(Vec::new, |u| {
            unit((0..ny).map(|a| u[(a, 0)].norm()).collect())
        }),
        input_direction: svd.v_t.as_ref().map_or_else(Vec::new, |v| {
            unit((0..nu).map(|b| v[(0, b)].norm()).collect())
        }),
    }
}

/// Median of `|G − Ĝ|/|G|` over every entry and line.
fn median_rel_error(
    e: &Entries,
    xs: &[Vec<f64>],
    real: &[f64],
    pairs: &[C],
    m: usize,
    feed: bool,
) -> f64 {
    let mut rel: Vec<f64> = residuals(e, xs, real, pairs, m, feed)
        .iter()
        .flatten()
        .map(|(dv, g)| dv.norm() / g.norm().max(f64::MIN_POSITIVE))
        .collect();
    rel.sort_by(f64::total_cmp);
    rel.get(rel.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The per-entry data of a discrete MIMO FRD and its sample time (checks as the SISO fit).
fn entries(frd: &Frd, fo: &FitOptions) -> Result<(f64, Entries)> {
    let ts = crate::fit::discrete_ts(frd)?;
    crate::fit::check_options(fo)?;
    let (ny, nu) = frd.shape();
    let nf = fo.order - fo.rigid_body;
    // per entry: its residues, rigid and feedthrough; shared: the poles
    let nparams = 2 * nf + ny * nu * (nf + fo.rigid_body + usize::from(fo.feedthrough));
    if 2 * frd.len() * ny * nu <= nparams {
        return Err(IdentError::Data(format!(
            "{} lines of {ny}x{nu} entries give {} real equations, too few for {nparams} parameters",
            frd.len(),
            2 * frd.len() * ny * nu
        )));
    }
    let z: Vec<C> = frd
        .freq_hz()
        .iter()
        .map(|&f| C::from_polar(1.0, 2.0 * PI * f * ts))
        .collect();
    let mut data = Vec::with_capacity(ny * nu);
    for a in 0..ny {
        for b in 0..nu {
            let g: Vec<C> = frd.response().iter().map(|m| m[(a, b)]).collect();
            if g.iter().any(|v| !v.is_finite()) {
                return Err(IdentError::Data(format!(
                    "the FRD's entry ({}, {}) has NaN or infinite values",
                    a + 1,
                    b + 1
                )));
            }
            data.push(Data {
                z: z.clone(),
                w: weights_entry(frd, fo.weighting, (a, b))?,
                g,
                ts,
                min_damping: fo.min_damping,
                min_bandwidth_hz: fo.min_bandwidth_hz,
            });
        }
    }
    Ok((
        ts,
        Entries {
            data,
            ny,
            nu,
            has_variance: frd.variance().is_some(),
        },
    ))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use crate::rng::SplitMix;

    /// A 2×2 system of three lightly damped pairs at 1 kHz with the residues `r(i)` and a
    /// feedthrough; its FRD on 300 lines with relative noise `rel` (variance stored).
    fn system(r: impl Fn(usize) -> DMatrix<C>, rel: f64, seed: u64) -> (Vec<C>, Frd) {
        let ts = 1e-3;
        let modes = [(40.0, 0.02), (110.0, 0.01), (260.0, 0.03)];
        let poles: Vec<C> = modes
            .iter()
            .map(|&(f, z): &(f64, f64)| {
                let w = 2.0 * PI * f;
                (C::new(-z * w, w * (1.0 - z * z).sqrt()) * ts).exp()
            })
            .collect();
        let freq: Vec<f64> = (0..300).map(|k| 1.0 + 479.0 * k as f64 / 299.0).collect();
        let mut rng = SplitMix::new(seed);
        let (mut resp, mut var) = (Vec::new(), Vec::new());
        for &f in &freq {
            let z = C::from_polar(1.0, 2.0 * PI * f * ts);
            let mut g = DMatrix::from_element(2, 2, C::new(0.01, 0.0));
            for (i, &p) in poles.iter().enumerate() {
                let ri = r(i);
                g += ri.map(|v| v / (z - p)) + ri.map(|v| v.conj() / (z - p.conj()));
            }
            let sd = g.map(|v| rel * v.norm());
            let noisy = DMatrix::from_fn(2, 2, |a, b| {
                g[(a, b)] + C::new(rng.normal(), rng.normal()) * (sd[(a, b)] / 2f64.sqrt())
            });
            resp.push(noisy);
            var.push(sd.map(|s| s * s));
        }
        let frd = Frd::new(freq, resp, Some(var), SampleTime::discrete(ts).unwrap()).unwrap();
        (poles, frd)
    }

    fn rank_one(i: usize) -> DMatrix<C> {
        let c = [C::new(1.0, 0.2), C::new(-0.5, 0.4)];
        let b = [
            [C::new(0.3, 0.0), C::new(0.2, -0.1)],
            [C::new(-0.2, 0.1), C::new(0.4, 0.0)],
            [C::new(0.1, 0.05), C::new(0.15, 0.0)],
        ][i];
        let s = [0.02, 0.01, 0.03][i];
        DMatrix::from_fn(2, 2, |a, bb| {
            c[a] * b[bb]
                * s
                * if i == 1 {
                    C::new(0.0, 1.0)
                } else {
                    C::new(1.0, 0.0)
                }
        })
    }

    fn options() -> MimoFitOptions {
        MimoFitOptions {
            fit: FitOptions {
                order: 6,
                ..FitOptions::default()
            },
            ..MimoFitOptions::default()
        }
    }

    #[test]
    fn recovers_common_poles_and_rank_one_residues() {
        let (poles, frd) = system(rank_one, 1e-3, 1);
        let r = fit_common_poles(&frd, &options()).unwrap();
        for p in &poles {
            let best = r
                .poles
                .iter()
                .map(|q| (q - p).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(best < 1e-4, "pole {p}: nearest fitted at {best:e}");
        }
        assert!(r.modes.iter().all(|m| m.rank == 1), "{:?}", r.modes);
        // three pairs of rank one: six states (four SISO fits of order 6 would have 24)
        assert_eq!(r.model.n(), 6);
        // with the noise's variance (of the complex value) as weights each term is χ²₂/2: the
        // cost is about (2·300·4 − p)/2 for p = 6 pole + 3·2·(2 + 2 − 1) residue + 4
        // feedthrough parameters (two-sigma band of χ²: ±√(2·2372)/2 = ±34)
        let expected = (2.0 * 300.0 * 4.0 - 28.0) / 2.0;
        assert!(
            (r.cost - expected).abs() < 70.0,
            "cost {} against {expected}",
            r.cost
        );
        assert!(r.full_rank_cost <= r.cost);
        // the realisation is the fitted model: its frequency response gives the same cost
        let g = r.model.freqresp(frd.freq_hz()).unwrap();
        let var = frd.variance().unwrap();
        let v: f64 = (0..frd.len())
            .map(|k| {
                (0..4)
                    .map(|e| {
                        let (a, b) = (e / 2, e % 2);
                        (g.response()[k][(a, b)] - frd.response()[k][(a, b)]).norm_sqr()
                            / var[k][(a, b)]
                    })
                    .sum::<f64>()
            })
            .sum();
        assert!((v - r.cost).abs() <= 1e-6 * r.cost, "{v} vs {}", r.cost);
        // model_cost is that sum (the held-out validation of a MIMO model); a shape that does
        // not match is an error
        let mc = crate::model_cost(&frd, &r.model, crate::Weighting::Variance).unwrap();
        assert!((mc - v).abs() <= 1e-12 * v, "{mc} vs {v}");
        let one = frd.entry(0, 1).unwrap();
        assert!(crate::model_cost(&one, &r.model, crate::Weighting::Variance).is_err());
    }

    #[test]
    fn keeps_the_rank_the_data_show() {
        // the middle mode has a rank-two residue (a second, independent direction at 40 %)
        let r2 = |i: usize| {
            let mut m = rank_one(i);
            if i == 1 {
                m[(0, 0)] += C::new(0.004, 0.0);
                m[(1, 1)] -= C::new(0.004, 0.0);
            }
            m
        };
        let (_, frd) = system(r2, 1e-3, 2);
        let r = fit_common_poles(&frd, &options()).unwrap();
        let ranks: Vec<usize> = r.modes.iter().map(|m| m.rank).collect();
        let mid = r
            .modes
            .iter()
            .position(|m| (m.freq_hz - 110.0).abs() < 1.0)
            .unwrap();
        assert_eq!(ranks[mid], 2, "{ranks:?}");
        assert_eq!(ranks.iter().sum::<usize>(), 4, "{ranks:?}");
        assert_eq!(r.model.n(), 8);
    }

    /// A rank-one double integrator (a rigid body both actuators push and both sensors see,
    /// ZOH: `C₁ = h²/2·c bᵀ`, `C₂ = h²·c bᵀ`) and one pair: two states for the rigid body
    /// (one chain per input would take four), two for the pair.
    #[test]
    fn a_rank_one_rigid_body_takes_two_states() {
        let ts = 1e-3;
        let (c, b) = ([1.0, 0.7], [0.05, 0.04]);
        let p = C::from_polar(0.97, 0.4);
        let r = DMatrix::from_fn(2, 2, |a, j| C::new(0.02 * c[a] * b[j], -0.01 * c[a] * b[j]));
        let freq: Vec<f64> = (1..=200).map(|k| k as f64 * 2.0).collect();
        let resp: Vec<DMatrix<C>> = freq
            .iter()
            .map(|&f| {
                let z = C::from_polar(1.0, 2.0 * PI * f * ts);
                let w = 1.0 / (z - 1.0);
                DMatrix::from_fn(2, 2, |a, j| {
                    let k = c[a] * b[j];
                    w * (ts * ts / 2.0 * k)
                        + w * w * (ts * ts * k)
                        + r[(a, j)] / (z - p)
                        + r[(a, j)].conj() / (z - p.conj())
                })
            })
            .collect();
        let frd = Frd::new(freq, resp, None, SampleTime::discrete(ts).unwrap()).unwrap();
        let o = MimoFitOptions {
            fit: FitOptions {
                order: 4,
                rigid_body: 2,
                feedthrough: false,
                ..FitOptions::default()
            },
            ..MimoFitOptions::default()
        };
        let fit = fit_common_poles(&frd, &o).unwrap();
        assert_eq!(fit.model.n(), 4, "{:?}", fit.modes);
        assert!(fit.median_rel_error < 1e-8, "{}", fit.median_rel_error);
        let g = fit.model.freqresp(frd.freq_hz()).unwrap();
        let worst = g
            .response()
            .iter()
            .zip(frd.response())
            .map(|(x, y)| (x - y).norm() / y.norm())
            .fold(0.0, f64::max);
        assert!(worst < 1e-8, "the realisation misses the fit by {worst:e}");
    }

    #[test]
    fn bad_settings_and_data_are_named() {
        let (_, frd) = system(rank_one, 1e-3, 3);
        let mut o = options();
        o.rank = ResidueRank::Fixed(3);
        let e = fit_common_poles(&frd, &o).unwrap_err().to_string();
        assert!(e.contains("rank 3"), "{e}");
        o.rank = ResidueRank::Select;
        o.fit.order = 400;
        let e = fit_common_poles(&frd, &o).unwrap_err().to_string();
        assert!(e.contains("too few"), "{e}");
        let ct = Frd::new(
            frd.freq_hz().to_vec(),
            frd.response().to_vec(),
            None,
            SampleTime::Continuous,
        )
        .unwrap();
        let e = fit_common_poles(&ct, &options()).unwrap_err().to_string();
        assert!(e.contains("discrete-time"), "{e}");
    }
}
