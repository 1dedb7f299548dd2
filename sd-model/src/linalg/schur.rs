//! Complex Schur form, reordering, and block diagonalisation by Sylvester decoupling.
//!
//! `A = Q T Qᴴ` with `T` upper triangular (complex Schur form, nalgebra's QR iteration).
//! Adjacent diagonal entries are swapped with one unitary plane rotation (the method of LAPACK
//! ZTREXC: the new leading basis vector is the eigenvector `[t₁₂, t₂₂ − t₁₁]` of the 2×2 block).
//!
//! **Block diagonalisation** (Bavely & Stewart, "An algorithm for computing reducing subspaces by
//! block diagonalization", SIAM J. Numer. Anal. 16(2), 1979): split the leading cluster `T₁₁`
//! from the rest by `S = [[I, X], [0, I]]`, where `T₁₁ X − X T₂₂ = −T₁₂` (a triangular Sylvester
//! equation solved column by column), accepting the split only when `‖X‖_max ≤ bound`; otherwise
//! the eigenvalue of `T₂₂` nearest to the cluster is moved next to it and the cluster grows. Close
//! or defective eigenvalues (the rigid-body Jordan block at z = 1) therefore stay together in one
//! triangular block, while the transformation stays well conditioned (its condition is bounded
//! by the product of `(1 + ‖X‖)` over the splits).

use crate::error::{ModelError, Result};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// Complex Schur form `A = Q T Qᴴ` of a real or complex square matrix.
pub fn complex_schur(a: &DMatrix<C>) -> Result<(DMatrix<C>, DMatrix<C>)> {
    let n = a.nrows();
    if n == 0 {
        return Ok((DMatrix::zeros(0, 0), DMatrix::zeros(0, 0)));
    }
    // nalgebra's deflation test `|t_{k+1,k}| ≤ tol·(|t_kk| + |t_{k+1,k+1}|)` with tol = ε can
    // stall on a matrix whose eigenvalues cluster at z = 1 (a rigid body); a looser test is
    // tried before giving up (the triangularity check below still bounds what is accepted).
    let (q, mut t) = match [f64::EPSILON, 16.0 * f64::EPSILON, 256.0 * f64::EPSILON]
        .iter()
        .find_map(|&tol| nalgebra::Schur::try_new(a.clone(), tol, 200 * n.max(10)))
    {
        Some(schur) => schur.unpack(),
        None => shifted_schur(a)?,
    };
    // nalgebra returns an upper-triangular T for complex input; clear rounding below the diagonal
    // and refuse anything that is not triangular.
    let scale = t
        .iter()
        .map(|v| v.norm())
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    for j in 0..n {
        for i in (j + 1)..n {
            if t[(i, j)].norm() > 1e-10 * scale {
                return Err(ModelError::NotConverged {
                    what: "the complex Schur form (subdiagonal not zero)".into(),
                });
            }
            t[(i, j)] = C::new(0.0, 0.0);
        }
    }
    Ok((q, t))
}

/// The Schur form through `A + σI` (same Schur vectors, `T = T_σ − σI`) with `|σ| = ‖A‖_F`
/// off the real axis: nalgebra's deflation test is relative to the diagonal entries, so on a
/// nilpotent block (a shift register of input delays: all eigenvalues 0) it never deflates,
/// and the zero Wilkinson shift only permutes the block. With the shift the test becomes
/// relative to `‖A‖`, LAPACK's own backward-stable scale.
fn shifted_schur(a: &DMatrix<C>) -> Result<(DMatrix<C>, DMatrix<C>)> {
    let n = a.nrows();
    let norm = a
        .iter()
        .map(|v| v.norm_sqr())
        .sum::<f64>()
        .sqrt()
        .max(f64::MIN_POSITIVE);
    let sigma = C::new(0.6, 0.8) * norm;
    let shifted = a + DMatrix::<C>::identity(n, n) * sigma;
    let schur =
        nalgebra::Schur::try_new(shifted, f64::EPSILON, 200 * n.max(10)).ok_or_else(|| {
            ModelError::NotConverged {
                what: "the QR iteration of the Schur decomposition".into(),
            }
        })?;
    let (q, t) = schur.unpack();
    Ok((q, t - DMatrix::<C>::identity(n, n) * sigma))
}

/// Real matrix to complex.
pub fn to_complex(a: &DMatrix<f64>) -> DMatrix<C> {
    a.map(|v| C::new(v, 0.0))
}

/// Swaps the diagonal entries k and k+1 of the upper-triangular `t`, updating `q` (A = Q T Qᴴ
/// stays true) and any extra row-basis `rows` (transformed like Qᴴ·M) and column-basis `cols`
/// (transformed like M·Q).
pub fn swap_adjacent(
    t: &mut DMatrix<C>,
    k: usize,
    rows: &mut [&mut DMatrix<C>],
    cols: &mut [&mut DMatrix<C>],
) {
    let t11 = t[(k, k)];
    let t22 = t[(k + 1, k + 1)];
    let v0 = t[(k, k + 1)];
    let v1 = t22 - t11;
    let nv = (v0.norm_sqr() + v1.norm_sqr()).sqrt();
    if nv == 0.0 {
        return;
    }
    let (z0, z1) = (v0 / nv, v1 / nv);
    // Z = [[z0, -conj(z1)], [z1, conj(z0)]], unitary; first column is the eigenvector for t22.
    let z = [[z0, -z1.conj()], [z1, z0.conj()]];
    let n = t.nrows();
    // T <- T Z on columns k, k+1
    for i in 0..n {
        let (a, b) = (t[(i, k)], t[(i, k + 1)]);
        t[(i, k)] = a * z[0][0] + b * z[1][0];
        t[(i, k + 1)] = a * z[0][1] + b * z[1][1];
    }
    // T <- Zᴴ T on rows k, k+1
    for j in 0..n {
        let (a, b) = (t[(k, j)], t[(k + 1, j)]);
        t[(k, j)] = z[0][0].conj() * a + z[1][0].conj() * b;
        t[(k + 1, j)] = z[0][1].conj() * a + z[1][1].conj() * b;
    }
    t[(k + 1, k)] = C::new(0.0, 0.0);
    t[(k, k)] = t22;
    t[(k + 1, k + 1)] = t11;
    for m in rows.iter_mut() {
        for j in 0..m.ncols() {
            let (a, b) = (m[(k, j)], m[(k + 1, j)]);
            m[(k, j)] = z[0][0].conj() * a + z[1][0].conj() * b;
            m[(k + 1, j)] = z[0][1].conj() * a + z[1][1].conj() * b;
        }
    }
    for m in cols.iter_mut() {
        for i in 0..m.nrows() {
            let (a, b) = (m[(i, k)], m[(i, k + 1)]);
            m[(i, k)] = a * z[0][0] + b * z[1][0];
            m[(i, k + 1)] = a * z[0][1] + b * z[1][1];
        }
    }
}

/// Solves `T₁₁ X − X T₂₂ = R` for upper-triangular `T₁₁` (m×m) and `T₂₂` (k×k), R m×k, column by
/// column: `(T₁₁ − t₂₂[j,j] I) x_j = r_j + Σ_{l<j} x_l t₂₂[l,j]`.
/// Returns `None` when a diagonal of the shifted triangular system is exactly zero (common
/// eigenvalue).
pub fn triangular_sylvester(
    t11: &DMatrix<C>,
    t22: &DMatrix<C>,
    r: &DMatrix<C>,
) -> Option<DMatrix<C>> {
    let m = t11.nrows();
    let k = t22.nrows();
    let mut x = DMatrix::<C>::zeros(m, k);
    let mut rhs = vec![C::new(0.0, 0.0); m];
    for j in 0..k {
        for i in 0..m {
            let mut s = r[(i, j)];
            for l in 0..j {
                s += x[(i, l)] * t22[(l, j)];
            }
            rhs[i] = s;
        }
        let shift = t22[(j, j)];
        for i in (0..m).rev() {
            let mut s = rhs[i];
            for l in (i + 1)..m {
                s -= t11[(i, l)] * x[(l, j)];
            }
            let dgn = t11[(i, i)] - shift;
            if dgn == C::new(0.0, 0.0) {
                return None;
            }
            x[(i, j)] = s / dgn;
        }
    }
    Some(x)
}

/// A block-diagonal (modal) form `T = V⁻¹ A V` with upper-triangular diagonal blocks, applied to
/// a model: `bt = V⁻¹ B`, `ct = C V`.
#[derive(Debug, Clone)]
pub struct BlockDiagonal {
    /// Block-diagonal T (each block upper triangular).
    pub t: DMatrix<C>,
    /// `(start, size)` of each block.
    pub blocks: Vec<(usize, usize)>,
    /// V⁻¹ B.
    pub bt: DMatrix<C>,
    /// C V.
    pub ct: DMatrix<C>,
}

/// Eigenvalues within this relative distance stay in one block (a defective eigenvalue of
/// multiplicity k is split by rounding into a cluster of radius ~ε^{1/k}: 6e-6 for k = 3,
/// 1e-4 for k = 4).
pub const CLOSE: f64 = 1e-3;

/// Bound on `‖X‖_max` of an accepted split (see the module documentation).
pub const SPLIT_BOUND: f64 = 1.0e4;

/// Block diagonalisation of a complex matrix with the input and output maps carried along.
pub fn block_diagonalize(
    a: &DMatrix<C>,
    b: &DMatrix<C>,
    c: &DMatrix<C>,
    bound: f64,
) -> Result<BlockDiagonal> {
    let n = a.nrows();
    let (q, mut t) = complex_schur(a)?;
    let mut bt = q.adjoint() * b;
    let mut ct = c * &q;
    let mut blocks = Vec::new();
    let mut start = 0;
    while start < n {
        let mut size = 1;
        loop {
            let end = start + size;
            if end == n {
                blocks.push((start, size));
                break;
            }
            let t11 = t.view((start, start), (size, size)).into_owned();
            let t22 = t.view((end, end), (n - end, n - end)).into_owned();
            let r = -t.view((start, end), (size, n - end)).into_owned();
            // eigenvalues closer than CLOSE (relative) are a perturbed multiple eigenvalue
            // (a Jordan block splits by ε^{1/k}): never separate them, whatever X says
            let close = (start..end).any(|i| {
                (end..n).any(|j| {
                    let (a, b) = (t[(i, i)], t[(j, j)]);
                    (a - b).norm() <= CLOSE * a.norm().max(b.norm()).max(1.0)
                })
            });
            let x = if close {
                None
            } else {
                triangular_sylvester(&t11, &t22, &r)
            };
            let ok = x
                .as_ref()
                .map(|x| x.iter().all(|v| v.norm() <= bound))
                .unwrap_or(false);
            if let (true, Some(x)) = (ok, x) {
                // B̃[block] -= X B̃[rest];  C̃[:, rest] += C̃[:, block] X;  T12 = 0
                let brest = bt.rows(end, n - end).into_owned();
                let upd = &x * brest;
                let mut bb = bt.rows_mut(start, size);
                bb -= upd;
                let cblk = ct.columns(start, size).into_owned();
                let upd = cblk * &x;
                let mut cr = ct.columns_mut(end, n - end);
                cr += upd;
                t.view_mut((start, end), (size, n - end))
                    .fill(C::new(0.0, 0.0));
                blocks.push((start, size));
                break;
            }
            // Grow the cluster: bring the nearest remaining eigenvalue to position `end`.
            let mut best = end;
            let mut best_d = f64::INFINITY;
            for j in end..n {
                let d = (start..end)
                    .map(|i| (t[(j, j)] - t[(i, i)]).norm())
                    .fold(f64::INFINITY, f64::min);
                if d < best_d {
                    best_d = d;
                    best = j;
                }
            }
            for k in (end..best).rev() {
                swap_adjacent(&mut t, k, &mut [&mut bt], &mut [&mut ct]);
            }
            size += 1;
        }
        start += blocks.last().map(|b| b.1).unwrap_or(1);
    }
    Ok(BlockDiagonal { t, blocks, bt, ct })
}

/// Solves `(s I − T) X = R` for upper-triangular T (in place on a copy of R).
pub fn shifted_triangular_solve(t: &DMatrix<C>, s: C, r: &DMatrix<C>) -> DMatrix<C> {
    let m = t.nrows();
    let mut x = r.clone();
    for j in 0..x.ncols() {
        for i in (0..m).rev() {
            let mut acc = x[(i, j)];
            for l in (i + 1)..m {
                acc += t[(i, l)] * x[(l, j)];
            }
            x[(i, j)] = acc / (s - t[(i, i)]);
        }
    }
    x
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
pub(crate) mod tests {
    use super::*;

    /// A model with three samples of input delay: a nilpotent 3×3 shift register beside a pole
    /// at 0.5 (nalgebra's QR never deflates the register); the shifted route decomposes it:
    /// `A = Q T Qᴴ` to `n·ε·‖A‖` (times 100), `T` triangular with the eigenvalues 0.5, 0, 0, 0
    /// (a triple defective eigenvalue is only determined to `ε^{1/3}`).
    #[test]
    fn nilpotent_shift_register_is_decomposed() {
        let mut a = DMatrix::<f64>::zeros(4, 4);
        a[(0, 0)] = 0.5;
        a[(0, 3)] = 1.0;
        a[(2, 1)] = 1.0;
        a[(3, 2)] = 1.0;
        let ac = to_complex(&a);
        let (q, t) = complex_schur(&ac).unwrap();
        let back = &q * &t * q.adjoint();
        let err = (back - &ac).iter().map(|v| v.norm()).fold(0.0, f64::max);
        assert!(err <= 100.0 * 4.0 * f64::EPSILON * a.norm(), "{err}");
        let mut ev: Vec<f64> = (0..4).map(|i| t[(i, i)].norm()).collect();
        ev.sort_by(f64::total_cmp);
        assert!((ev[3] - 0.5).abs() < 1e-12, "{ev:?}");
        assert!(ev[..3].iter().all(|&x| x < 1e-4), "{ev:?}");
    }

    /// A matrix on which the QR iteration with deflation tolerance ε stalls (test_data/README.md)
    /// is decomposed with the looser tolerance: `Q` unitary and `A = Q T Qᴴ` to `n·ε·‖A‖`
    /// (times a safety factor of 100).
    #[test]
    fn stalling_matrix_is_decomposed() {
        let v: serde_json::Value =
            serde_json::from_str(include_str!("../../../test_data/schur_stall_20.json")).unwrap();
        let rows = v["bits"].as_array().unwrap();
        let n = rows.len();
        let a = DMatrix::from_fn(n, n, |i, j| {
            let hex = rows[i][j].as_str().unwrap();
            C::new(f64::from_bits(u64::from_str_radix(hex, 16).unwrap()), 0.0)
        });
        assert!(nalgebra::Schur::try_new(a.clone(), f64::EPSILON, 200 * n).is_none());
        let (q, t) = complex_schur(&a).unwrap();
        let norm = a.iter().map(|v| v.norm()).fold(0.0, f64::max) * n as f64;
        let back = &q * &t * q.adjoint() - &a;
        let err = back.iter().map(|v| v.norm()).fold(0.0, f64::max);
        assert!(err < 100.0 * n as f64 * f64::EPSILON * norm, "{err:e}");
        let qq = q.adjoint() * &q - DMatrix::<C>::identity(n, n);
        assert!(qq.iter().map(|v| v.norm()).fold(0.0, f64::max) < 1e-13);
    }

    /// A seeded n×n matrix with entries uniform in [−½, ½) (also used by the other linalg
    /// modules' tests).
    pub(crate) fn rand_mat(n: usize, seed: u64) -> DMatrix<f64> {
        let mut s = seed;
        DMatrix::from_fn(n, n, |_, _| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        })
    }

    #[test]
    fn swap_keeps_similarity() {
        let a = to_complex(&rand_mat(6, 3));
        let (mut q, mut t) = complex_schur(&a).unwrap();
        let d0 = t[(2, 2)];
        let d1 = t[(3, 3)];
        let mut qh = q.adjoint();
        swap_adjacent(&mut t, 2, &mut [&mut qh], &mut []);
        q = qh.adjoint();
        assert!((t[(2, 2)] - d1).norm() < 1e-14 && (t[(3, 3)] - d0).norm() < 1e-14);
        let back = &q * &t * q.adjoint();
        assert!((back - a).iter().map(|v| v.norm()).fold(0.0, f64::max) < 1e-13);
    }

    #[test]
    fn block_diag_reproduces_resolvent_with_jordan_block() {
        // A Jordan block at 1 plus distinct eigenvalues.
        let mut a = rand_mat(5, 9) * 0.3;
        a[(0, 0)] = 1.0;
        a[(1, 1)] = 1.0;
        a[(0, 1)] = 1.0;
        a[(1, 0)] = 0.0;
        for j in 0..2 {
            for i in 2..5 {
                a[(i, j)] = 0.0;
            }
        }
        let b = rand_mat(5, 1).columns(0, 2).into_owned();
        let c = rand_mat(5, 2).rows(0, 2).into_owned();
        let bd = block_diagonalize(
            &to_complex(&a),
            &to_complex(&b),
            &to_complex(&c),
            SPLIT_BOUND,
        )
        .unwrap();
        let s = C::new(0.3, 0.7);
        let mut g = DMatrix::<C>::zeros(2, 2);
        for &(st, sz) in &bd.blocks {
            let tb = bd.t.view((st, st), (sz, sz)).into_owned();
            let x = shifted_triangular_solve(&tb, s, &bd.bt.rows(st, sz).into_owned());
            g += bd.ct.columns(st, sz) * x;
        }
        let m = DMatrix::<C>::identity(5, 5) * s - to_complex(&a);
        let direct = to_complex(&c) * m.lu().solve(&to_complex(&b)).unwrap();
        let err = (g - &direct).iter().map(|v| v.norm()).fold(0.0, f64::max);
        assert!(
            err < 1e-12 * direct.iter().map(|v| v.norm()).fold(0.0, f64::max),
            "err {err}"
        );
    }
}
