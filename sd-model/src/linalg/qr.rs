//! The R factor of a Householder QR, computed where faer's kernel runs at full speed.
//!
//! # Math
//!
//! For `A` m×n, `A = Q R` with `Q` orthogonal and `R` upper triangular (`min(m, n) × n`). Scaling
//! the columns, `A D = Q (R D)` for a diagonal `D`, leaves `Q` unchanged and scales `R`'s columns
//! the same way, so `R = R_D D⁻¹` where `R_D` is the factor of `A D`. With `D`'s entries powers of
//! two both scalings are exact in binary floating point (no rounding, barring overflow or
//! underflow, which the choice below rules out for every entry within `2⁶⁰⁰` of its column's
//! largest).
//!
//! # Why the scaling
//!
//! faer computes each Householder vector's norm overflow- and underflow-safely: besides `Σ x²`
//! it accumulates `Σ (x·2⁻⁵¹¹)²`, which is a subnormal number for every `|x| < 1`. On x86 an
//! operation that produces a subnormal takes a microcode assist, and the columns of a
//! least-squares basis scaled to unit norm have nearly all entries below 1, so the norms slow
//! the whole factorisation (`cargo test --release -p sd-model --lib scaled_qr_speed --
//! --ignored --nocapture` times the QR with and without the scaling on a 20 000 × 40 matrix).
//! Scaled so that each column's largest entry is near `2³⁰⁰`, every entry within 300 binades of it
//! stays at or above 1, the safe accumulator stays normal and the plain one far below overflow
//! (`m·2⁶⁰⁰ ≪ 2¹⁰²⁴`), and faer takes its plain branch. The factor is bit-for-bit the one of the
//! scaled problem, whose backward error is the usual `O(m n ε)‖A D‖` of Householder QR (Golub
//! & Van Loan, *Matrix Computations*, 4th ed., §5.2.2), i.e. column-wise relative, unchanged by
//! the exact unscaling.

use faer::Mat;

/// The binary exponent the largest entry of each column is brought to.
const TARGET_EXPONENT: i32 = 300;

/// The power-of-two factor that brings the column's largest magnitude to about `2³⁰⁰` (1 for a
/// zero column).
fn column_factor(col: &[f64]) -> f64 {
    let amax = col.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if amax == 0.0 || !amax.is_finite() {
        return 1.0;
    }
    // the exponent of amax (amax = f·2^e, 1 ≤ f < 2), read without the float's bits
    let e = amax.log2().floor() as i32;
    2f64.powi((TARGET_EXPONENT - e).clamp(-1000, 1000))
}

/// The upper-triangular factor `R` (`min(m, n) × n`) of the Householder QR of `a`, by faer's
/// blocked kernel on the column-scaled matrix (see the [module](self) docs; `a` is scaled in
/// place and consumed); `Q` is not formed. Entries must be finite (the callers check their
/// inputs).
pub fn qr_r(mut a: Mat<f64>) -> Mat<f64> {
    let n = a.ncols();
    let factors: Vec<f64> = (0..n)
        .map(|c| {
            let col = a.col_as_slice_mut(c);
            let f = column_factor(col);
            col.iter_mut().for_each(|v| *v *= f);
            f
        })
        .collect();
    let qr = a.qr();
    let rs = qr.thin_R();
    Mat::<f64>::from_fn(rs.nrows(), n, |r, c| rs[(r, c)] / factors[c])
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// `RᵀR = AᵀA` to `n·ε·‖A‖²` (R determines the Gram matrix, whatever its signs), on a tall
    /// matrix with columns ten decades apart and entries far below 1, and a zero column.
    #[test]
    fn r_reproduces_the_gram_matrix() {
        let (m, n) = (500, 6);
        let a = Mat::<f64>::from_fn(m, n, |r, c| {
            if c == 3 {
                return 0.0;
            }
            let t = r as f64 / m as f64;
            (1.0 + (c as f64 + 1.0) * 3.1 * t).cos() * 10f64.powi(2 * c as i32 - 12)
        });
        let r = qr_r(a.clone());
        assert_eq!((r.nrows(), r.ncols()), (n, n));
        for i in 0..n {
            for j in 0..n {
                let g: f64 = (0..m).map(|k| a[(k, i)] * a[(k, j)]).sum();
                let h: f64 = (0..n).map(|k| r[(k, i)] * r[(k, j)]).sum();
                let ni: f64 = (0..m).map(|k| a[(k, i)].powi(2)).sum::<f64>().sqrt();
                let nj: f64 = (0..m).map(|k| a[(k, j)].powi(2)).sum::<f64>().sqrt();
                let tol = 50.0 * (m * n) as f64 * f64::EPSILON * ni * nj;
                assert!((g - h).abs() <= tol, "({i},{j}): {g:e} vs {h:e}");
            }
            for k in i + 1..n {
                assert_eq!(r[(k, i)], 0.0, "below the diagonal");
            }
        }
    }

    /// The factor is the plain QR's up to the exact power-of-two scaling: against faer's
    /// unscaled R, entry by entry, to `m·ε·‖a_j‖`.
    #[test]
    fn matches_the_unscaled_factor() {
        let (m, n) = (200, 5);
        let a = Mat::<f64>::from_fn(m, n, |r, c| ((r * (c + 2)) as f64 * 0.37).sin() * 1e-3);
        let r = qr_r(a.clone());
        let plain = a.qr().thin_R().to_owned();
        for c in 0..n {
            let nc: f64 = (0..m).map(|k| a[(k, c)].powi(2)).sum::<f64>().sqrt();
            for i in 0..=c {
                let d = (r[(i, c)] - plain[(i, c)]).abs();
                assert!(d <= 10.0 * m as f64 * f64::EPSILON * nc, "({i},{c}): {d:e}");
            }
        }
    }

    /// The speed the scaling buys: faer's QR of a 20 000 × 40 matrix with unit-norm columns, as
    /// given and through [`qr_r`] (printed; asserts only that both factors agree).
    #[test]
    #[ignore]
    fn scaled_qr_speed() {
        let (m, n) = (20_000, 40);
        let a = Mat::<f64>::from_fn(m, n, |r, c| {
            ((r * (c + 1)) as f64 * 0.613).sin() / (m as f64 / 2.0).sqrt()
        });
        let reps = 10;
        let t = std::time::Instant::now();
        let mut plain = a.qr().thin_R().to_owned();
        for _ in 1..reps {
            plain = a.qr().thin_R().to_owned();
        }
        let tp = t.elapsed().as_secs_f64() / reps as f64;
        let t = std::time::Instant::now();
        let mut r = qr_r(a.clone());
        for _ in 1..reps {
            r = qr_r(a.clone());
        }
        let ts = t.elapsed().as_secs_f64() / reps as f64;
        println!(
            "{m} x {n}: faer's QR {:.1} ms, scaled {:.1} ms ({:.2}x)",
            tp * 1e3,
            ts * 1e3,
            tp / ts
        );
        let d = (0..n)
            .map(|c| (r[(c, c)].abs() - plain[(c, c)].abs()).abs())
            .fold(0.0, f64::max);
        assert!(d < 1e-10, "diagonals differ by {d:e}");
    }

    /// A wide matrix gives the `m × n` trapezoidal factor.
    #[test]
    fn wide_matrix_gives_a_trapezoid() {
        let a = Mat::<f64>::from_fn(2, 3, |r, c| (r + 2 * c) as f64 + 0.5);
        let r = qr_r(a.clone());
        assert_eq!((r.nrows(), r.ncols()), (2, 3));
        assert_eq!(r[(1, 0)], 0.0);
    }
}
