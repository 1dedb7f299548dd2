//! Discrete-time rational models fitted to an FRD, up to order ~60.
//!
//! **Model** (partial fractions in z, a well-conditioned basis):
//! `Ĝ(z) = Σ_i r_i/(z − p_i) + Σ_{l=1}^{m} c_l/(z − 1)^l + d`, free poles p_i real or in
//! complex-conjugate pairs, m ∈ {0, 1, 2} fixed rigid-body poles at z = 1, optional d.
//!
//! **Cost**: `V = Σ_k w_k² |G_k − Ĝ(z_k)|²`, `z_k = e^{j2πf_k T}`, with `w_k = 1/σ_k` from the
//! FRD's variance (default when present), or relative `w_k = 1/|G_k|`, or uniform.
//!
//! **Step 1, Sanathanan–Koerner iterations in the partial-fraction basis** (vector fitting;
//! Gustavsen & Semlyen, IEEE TPWRD 14(3), 1999, in the z-domain): with the current poles, solve
//! the linear weighted least-squares problem `N(z_k) − G_k σ(z_k) ≈ G_k`,
//! `σ(z) = 1 + Σ c̃_i φ_i(z)`, by QR of the stacked real equations (columns scaled; never
//! normal equations). The zeros of σ, `eig(A − b c̃ᵀ)`, are the new poles; unstable ones are
//! **reflected** (p ↦ 1/p̄), never clamped. Start: lightly damped pairs spread over the band.
//!
//! **Step 2, Levenberg–Marquardt** on V itself over poles (real and imaginary parts), residues,
//! rigid-body residues and d, with the analytic Jacobian (`∂/∂p r/(z − p) = r/(z − p)²`),
//! Marquardt's column scaling, QR of `[J; √λ D]`, and reflection of any pole that leaves the
//! unit disc. It stops when an accepted step improves V by less than 1e-9 relative.
//!
//! **Result**: a real modal state-space model (2×2 blocks `[[α, β], [−β, α]]` per pair, a
//! Jordan block for the rigid body), the cost history, the median relative error.

use crate::error::{IdentError, Result};
use crate::tol;
use faer::Mat;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::linalg::convert::eigenvalues;
use sd_model::{Frd, SampleTime, StateSpace};
use std::f64::consts::PI;

mod lm;
mod options;
use lm::*;
use options::*;
pub use options::{FitOptions, FitProgress, FitResult, FitWarning, ModalTerm, Weighting};

/// The model in partial fractions.
#[derive(Debug, Clone)]
struct Pf {
    /// Real free poles with residues.
    real: Vec<(f64, f64)>,
    /// Complex pairs: pole (upper half plane) and residue.
    pairs: Vec<(C, C)>,
    /// Rigid-body residues c_1 … c_m.
    rigid: Vec<f64>,
    d: f64,
}

impl Pf {
    fn eval(&self, z: C) -> C {
        let mut g = C::new(self.d, 0.0);
        for &(p, r) in &self.real {
            g += r / (z - p);
        }
        for &(a, r) in &self.pairs {
            g += r / (z - a) + r.conj() / (z - a.conj());
        }
        let mut q = C::new(1.0, 0.0);
        for &c in &self.rigid {
            q /= z - 1.0;
            g += q * c;
        }
        g
    }
    fn terms(&self) -> Vec<ModalTerm> {
        let mut t: Vec<ModalTerm> = Vec::new();
        if !self.rigid.is_empty() {
            let mut residues = [0.0; 2];
            for (slot, c) in residues.iter_mut().zip(&self.rigid) {
                *slot = *c;
            }
            t.push(ModalTerm::Rigid {
                residues,
                count: self.rigid.len().min(2),
            });
        }
        t.extend(
            self.real
                .iter()
                .map(|&(pole, residue)| ModalTerm::Real { pole, residue }),
        );
        t.extend(
            self.pairs
                .iter()
                .map(|&(pole, residue)| ModalTerm::Pair { pole, residue }),
        );
        t
    }
    fn poles(&self) -> Vec<C> {
        let mut p: Vec<C> = self.real.iter().map(|&(p, _)| C::new(p, 0.0)).collect();
        for &(a, _) in &self.pairs {
            p.push(a);
            p.push(a.conj());
        }
        p.extend(std::iter::repeat_n(C::new(1.0, 0.0), self.rigid.len()));
        p
    }
}

/// One SISO data set of a fit: the points `z_k`, the responses and their weights.
pub(crate) struct Data {
    pub(crate) z: Vec<C>,
    pub(crate) g: Vec<C>,
    pub(crate) w: Vec<f64>,
    pub(crate) ts: f64,
    pub(crate) min_damping: f64,
    /// Narrowest half-power bandwidth of a pair (Hz; 0: none).
    pub(crate) min_bandwidth_hz: f64,
}

impl Data {
    /// A free pole made admissible: reflected into the unit disc ([`reflect`]) and, for a
    /// complex pole below the damping floor, moved onto it at the same natural frequency.
    pub(crate) fn constrain(&self, p: C) -> C {
        let p = reflect(p);
        let floored = self.min_damping > 0.0 || self.min_bandwidth_hz > 0.0;
        if !floored || p.im.abs() <= 1e-12 * p.norm() || p.norm() == 0.0 {
            return p;
        }
        let s = p.ln() / self.ts;
        let wn = s.norm();
        // 2ζf_n ≥ B  ⇔  ζ ≥ B/(2f_n) = πB/ω_n
        let z = self
            .min_damping
            .max((PI * self.min_bandwidth_hz / wn.max(f64::MIN_POSITIVE)).min(0.99));
        if -s.re >= z * wn {
            return p;
        }
        let s2 = C::new(-z * wn, s.im.signum() * wn * (1.0 - z * z).sqrt());
        (s2 * self.ts).exp()
    }
}

pub(crate) fn reflect(p: C) -> C {
    let m = p.norm();
    if m > 1.0 {
        p / (m * m) // 1/p̄ = p/|p|²
    } else if m > 1.0 - tol::STABILITY_MARGIN {
        p * ((1.0 - tol::STABILITY_MARGIN) / m)
    } else {
        p
    }
}

fn cost(data: &Data, pf: &Pf) -> f64 {
    terms(data, pf).sum()
}

/// The terms `w_k²|G_k − Ĝ(z_k)|²` of the cost.
fn line_costs(data: &Data, pf: &Pf) -> Vec<f64> {
    terms(data, pf).collect()
}

/// The cost's terms, line by line (no allocation: `cost` runs at every LM trial).
fn terms<'a>(data: &'a Data, pf: &'a Pf) -> impl Iterator<Item = f64> + 'a {
    data.z
        .iter()
        .zip(&data.g)
        .zip(&data.w)
        .map(|((&z, &g), &w)| (w * (pf.eval(z) - g).norm()).powi(2))
}

/// Weighted least squares `min ‖A x − b‖` (b one column) by the toolkit's one solver,
/// [`sd_model::linalg::lstsq_faer`] (column-scaled QR, then the SVD of R with a rank cut).
fn lstsq(a: &Mat<f64>, b: &Mat<f64>) -> Result<Vec<f64>> {
    let rhs: Vec<f64> = (0..b.nrows()).map(|r| b[(r, 0)]).collect();
    let ls = sd_model::linalg::lstsq_faer(a.as_ref(), &rhs).map_err(|e| {
        IdentError::Numerical(format!("the least-squares problem of the fit failed: {e}"))
    })?;
    Ok(ls.x.iter().copied().collect())
}

/// Free-pole basis (real and pair functions) at z, as complex values per column.
fn free_basis(real: &[f64], pairs: &[C], z: C, out: &mut Vec<C>) {
    for &p in real {
        out.push(1.0 / (z - p));
    }
    for &a in pairs {
        let (u, v) = (1.0 / (z - a), 1.0 / (z - a.conj()));
        out.push(u + v);
        out.push(C::new(0.0, 1.0) * (u - v));
    }
}

pub(crate) fn rigid_basis(m: usize, z: C, out: &mut Vec<C>) {
    let mut q = C::new(1.0, 0.0);
    for _ in 0..m {
        q /= z - 1.0;
        out.push(q);
    }
}

/// One row of the numerator basis at `z`: free poles, rigid-body terms, feedthrough.
pub(crate) fn numerator_basis(
    real: &[f64],
    pairs: &[C],
    m: usize,
    feed: bool,
    z: C,
    row: &mut Vec<C>,
) {
    row.clear();
    free_basis(real, pairs, z, row);
    rigid_basis(m, z, row);
    if feed {
        row.push(C::new(1.0, 0.0));
    }
}

/// Residues and d for given poles (the linear step).
fn residues(data: &Data, real: &[f64], pairs: &[C], m: usize, feed: bool) -> Result<Pf> {
    let nf = real.len() + 2 * pairs.len();
    let ncol = nf + m + usize::from(feed);
    let k = data.z.len();
    let mut a = Mat::<f64>::zeros(2 * k, ncol);
    let mut b = Mat::<f64>::zeros(2 * k, 1);
    let mut row = Vec::with_capacity(ncol);
    for (i, ((&z, &g), &w)) in data.z.iter().zip(&data.g).zip(&data.w).enumerate() {
        numerator_basis(real, pairs, m, feed, z, &mut row);
        for (j, v) in row.iter().enumerate() {
            a[(2 * i, j)] = w * v.re;
            a[(2 * i + 1, j)] = w * v.im;
        }
        b[(2 * i, 0)] = w * g.re;
        b[(2 * i + 1, 0)] = w * g.im;
    }
    let x = lstsq(&a, &b)?;
    let mut it = x.into_iter();
    let mut next = || it.next().unwrap_or(0.0);
    let real_r: Vec<(f64, f64)> = real.iter().map(|&p| (p, next())).collect();
    let pairs_r: Vec<(C, C)> = pairs
        .iter()
        .map(|&a| {
            let (c1, c2) = (next(), next());
            (a, C::new(c1, c2))
        })
        .collect();
    let rigid: Vec<f64> = (0..m).map(|_| next()).collect();
    let d = if feed { next() } else { 0.0 };
    Ok(Pf {
        real: real_r,
        pairs: pairs_r,
        rigid,
        d,
    })
}

/// One SK / vector-fitting pole relocation.
fn relocate(
    data: &Data,
    real: &[f64],
    pairs: &[C],
    m: usize,
    feed: bool,
) -> Result<(Vec<f64>, Vec<C>)> {
    let nf = real.len() + 2 * pairs.len();
    let nn = nf + m + usize::from(feed);
    let ncol = nn + nf;
    let k = data.z.len();
    let mut a = Mat::<f64>::zeros(2 * k, ncol);
    let mut b = Mat::<f64>::zeros(2 * k, 1);
    let mut row = Vec::with_capacity(nn);
    for (i, ((&z, &g), &w)) in data.z.iter().zip(&data.g).zip(&data.w).enumerate() {
        numerator_basis(real, pairs, m, feed, z, &mut row);
        for (j, v) in row.iter().enumerate() {
            a[(2 * i, j)] = w * v.re;
            a[(2 * i + 1, j)] = w * v.im;
        }
        // σ's basis is the free part of the numerator's (its first nf columns)
        for (j, v) in row[..nf].iter().enumerate() {
            let t = -g * v * w;
            a[(2 * i, nn + j)] = t.re;
            a[(2 * i + 1, nn + j)] = t.im;
        }
        b[(2 * i, 0)] = w * g.re;
        b[(2 * i + 1, 0)] = w * g.im;
    }
    let x = lstsq(&a, &b)?;
    sigma_zeros(real, pairs, &x[nn..], data)
}

/// The zeros of `σ = 1 + Σ c̃_i φ_i` (`ct` = c̃ over the free basis of `real`, `pairs`):
/// `eig(A − b c̃ᵀ)` in the real block realisation of the basis, made admissible
/// ([`split_poles`]).
pub(crate) fn sigma_zeros(
    real: &[f64],
    pairs: &[C],
    ct: &[f64],
    data: &Data,
) -> Result<(Vec<f64>, Vec<C>)> {
    let nf = ct.len();
    let mut am = DMatrix::<f64>::zeros(nf, nf);
    let mut bv = vec![0.0; nf];
    let mut idx = 0;
    for &p in real {
        am[(idx, idx)] = p;
        bv[idx] = 1.0;
        idx += 1;
    }
    for &p in pairs {
        am[(idx, idx)] = p.re;
        am[(idx, idx + 1)] = p.im;
        am[(idx + 1, idx)] = -p.im;
        am[(idx + 1, idx + 1)] = p.re;
        bv[idx] = 2.0;
        idx += 2;
    }
    for i in 0..nf {
        for j in 0..nf {
            am[(i, j)] -= bv[i] * ct[j];
        }
    }
    let ev = eigenvalues(&am)?;
    split_poles(&ev, data)
}

/// Sorts eigenvalues into reflected real poles and upper-half-plane pair representatives.
pub(crate) fn split_poles(ev: &[C], data: &Data) -> Result<(Vec<f64>, Vec<C>)> {
    let mut real = Vec::new();
    let mut pairs = Vec::new();
    for &e in ev {
        let e = data.constrain(e);
        if e.im.abs() <= 1e-12 * e.norm().max(1e-300) {
            real.push(e.re);
        } else if e.im > 0.0 {
            pairs.push(e);
        }
    }
    if real.len() + 2 * pairs.len() != ev.len() {
        return Err(IdentError::Numerical(
            "pole relocation gave an unpaired complex pole".into(),
        ));
    }
    Ok((real, pairs))
}

pub(crate) fn starting_poles(freq_hz: &[f64], ts: f64, nf: usize) -> (Vec<f64>, Vec<C>) {
    let npairs = nf / 2;
    let fmax = freq_hz.iter().cloned().fold(0.0, f64::max).min(0.499 / ts);
    let fmin_data = freq_hz
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min)
        .max(1e-6 / ts);
    let fmin = fmin_data.max(fmax / 1000.0);
    // linear spacing (Gustavsen & Semlyen's advice for resonant responses), unless the band
    // spans more than three decades
    let logspace = fmax / fmin > 1000.0;
    let pairs = (0..npairs)
        .map(|i| {
            let t = (i as f64 + 0.5) / npairs as f64;
            let f = if logspace {
                fmin * (fmax / fmin).powf(t)
            } else {
                fmin + (fmax - fmin) * t
            };
            let beta = 2.0 * PI * f * ts;
            C::from_polar((-tol::START_DAMPING * beta).exp(), beta)
        })
        .collect();
    let real = if nf % 2 == 1 {
        vec![(-2.0 * PI * (fmin * fmax).sqrt() * ts).exp()]
    } else {
        Vec::new()
    };
    (real, pairs)
}

fn weights(frd: &Frd, w: Weighting) -> Result<Vec<f64>> {
    weights_entry(frd, w, (0, 0))
}

/// The weights of entry `(a, b)` of an FRD ([`Weighting`]).
pub(crate) fn weights_entry(frd: &Frd, w: Weighting, (a, b): (usize, usize)) -> Result<Vec<f64>> {
    let g: Vec<C> = frd.response().iter().map(|m| m[(a, b)]).collect();
    let rel = || {
        g.iter()
            .map(|v| 1.0 / v.norm().max(f64::MIN_POSITIVE))
            .collect::<Vec<f64>>()
    };
    Ok(match w {
        Weighting::Uniform => vec![1.0; g.len()],
        Weighting::Relative => rel(),
        Weighting::Variance => match frd.variance() {
            Some(var) => {
                let v: Vec<f64> = var.iter().map(|m| m[(a, b)]).collect();
                if v.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
                    return Err(IdentError::Data(
                        "the FRD variance must be positive at every line for variance weighting; \
                         use relative weighting"
                            .into(),
                    ));
                }
                v.iter().map(|x| 1.0 / x.sqrt()).collect()
            }
            None => rel(),
        },
    })
}

/// The sample time of a discrete FRD (a fit's `z = e^{jωT}` needs it).
pub(crate) fn discrete_ts(frd: &Frd) -> Result<f64> {
    match frd.time() {
        SampleTime::Discrete { ts } => Ok(ts),
        SampleTime::Continuous => Err(IdentError::InvalidArgument(
            "fit needs a discrete-time FRD (its ts fixes z = e^{jωT})".into(),
        )),
    }
}

/// The settings' own checks: the damping floor in `[0, 1)`, `1 ≤ order`, `rigid_body ≤ 2`
/// and `rigid_body ≤ order`.
pub(crate) fn check_options(opt: &FitOptions) -> Result<()> {
    if !(opt.min_bandwidth_hz.is_finite() && opt.min_bandwidth_hz >= 0.0) {
        return Err(IdentError::InvalidArgument(format!(
            "min_bandwidth_hz {} must be finite and ≥ 0",
            opt.min_bandwidth_hz
        )));
    }
    if !(opt.min_damping.is_finite() && (0.0..1.0).contains(&opt.min_damping)) {
        return Err(IdentError::InvalidArgument(format!(
            "min_damping {} must be in [0, 1)",
            opt.min_damping
        )));
    }
    if opt.rigid_body > 2 || opt.order < opt.rigid_body || opt.order == 0 {
        return Err(IdentError::InvalidArgument(format!(
            "order {} with {} rigid-body poles: need 1 ≤ order, rigid_body ≤ 2 and rigid_body ≤ order",
            opt.order, opt.rigid_body
        )));
    }
    Ok(())
}

/// `Err` unless `lines` FRF lines determine the real parameters of a fit with `opt`: at most
/// one parameter per line (half the `2·lines` real equations; [`fit`] itself only needs
/// fewer parameters than equations, and [`select_order`] scans orders up to that). Beyond it Akaike's final prediction error
/// factor `(1 + p/N)/(1 − p/N)` (`N = 2·lines`) exceeds 3 — the model's expected error on new
/// data three times its fit error or more — and the fit's cost grows with the order for
/// minutes (an order of 600 typed for 60). The message names the highest order allowed.
///
/// # Errors
/// `InvalidArgument` naming the highest order the lines determine.
pub fn check_order_determined(lines: usize, opt: &FitOptions) -> Result<()> {
    let nparams = 2 * opt.order.saturating_sub(opt.rigid_body)
        + opt.rigid_body
        + usize::from(opt.feedthrough);
    if nparams <= lines {
        return Ok(());
    }
    // nparams = 2(order − rigid) + rigid + feedthrough ≤ lines
    let spare = lines.saturating_sub(usize::from(opt.feedthrough) + opt.rigid_body);
    let highest = opt.rigid_body + spare / 2;
    Err(IdentError::InvalidArgument(format!(
        "order {} has {nparams} real parameters; {lines} lines determine at most {lines} (one \
         per line: beyond it the expected error on new data is over three times the fit \
         error): give an order of at most {highest}, or measure more lines",
        opt.order
    )))
}

/// Fits a discrete-time model to a SISO FRD (module documentation).
///
/// # Errors
/// A continuous-time or MIMO FRD, an order below the rigid-body count, too few lines for the
/// parameters, a singular least-squares problem.
pub fn fit(frd: &Frd, opt: &FitOptions) -> Result<FitResult> {
    fit_with_progress(frd, opt, &mut |_| {})
}

/// [`fit`] reporting each iteration to `progress`.
pub fn fit_with_progress(
    frd: &Frd,
    opt: &FitOptions,
    progress: &mut dyn FnMut(&FitProgress),
) -> Result<FitResult> {
    let ts = discrete_ts(frd)?;
    if frd.shape() != (1, 1) {
        return Err(IdentError::InvalidArgument(format!(
            "fit is SISO; the FRD is {}x{} (fit_common_poles fits one set of poles to every entry)",
            frd.shape().0,
            frd.shape().1
        )));
    }
    check_options(opt)?;
    let nf = opt.order - opt.rigid_body;
    let nparams = 2 * nf + opt.rigid_body + usize::from(opt.feedthrough);
    if 2 * frd.len() <= nparams {
        return Err(IdentError::Data(format!(
            "{} lines give {} real equations, too few for {nparams} parameters",
            frd.len(),
            2 * frd.len()
        )));
    }
    let data = Data {
        z: frd
            .freq_hz()
            .iter()
            .map(|&f| C::from_polar(1.0, 2.0 * PI * f * ts))
            .collect(),
        g: frd.response().iter().map(|m| m[(0, 0)]).collect(),
        w: weights(frd, opt.weighting)?,
        ts,
        min_damping: opt.min_damping,
        min_bandwidth_hz: opt.min_bandwidth_hz,
    };
    if data.g.iter().any(|v| !v.is_finite()) {
        return Err(IdentError::Data(
            "the FRD has NaN or infinite values".into(),
        ));
    }
    let (mut real, mut pairs) = starting_poles(frd.freq_hz(), ts, nf);
    let mut history = Vec::new();
    let mut best: Option<(f64, Pf)> = None;
    for it in 0..opt.sk_iterations {
        let (r2, p2) = relocate(&data, &real, &pairs, opt.rigid_body, opt.feedthrough)?;
        real = r2;
        pairs = p2;
        let pf = residues(&data, &real, &pairs, opt.rigid_body, opt.feedthrough)?;
        let v = cost(&data, &pf);
        let p = FitProgress {
            stage: "sk",
            iteration: it + 1,
            cost: v,
        };
        progress(&p);
        history.push(p);
        if best.as_ref().map(|b| v < b.0).unwrap_or(true) {
            best = Some((v, pf));
        }
    }
    let pf = match best {
        Some((_, pf)) => pf,
        None => residues(&data, &real, &pairs, opt.rigid_body, opt.feedthrough)?,
    };
    let pf = lm(&data, pf, opt, &mut history, progress)?;
    let line_cost = line_costs(&data, &pf);
    let significant = if opt.weighting == Weighting::Variance && frd.variance().is_some() {
        5.0
    } else {
        let wg: Vec<f64> = data
            .g
            .iter()
            .zip(&data.w)
            .map(|(g, w)| w * g.norm())
            .collect();
        1e-3 * sd_model::median(&wg)
    };
    let v: f64 = line_cost.iter().sum();
    let mut rel: Vec<f64> = data
        .z
        .iter()
        .zip(&data.g)
        .map(|(&z, &g)| (pf.eval(z) - g).norm() / g.norm().max(f64::MIN_POSITIVE))
        .collect();
    rel.sort_by(f64::total_cmp);
    let median = rel[rel.len() / 2];
    Ok(FitResult {
        model: to_state_space(&pf, ts)?,
        cost: v,
        history,
        poles: pf.poles(),
        median_rel_error: median,
        warnings: fit_warnings(frd.freq_hz(), &pf, ts, &line_cost, significant),
        line_cost,
        terms: pf.terms(),
    })
}

/// The cost V of a given model on an FRD with the weighting of [`fit`]:
/// `V = Σ_k Σ_{a,b} w_ab(k)² |G_ab(k) − Ĝ_ab(e^{jω_k T})|²`, summed over every entry of an
/// ny×nu FRD (the cost [`crate::fit_common_poles`] minimises). With variance weights it is the
/// whitened squared error, e.g. of the true model, or of a model fitted to another experiment
/// (a held-out validation).
///
/// # Errors
/// Shapes or sample times that do not match; variance weighting with a non-positive variance.
pub fn model_cost(frd: &Frd, model: &StateSpace, weighting: Weighting) -> Result<f64> {
    let (ny, nu) = frd.shape();
    if !frd.time().compatible(&model.time()) || model.nu() != nu || model.ny() != ny {
        return Err(IdentError::InvalidArgument(format!(
            "the model ({}x{}) and the FRD ({ny}x{nu}) need the same shape and sample time",
            model.ny(),
            model.nu()
        )));
    }
    let m = model.freqresp(frd.freq_hz())?;
    let mut v = 0.0;
    for a in 0..ny {
        for b in 0..nu {
            let w = weights_entry(frd, weighting, (a, b))?;
            v += m
                .response()
                .iter()
                .zip(frd.response())
                .zip(&w)
                .map(|((x, y), w)| (w * (x[(a, b)] - y[(a, b)]).norm()).powi(2))
                .sum::<f64>();
        }
    }
    Ok(v)
}

fn to_state_space(pf: &Pf, ts: f64) -> Result<StateSpace> {
    let n = pf.real.len() + 2 * pf.pairs.len() + pf.rigid.len();
    let mut a = DMatrix::<f64>::zeros(n, n);
    let mut b = DMatrix::<f64>::zeros(n, 1);
    let mut c = DMatrix::<f64>::zeros(1, n);
    let mut i = 0;
    match pf.rigid.len() {
        0 => {}
        1 => {
            a[(0, 0)] = 1.0;
            b[(0, 0)] = 1.0;
            c[(0, 0)] = pf.rigid[0];
            i = 1;
        }
        _ => {
            // c1/(z−1) + c2/(z−1)²: Jordan block, B = [0; 1], C = [c2, c1]
            a[(0, 0)] = 1.0;
            a[(0, 1)] = 1.0;
            a[(1, 1)] = 1.0;
            b[(1, 0)] = 1.0;
            c[(0, 0)] = pf.rigid[1];
            c[(0, 1)] = pf.rigid[0];
            i = 2;
        }
    }
    for &(p, r) in &pf.real {
        a[(i, i)] = p;
        b[(i, 0)] = 1.0;
        c[(0, i)] = r;
        i += 1;
    }
    for &(p, r) in &pf.pairs {
        a[(i, i)] = p.re;
        a[(i, i + 1)] = p.im;
        a[(i + 1, i)] = -p.im;
        a[(i + 1, i + 1)] = p.re;
        b[(i, 0)] = 2.0;
        c[(0, i)] = r.re;
        c[(0, i + 1)] = r.im;
        i += 2;
    }
    Ok(StateSpace::new(
        a,
        b,
        c,
        DMatrix::from_element(1, 1, pf.d),
        SampleTime::discrete(ts)?,
    )?)
}

/// Akaike's final prediction error `V·(1 + p/N)/(1 − p/N)` of a fit with cost `V` and the
/// settings `opt` on `lines` complex lines: p counts two per free pole (pole and residue), one
/// per fixed pole's residue and one for a feedthrough; N = 2·lines real equations; ∞ when
/// p ≥ N.
pub fn final_prediction_error(cost: f64, opt: &FitOptions, lines: usize) -> f64 {
    let p = (2 * opt.order.saturating_sub(opt.rigid_body)
        + opt.rigid_body
        + usize::from(opt.feedthrough)) as f64;
    let neq = 2.0 * lines as f64;
    if p < neq {
        cost * (1.0 + p / neq) / (1.0 - p / neq)
    } else {
        f64::INFINITY
    }
}

/// Fits every order in `orders` and reports the cost of each; the selected order minimizes
/// Akaike's final prediction error `V·(1 + p/N)/(1 − p/N)` (p parameters, N real equations).
///
/// # Errors
/// As [`fit`]; an empty order list.
pub fn select_order(
    frd: &Frd,
    orders: &[usize],
    base: &FitOptions,
) -> Result<(Vec<(usize, f64)>, FitResult)> {
    let mut table = Vec::new();
    let mut best: Option<(f64, FitResult)> = None;
    for &n in orders {
        let opt = FitOptions {
            order: n,
            ..base.clone()
        };
        let r = fit(frd, &opt)?;
        let fpe = final_prediction_error(r.cost, &opt, frd.len());
        table.push((n, r.cost));
        if best.as_ref().map(|b| fpe < b.0).unwrap_or(true) {
            best = Some((fpe, r));
        }
    }
    match best {
        Some((_, r)) => Ok((table, r)),
        None => Err(IdentError::InvalidArgument("no order to try".into())),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_two_mode_model_exactly_from_noise_free_data() {
        let p = sd_model::stage::paper_stage_two_modes().unwrap();
        let pd = sd_model::c2d(&p, 2e-4, sd_model::Discretization::Zoh).unwrap();
        let f = sd_model::grid(1.0, 2400.0, 600, true).unwrap();
        let frd = pd.freqresp(&f).unwrap();
        let r = fit(
            &frd,
            &FitOptions {
                order: pd.n(),
                rigid_body: 2,
                feedthrough: false,
                weighting: Weighting::Relative,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(r.median_rel_error < 1e-8, "{}", r.median_rel_error);
        assert!(r
            .model
            .poles()
            .unwrap()
            .iter()
            .all(|z| z.norm() <= 1.0 + 1e-12));
    }

    #[test]
    fn nothing_depends_on_the_scale_of_the_data() {
        let p = sd_model::stage::paper_stage_two_modes().unwrap();
        let pd = sd_model::c2d(&p, 2e-4, sd_model::Discretization::Zoh).unwrap();
        let f = sd_model::grid(1.0, 2400.0, 400, true).unwrap();
        let frd = pd.freqresp(&f).unwrap();
        let opt = FitOptions {
            order: pd.n(),
            rigid_body: 2,
            feedthrough: false,
            weighting: Weighting::Relative,
            ..Default::default()
        };
        let a = fit(&frd, &opt).unwrap();
        for scale in [1e-12, 1e9] {
            let resp = frd
                .response()
                .iter()
                .map(|g| g * C::new(scale, 0.0))
                .collect();
            let scaled = Frd::new(f.clone(), resp, None, frd.time()).unwrap();
            let b = fit(&scaled, &opt).unwrap();
            assert!(
                (b.median_rel_error - a.median_rel_error).abs() < 1e-9,
                "{scale}"
            );
            assert!(
                (b.cost - a.cost).abs() <= 1e-6 * a.cost.max(1e-20),
                "{scale}: {} vs {}",
                b.cost,
                a.cost
            );
        }
    }

    /// The two-mode stage's FRD at 5 kHz on `n` lines, with a variance of (1 % of |G|)².
    fn stage_frd(n: usize) -> (StateSpace, Frd) {
        let p = sd_model::stage::paper_stage_two_modes().unwrap();
        let pd = sd_model::c2d(&p, 2e-4, sd_model::Discretization::Zoh).unwrap();
        let f = sd_model::grid(1.0, 2400.0, n, false).unwrap();
        let frd = pd.freqresp(&f).unwrap();
        let var = frd
            .response()
            .iter()
            .map(|g| g.map(|v| C::new((0.01 * v.norm()).powi(2), 0.0).re))
            .collect();
        let frd = Frd::new(f, frd.response().to_vec(), Some(var), frd.time()).unwrap();
        (pd, frd)
    }

    #[test]
    fn a_line_that_steers_the_fit_is_named() {
        let (pd, frd) = stage_frd(300);
        let opt = FitOptions {
            order: pd.n(),
            rigid_body: 2,
            feedthrough: false,
            ..Default::default()
        };
        let clean = fit(&frd, &opt).unwrap();
        assert!(clean.warnings.is_empty(), "{:?}", clean.warnings);
        assert_eq!(clean.line_cost.len(), frd.len());
        let sum: f64 = clean.line_cost.iter().sum();
        assert!((sum - clean.cost).abs() <= 1e-12 * clean.cost.max(1e-300));
        // one line 40 dB off: 100× its value, ~10⁴ σ
        let mut resp = frd.response().to_vec();
        resp[150] *= C::new(100.0, 0.0);
        let bad = Frd::new(
            frd.freq_hz().to_vec(),
            resp,
            frd.variance().map(|v| v.to_vec()),
            frd.time(),
        )
        .unwrap();
        let f_bad = frd.freq_hz()[150];
        let spacing = frd.freq_hz()[151] - f_bad;
        // the free fit spends a pole pair on the outlier: an undamped spike at that line, which
        // the lines cannot resolve, and is flagged as such
        let r = fit(&bad, &opt).unwrap();
        assert!(
            r.warnings.iter().any(|w| matches!(w,
                FitWarning::UnresolvedMode { freq_hz, .. } if (freq_hz - f_bad).abs() < spacing)),
            "{:?}",
            r.warnings
        );
        // with a damping floor (ζ ≥ 0.005, the stage's lightest mode: 12 Hz wide at 1.2 kHz,
        // wider than the 8 Hz line spacing) it cannot, and the line itself is named as
        // dominating the cost
        let floored = fit(
            &bad,
            &FitOptions {
                min_damping: 0.005,
                ..opt.clone()
            },
        )
        .unwrap();
        let named: Vec<f64> = floored
            .warnings
            .iter()
            .filter_map(|w| match w {
                FitWarning::DominantLine { freq_hz, share, .. } if *share > 0.5 => Some(*freq_hz),
                _ => None,
            })
            .collect();
        assert_eq!(named, vec![f_bad], "{:?}", floored.warnings);
    }

    #[test]
    fn unresolved_modes_are_flagged_and_the_damping_floor_holds() {
        let (_, frd) = stage_frd(300);
        let ts = 2e-4;
        let data_of = |min_damping| Data {
            z: vec![],
            g: vec![],
            w: vec![],
            ts,
            min_damping,
            min_bandwidth_hz: 0.0,
        };
        // a pair at 500 Hz with ζ = 1e-6: 1 mHz wide on 8 Hz lines
        let at = |zeta: f64| {
            let wn = 2.0 * PI * 500.0;
            (C::new(-zeta * wn, wn * (1.0 - zeta * zeta).sqrt()) * ts).exp()
        };
        let pf = |p: C| Pf {
            real: vec![],
            pairs: vec![(p, C::new(1.0, 0.0))],
            rigid: vec![],
            d: 0.0,
        };
        let costs = vec![1.0; frd.len()];
        let w = fit_warnings(frd.freq_hz(), &pf(at(1e-6)), ts, &costs, 5.0);
        match w.as_slice() {
            [FitWarning::UnresolvedMode {
                freq_hz,
                damping,
                line_spacing_hz,
                ..
            }] => {
                assert!((freq_hz - 500.0).abs() < 1e-6);
                assert!((damping - 1e-6).abs() < 1e-9);
                assert!((line_spacing_hz - 2399.0 / 299.0).abs() < 1e-9);
            }
            other => panic!("{other:?}"),
        }
        assert!(fit_warnings(frd.freq_hz(), &pf(at(0.02)), ts, &costs, 5.0).is_empty());
        // the floor moves a pole onto ζ = 0.01 at the same natural frequency
        let moved = data_of(0.01).constrain(at(1e-6));
        let s = moved.ln() / ts;
        assert!((s.norm() / (2.0 * PI) - 500.0).abs() < 1e-9);
        assert!((-s.re / s.norm() - 0.01).abs() < 1e-12);
        assert_eq!(data_of(0.0).constrain(at(1e-6)), at(1e-6));
        // and a fit with a floor keeps every pair on or above it
        let opt = FitOptions {
            order: 8,
            rigid_body: 2,
            feedthrough: false,
            min_damping: 0.05,
            ..Default::default()
        };
        let r = fit(&frd, &opt).unwrap();
        for p in r.poles.iter().filter(|p| p.im > 1e-9) {
            let s = p.ln() / ts;
            assert!(-s.re / s.norm() >= 0.05 - 1e-9, "{p}");
        }
        let bad = FitOptions {
            min_damping: 1.0,
            ..opt
        };
        assert!(fit(&frd, &bad).is_err());
    }
}
