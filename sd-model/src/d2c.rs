//! Discrete → continuous conversion (inverse ZOH) with the alias candidates of every mode.
//!
//! The ZOH map is not injective (the paper's Proposition 4): a discrete pole `p = e^{(σ+jω)h}`
//! arises from every continuous pole `σ + j(ω + 2πk/h)`, k ∈ ℤ. [`d2c`] returns the principal
//! branch, `[[A h, B h], [0, 0]] = log([[A_d, B_d], [0, I]])` with the principal matrix logarithm
//! (every eigenvalue's imaginary part in (−π, π]), and [`d2c_with_aliases`] adds, per discrete
//! pole, the continuous frequencies it could have come from.
//!
//! The logarithm is computed by inverse scaling and squaring on the complex Schur form
//! (Higham, *Functions of Matrices*, SIAM 2008, Alg. 11.10, simplified): after exact diagonal
//! balancing, take triangular square roots (Björck–Hammarling recurrence) until `‖T − I‖₁ ≤ 1/4`,
//! evaluate `log(I + X)` by 10-point Gauss–Legendre quadrature of `∫₀¹ X (I + tX)⁻¹ dt` (the
//! diagonal Padé approximant; error < 1e-17 for ‖X‖ ≤ 1/4) and multiply by `2^k`. Jordan blocks
//! (the rigid-body double pole at z = 1) are handled: nothing is diagonalised.
//!
//! A pole that is zero or on the negative real axis has no real logarithm: that is an error, not
//! a silently dropped imaginary part.

use crate::error::{ModelError, Result};
use crate::linalg::convert::eigenvalues;
use crate::linalg::expm::{balance_diag, norm1};
use crate::linalg::schur::{complex_schur, to_complex};
use crate::ss::StateSpace;
use crate::time::SampleTime;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use std::f64::consts::PI;

/// One discrete mode and the continuous frequencies that produce it under sampling.
#[derive(Debug, Clone, PartialEq)]
pub struct ModeAliases {
    /// The discrete pole.
    pub z: C,
    /// Principal continuous pole `log(z)/h`.
    pub s: C,
    /// Natural frequency `|s|/2π` of the principal pole in Hz: the toolkit's one frequency of
    /// a pole, as `sdctl poles` prints it and python-control's `damp` gives it (the oscillation
    /// frequency is `freq_hz·√(1 − ζ²)`).
    pub freq_hz: f64,
    /// Damping ratio of the principal pole `−Re s/|s|` (1 for s = 0).
    pub damping: f64,
    /// Candidate continuous poles `s_k = Re s + j(Im s + 2πk/h)` as natural frequencies
    /// `|s_k|/2π` up to `max_hz`, ascending, each with the damping ratio `−Re s_k/|s_k|`.
    pub candidates: Vec<(f64, f64)>,
}

/// Principal-branch inverse ZOH of a discrete model.
///
/// # Errors
/// A continuous model; a pole at zero or on the negative real axis ([`ModelError::NoRealLogarithm`]).
pub fn d2c(sys: &StateSpace) -> Result<StateSpace> {
    let h = match sys.time() {
        SampleTime::Discrete { ts } => ts,
        SampleTime::Continuous => {
            return Err(ModelError::WrongDomain {
                operation: "d2c".into(),
                expected: "discrete-time".into(),
                found: "continuous-time".into(),
            })
        }
    };
    check_real_log(sys.a())?;
    let blk = augmented(sys);
    from_log(sys, &logm(&blk)?, h)
}

/// `[[A_d, B_d], [0, I]]`, the matrix whose logarithm is `[[A h, B h], [0, 0]]`.
fn augmented(sys: &StateSpace) -> DMatrix<f64> {
    let (n, nu) = (sys.n(), sys.nu());
    let mut blk = DMatrix::<f64>::identity(n + nu, n + nu);
    blk.view_mut((0, 0), (n, n)).copy_from(sys.a());
    blk.view_mut((0, n), (n, nu)).copy_from(sys.b());
    blk
}

/// The continuous model `(L₁₁/h, L₁₂/h, C, D)` read off a logarithm `L` of [`augmented`].
fn from_log(sys: &StateSpace, l: &DMatrix<f64>, h: f64) -> Result<StateSpace> {
    let (n, nu) = (sys.n(), sys.nu());
    let a = l.view((0, 0), (n, n)) / h;
    let b = l.view((0, n), (n, nu)) / h;
    Ok(StateSpace::new(
        a,
        b,
        sys.c().clone(),
        sys.d().clone(),
        SampleTime::Continuous,
    )?
    .with_labels_of(sys))
}

/// One alias branch chosen by [`d2c_near`].
#[derive(Debug, Clone, PartialEq)]
pub struct BranchPick {
    /// The frequency the user asked for (Hz).
    pub requested_hz: f64,
    /// The discrete pole (upper half plane) whose branch was chosen.
    pub z: C,
    /// The branch `k`: the continuous pole is `log(z)/h + j2πk/h` (0 = principal).
    pub branch: i64,
    /// Natural frequency `|s_k|/2π` of the chosen continuous pole (Hz).
    pub freq_hz: f64,
    /// Damping ratio `−Re s_k/|s_k|` of the chosen continuous pole.
    pub damping: f64,
    /// Natural frequency of the principal branch (Hz), what [`d2c`] would give.
    pub principal_hz: f64,
}

/// Inverse ZOH with chosen alias branches: for every frequency in `near_hz`, the oscillatory
/// mode and branch `k` whose natural frequency `|log(z)/h + j2πk/h|/2π` is nearest to it are
/// used instead of the principal branch; all other modes stay principal.
///
/// **Math.** With `M = [[A_d, B_d], [0, I]]` and `L` its principal logarithm, a pole pair
/// `(z, z̄)` with spectral projectors `P` and `P̄` of `M` moves to branch `k` by
/// `L' = L + j2πk (P − P̄) = L − 4πk Im P`, which is real, commutes with `M` and satisfies
/// `e^{L'} = e^{L}` (the shift is `2πjk` on an invariant subspace). `P = v wᴴ/(wᴴv)` from right
/// and left eigenvectors found by inverse iteration. The result is checked: `‖e^{L'} − M‖` must
/// stay below `1e-8·‖M‖`, so `c2d` (ZOH) of the returned model gives the discrete model back.
/// A continuous model sampled above its Nyquist rate is recovered exactly when its aliased modes
/// are named (a 653 Hz mode sampled at 1 kHz appears at 347 Hz; `near_hz = [653]` returns it).
///
/// # Errors
/// What [`d2c`] refuses; a requested frequency that is not finite and positive; no oscillatory
/// mode (a real pole cannot move to another branch alone); one mode asked for two branches; a
/// repeated or ill-conditioned pole whose eigenvectors cannot be trusted.
pub fn d2c_near(sys: &StateSpace, near_hz: &[f64]) -> Result<(StateSpace, Vec<BranchPick>)> {
    let h = sys.ts().ok_or_else(|| ModelError::WrongDomain {
        operation: "d2c".into(),
        expected: "discrete-time".into(),
        found: "continuous-time".into(),
    })?;
    check_real_log(sys.a())?;
    let blk = augmented(sys);
    let mut l = logm(&blk)?;
    let poles = eigenvalues(sys.a())?;
    let mut picks: Vec<BranchPick> = Vec::new();
    for &f in near_hz {
        let pick = nearest_branch(&poles, h, f)?;
        if let Some(prev) = picks
            .iter()
            .find(|p| (p.z - pick.z).norm() <= 1e-12 * pick.z.norm())
        {
            if prev.branch != pick.branch {
                return Err(ModelError::InvalidArgument(format!(
                    "{} Hz and {} Hz both pick the mode z = {:.6}{:+.6}i; a mode has one branch, \
                     ask for one of them",
                    prev.requested_hz, f, pick.z.re, pick.z.im
                )));
            }
            continue;
        }
        if pick.branch != 0 {
            let p = spectral_projector(&blk, pick.z, &poles)?;
            l -= p.map(|v| v.im) * (4.0 * PI * pick.branch as f64);
        }
        picks.push(pick);
    }
    let back = crate::linalg::expm(&l)?;
    let scale = norm1(&blk).max(1.0);
    let err = norm1(&(back - &blk));
    if err > 1e-8 * scale {
        return Err(ModelError::NotConverged {
            what: format!(
                "the branch-shifted logarithm (e^L misses [[A, B], [0, I]] by {err:.2e}; \
                 the chosen poles are too close to others)"
            ),
        });
    }
    Ok((from_log(sys, &l, h)?, picks))
}

/// The oscillatory pole (upper half plane) and branch nearest to `f` Hz in natural frequency.
fn nearest_branch(poles: &[C], h: f64, f: f64) -> Result<BranchPick> {
    if !(f.is_finite() && f > 0.0) {
        return Err(ModelError::InvalidArgument(format!(
            "a branch frequency must be finite and positive (Hz), got {f}"
        )));
    }
    let tol = 1e-9;
    let mut best: Option<(f64, BranchPick)> = None;
    for &z in poles.iter().filter(|z| z.im > tol * z.norm()) {
        let s = z.ln() / h;
        let kmax = (f * h).ceil() as i64 + 2;
        for k in -kmax..=kmax {
            let sk = C::new(s.re, s.im + 2.0 * PI * k as f64 / h);
            let (fk, zeta) = crate::poles::natural_frequency(sk, None);
            let d = (fk - f).abs();
            let better = match &best {
                None => true,
                Some((bd, bp)) => {
                    d < bd - 1e-12 * f || (d <= bd + 1e-12 * f && k.abs() < bp.branch.abs())
                }
            };
            if better {
                let principal_hz = crate::poles::natural_frequency(s, None).0;
                let pick = BranchPick {
                    requested_hz: f,
                    z,
                    branch: k,
                    freq_hz: fk,
                    damping: zeta,
                    principal_hz,
                };
                best = Some((d, pick));
            }
        }
    }
    best.map(|(_, p)| p).ok_or_else(|| {
        ModelError::InvalidArgument(
            "the model has no oscillatory mode: a real pole cannot move to another alias \
             branch alone, so there is nothing to pick"
                .into(),
        )
    })
}

/// Spectral projector `v wᴴ/(wᴴ v)` of `m` for the simple eigenvalue `z`.
fn spectral_projector(m: &DMatrix<f64>, z: C, poles: &[C]) -> Result<DMatrix<C>> {
    let n = m.nrows();
    let scale = norm1(m).max(1.0);
    let close = poles
        .iter()
        .filter(|p| (*p - z).norm() <= 1e-6 * scale)
        .count();
    if close > 1 {
        return Err(ModelError::InvalidArgument(format!(
            "the pole z = {:.6}{:+.6}i is repeated; its alias branch cannot be chosen alone",
            z.re, z.im
        )));
    }
    let mc = to_complex(m);
    let mu = z + C::new(1e-10, 1e-10) * scale;
    let shifted = &mc - DMatrix::<C>::identity(n, n) * mu;
    let lu = shifted.clone().lu();
    let lu_h = shifted.adjoint().lu();
    let start = nalgebra::DVector::<C>::from_fn(n, |i, _| C::new(1.0, 0.1 * i as f64));
    let (mut v, mut w) = (start.clone(), start);
    let singular = || ModelError::Singular {
        what: "the inverse iteration for a pole's eigenvectors".into(),
    };
    for _ in 0..4 {
        v = lu.solve(&v).ok_or_else(singular)?;
        v /= C::new(v.norm(), 0.0);
        w = lu_h.solve(&w).ok_or_else(singular)?;
        w /= C::new(w.norm(), 0.0);
    }
    let zi = DMatrix::<C>::identity(n, n) * z;
    let res_v = ((&mc - &zi) * &v).norm();
    let res_w = ((mc.adjoint() - zi.adjoint()) * &w).norm();
    let d = (w.adjoint() * &v)[(0, 0)];
    if res_v > 1e-8 * scale || res_w > 1e-8 * scale || d.norm() < 1e-8 {
        return Err(ModelError::NotConverged {
            what: format!(
                "the eigenvectors of z = {:.6}{:+.6}i (residuals {res_v:.1e}, {res_w:.1e}, \
                 wᴴv = {:.1e}: the pole is ill-conditioned)",
                z.re,
                z.im,
                d.norm()
            ),
        });
    }
    Ok(&v * w.adjoint() / d)
}

/// [`d2c`] plus the alias candidates of every mode up to `max_hz`.
pub fn d2c_with_aliases(sys: &StateSpace, max_hz: f64) -> Result<(StateSpace, Vec<ModeAliases>)> {
    let c = d2c(sys)?;
    let h = sys.ts().unwrap_or(1.0);
    let mut modes = Vec::new();
    for z in eigenvalues(sys.a())? {
        if z.im < 0.0 {
            continue; // report each conjugate pair once
        }
        modes.push(mode_aliases(z, h, max_hz));
    }
    modes.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    Ok((c, modes))
}

/// Alias candidates of a single discrete pole `z` at period `h`.
pub fn mode_aliases(z: C, h: f64, max_hz: f64) -> ModeAliases {
    let s = z.ln() / h;
    let damp = |s: C| crate::poles::natural_frequency(s, None).1;
    let fs = 1.0 / h;
    let f0 = s.norm() / (2.0 * PI);
    let mut cands = Vec::new();
    let kmax = (max_hz / fs).ceil() as i64 + 1;
    for k in -kmax..=kmax {
        let w = s.im + 2.0 * PI * k as f64 * fs;
        let sk = C::new(s.re, w);
        let f = sk.norm() / (2.0 * PI);
        let seen = cands
            .iter()
            .any(|(g, _): &(f64, f64)| (g - f).abs() <= 1e-9 * fs);
        if f <= max_hz * (1.0 + 1e-12) && !seen {
            cands.push((f, damp(sk)));
        }
    }
    cands.sort_by(|a, b| a.0.total_cmp(&b.0));
    ModeAliases {
        z,
        s,
        freq_hz: f0,
        damping: damp(s),
        candidates: cands,
    }
}

fn check_real_log(a: &DMatrix<f64>) -> Result<()> {
    let scale = norm1(a).max(1.0);
    for z in eigenvalues(a)? {
        if z.norm() <= 1e3 * f64::EPSILON * scale {
            return Err(ModelError::no_log(z, "it is zero"));
        }
        if z.re < 0.0 && z.im.abs() <= 1e-10 * z.norm() {
            return Err(ModelError::no_log(z, "it lies on the negative real axis"));
        }
    }
    Ok(())
}

/// Gauss–Legendre nodes and weights on [0, 1] (Newton on the Legendre recurrence).
fn gauss_legendre01(m: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(m);
    for i in 1..=m {
        let mut x = (PI * (i as f64 - 0.25) / (m as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=m {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = m as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push(((x + 1.0) / 2.0, w / 2.0));
    }
    out
}

fn tri_norm1_minus_identity(t: &DMatrix<C>) -> f64 {
    let n = t.nrows();
    (0..n)
        .map(|j| {
            (0..=j)
                .map(|i| {
                    (t[(i, j)]
                        - if i == j {
                            C::new(1.0, 0.0)
                        } else {
                            C::new(0.0, 0.0)
                        })
                    .norm()
                })
                .sum::<f64>()
        })
        .fold(0.0, f64::max)
}

/// Principal square root of an upper-triangular matrix (Björck & Hammarling 1983).
fn sqrt_triangular(t: &DMatrix<C>) -> Result<DMatrix<C>> {
    let n = t.nrows();
    let mut r = DMatrix::<C>::zeros(n, n);
    for j in 0..n {
        r[(j, j)] = t[(j, j)].sqrt();
        for i in (0..j).rev() {
            let mut s = t[(i, j)];
            for k in (i + 1)..j {
                s -= r[(i, k)] * r[(k, j)];
            }
            let d = r[(i, i)] + r[(j, j)];
            if d.norm() == 0.0 {
                return Err(ModelError::Singular {
                    what: "the triangular square root (eigenvalue at zero)".into(),
                });
            }
            r[(i, j)] = s / d;
        }
    }
    Ok(r)
}

/// Principal logarithm of a real matrix whose eigenvalues avoid the closed negative real axis.
pub fn logm(m: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let n = m.nrows();
    if n == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    let (bal, d) = balance_diag(m);
    let (q, mut t) = complex_schur(&to_complex(&bal))?;
    let mut k = 0;
    while tri_norm1_minus_identity(&t) > 0.25 {
        if k >= 100 {
            return Err(ModelError::NotConverged {
                what: "the inverse scaling and squaring of logm".into(),
            });
        }
        t = sqrt_triangular(&t)?;
        k += 1;
    }
    let x = &t - DMatrix::<C>::identity(n, n);
    let mut l = DMatrix::<C>::zeros(n, n);
    for (node, w) in gauss_legendre01(10) {
        // solve (I + node X) Y = X (upper triangular)
        let mut y = x.clone();
        for col in 0..n {
            for i in (0..n).rev() {
                let mut s = y[(i, col)];
                for l2 in (i + 1)..n {
                    s -= x[(i, l2)] * node * y[(l2, col)];
                }
                y[(i, col)] = s / (C::new(1.0, 0.0) + x[(i, i)] * node);
            }
        }
        l += y * C::new(w, 0.0);
    }
    l *= C::new(2f64.powi(k), 0.0);
    let full = &q * l * q.adjoint();
    let scale = full.iter().map(|v| v.norm()).fold(0.0, f64::max).max(1.0);
    if full.iter().any(|v| v.im.abs() > 1e-6 * scale) {
        return Err(ModelError::NotConverged {
            what: "the real matrix logarithm (complex result: a pole pair is on or too close to the negative real axis)".into(),
        });
    }
    let mut out = full.map(|v| v.re);
    for i in 0..n {
        for j in 0..n {
            out[(i, j)] *= d[i] / d[j];
        }
    }
    Ok(out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials() {
        let gl = gauss_legendre01(10);
        let s: f64 = gl.iter().map(|(x, w)| w * x.powi(7)).sum();
        assert!((s - 1.0 / 8.0).abs() < 1e-15);
    }

    /// Two lightly damped modes, 100 Hz and 653 Hz, as a continuous modal model.
    fn two_mode_stage() -> StateSpace {
        let mut a = DMatrix::zeros(4, 4);
        for (i, (f, z)) in [(100.0, 0.01), (653.0, 0.005)].iter().enumerate() {
            let w: f64 = 2.0 * PI * f;
            a[(2 * i, 2 * i + 1)] = 1.0;
            a[(2 * i + 1, 2 * i)] = -w * w;
            a[(2 * i + 1, 2 * i + 1)] = -2.0 * z * w;
        }
        let b = DMatrix::from_column_slice(4, 1, &[0.0, 1.0, 0.0, 1.0]);
        let c = DMatrix::from_row_slice(1, 4, &[1.0, 0.0, 3.0, 0.0]);
        StateSpace::new(a, b, c, DMatrix::zeros(1, 1), SampleTime::Continuous).unwrap()
    }

    fn response(sys: &StateSpace, f: f64) -> C {
        let n = sys.n();
        let s = C::new(0.0, 2.0 * PI * f);
        let m = DMatrix::<C>::identity(n, n) * s - to_complex(sys.a());
        let x = m.lu().solve(&to_complex(sys.b())).unwrap();
        (to_complex(sys.c()) * x)[(0, 0)]
    }

    #[test]
    fn near_hz_recovers_an_aliased_mode_exactly() {
        let ct = two_mode_stage();
        let dt = crate::c2d(&ct, 1e-3, crate::Discretization::Zoh).unwrap();
        // The principal branch puts the 653 Hz mode at 347 Hz.
        let (_, modes) = d2c_with_aliases(&dt, 3000.0).unwrap();
        assert!(modes.iter().any(|m| (m.freq_hz - 347.0).abs() < 0.1));
        let (back, picks) = d2c_near(&dt, &[650.0]).unwrap();
        assert_eq!(picks.len(), 1);
        assert_eq!(picks[0].branch.abs(), 1);
        assert!((picks[0].freq_hz - 653.0).abs() < 1e-6, "{:?}", picks[0]);
        assert!((picks[0].principal_hz - 347.0).abs() < 0.1);
        // The continuous model itself comes back: its frequency response, not only its poles.
        for f in [1.0, 50.0, 100.0, 400.0, 653.0, 2000.0] {
            let (h0, h1) = (response(&ct, f), response(&back, f));
            assert!((h0 - h1).norm() <= 1e-7 * h0.norm(), "{f} Hz: {h0} vs {h1}");
        }
        // And it samples to the discrete model again.
        let again = crate::c2d(&back, 1e-3, crate::Discretization::Zoh).unwrap();
        assert!((again.a() - dt.a()).abs().max() < 1e-10);
        assert!((again.b() - dt.b()).abs().max() < 1e-10 * dt.b().abs().max());
    }

    #[test]
    fn near_hz_refuses_what_it_cannot_do() {
        let dt = crate::c2d(&two_mode_stage(), 1e-3, crate::Discretization::Zoh).unwrap();
        assert!(d2c_near(&dt, &[f64::NAN]).is_err());
        assert!(d2c_near(&dt, &[-5.0]).is_err());
        let both = d2c_near(&dt, &[653.0, 347.0]).unwrap_err().to_string();
        assert!(both.contains("one branch"), "{both}");
        // Asking for the principal branch changes nothing.
        let (p, _) = d2c_near(&dt, &[100.0]).unwrap();
        assert!((p.a() - d2c(&dt).unwrap().a()).abs().max() < 1e-12 * 1e6);
        let real = StateSpace::new(
            DMatrix::from_element(1, 1, 0.5),
            DMatrix::from_element(1, 1, 1.0),
            DMatrix::from_element(1, 1, 1.0),
            DMatrix::zeros(1, 1),
            SampleTime::Discrete { ts: 1e-3 },
        )
        .unwrap();
        let msg = d2c_near(&real, &[600.0]).unwrap_err().to_string();
        assert!(msg.contains("no oscillatory mode"), "{msg}");
    }

    #[test]
    fn logm_inverts_expm_with_jordan_block() {
        let a = DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, 0.0, 0.0, 0.5, 0.0, -2.0, -0.1]);
        let e = crate::linalg::expm(&a).unwrap();
        let l = logm(&e).unwrap();
        assert!((l - a).abs().max() < 1e-13);
    }
}
