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
//! **The squaring phase in double-double where it loses digits.** Squaring is not backward
//! stable for non-normal matrices: `fl(X²) = X² + E` with `‖E‖ ≤ γₙ‖X‖²`, so each squaring's
//! relative rounding is amplified by `‖X_k‖²/‖X_k²‖`, and the product of those ratios over the
//! `s` squarings measures the loss (Higham 2005, §3; Al-Mohy & Higham 2009, §2). When
//! `n·ε·∏ₖ ‖X_k‖₁²/‖X_k²‖₁ > 10⁻⁹` the squarings are redone from the Padé result in
//! double-double arithmetic (each product's `H·H` part accumulated exactly by Dekker's
//! product and Knuth's TwoSum, the cross terms `H·L + L·H` in double; Ogita, Rump & Oishi,
//! "Accurate sum and dot product", SIAM J. Sci. Comput. 26(6), 2005). On lightly damped and
//! stiff systems in non-modal coordinates (the exponential's condition 4e7–5e7) this takes the
//! error against a 60-digit reference from 6.4e-6 to 2.8e-9 and from 2.2e-6 to 3.7e-10, where
//! scipy's `expm` (the same algorithm in double) is at 5.8e-6 and 1.8e-6
//! (`tests/tests/zoh_reference.rs`); on normal or modal inputs the product stays below 10⁴
//! and nothing changes.
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

/// The squaring phase is redone in double-double when `n·ε·∏ₖ ‖X_k‖₁²/‖X_k²‖₁` exceeds this
/// (module documentation).
const DD_GROWTH_BOUND: f64 = 1e-9;

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
    let r0 = pade_solve(&as1, &as2, &as4, &as6, 13, &ident)?;
    // the squarings in double, with the growth ∏ ‖X_k‖₁²/‖X_k²‖₁ that bounds how much their
    // rounding is amplified; beyond DD_GROWTH_BOUND again in double-double
    let mut r = r0.clone();
    let mut growth = 1.0f64;
    for _ in 0..s {
        let next = &r * &r;
        growth *= norm1(&r).powi(2) / norm1(&next).max(f64::MIN_POSITIVE);
        r = next;
    }
    if (n as f64) * f64::EPSILON * growth > DD_GROWTH_BOUND {
        return Ok(square_dd(r0, s));
    }
    Ok(r)
}

/// `a·b` exactly as `(hi, lo)` (Dekker's product with Veltkamp's split; no FMA needed).
fn two_prod(a: f64, b: f64) -> (f64, f64) {
    const SPLIT: f64 = 134_217_729.0; // 2^27 + 1
    let p = a * b;
    let split = |x: f64| {
        let c = SPLIT * x;
        let hi = c - (c - x);
        (hi, x - hi)
    };
    let ((ah, al), (bh, bl)) = (split(a), split(b));
    let e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
    (p, e)
}

/// `a + b` exactly as `(sum, error)` (Knuth's TwoSum).
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `X^(2^s)` with `X` squared `s` times in double-double arithmetic (`X = H + L`, every
/// product `H·H` accumulated exactly by compensated dot products, `H·L + L·H` in double).
fn square_dd(x: DMatrix<f64>, s: i32) -> DMatrix<f64> {
    let n = x.nrows();
    let mut h = x;
    let mut l = DMatrix::<f64>::zeros(n, n);
    for _ in 0..s {
        let cross = &h * &l + &l * &h;
        let mut nh = DMatrix::<f64>::zeros(n, n);
        let mut nl = DMatrix::<f64>::zeros(n, n);
        for j in 0..n {
            for i in 0..n {
                let (mut p, mut e) = (0.0f64, 0.0f64);
                for k in 0..n {
                    let (q, r) = two_prod(h[(i, k)], h[(k, j)]);
                    let (t, u) = two_sum(p, q);
                    p = t;
                    e += u + r;
                }
                e += cross[(i, j)];
                let (hi, lo) = two_sum(p, e);
                nh[(i, j)] = hi;
                nl[(i, j)] = lo;
            }
        }
        h = nh;
        l = nl;
    }
    h + l
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

    /// A non-normal triangular matrix (the growth `∏‖X_k‖²/‖X_k²‖` is 1e18–1e79, so the
    /// squarings run in double-double; the ill-conditioned cases where that matters are
    /// `tests/tests/zoh_reference.rs`'s, against a 60-digit reference): against the closed form
    /// `e^[[a, b], [0, d]] = [[eᵃ, b(eᵃ − eᵈ)/(a − d)], [0, eᵈ]]`.
    #[test]
    fn non_normal_triangular_against_its_closed_form() {
        for (t, c) in [(30.0f64, 1e6f64), (200.0, 1e8), (60.0, 1e3)] {
            let (a, d, b) = (-t, -1.5 * t, c * t);
            let m = DMatrix::from_row_slice(2, 2, &[a, b, 0.0, d]);
            let e = expm(&m).unwrap();
            // b(eᵃ − eᵈ)/(a − d) = b·eᵃ·(1 − e^{d−a})/(a − d), without cancellation
            let off = b * a.exp() * -(d - a).exp_m1() / (a - d);
            let exact = DMatrix::from_row_slice(2, 2, &[a.exp(), off, 0.0, d.exp()]);
            let err = (&e - &exact).norm() / exact.norm();
            assert!(err < 1e-13, "t = {t}, c = {c}: relative error {err:e}");
        }
    }
}
