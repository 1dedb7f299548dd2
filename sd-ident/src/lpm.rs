//! The local polynomial method (Pintelon, Schoukens, Vandersteen & Barbé, "Estimation of
//! nonparametric noise and FRF models for multivariable systems", MSSP 24(3), 2010): FRFs from
//! transient-affected or non-periodic data.
//!
//! With the N-point DFTs `X(k)` (nx excitations) and `Z(k)` (nz responses), around every line k
//! the FRF and the transient (leakage) term are modelled as polynomials of degree R in the
//! line offset r ∈ [−n, n]:
//! `Z(k+r) = (G_k + Σ_s g_s r^s) X(k+r) + T_k + Σ_s t_s r^s + V(k+r)`.
//! The `(nx + 1)(R + 1)` coefficients per output follow by least squares over the `2n + 1`
//! lines (solved by a small Householder QR, r scaled to [−1, 1]; `small_ls`); `G_k` is the
//! estimate, the residual gives the noise covariance `C_V = EᴴE/(2n + 1 − q)`, and
//! `var Ĝ_k(i, j) = C_V(i, i)·[(KᴴK)⁻¹]_jj`; the covariance of entries (i, j) and (i', j')
//! is `C_V(i, i')·[(KᴴK)⁻¹]_{jj'}`.
//! The window is shifted (not shrunk) at the band edges. Default R = 2 and the smallest n with
//! at least `nx + 2` residual degrees of freedom.
//!
//! In closed loop, use the reference as excitation: [`lpm_closed_loop`] estimates `Y/R` and
//! `U/R` and returns their ratio with first-order variance.

use crate::error::{IdentError, Result};

mod small_ls;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use rayon::prelude::*;
use rustfft::FftPlanner;
use sd_model::{Frd, SampleTime};

/// LPM settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LpmOptions {
    /// Polynomial degree R.
    pub degree: usize,
    /// Half-width n of the local window (default: smallest with nx + 2 residual DOF).
    pub half_width: Option<usize>,
}

impl Default for LpmOptions {
    fn default() -> Self {
        LpmOptions {
            degree: 2,
            half_width: None,
        }
    }
}

/// An LPM estimate.
#[derive(Debug, Clone)]
pub struct LpmEstimate {
    /// The FRF (nz × nx per line) with the variance of each entry.
    pub frd: Frd,
    /// Noise covariance of the responses per line (nz × nz).
    pub noise_cov: Vec<DMatrix<C>>,
    /// Covariance of `vec(Ĝ_k)` per line (`nz·nx` square, columns stacked: index `j·nz + i`
    /// for entry (i, j)): `C_V(i, i')·[(KᴴK)⁻¹]_{jj'}` (module documentation).
    pub covariance: Vec<DMatrix<C>>,
    /// Residual degrees of freedom `q` of each local fit (window lines minus local
    /// parameters). The variance estimates carry them: for a model equal to the true FRF the
    /// whitened squared error `|Ĝ − G|²/σ̂²` of an entry is F(2, 2q) distributed, mean
    /// `q/(q − 1)` (Pintelon & Schoukens, *System Identification*, 2nd ed., §7.2.2 for the
    /// LPM's noise estimate) — the level "within the LPM noise" means.
    pub dof: usize,
    /// Half-width `n` of the local windows (`2n + 1` lines).
    pub half_width: usize,
}

impl LpmEstimate {
    /// Per line of a SISO estimate, the expected size of its variance estimate: the line's
    /// own design factor `[(KᴴK)⁻¹]₀₀ = var Ĝ_k/σ̂²_k` times the noise variance averaged over
    /// ±[`EXPECTED_VAR_HALF_WIDTH`] lines (only `σ̂²`'s estimation noise averaged out; the
    /// noise spectrum is smooth). `None` for MIMO, without variance, or where a line's noise
    /// variance is not positive.
    pub fn expected_var(&self) -> Option<Vec<f64>> {
        let var = self.frd.variance()?;
        if self.frd.response().first()?.len() != 1 {
            return None;
        }
        let noise: Vec<f64> = self.noise_cov.iter().map(|c| c[(0, 0)].re).collect();
        if noise
            .iter()
            .any(|v| v.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater))
        {
            return None;
        }
        let smooth = moving_mean(&noise, EXPECTED_VAR_HALF_WIDTH);
        Some(
            (0..noise.len())
                .map(|k| var[k][(0, 0)] / noise[k] * smooth[k])
                .collect(),
        )
    }
}

pub(crate) fn dft_columns(x: &DMatrix<f64>) -> Vec<Vec<C>> {
    let n = x.nrows();
    let fft = FftPlanner::<f64>::new().plan_fft_forward(n);
    (0..x.ncols())
        .map(|j| {
            let mut buf: Vec<C> = x.column(j).iter().map(|&v| C::new(v, 0.0)).collect();
            fft.process(&mut buf);
            buf
        })
        .collect()
}

/// LPM estimate of the FRF from `x` (N×nx) to `z` (N×nz) sampled at `fs`, at the DFT lines
/// 1 … N/2 − 1.
///
/// # Errors
/// Mismatched lengths, a record too short for the window, a singular local problem (an
/// excitation with no power in a window).
pub fn lpm(fs: f64, x: &DMatrix<f64>, z: &DMatrix<f64>, opt: &LpmOptions) -> Result<LpmEstimate> {
    let (n_samp, nx, nz) = (x.nrows(), x.ncols(), z.ncols());
    if z.nrows() != n_samp || nx == 0 || nz == 0 {
        return Err(IdentError::Data(format!(
            "excitation ({}x{nx}) and response ({}x{nz}) need the same number of rows and at \
             least one column each",
            n_samp,
            z.nrows()
        )));
    }
    if x.iter().chain(z.iter()).any(|v| !v.is_finite()) {
        return Err(IdentError::Data(
            "the signals contain NaN or infinite values".into(),
        ));
    }
    let r = opt.degree;
    let q = (nx + 1) * (r + 1);
    let hw = opt
        .half_width
        .unwrap_or_else(|| (q + nx + 2).saturating_sub(1).div_ceil(2));
    let w = 2 * hw + 1;
    if w <= q {
        return Err(IdentError::InvalidArgument(format!(
            "window of {w} lines cannot fit {q} local parameters; widen it"
        )));
    }
    let half = n_samp / 2;
    if half < w + 2 {
        return Err(IdentError::Data(format!(
            "{n_samp} samples are too few for a local window of {w} lines"
        )));
    }
    let xs = dft_columns(x);
    let zs = dft_columns(z);
    let (lo, hi) = (1usize, half - 1);
    // the lines' local problems are independent: solved in parallel, collected in order
    let fits = (lo..=hi)
        .into_par_iter()
        .map(|k| {
            // window centre shifted to stay inside [lo, hi]
            let start = k.saturating_sub(hw).max(lo).min(hi + 1 - w);
            local_fit((&xs, &zs), k, start, (w, hw, r))
        })
        .collect::<Result<Vec<_>>>()?;
    let freq: Vec<f64> = (lo..=hi).map(|k| k as f64 * fs / n_samp as f64).collect();
    let (mut resp, mut var, mut noise, mut covs) = (
        Vec::with_capacity(fits.len()),
        Vec::with_capacity(fits.len()),
        Vec::with_capacity(fits.len()),
        Vec::with_capacity(fits.len()),
    );
    for f in fits {
        resp.push(f.g);
        var.push(f.var);
        noise.push(f.noise);
        covs.push(f.cov);
    }
    Ok(LpmEstimate {
        frd: Frd::new(freq, resp, Some(var), SampleTime::discrete(1.0 / fs)?)?,
        noise_cov: noise,
        covariance: covs,
        dof: w - q,
        half_width: hw,
    })
}

/// One line's local fit (module documentation).
struct LocalFit {
    g: DMatrix<C>,
    var: DMatrix<f64>,
    noise: DMatrix<C>,
    cov: DMatrix<C>,
}

/// The local regressors around line `k` over the `w` lines from `start` (`hw` the half-width
/// scaling the offsets, `r` the degree): columns `X_j(k+i)·iˢ` then `iˢ` (the transient),
/// each scaled to unit norm; returned with the scales.
fn design(
    xs: &[Vec<C>],
    k: usize,
    start: usize,
    (w, hw, r): (usize, usize, usize),
) -> (DMatrix<C>, Vec<f64>) {
    let nx = xs.len();
    let q = (nx + 1) * (r + 1);
    let mut kmat = DMatrix::<C>::zeros(w, q);
    for (row, line) in (start..start + w).enumerate() {
        let off = (line as f64 - k as f64) / hw.max(1) as f64;
        let mut pw = 1.0;
        for s in 0..=r {
            for j in 0..nx {
                kmat[(row, s * nx + j)] = xs[j][line] * pw;
            }
            kmat[(row, (r + 1) * nx + s)] = C::new(pw, 0.0);
            pw *= off;
        }
    }
    let scale: Vec<f64> = (0..q)
        .map(|c| kmat.column(c).norm().max(f64::MIN_POSITIVE))
        .collect();
    for c in 0..q {
        let s = scale[c];
        kmat.column_mut(c).iter_mut().for_each(|v| *v /= s);
    }
    (kmat, scale)
}

/// The local polynomial fit around line `k` over the `w` lines from `start` (`hw` the
/// half-width scaling the offsets, `r` the degree), from the excitations' and responses'
/// DFTs `(xs, zs)`.
fn local_fit(
    (xs, zs): (&[Vec<C>], &[Vec<C>]),
    k: usize,
    start: usize,
    (w, hw, r): (usize, usize, usize),
) -> Result<LocalFit> {
    let nz = zs.len();
    let (kmat, scale) = design(xs, k, start, (w, hw, r));
    let q = kmat.ncols();
    let nx = xs.len();
    let mut zw = DMatrix::<C>::zeros(w, nz);
    for (row, line) in (start..start + w).enumerate() {
        for i in 0..nz {
            zw[(row, i)] = zs[i][line];
        }
    }
    let ls = small_ls::solve(&kmat, &zw).ok_or_else(|| {
        IdentError::Data(format!(
            "the local LPM problem at line {k} is singular: the excitation has no power \
             there (or the inputs are collinear)"
        ))
    })?;
    let theta = &ls.theta;
    let dof = (w - q) as f64;
    let cv = ls.residual_gram.map(|v| v / dof);
    let mut g = DMatrix::<C>::zeros(nz, nx);
    let mut gv = DMatrix::<f64>::zeros(nz, nx);
    // (KᴴK)⁻¹ = R⁻¹R⁻ᴴ in the scaled coordinates, unscaled
    let pinv = DMatrix::<C>::from_fn(nx, nx, |j, jj| {
        ls.gram_inverse(j, jj) / (scale[j] * scale[jj])
    });
    for j in 0..nx {
        for i in 0..nz {
            g[(i, j)] = theta[(j, i)] / scale[j];
            gv[(i, j)] = cv[(i, i)].re * pinv[(j, j)].re;
        }
    }
    let cov = DMatrix::<C>::from_fn(nz * nx, nz * nx, |a, b| {
        let (j, i, jj, ii) = (a / nz, a % nz, b / nz, b % nz);
        cv[(i, ii)] * pinv[(j, jj)]
    });
    Ok(LocalFit {
        g,
        var: gv,
        noise: cv,
        cov,
    })
}

/// Closed-loop LPM (SISO): `Ĝ = (Y/R)/(U/R)` with both ratios from one LPM with the reference
/// as excitation, and the first-order variance including their correlation.
///
/// # Errors
/// As [`lpm`]; a line where `U/R` vanishes.
pub fn lpm_closed_loop(fs: f64, r: &[f64], u: &[f64], y: &[f64], opt: &LpmOptions) -> Result<Frd> {
    Ok(lpm_closed_loop_snr(fs, r, u, y, opt)?.0)
}

/// [`lpm_closed_loop`] with the input SNR `|U/R|²/var(U/R)` of every line (see
/// [`crate::MIN_INPUT_SNR`]: below it the ratio is biased and its variance invalid).
///
/// # Errors
/// As [`lpm_closed_loop`].
pub fn lpm_closed_loop_snr(
    fs: f64,
    r: &[f64],
    u: &[f64],
    y: &[f64],
    opt: &LpmOptions,
) -> Result<(Frd, Vec<f64>)> {
    let cl = lpm_closed_loop_full(fs, r, u, y, opt)?;
    Ok((cl.frd, cl.input_snr))
}

/// A closed-loop LPM estimate ([`lpm_closed_loop_full`]).
#[derive(Debug, Clone)]
pub struct ClosedLoopLpm {
    /// `Ĝ = (Y/R)/(U/R)` with its first-order variance.
    pub frd: Frd,
    /// Input SNR `|U/R|²/var(U/R)` per line, the median over overlapping windows.
    pub input_snr: Vec<f64>,
    /// Per line, the variance the line's formula gives with the noise covariance `C_V`
    /// replaced by its mean over ±[`EXPECTED_VAR_HALF_WIDTH`] lines: the expected size of
    /// the variance estimate (its design factor `[(KᴴK)⁻¹]₀₀` and the ratios are the line's
    /// own, only `C_V`'s estimation noise is averaged out; the noise spectrum is smooth).
    pub expected_var: Vec<f64>,
}

/// Half-width (lines) of the mean of the noise covariances behind
/// [`ClosedLoopLpm::expected_var`].
pub const EXPECTED_VAR_HALF_WIDTH: usize = 16;

/// [`lpm_closed_loop`] with the input SNR and the expected variance of every line.
///
/// # Errors
/// As [`lpm_closed_loop`].
pub fn lpm_closed_loop_full(
    fs: f64,
    r: &[f64],
    u: &[f64],
    y: &[f64],
    opt: &LpmOptions,
) -> Result<ClosedLoopLpm> {
    let n = r.len();
    if u.len() != n || y.len() != n {
        return Err(IdentError::Data(
            "r, u and y must have the same length".into(),
        ));
    }
    let x = DMatrix::from_column_slice(n, 1, r);
    let mut z = DMatrix::zeros(n, 2);
    z.column_mut(0).copy_from_slice(y);
    z.column_mut(1).copy_from_slice(u);
    let est = lpm(fs, &x, &z, opt)?;
    let mean_of = |f: &dyn Fn(&DMatrix<C>) -> f64| {
        let v: Vec<f64> = est.noise_cov.iter().map(f).collect();
        moving_mean(&v, EXPECTED_VAR_HALF_WIDTH)
    };
    let (syy, suu) = (mean_of(&|c| c[(0, 0)].re), mean_of(&|c| c[(1, 1)].re));
    let (syu_re, syu_im) = (mean_of(&|c| c[(0, 1)].re), mean_of(&|c| c[(0, 1)].im));
    let mut resp = Vec::new();
    let mut var = Vec::new();
    let mut expected = Vec::new();
    let mut snr = Vec::new();
    for (i, g) in est.frd.response().iter().enumerate() {
        let (gy, gu) = (g[(0, 0)], g[(1, 0)]);
        if gu.norm() == 0.0 {
            return Err(IdentError::Data(format!(
                "U/R vanishes at {} Hz",
                est.frd.freq_hz()[i]
            )));
        }
        let gg = gy / gu;
        let v = est.frd.variance().map(|v| &v[i]);
        snr.push(match v {
            Some(v) if v[(1, 0)] > 0.0 => gu.norm_sqr() / v[(1, 0)],
            _ => f64::INFINITY,
        });
        let cv = &est.noise_cov[i];
        // var(Gy), var(Gu) and their covariance share the same (KᴴK)⁻¹ factor
        let factor = match v {
            Some(v) if cv[(0, 0)].re > 0.0 => v[(0, 0)] / cv[(0, 0)].re,
            _ => 0.0,
        };
        let ratio_var = |cyy: f64, cuu: f64, cyu: C| {
            let (vy, vu, cyu) = (cyy * factor, cuu * factor, cyu * factor);
            (gg.norm_sqr()
                * (vy / gy.norm_sqr().max(f64::MIN_POSITIVE) + vu / gu.norm_sqr()
                    - 2.0 * (cyu / (gy * gu.conj())).re))
                .max(0.0)
        };
        resp.push(DMatrix::from_element(1, 1, gg));
        var.push(DMatrix::from_element(
            1,
            1,
            ratio_var(cv[(0, 0)].re, cv[(1, 1)].re, cv[(0, 1)]),
        ));
        expected.push(ratio_var(syy[i], suu[i], C::new(syu_re[i], syu_im[i])));
    }
    Ok(ClosedLoopLpm {
        frd: Frd::new(est.frd.freq_hz().to_vec(), resp, Some(var), est.frd.time())?,
        input_snr: running_median(&snr, 2 * est.half_width),
        expected_var: expected,
    })
}

/// The mean of `x` over `±half` neighbours of each entry (fewer at the ends).
pub fn moving_mean(x: &[f64], half: usize) -> Vec<f64> {
    let mut cum = Vec::with_capacity(x.len() + 1);
    cum.push(0.0);
    for v in x {
        cum.push(cum[cum.len() - 1] + v);
    }
    (0..x.len())
        .map(|k| {
            let (lo, hi) = (k.saturating_sub(half), (k + half + 1).min(x.len()));
            (cum[hi] - cum[lo]) / (hi - lo) as f64
        })
        .collect()
}

/// The median of `x` over `±reach` neighbours of each entry (fewer at the ends).
///
/// A closed-loop line's input SNR comes from its window's `2(2n + 1 − q)` real degrees of
/// freedom: too few to decide a line alone (a line whose SNR is 300 reads below 100 by
/// chance), and a choice of lines made on each one's noisy reading selects lines by the
/// noise they share with the estimate (on closed-loop records with force noise it biased a
/// local modal fit's frequency by a third of its standard error and widened its spread by
/// 30 %). The median over the lines whose windows overlap leaves out only where the input
/// SNR is low for all of them.
fn running_median(x: &[f64], reach: usize) -> Vec<f64> {
    (0..x.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(reach), (i + reach + 1).min(x.len()));
            let mut w: Vec<f64> = x[a..b].to_vec();
            w.sort_by(f64::total_cmp);
            w[w.len() / 2]
        })
        .collect()
}

/// Closed-loop MIMO LPM: one LPM from the references `r` (N × nu) to `[y u]` gives
/// `H = [G_yr; G_ur]` ((ny + nu) × nu) with the covariance of `vec(H)`; then
/// `Ĝ = G_yr G_ur⁻¹` (ny × nu). To first order `dĜ = [I, −Ĝ] dH G_ur⁻¹`, so
/// `vec(dĜ) = (G_ur⁻ᵀ ⊗ [I, −Ĝ]) vec(dH)` and `Cov vec(Ĝ) = M Cov vec(H) Mᴴ` (the references
/// are known exactly; the noise on u and y, correlated through the loop, is in `Cov vec(H)`).
/// The default window leaves `ν = ny + nu + 2` residual degrees of freedom (the open-loop
/// default, `nx + 2`, would leave the `(ny + nu)`-square noise covariance singular); the
/// covariance's Hotelling-type whitened error `eᴴĈ⁻¹e` then averages `ny·nu·ν/(ν − ny)`.
/// Returns the estimate with per-entry variances and the covariance of `vec(Ĝ)` per line.
///
/// # Errors
/// As [`lpm`]; references not one per input; a line where `G_ur` is singular (a reference that
/// does not reach the inputs there).
pub fn lpm_closed_loop_mimo(
    fs: f64,
    r: &DMatrix<f64>,
    u: &DMatrix<f64>,
    y: &DMatrix<f64>,
    opt: &LpmOptions,
) -> Result<LpmEstimate> {
    let (n, nu, ny) = (r.nrows(), u.ncols(), y.ncols());
    if r.ncols() != nu || u.nrows() != n || y.nrows() != n {
        return Err(IdentError::Data(format!(
            "closed-loop LPM: {} references for {nu} inputs, or records of different lengths \
             (one reference per input, all of one length)",
            r.ncols()
        )));
    }
    let mut z = DMatrix::zeros(n, ny + nu);
    z.view_mut((0, 0), (n, ny)).copy_from(y);
    z.view_mut((0, ny), (n, nu)).copy_from(u);
    // default window: ν = ny + nu + 2 residual degrees of freedom, so that the noise
    // covariance of [y; u] is estimated with full rank and the covariance of vec(Ĝ) can be
    // inverted (its whitened error then averages ny·nu·ν/(ν − ny))
    let q = (nu + 1) * (opt.degree + 1);
    let opt = LpmOptions {
        half_width: opt
            .half_width
            .or(Some((q + ny + nu + 2).saturating_sub(1).div_ceil(2))),
        ..*opt
    };
    let est = lpm(fs, r, &z, &opt)?;
    let nz = ny + nu;
    let (mut resp, mut var, mut cov) = (Vec::new(), Vec::new(), Vec::new());
    for (k, h) in est.frd.response().iter().enumerate() {
        let gyr = h.view((0, 0), (ny, nu)).into_owned();
        let gur = h.view((ny, 0), (nu, nu)).into_owned();
        let inv = gur.try_inverse().ok_or_else(|| {
            IdentError::Data(format!(
                "the references do not reach the inputs independently at {} Hz (G_ur singular)",
                est.frd.freq_hz()[k]
            ))
        })?;
        let g = &gyr * &inv;
        // [I, −Ĝ] (ny × nz) and M = G_ur⁻ᵀ ⊗ [I, −Ĝ] (ny·nu × nz·nu)
        let mut left = DMatrix::<C>::zeros(ny, nz);
        left.view_mut((0, 0), (ny, ny))
            .copy_from(&DMatrix::identity(ny, ny));
        left.view_mut((0, ny), (ny, nu)).copy_from(&(-&g));
        let inv_t = inv.transpose();
        let mut m = DMatrix::<C>::zeros(ny * nu, nz * nu);
        for a in 0..nu {
            for b in 0..nu {
                m.view_mut((a * ny, b * nz), (ny, nz))
                    .copy_from(&(&left * inv_t[(a, b)]));
            }
        }
        let c = &m * &est.covariance[k] * m.adjoint();
        var.push(DMatrix::from_fn(ny, nu, |i, j| {
            c[(j * ny + i, j * ny + i)].re.max(0.0)
        }));
        resp.push(g);
        cov.push(c);
    }
    Ok(LpmEstimate {
        frd: Frd::new(est.frd.freq_hz().to_vec(), resp, Some(var), est.frd.time())?,
        noise_cov: est.noise_cov,
        covariance: cov,
        dof: est.dof,
        half_width: est.half_width,
    })
}

/// Correlation `ρ(d)`, `d = 0, 1, …, 2n`, of the errors of LPM estimates `d` lines apart
/// for a locally white excitation and noise (degree `degree`, half-width `n`): the
/// polynomial's share only — each estimate taken as the centre value of a local polynomial,
/// `ρ(d) = Σ_i h_i h_{i+d} / Σ_i h_i²` with `h` the centre row of the hat matrix
/// `(VᵀV)⁻¹Vᵀ` of the Vandermonde matrix in `i/n` (0 beyond `2n`). It ignores the transient
/// columns and the excitation's scatter, which decorrelate neighbouring estimates further;
/// [`lpm_excitation_correlation`] has them. `[1.0]` when the window cannot hold the
/// polynomial.
pub fn lpm_polynomial_correlation(n: usize, degree: usize) -> Vec<f64> {
    let w = 2 * n + 1;
    let p = degree + 1;
    if w <= p {
        return vec![1.0];
    }
    let v = DMatrix::from_fn(w, p, |i, j| {
        ((i as f64 - n as f64) / n as f64).powi(j as i32)
    });
    let Some(inv) = (v.transpose() * &v).try_inverse() else {
        return vec![1.0];
    };
    let row = (inv * v.transpose()).row(0).into_owned();
    let s2: f64 = row.iter().map(|x| x * x).sum();
    (0..w)
        .map(|d| (0..w - d).map(|i| row[i] * row[i + d]).sum::<f64>() / s2)
        .collect()
}

/// Lines at which [`lpm_excitation_correlation`] averages (spread over the record's band).
const CORRELATION_SAMPLES: usize = 256;

/// Correlation `ρ(d)`, `d = 0, 1, …, 2n`, of the errors of the LPM estimates of one
/// excitation `x` (the input, or the reference in closed loop) `d` lines apart, for noise
/// that is white over a window: `Ĝ_k − G_k = Σ_i a_{k,i} V_i` with `a_k` the row of the
/// local problem's pseudo-inverse `(KᴴK)⁻¹Kᴴ` that gives `G_k` (it depends on the
/// excitation only), so `E[(Ĝ_k − G_k)(Ĝ_l − G_l)*] = σ²_V Σ_i a_{k,i} a*_{l,i}` over the
/// lines the windows share. Returned: `Re Σ_i a_{k,i} a*_{k+d,i} / (‖a_k‖·‖a_{k+d}‖)`
/// averaged (numerator and denominator apart) over up to 256 lines `k` spread over the
/// record; the imaginary part averages out for an excitation of random phase, and is
/// dropped. Compared with the estimates' empirical correlation in a unit test.
///
/// # Errors
/// A record too short for the window, non-finite samples, a singular local problem.
pub fn lpm_excitation_correlation(x: &[f64], opt: &LpmOptions) -> Result<Vec<f64>> {
    if x.iter().any(|v| !v.is_finite()) {
        return Err(IdentError::Data(
            "the excitation contains NaN or infinite values".into(),
        ));
    }
    let r = opt.degree;
    let q = 2 * (r + 1);
    let hw = opt.half_width.unwrap_or_else(|| (q + 2).div_ceil(2));
    let w = 2 * hw + 1;
    let half = x.len() / 2;
    if w <= q || half < 2 * w + 2 {
        return Err(IdentError::Data(format!(
            "{} samples are too few for the correlation of a local window of {w} lines",
            x.len()
        )));
    }
    let xs = dft_columns(&DMatrix::from_column_slice(x.len(), 1, x));
    let (lo, hi) = (1usize, half - 1);
    // a_k over the absolute lines of its window
    let weights = |k: usize| -> Result<(usize, Vec<C>)> {
        let start = k.saturating_sub(hw).max(lo).min(hi + 1 - w);
        let (kmat, scale) = design(&xs, k, start, (w, hw, r));
        let svd = nalgebra::linalg::SVD::try_new(kmat, true, true, f64::EPSILON, 200)
            .ok_or_else(|| IdentError::Numerical("SVD of a local LPM problem".into()))?;
        let (Some(u), Some(v_t)) = (svd.u.as_ref(), svd.v_t.as_ref()) else {
            return Err(IdentError::Numerical("SVD without U or V".into()));
        };
        let a = (0..w)
            .map(|i| {
                svd.singular_values
                    .iter()
                    .enumerate()
                    .map(|(l, &sv)| {
                        v_t[(l, 0)].conj() * u[(i, l)].conj() / sv.max(f64::MIN_POSITIVE)
                    })
                    .sum::<C>()
                    / scale[0]
            })
            .collect();
        Ok((start, a))
    };
    let last = hi - w;
    let step = ((last - lo) / CORRELATION_SAMPLES).max(1);
    let (mut num, mut den) = (vec![0.0; w], vec![0.0; w]);
    for k in (lo + hw..=last).step_by(step) {
        let (s0, a0) = weights(k)?;
        let n0 = a0.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
        for d in 0..w {
            let (s1, a1) = weights(k + d)?;
            let n1 = a1.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
            let dot: C = (0..w)
                .filter_map(|i| {
                    let line = s0 + i;
                    (line >= s1 && line < s1 + w).then(|| a0[i] * a1[line - s1].conj())
                })
                .sum();
            num[d] += dot.re;
            den[d] += n0 * n1;
        }
    }
    Ok(num
        .iter()
        .zip(&den)
        .map(|(n, d)| if *d > 0.0 { n / d } else { 0.0 })
        .collect())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// The correlation from the pseudo-inverse's rows against the empirical correlation of
    /// the LPM's errors on a record `y = x + v` (`G = 1`; x and v white, 2¹⁶ samples):
    /// their standard error over ~32 000 lines is ≈ 0.01; the polynomial-only form misses
    /// ρ(1) by about 0.1.
    #[test]
    fn excitation_correlation_matches_the_estimates_errors() {
        let n = 1 << 16;
        let mut rng = crate::rng::SplitMix::new(11);
        let x: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let y: Vec<f64> = x.iter().map(|v| v + 0.3 * rng.normal()).collect();
        let opt = LpmOptions::default();
        let est = lpm(
            1.0,
            &DMatrix::from_column_slice(n, 1, &x),
            &DMatrix::from_column_slice(n, 1, &y),
            &opt,
        )
        .unwrap();
        let var = est.frd.variance().unwrap();
        let e: Vec<C> = (0..est.frd.len())
            .map(|i| (est.frd.response()[i][(0, 0)] - 1.0) / var[i][(0, 0)].sqrt())
            .collect();
        let rho = lpm_excitation_correlation(&x, &opt).unwrap();
        let poly = lpm_polynomial_correlation(4, opt.degree);
        assert_eq!(rho.len(), 9);
        for d in 0..rho.len() {
            let m = e.len() - d;
            let num: f64 = (0..m).map(|i| (e[i] * e[i + d].conj()).re).sum();
            let power = |r: std::ops::Range<usize>| r.map(|i| e[i].norm_sqr()).sum::<f64>();
            let den = (power(0..m) * power(d..m + d)).sqrt();
            let emp = num / den;
            assert!(
                (rho[d] - emp).abs() < 0.05,
                "ρ({d}) = {} vs empirical {emp}",
                rho[d]
            );
        }
        assert!((poly[1] - rho[1]).abs() > 0.05, "{poly:?} vs {rho:?}");
    }

    /// The expected variances (closed and open loop): the closed-loop raw variance is the one
    /// [`lpm_closed_loop`] gives, and raw over expected scatters as the noise covariance's
    /// estimate alone (the design factor, which varies far more from line to line, is
    /// shared). Static plant `y = u + v`, controller `u = r − 0.5y`, white
    /// `r` and `v`, 2¹⁴ samples.
    #[test]
    fn closed_loop_expected_variance() {
        let n = 1 << 14;
        let mut rng = crate::rng::SplitMix::new(5);
        let r: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let v: Vec<f64> = (0..n).map(|_| 0.2 * rng.normal()).collect();
        let u: Vec<f64> = r.iter().zip(&v).map(|(r, v)| (r - 0.5 * v) / 1.5).collect();
        let y: Vec<f64> = u.iter().zip(&v).map(|(u, v)| u + v).collect();
        let opt = LpmOptions::default();
        let full = lpm_closed_loop_full(1.0, &r, &u, &y, &opt).unwrap();
        let plain = lpm_closed_loop(1.0, &r, &u, &y, &opt).unwrap();
        let raw: Vec<f64> = full
            .frd
            .variance()
            .unwrap()
            .iter()
            .map(|m| m[(0, 0)])
            .collect();
        let same = plain.variance().unwrap();
        for (a, b) in raw.iter().zip(same) {
            assert!((a - b[(0, 0)]).abs() <= 1e-12 * a.abs());
        }
        let stats = |x: &[f64]| {
            let m = x.iter().sum::<f64>() / x.len() as f64;
            let sd = (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
            (m, sd / m)
        };
        let ratio: Vec<f64> = raw
            .iter()
            .zip(&full.expected_var)
            .map(|(a, b)| a / b)
            .collect();
        let (m, cv) = stats(&ratio);
        // raw/expected is the noise covariance's scatter alone: χ²_ν/ν, ν = 6 (mean 1, CV
        // √(2/ν) = 0.58; neighbouring windows overlap, so the mean's error is ~1 %)
        assert!((m - 1.0).abs() < 0.03, "mean ratio {m}");
        assert!((0.45..0.7).contains(&cv), "ratio's spread {cv}");
        // the open-loop estimate's (input u to output y) likewise
        let ol = lpm(
            1.0,
            &DMatrix::from_column_slice(n, 1, &u),
            &DMatrix::from_column_slice(n, 1, &y),
            &opt,
        )
        .unwrap();
        let expected = ol.expected_var().unwrap();
        let ratio: Vec<f64> = ol
            .frd
            .variance()
            .unwrap()
            .iter()
            .zip(&expected)
            .map(|(a, b)| a[(0, 0)] / b)
            .collect();
        let (m, cv) = stats(&ratio);
        assert!((m - 1.0).abs() < 0.03, "open loop: mean ratio {m}");
        assert!((0.45..0.7).contains(&cv), "open loop: ratio's spread {cv}");
        assert_eq!(
            moving_mean(&[1.0, 2.0, 3.0, 10.0], 1),
            vec![1.5, 2.0, 5.0, 6.5]
        );
    }
}
