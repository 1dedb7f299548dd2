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
    let (n, nu) = (sys.n(), sys.nu());
    let mut blk = DMatrix::<f64>::identity(n + nu, n + nu);
    blk.view_mut((0, 0), (n, n)).copy_from(sys.a());
    blk.view_mut((0, n), (n, nu)).copy_from(sys.b());
    let l = logm(&blk)?;
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

    #[test]
    fn logm_inverts_expm_with_jordan_block() {
        let a = DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, 0.0, 0.0, 0.5, 0.0, -2.0, -0.1]);
        let e = crate::linalg::expm(&a).unwrap();
        let l = logm(&e).unwrap();
        assert!((l - a).abs().max() < 1e-13);
    }
}
