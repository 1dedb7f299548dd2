//! Matrix exponential by scaling and squaring with Padé approximants.
//!
//! Algorithm 3.1 of A. H. Al-Mohy and N. J. Higham, "A new scaling and squaring algorithm for the
//! matrix exponential", SIAM J. Matrix Anal. Appl. 31(3), 2009 (building on N. J. Higham, SIAM
//! J. Matrix Anal. Appl. 26(4), 2005): choose the Padé degree m ∈ {3, 5, 7, 9, 13} and the number
//! of squarings s from the sequence `d_k = ‖A^k‖₁^{1/k}` (which avoids the overscaling of the 2005
//! algorithm for non-normal matrices), correct s by the backward-error bound `ℓ(A, m)` computed
//! from `‖|A|^{2m+1}‖₁`, evaluate `r_m(2^{-s}A) = (V − U)⁻¹(V + U)` by LU and square s times.
//! Backward error ≤ u = 2⁻⁵³ in exact arithmetic; forward error bounded by the condition number
//! of the exponential times u. The same algorithm as scipy.linalg.expm and Julia's `exp`.
//!
//! An optional diagonal (power-of-two, hence exact) balancing `D⁻¹ A D` is applied first when it
//! reduces ‖A‖₁ by more than a factor 8: e.g. a lightly damped stage in physical coordinates at
//! h = 0.2 ms has ‖A h‖₁ ≈ 3·10⁵, balanced ≈ 10, which saves ~15 squarings and their rounding.
//! Diagonal similarity keeps every zero block, so `[[A, B], [0, 0]]` keeps its structure.

use crate::error::{ModelError, Result};
use nalgebra::DMatrix;

const THETA: [(usize, f64); 5] = [
    (3, 1.495585217958292e-2),
    (5, 2.539_398_330_063_23e-1),
    (7, 9.504178996162932e-1),
    (9, 2.097847961257068e0),
    (13, 5.371920351148152e0),
];

fn pade_coeffs(m: usize) -> &'static [f64] {
    match m {
        3 => &[120.0, 60.0, 12.0, 1.0],
        5 => &[30240.0, 15120.0, 3360.0, 420.0, 30.0, 1.0],
        7 => &[
            17297280.0, 8648640.0, 1995840.0, 277200.0, 25200.0, 1512.0, 56.0, 1.0,
        ],
        9 => &[
            17643225600.0,
            8821612800.0,
            2075673600.0,
            302702400.0,
            30270240.0,
            2162160.0,
            110880.0,
            3960.0,
            90.0,
            1.0,
        ],
        _ => &[
            64764752532480000.0,
            32382376266240000.0,
            7771770303897600.0,
            1187353796428800.0,
            129060195264000.0,
            10559470521600.0,
            670442572800.0,
            33522128640.0,
            1323241920.0,
            40840800.0,
            960960.0,
            16380.0,
            182.0,
            1.0,
        ],
    }
}

/// Matrix 1-norm (maximum absolute column sum).
pub fn norm1(a: &DMatrix<f64>) -> f64 {
    a.column_iter()
        .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// `ℓ(A, m)` of Al-Mohy & Higham (2009), eq. (3.11)–(3.13): extra squarings needed so that the
/// relative backward error bound of `r_m` stays below u.
fn ell(a: &DMatrix<f64>, m: usize) -> i32 {
    // |c_{2m+1}|⁻¹ of the Padé remainder series (Higham 2005, eq. 2.2/2.6).
    let c_recip = match m {
        3 => 100800.0,
        5 => 10059033600.0,
        7 => 4487938430976000.0,
        9 => 5914384781877411840000.0,
        _ => 113250775606021113483283660800000000.0,
    };
    let p = 2 * m + 1;
    let n = a.nrows();
    let abs = a.abs();
    // ‖|A|^p‖₁ = max entry of 1ᵀ |A|^p (nonnegative matrix).
    let mut v = nalgebra::RowDVector::from_element(n, 1.0);
    for _ in 0..p {
        v = &v * &abs;
    }
    let abs_pow_norm = v.iter().cloned().fold(0.0, f64::max);
    if abs_pow_norm == 0.0 {
        return 0;
    }
    let alpha = abs_pow_norm / (norm1(a) * c_recip);
    let u = f64::EPSILON / 2.0;
    let val = ((alpha / u).log2() / (2 * m) as f64).ceil();
    if val.is_finite() && val > 0.0 {
        val as i32
    } else {
        0
    }
}

/// Diagonal balancing with powers of two (LAPACK xGEBAL, scaling only, no permutation).
/// Returns `(D⁻¹ A D, d)`.
pub fn balance_diag(a: &DMatrix<f64>) -> (DMatrix<f64>, Vec<f64>) {
    balance_leading(a, a.nrows())
}

/// [`balance_diag`] with only the first `k` indices scaled (their row and column sums include
/// all the others): for the state part of `[A B; C D]`, where the inputs and outputs keep their
/// units (MATLAB's `ssbal`). Returns the balanced matrix and the k scalings (`x = D x̃`).
pub fn balance_leading(a: &DMatrix<f64>, k: usize) -> (DMatrix<f64>, Vec<f64>) {
    let n = a.nrows();
    let k = k.min(n);
    let mut m = a.clone();
    let mut d = vec![1.0; k];
    let radix: f64 = 2.0;
    for _sweep in 0..100 {
        let mut converged = true;
        for i in 0..k {
            let mut c = 0.0;
            let mut r = 0.0;
            for j in 0..n {
                if j != i {
                    c += m[(j, i)].abs();
                    r += m[(i, j)].abs();
                }
            }
            if c == 0.0 || r == 0.0 {
                continue;
            }
            let s = c + r;
            let mut f = 1.0;
            let mut cc = c;
            let mut rr = r;
            while cc < rr / radix {
                cc *= radix;
                rr /= radix;
                f *= radix;
            }
            while cc >= rr * radix {
                cc /= radix;
                rr *= radix;
                f /= radix;
            }
            if (cc + rr) < 0.95 * s {
                converged = false;
                d[i] *= f;
                // column i times f, row i divided by f  (D⁻¹ A D with D_ii = f)
                for j in 0..n {
                    m[(j, i)] *= f;
                    m[(i, j)] /= f;
                }
            }
        }
        if converged {
            break;
        }
    }
    (m, d)
}

/// `e^A` for a square finite matrix (see the module documentation for the algorithm).
///
/// # Errors
/// Non-square or non-finite input; a singular Padé denominator (impossible in exact arithmetic
/// for the chosen degrees, reported rather than trusted).
pub fn expm(a: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    if !a.is_square() {
        return Err(ModelError::dim(
            "expm argument",
            "square",
            format!("{}x{}", a.nrows(), a.ncols()),
        ));
    }
    crate::ss::check_finite(a, "expm argument")?;
    let n = a.nrows();
    if n == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    let (bal, d) = balance_diag(a);
    let use_bal = norm1(&bal) * 8.0 < norm1(a);
    let e = if use_bal {
        expm_core(&bal)?
    } else {
        expm_core(a)?
    };
    if !use_bal {
        return Ok(e);
    }
    // e^A = D e^{D⁻¹AD} D⁻¹
    let mut out = e;
    for i in 0..n {
        for j in 0..n {
            out[(i, j)] *= d[i] / d[j];
        }
    }
    Ok(out)
}

fn expm_core(a: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let n = a.nrows();
    let ident = DMatrix::<f64>::identity(n, n);
    let a2 = a * a;
    let a4 = &a2 * &a2;
    let a6 = &a4 * &a2;
    let d4 = norm1(&a4).powf(0.25);
    let d6 = norm1(&a6).powf(1.0 / 6.0);
    let eta1 = d4.max(d6);
    if eta1 <= THETA[0].1 && ell(a, 3) == 0 {
        return pade_solve(a, &a2, &a4, &a6, 3, &ident);
    }
    if eta1 <= THETA[1].1 && ell(a, 5) == 0 {
        return pade_solve(a, &a2, &a4, &a6, 5, &ident);
    }
    let a8 = &a4 * &a4;
    let d8 = norm1(&a8).powf(0.125);
    let eta3 = d6.max(d8);
    if eta3 <= THETA[2].1 && ell(a, 7) == 0 {
        return pade_solve(a, &a2, &a4, &a6, 7, &ident);
    }
    if eta3 <= THETA[3].1 && ell(a, 9) == 0 {
        return pade_solve(a, &a2, &a4, &a6, 9, &ident);
    }
    let a10 = &a4 * &a6;
    let d10 = norm1(&a10).powf(0.1);
    let eta4 = d8.max(d10);
    let eta5 = eta3.min(eta4);
    let mut s = if eta5 > 0.0 {
        (eta5 / THETA[4].1).log2().ceil().max(0.0) as i32
    } else {
        0
    };
    let scale = |k: i32| 2f64.powi(-k);
    s += ell(&(a * scale(s)), 13);
    let sc = scale(s);
    let (as1, as2, as4, as6) = (a * sc, &a2 * sc.powi(2), &a4 * sc.powi(4), &a6 * sc.powi(6));
    let mut r = pade_solve(&as1, &as2, &as4, &as6, 13, &ident)?;
    for _ in 0..s {
        r = &r * &r;
    }
    Ok(r)
}

fn pade_solve(
    a: &DMatrix<f64>,
    a2: &DMatrix<f64>,
    a4: &DMatrix<f64>,
    a6: &DMatrix<f64>,
    m: usize,
    ident: &DMatrix<f64>,
) -> Result<DMatrix<f64>> {
    let b = pade_coeffs(m);
    let (u, v) = if m == 13 {
        let u_in = a6 * (a6 * b[13] + a4 * b[11] + a2 * b[9])
            + a6 * b[7]
            + a4 * b[5]
            + a2 * b[3]
            + ident * b[1];
        let u = a * u_in;
        let v = a6 * (a6 * b[12] + a4 * b[10] + a2 * b[8])
            + a6 * b[6]
            + a4 * b[4]
            + a2 * b[2]
            + ident * b[0];
        (u, v)
    } else {
        let pows = [ident, a2, a4, a6];
        let mut u_in = DMatrix::zeros(a.nrows(), a.ncols());
        let mut v = DMatrix::zeros(a.nrows(), a.ncols());
        let mut a8 = None;
        for k in 0..=(m / 2) {
            let p: &DMatrix<f64> = if k < 4 {
                pows[k]
            } else {
                a8.get_or_insert_with(|| a4 * a4)
            };
            u_in += p * b[2 * k + 1];
            v += p * b[2 * k];
        }
        (a * u_in, v)
    };
    let lu = (&v - &u).lu();
    lu.solve(&(&v + &u)).ok_or_else(|| ModelError::Singular {
        what: "the Padé denominator in expm (input too large or badly scaled)".into(),
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn scalar_and_rotation() {
        let a = DMatrix::from_row_slice(1, 1, &[1.0]);
        assert!((expm(&a).unwrap()[(0, 0)] - 1f64.exp()).abs() < 4e-16 * 1f64.exp());
        let w = 3.0;
        let r = expm(&DMatrix::from_row_slice(2, 2, &[0.0, w, -w, 0.0])).unwrap();
        assert!((r[(0, 0)] - w.cos()).abs() < 1e-15);
        assert!((r[(0, 1)] - w.sin()).abs() < 1e-15);
    }

    #[test]
    fn nilpotent_is_exact() {
        let a = DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
        let e = expm(&(a * 2.0)).unwrap();
        let want = DMatrix::from_row_slice(3, 3, &[1.0, 2.0, 2.0, 0.0, 1.0, 2.0, 0.0, 0.0, 1.0]);
        assert!((e - want).abs().max() < 1e-15);
    }
}
