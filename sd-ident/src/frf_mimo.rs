//! The FRF of a MIMO system from periodic experiments, with the covariance of the vectorised
//! estimate.
//!
//! **Data.** E experiments at one rate and period, each with nu inputs, ny outputs and
//! optionally nu references (closed loop). Per experiment and channel the steady record
//! (M periods after the skipped ones) is transformed once; the period mean at harmonic k is
//! bin `kM` over M, and the noise (co)variance of the means comes from the `2(M − 1)` bins
//! between harmonics (as the SISO estimate, [`crate::frf_periodic`]), here for the stacked
//! vector `z = [Ȳ; Ū]` of each experiment.
//!
//! **Estimate** at every line where the excitation matrix `R_k` (nu × E: the references, or
//! the inputs in open loop, of all experiments) has full rank:
//! `Ĝ_k = (Y_k R_kᴴ)(U_k R_kᴴ)⁻¹` (Pintelon & Schoukens, *System Identification*, 2nd ed.,
//! §2.7 and §3.7: with E = nu orthogonal multisines `U_k R_kᴴ` is well conditioned; in closed
//! loop through the references the estimate is unbiased where the noise does not correlate
//! with `r`).
//!
//! **Covariance** (first order): `δĜ = Σ_e (δȲ_e − Ĝ δŪ_e) w_eᵀ`, `W = R_kᴴ (U_k R_kᴴ)⁻¹`
//! (E × nu, row `w_e`), the experiments' noises independent, so the covariance of column i
//! with column j is `Σ_e W_ei W̄_ej C_e`, `C_e = [I, −Ĝ] Σ_e [I, −Ĝ]ᴴ` with `Σ_e` the noise
//! covariance of experiment e's `[Ȳ; Ū]`. `covariance[k]` is that of `vec(Ĝ_k)` (columns
//! stacked: index `i·ny + a` for entry (a, i)); the FRD's variances are its diagonal. Needs
//! M ≥ 2 periods in every experiment (else no variance).

use crate::error::{IdentError, Result};
use crate::frf::PeriodicOptions;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::{Frd, SampleTime};

/// One periodic experiment's channels (each a full record, same length).
#[derive(Debug, Clone, Copy)]
pub struct Channels<'a> {
    /// References, one per input (closed loop), or none (open loop: the inputs excite).
    pub r: &'a [&'a [f64]],
    /// Plant inputs.
    pub u: &'a [&'a [f64]],
    /// Measured outputs.
    pub y: &'a [&'a [f64]],
}

/// A MIMO FRF estimate.
#[derive(Debug, Clone)]
pub struct MimoFrfEstimate {
    /// ny × nu estimate at the excited lines, with per-entry variances (M ≥ 2).
    pub frd: Frd,
    /// The excited DFT bins (empty for a local-polynomial estimate, which has every line).
    pub lines: Vec<usize>,
    /// Covariance of `vec(Ĝ_k)` per line (`ny·nu` square, columns stacked); empty without
    /// variances.
    pub covariance: Vec<DMatrix<C>>,
    /// The fewest steady periods of any experiment (0: a non-periodic record).
    pub periods: usize,
}

/// Period means at the harmonics and their noise covariance, per experiment.
struct Spectra {
    /// Per harmonic 0..=P/2: `[Ȳ; Ū; R̄]` (R̄ absent in open loop).
    mean: Vec<Vec<C>>,
    /// Per harmonic: noise covariance of `[Ȳ; Ū]` (None with one period).
    cov: Option<Vec<DMatrix<C>>>,
}

/// The spectra of one experiment (module documentation).
fn spectra(
    ch: &Channels<'_>,
    opt: &PeriodicOptions,
    ny: usize,
    nu: usize,
) -> Result<(Spectra, usize)> {
    let p = opt.period;
    let n = ch.u[0].len();
    let all: Vec<&[f64]> = ch.y.iter().chain(ch.u).chain(ch.r).copied().collect();
    if all.iter().any(|x| x.len() != n) {
        return Err(IdentError::Data(
            "every channel of an experiment must have the same length".into(),
        ));
    }
    if all.iter().any(|x| x.iter().any(|v| !v.is_finite())) {
        return Err(IdentError::Data(
            "the signals contain NaN or infinite values".into(),
        ));
    }
    let total = n / p;
    if total <= opt.skip_periods {
        return Err(IdentError::Data(format!(
            "{n} samples hold {total} periods of {p}; none is left after skipping {}",
            opt.skip_periods
        )));
    }
    let m = total - opt.skip_periods;
    let (start, len) = (opt.skip_periods * p, m * p);
    // bins 0 … len/2 of each record; above, X_b = conj(X_{len − b})
    let long: Vec<Vec<C>> = all
        .iter()
        .map(|x| crate::frf::transform_real(&x[start..start + len]))
        .collect();
    let bin = |x: &[C], b: usize| {
        if b < x.len() {
            x[b]
        } else {
            x[len - b].conj()
        }
    };
    let mf = m as f64;
    let half = p / 2;
    let mean: Vec<Vec<C>> = (0..=half)
        .map(|k| long.iter().map(|x| x[k * m] / mf).collect())
        .collect();
    let nz = ny + nu;
    let cov = (m >= 2).then(|| {
        (0..=half)
            .map(|k| {
                let mut s = DMatrix::<C>::zeros(nz, nz);
                let mut cnt = 0.0f64;
                for j in 1..m {
                    for b in [k * m + j, (k * m).wrapping_sub(j)] {
                        if b >= len {
                            continue;
                        }
                        let z = DMatrix::from_fn(nz, 1, |i, _| bin(&long[i], b));
                        s += &z * z.adjoint();
                        cnt += 1.0;
                    }
                }
                s / C::new(cnt.max(1.0) * mf * mf, 0.0)
            })
            .collect()
    });
    crate::frf::recycle_spectra(long);
    Ok((Spectra { mean, cov }, m))
}

/// MIMO FRF of periodic experiments (module documentation).
///
/// # Errors
/// No experiment, channels of different counts across experiments or lengths within one,
/// references that are not one per input, fewer experiments than inputs (the inputs cannot
/// be told apart), too few periods, no line where every input is excited independently.
pub fn frf_periodic_mimo(
    fs: f64,
    exps: &[Channels<'_>],
    opt: &PeriodicOptions,
) -> Result<MimoFrfEstimate> {
    let first = exps
        .first()
        .ok_or_else(|| IdentError::InvalidArgument("no experiment to estimate from".into()))?;
    let (ny, nu, nr) = (first.y.len(), first.u.len(), first.r.len());
    if ny == 0 || nu == 0 {
        return Err(IdentError::InvalidArgument(
            "an experiment needs at least one input and one output".into(),
        ));
    }
    if nr != 0 && nr != nu {
        return Err(IdentError::InvalidArgument(format!(
            "{nr} references for {nu} inputs: give one reference per input, or none"
        )));
    }
    if let Some(e) = exps
        .iter()
        .position(|e| (e.y.len(), e.u.len(), e.r.len()) != (ny, nu, nr))
    {
        return Err(IdentError::InvalidArgument(format!(
            "experiment {} has {} outputs, {} inputs and {} references; the first has {ny}, {nu} and {nr}",
            e + 1,
            exps[e].y.len(),
            exps[e].u.len(),
            exps[e].r.len()
        )));
    }
    if exps.len() < nu {
        return Err(IdentError::InvalidArgument(format!(
            "{} experiment(s) for {nu} inputs: at least one experiment per input is needed to \
             tell the inputs apart (one input excited per experiment, or orthogonal multisines)",
            exps.len()
        )));
    }
    if !(fs.is_finite() && fs > 0.0) || opt.period < 4 {
        return Err(IdentError::InvalidArgument(format!(
            "sample rate {fs} must be > 0 and the period {} ≥ 4 samples",
            opt.period
        )));
    }
    let mut sp = Vec::with_capacity(exps.len());
    let mut periods = usize::MAX;
    for e in exps {
        let (s, m) = spectra(e, opt, ny, nu)?;
        periods = periods.min(m);
        sp.push(s);
    }
    estimate(fs, &sp, (ny, nu, nr), opt, periods)
}

/// The excitation matrix `R_k` (nu × E) at harmonic k.
fn excitation(sp: &[Spectra], k: usize, (ny, nu, nr): (usize, usize, usize)) -> DMatrix<C> {
    let off = if nr > 0 { ny + nu } else { ny };
    DMatrix::from_fn(nu, sp.len(), |i, e| sp[e].mean[k][off + i])
}

/// The estimate and covariance at the excited lines.
fn estimate(
    fs: f64,
    sp: &[Spectra],
    dims: (usize, usize, usize),
    opt: &PeriodicOptions,
    periods: usize,
) -> Result<MimoFrfEstimate> {
    let (ny, nu, _) = dims;
    let half = opt.period / 2;
    let smin = |k: usize| {
        let s = excitation(sp, k, dims).singular_values();
        s.iter().cloned().fold(f64::INFINITY, f64::min)
    };
    let strength: Vec<f64> = (0..half)
        .map(|k| if k == 0 { 0.0 } else { smin(k) })
        .collect();
    let top = strength.iter().cloned().fold(0.0, f64::max);
    if top == 0.0 {
        return Err(IdentError::Data(
            "no line where every input is excited independently (the experiments' excitations \
             are linearly dependent at every line)"
                .into(),
        ));
    }
    let lines: Vec<usize> = (1..half)
        .filter(|&k| strength[k] > opt.excited_fraction * top)
        .collect();
    let with_var = sp.iter().all(|s| s.cov.is_some());
    let (mut resp, mut var, mut covs) = (Vec::new(), Vec::new(), Vec::new());
    for &k in &lines {
        let r = excitation(sp, k, dims);
        let y = DMatrix::from_fn(ny, sp.len(), |a, e| sp[e].mean[k][a]);
        let u = DMatrix::from_fn(nu, sp.len(), |i, e| sp[e].mean[k][ny + i]);
        let ur = &u * r.adjoint();
        let inv = ur.clone().try_inverse().ok_or_else(|| {
            IdentError::Numerical(format!(
                "the input-excitation matrix is singular at bin {k}"
            ))
        })?;
        let w = r.adjoint() * &inv;
        let g = &y * &w;
        if with_var {
            let cov = line_covariance(sp, k, &g, &w, (ny, nu));
            var.push(DMatrix::from_fn(ny, nu, |a, i| {
                cov[(i * ny + a, i * ny + a)].re.max(0.0)
            }));
            covs.push(cov);
        }
        resp.push(g);
    }
    let freq: Vec<f64> = lines
        .iter()
        .map(|&k| k as f64 * fs / opt.period as f64)
        .collect();
    let frd = Frd::new(
        freq,
        resp,
        with_var.then_some(var),
        SampleTime::discrete(1.0 / fs)?,
    )?;
    Ok(MimoFrfEstimate {
        frd,
        lines,
        covariance: covs,
        periods,
    })
}

/// The covariance of `vec(Ĝ)` at one line (module documentation).
fn line_covariance(
    sp: &[Spectra],
    k: usize,
    g: &DMatrix<C>,
    w: &DMatrix<C>,
    (ny, nu): (usize, usize),
) -> DMatrix<C> {
    // [I, −Ĝ]: the output equation's residual from [δȲ; δŪ]
    let mut t = DMatrix::<C>::zeros(ny, ny + nu);
    for a in 0..ny {
        t[(a, a)] = C::new(1.0, 0.0);
        for i in 0..nu {
            t[(a, ny + i)] = -g[(a, i)];
        }
    }
    let mut out = DMatrix::<C>::zeros(ny * nu, ny * nu);
    for (e, s) in sp.iter().enumerate() {
        let Some(cov) = &s.cov else { continue };
        let ce = &t * &cov[k] * t.adjoint();
        for i in 0..nu {
            for j in 0..nu {
                let f = w[(e, i)] * w[(e, j)].conj();
                for a in 0..ny {
                    for b in 0..ny {
                        out[(i * ny + a, j * ny + b)] += f * ce[(a, b)];
                    }
                }
            }
        }
    }
    out
}
