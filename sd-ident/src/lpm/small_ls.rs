//! The LPM's local least-squares problem: a small complex `w × q` system (`w ≈ 9`, `q ≈ 6`),
//! solved tens of thousands of times per record.
//!
//! # Math
//!
//! Householder QR (Golub & Van Loan, *Matrix Computations*, 4th ed., §5.1.13 for the complex
//! reflector): for the column `x` below the diagonal, `u = x + e^{iθ}‖x‖e₁` with
//! `θ = arg x₁` and `H = I − 2uuᴴ/(uᴴu)` (unitary, Hermitian) give `Hx = −e^{iθ}‖x‖e₁`. After
//! `q` reflections `QᴴK = [R; 0]` and `QᴴZ = [C₁; C₂]`, so
//!
//! ```text
//! Θ = R⁻¹ C₁,     EᴴE = C₂ᴴ C₂  (E = Z − KΘ),     (KᴴK)⁻¹ = R⁻¹ R⁻ᴴ.
//! ```
//!
//! The problem counts as singular when `κ_F(R) = ‖R‖_F ‖R⁻¹‖_F` exceeds [`MAX_CONDITION`]
//! (`κ₂ ≤ κ_F ≤ q κ₂`) or `R⁻¹` is not finite.
//!
//! # Accuracy
//!
//! Householder QR is backward stable (ibid., §5.3.3): `Θ` has relative error `O(ε κ(K))` for a
//! small residual, as the SVD route gives; the columns arrive scaled to unit norm, so `κ(K)` is
//! the conditioning of the regressors, not of their units. Tested against nalgebra's SVD.
//!
//! # Cost
//!
//! `O(w q (q + nz))` flops; no iteration, where the SVD it replaces (both singular-vector
//! sets) iterates to convergence.

use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// Above this Frobenius condition number of `R` the local problem is singular.
pub(super) const MAX_CONDITION: f64 = 1e12;

/// A solved local problem.
pub(super) struct SmallLs {
    /// The solution `Θ` (`q × nz`).
    pub(super) theta: DMatrix<C>,
    /// `EᴴE` of the residual (`nz × nz`).
    pub(super) residual_gram: DMatrix<C>,
    /// `R⁻¹` (`q × q`, upper triangular): `(KᴴK)⁻¹ = R⁻¹R⁻ᴴ`.
    pub(super) r_inv: DMatrix<C>,
}

impl SmallLs {
    /// `[(KᴴK)⁻¹]_{j, jj} = Σ_l R⁻¹_{j l} conj(R⁻¹_{jj l})`.
    pub(super) fn gram_inverse(&self, j: usize, jj: usize) -> C {
        let q = self.r_inv.ncols();
        (0..q)
            .map(|l| self.r_inv[(j, l)] * self.r_inv[(jj, l)].conj())
            .sum()
    }
}

/// Reflects every column `c` of `cols` with the reflector `u` acting on rows `j..`:
/// `c ← c − 2u(uᴴc)/(uᴴu)`.
fn reflect(u: &[C], unorm2: f64, j: usize, cols: &mut [Vec<C>]) {
    for c in cols.iter_mut() {
        let s: C = u.iter().zip(&c[j..]).map(|(ui, ci)| ui.conj() * ci).sum();
        let f = s * (2.0 / unorm2);
        for (ci, ui) in c[j..].iter_mut().zip(u) {
            *ci -= f * ui;
        }
    }
}

/// `min ‖KΘ − Z‖_F` for `k` (`w × q`, `w > q`) and `z` (`w × nz`) by Householder QR; `None`
/// when the problem is singular (module docs).
pub(super) fn solve(k: &DMatrix<C>, z: &DMatrix<C>) -> Option<SmallLs> {
    let (w, q, nz) = (k.nrows(), k.ncols(), z.ncols());
    if w <= q || z.nrows() != w {
        return None;
    }
    // columns as contiguous vectors: the K columns, then the Z columns
    let mut cols: Vec<Vec<C>> = (0..q)
        .map(|c| k.column(c).iter().copied().collect())
        .chain((0..nz).map(|c| z.column(c).iter().copied().collect()))
        .collect();
    let mut u = vec![C::new(0.0, 0.0); w];
    for j in 0..q {
        let x = &cols[j][j..];
        let xnorm = x.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
        // a zero column below the diagonal: R's diagonal entry would be zero (and the
        // reflector undefined)
        if xnorm == 0.0 {
            return None;
        }
        let phase = if x[0].norm() > 0.0 {
            x[0] / x[0].norm()
        } else {
            C::new(1.0, 0.0)
        };
        let uj = &mut u[..w - j];
        uj.copy_from_slice(x);
        uj[0] += phase * xnorm;
        let unorm2: f64 = uj.iter().map(|v| v.norm_sqr()).sum();
        let (done, rest) = cols.split_at_mut(j + 1);
        done[j][j] = -phase * xnorm;
        for v in done[j][j + 1..].iter_mut() {
            *v = C::new(0.0, 0.0);
        }
        reflect(uj, unorm2, j, rest);
    }
    let r = DMatrix::<C>::from_fn(
        q,
        q,
        |i, c| if i <= c { cols[c][i] } else { C::new(0.0, 0.0) },
    );
    let r_inv = upper_inverse(&r);
    let fro = |m: &DMatrix<C>| m.iter().map(|v| v.norm_sqr()).sum::<f64>().sqrt();
    let cond = fro(&r) * fro(&r_inv);
    if !(cond.is_finite() && cond <= MAX_CONDITION) {
        return None;
    }
    let c1 = DMatrix::<C>::from_fn(q, nz, |i, c| cols[q + c][i]);
    let theta = &r_inv * c1;
    let residual_gram = DMatrix::<C>::from_fn(nz, nz, |a, b| {
        (q..w).map(|i| cols[q + a][i].conj() * cols[q + b][i]).sum()
    });
    Some(SmallLs {
        theta,
        residual_gram,
        r_inv,
    })
}

/// The inverse of an upper-triangular `r` by back substitution. Its diagonal is nonzero
/// ([`solve`]'s reflections give `−e^{iθ}‖x‖` with `‖x‖ > 0`); an entry that overflows
/// makes `R⁻¹` non-finite, which [`solve`] refuses.
fn upper_inverse(r: &DMatrix<C>) -> DMatrix<C> {
    let q = r.nrows();
    let mut inv = DMatrix::<C>::zeros(q, q);
    for c in 0..q {
        inv[(c, c)] = C::new(1.0, 0.0) / r[(c, c)];
        for i in (0..c).rev() {
            let s: C = (i + 1..=c).map(|l| r[(i, l)] * inv[(l, c)]).sum();
            inv[(i, c)] = -s / r[(i, i)];
        }
    }
    inv
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn problem(w: usize, q: usize, nz: usize, seed: u64) -> (DMatrix<C>, DMatrix<C>) {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let k = DMatrix::<C>::from_fn(w, q, |_, _| C::new(next(), next()));
        let z = DMatrix::<C>::from_fn(w, nz, |_, _| C::new(next(), next()));
        (k, z)
    }

    /// Solution, residual Gram matrix and `(KᴴK)⁻¹` against nalgebra's SVD, to `w·q·ε·κ`.
    #[test]
    fn matches_the_svd_solution() {
        for seed in 0..20 {
            let (w, q, nz) = (9 + seed as usize % 4, 6, 1 + seed as usize % 2);
            let (k, z) = problem(w, q, nz, seed);
            let ls = solve(&k, &z).unwrap();
            let svd = nalgebra::linalg::SVD::new(k.clone(), true, true);
            let theta = svd.solve(&z, 0.0).unwrap();
            let smax = svd.singular_values.max();
            let smin = svd.singular_values.min();
            let tol = 10.0 * (w * q) as f64 * f64::EPSILON * smax / smin;
            let scale = theta.iter().map(|v| v.norm()).fold(0.0, f64::max);
            assert!(
                (&ls.theta - &theta).iter().all(|d| d.norm() <= tol * scale),
                "seed {seed}"
            );
            let e = &z - &k * &theta;
            let gram = e.adjoint() * &e;
            let gs = gram.iter().map(|v| v.norm()).fold(0.0, f64::max);
            assert!((&ls.residual_gram - &gram)
                .iter()
                .all(|d| d.norm() <= tol * gs));
            let inv = (k.adjoint() * &k).try_inverse().unwrap();
            let is = inv.iter().map(|v| v.norm()).fold(0.0, f64::max);
            for j in 0..q {
                for jj in 0..q {
                    let d = (ls.gram_inverse(j, jj) - inv[(j, jj)]).norm();
                    assert!(d <= tol * is, "seed {seed} ({j},{jj}): {d:e}");
                }
            }
        }
    }

    /// Two equal columns, a zero column, too few rows: no solution.
    #[test]
    fn singular_problems_are_refused() {
        let (mut k, z) = problem(9, 6, 1, 7);
        let c0 = k.column(0).clone_owned();
        k.set_column(3, &c0);
        assert!(solve(&k, &z).is_none());
        let (mut k, z) = problem(9, 6, 1, 8);
        k.column_mut(2).fill(C::new(0.0, 0.0));
        assert!(solve(&k, &z).is_none());
        let (k, z) = problem(6, 6, 1, 9);
        assert!(solve(&k, &z).is_none());
    }
}
