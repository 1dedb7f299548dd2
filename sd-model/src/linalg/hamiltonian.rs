//! Eigenvalues of a Hamiltonian matrix from its square, at half the order (Van Loan's
//! square-reduced method).
//!
//! For `H = [[F, G], [Q, −Fᵀ]]` (G, Q symmetric, each block n×n) the square
//! `W = H² = [[F² + GQ, FG − GFᵀ], [QF − FᵀQ, (F² + GQ)ᵀ]]` is skew-Hamiltonian: its off-diagonal
//! blocks are skew-symmetric. An orthogonal symplectic similarity `UᵀWU` (the PVL
//! decomposition: Paige & Van Loan 1981; Van Loan, *Linear Algebra Appl.* 61, 1984, §3;
//! Kressner, *Numerical Methods for General and Structured Eigenvalue Problems*, 2005, Alg. 8)
//! brings it to `[[Ã, G̃], [0, Ãᵀ]]` with `Ã` upper Hessenberg, column by column: a reflector
//! `diag(P, P)` clears the lower block's column below its first entry, a symplectic plane
//! rotation in the coordinates `(k, n + k)` clears that entry against `Ã`'s, and a second
//! reflector makes `Ã`'s column Hessenberg. The eigenvalues of `Ã` (order n, not 2n) are the
//! squares `μ = λ²` of H's eigenvalues, each pair `±λ` once: the QR iteration runs on a matrix
//! of half the order, about an eighth of the work.
//!
//! **Accuracy.** The reduction is backward stable for W, so μ carries an absolute error of
//! order `n·ε·‖H‖²` (the blocks of W are formed from products of H's), and `λ = √μ` one of order `n·ε·‖H‖²/|λ|`: worse than a direct
//! eigenvalue computation of H by `‖H‖/|λ|` (Van Loan's "square-root" loss for eigenvalues
//! small against ‖H‖). [`SquaredEigenvalues::mu_error`] states the scale so that a caller can
//! tell when a decision taken on λ could flip within it (the H∞ norm then brackets the
//! frequencies such a λ could cross at).
//!
//! **What the square keeps exactly.** An eigenvalue on the imaginary axis, `λ = jω`, is a real
//! `μ = −ω²` of the real matrix `Ã`; a real perturbation keeps a simple real eigenvalue real,
//! so a crossing stays a real μ under rounding unless two crossings lie within the error of
//! each other. A direct eigenvalue computation of H (not structure-preserving) moves `jω` off
//! the axis by its rounding instead, and must classify with a tolerance.

use crate::error::Result;
use crate::linalg::convert::eigenvalues;
use crate::linalg::convert::to_faer;
use faer::linalg::matmul::matmul;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Accum, Mat, Par};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use std::ops::Range;

/// The squares `μ = λ²` of a Hamiltonian matrix's eigenvalues (one per ± pair), with the norm
/// of the square they were computed from.
#[derive(Debug, Clone)]
pub struct SquaredEigenvalues {
    /// `μ_i = λ_i²`, n of them for a 2n×2n Hamiltonian.
    pub mu: Vec<C>,
    /// `‖H‖₁²`, the scale of the rounding in `H²` (its blocks are formed from products of
    /// H's) and in the reduction.
    pub square_norm: f64,
}

impl SquaredEigenvalues {
    /// The absolute error scale of μ, `16·n·ε·‖H‖₁²` (module documentation); λ = √μ carries
    /// this divided by `2|λ|`.
    pub fn mu_error(&self) -> f64 {
        16.0 * self.mu.len().max(1) as f64 * f64::EPSILON * self.square_norm
    }
}

/// Eigenvalues of `H = [[f, g], [q, −fᵀ]]` (g, q symmetric n×n) as squares, by the PVL
/// reduction of `H²` (module documentation).
///
/// # Errors
/// When the QR iteration on the half-order matrix does not converge.
pub fn hamiltonian_squared_eigenvalues(
    f: &DMatrix<f64>,
    g: &DMatrix<f64>,
    q: &DMatrix<f64>,
) -> Result<SquaredEigenvalues> {
    let n = f.nrows();
    if n == 0 {
        return Ok(SquaredEigenvalues {
            mu: Vec::new(),
            square_norm: 0.0,
        });
    }
    let square_norm = hamiltonian_norm1(f, g, q).powi(2);
    let mut w = Square::of(f, g, q);
    for j in 0..n.saturating_sub(1) {
        w.reduce_column(j);
    }
    let a = DMatrix::from_fn(n, n, |i, j| w.a[(i, j)]);
    Ok(SquaredEigenvalues {
        mu: eigenvalues(&a)?,
        square_norm,
    })
}

/// `‖H‖₁` of `[[F, G], [Q, −Fᵀ]]`: the largest column sum over `[F; Q]` and `[G; −Fᵀ]`.
fn hamiltonian_norm1(f: &DMatrix<f64>, g: &DMatrix<f64>, q: &DMatrix<f64>) -> f64 {
    let n = f.nrows();
    let col = |m: &DMatrix<f64>, c: usize| m.column(c).iter().map(|v| v.abs()).sum::<f64>();
    let row = |m: &DMatrix<f64>, r: usize| m.row(r).iter().map(|v| v.abs()).sum::<f64>();
    (0..n)
        .map(|c| (col(f, c) + col(q, c)).max(col(g, c) + row(f, c)))
        .fold(0.0, f64::max)
}

/// The skew-Hamiltonian `[[A, G], [Q, Aᵀ]]` by its three n×n blocks (G and Q
/// skew-symmetric, stored whole).
struct Square {
    a: Mat<f64>,
    g: Mat<f64>,
    q: Mat<f64>,
}

/// A reflector `I − τvvᵀ` (v₀ = 1) on the indices `k0..k0 + v.len()`.
struct Reflector {
    k0: usize,
    v: Mat<f64>,
    tau: f64,
}

impl Reflector {
    /// The reflector that maps `x` to a multiple of e₁ (LAPACK's DLARFG); `None` when x is
    /// already such a multiple.
    fn annihilating(x: &[f64], k0: usize) -> Option<Self> {
        let (alpha, rest) = x.split_first()?;
        let xnorm = rest.iter().map(|v| v * v).sum::<f64>().sqrt();
        if xnorm == 0.0 {
            return None;
        }
        let beta = -alpha.signum() * alpha.hypot(xnorm);
        let tau = (beta - alpha) / beta;
        let scale = 1.0 / (alpha - beta);
        let v = Mat::from_fn(
            x.len(),
            1,
            |i, _| if i == 0 { 1.0 } else { rest[i - 1] * scale },
        );
        Some(Reflector { k0, v, tau })
    }

    /// `M ← P·M` on rows `k0..`, columns `cols` (two matrix-vector products through faer).
    fn left(&self, m: &mut Mat<f64>, cols: Range<usize>) {
        let len = self.v.nrows();
        let mut sub = m
            .as_mut()
            .submatrix_mut(self.k0, cols.start, len, cols.len());
        let mut w = Mat::<f64>::zeros(1, cols.len());
        matmul(
            w.as_mut(),
            Accum::Replace,
            self.v.transpose(),
            sub.rb(),
            1.0,
            Par::Seq,
        );
        matmul(
            sub.rb_mut(),
            Accum::Add,
            self.v.as_ref(),
            w.as_ref(),
            -self.tau,
            Par::Seq,
        );
    }

    /// `M ← M·P` on rows `rows`, columns `k0..`.
    fn right(&self, m: &mut Mat<f64>, rows: Range<usize>) {
        let len = self.v.nrows();
        let mut sub = m
            .as_mut()
            .submatrix_mut(rows.start, self.k0, rows.len(), len);
        let mut w = Mat::<f64>::zeros(rows.len(), 1);
        matmul(
            w.as_mut(),
            Accum::Replace,
            sub.rb(),
            self.v.as_ref(),
            1.0,
            Par::Seq,
        );
        matmul(
            sub.rb_mut(),
            Accum::Add,
            w.as_ref(),
            self.v.transpose(),
            -self.tau,
            Par::Seq,
        );
    }
}

impl Square {
    /// `H²` by blocks: `F² + GQ`, `X − Xᵀ` with `X = FG`, `Y − Yᵀ` with `Y = QF` (skew by
    /// construction).
    fn of(f: &DMatrix<f64>, g: &DMatrix<f64>, q: &DMatrix<f64>) -> Self {
        let (f, g, q) = (to_faer(f), to_faer(g), to_faer(q));
        let a = &f * &f + &g * &q;
        let x = &f * &g;
        let y = &q * &f;
        Square {
            a,
            g: &x - x.transpose(),
            q: &y - y.transpose(),
        }
    }

    /// Applies `diag(P, P)` as a similarity (A's columns before j and Q's rows and columns
    /// before j are already zero where P acts).
    fn reflect(&mut self, p: &Reflector, j: usize) {
        let n = self.a.nrows();
        p.left(&mut self.a, j..n);
        p.right(&mut self.a, 0..n);
        p.left(&mut self.g, 0..n);
        p.right(&mut self.g, 0..n);
        p.left(&mut self.q, j..n);
        p.right(&mut self.q, j..n);
    }

    /// The symplectic rotation `[[C, S], [−S, C]]` (c, s at coordinate k) as a similarity:
    /// row and column k of the three blocks (derived from `UᵀWU` blockwise; the diagonal
    /// entries of G and Q stay zero and A(k, k) is unchanged).
    fn rotate(&mut self, k: usize, c: f64, s: f64) {
        let n = self.a.nrows();
        let a_row: Vec<f64> = (0..n).map(|l| self.a[(k, l)]).collect();
        let a_col: Vec<f64> = (0..n).map(|i| self.a[(i, k)]).collect();
        let g_col: Vec<f64> = (0..n).map(|i| self.g[(i, k)]).collect();
        let q_row: Vec<f64> = (0..n).map(|l| self.q[(k, l)]).collect();
        for l in (0..n).filter(|&l| l != k) {
            self.a[(k, l)] = c * a_row[l] - s * q_row[l];
            self.a[(l, k)] = c * a_col[l] - s * g_col[l];
            let gk = c * g_col[l] + s * a_col[l]; // G'(l, k)
            self.g[(l, k)] = gk;
            self.g[(k, l)] = -gk;
            let qk = c * q_row[l] + s * a_row[l]; // Q'(k, l)
            self.q[(k, l)] = qk;
            self.q[(l, k)] = -qk;
        }
    }

    /// Step j of the PVL reduction: afterwards Q's column j is zero and A's is Hessenberg.
    fn reduce_column(&mut self, j: usize) {
        let n = self.a.nrows();
        let k = j + 1;
        if let Some(p) = Reflector::annihilating(&self.q.col_as_slice(j)[k..], k) {
            self.reflect(&p, j);
        }
        let (ak, qk) = (self.a[(k, j)], self.q[(k, j)]);
        let r = ak.hypot(qk);
        if qk != 0.0 && r > 0.0 {
            self.rotate(k, ak / r, -qk / r);
        }
        if let Some(p) = Reflector::annihilating(&self.a.col_as_slice(j)[k..], k) {
            self.reflect(&p, j);
        }
        for i in k + 1..n {
            self.a[(i, j)] = 0.0;
        }
        for i in 0..n {
            self.q[(i, j)] = 0.0;
            self.q[(j, i)] = 0.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::schur::tests::rand_mat;

    /// μ matches the squares of a direct eigenvalue computation of H (sorted by value), within
    /// the stated bound, for random Hamiltonians of several orders; the skew blocks stay skew.
    #[test]
    fn squares_of_the_direct_eigenvalues() {
        for (n, seed) in [(1usize, 3u64), (2, 5), (7, 11), (30, 17), (61, 23)] {
            let f = rand_mat(n, seed);
            let b = rand_mat(n, seed + 1);
            let c = rand_mat(n, seed + 2);
            let g = -(&b * b.transpose());
            let q = &c * c.transpose();
            let mut h = DMatrix::zeros(2 * n, 2 * n);
            h.view_mut((0, 0), (n, n)).copy_from(&f);
            h.view_mut((0, n), (n, n)).copy_from(&g);
            h.view_mut((n, 0), (n, n)).copy_from(&q);
            h.view_mut((n, n), (n, n)).copy_from(&(-f.transpose()));
            let direct = eigenvalues(&h).unwrap_or_else(|e| panic!("{e}"));
            let sq = hamiltonian_squared_eigenvalues(&f, &g, &q).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(sq.mu.len(), n);
            // each μ is the square of a direct eigenvalue within n·ε·‖H‖² (scaled), and every
            // direct λ² is matched by some μ
            let hn = crate::linalg::expm::norm1(&h);
            let tol = 1e3 * (2 * n) as f64 * f64::EPSILON * hn * hn;
            let squares: Vec<C> = direct.iter().map(|l| l * l).collect();
            let nearest = |z: &C, set: &[C]| {
                set.iter()
                    .map(|w| (w - z).norm())
                    .fold(f64::INFINITY, f64::min)
            };
            for mu in &sq.mu {
                let d = nearest(mu, &squares);
                assert!(d <= tol, "n {n}: μ {mu} is {d:e} from every λ²");
            }
            for l2 in &squares {
                let d = nearest(l2, &sq.mu);
                assert!(d <= tol, "n {n}: λ² {l2} is {d:e} from every μ");
            }
        }
    }

    /// An imaginary pair ±jω gives μ = −ω² (a Hamiltonian with known spectrum: the
    /// undamped oscillator `F = [[0, 1], [−ω², 0]]`, G = Q = 0).
    #[test]
    fn an_oscillator_gives_minus_omega_squared() {
        let w = 3.0;
        let f = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, 0.0]);
        let z = DMatrix::zeros(2, 2);
        let sq = hamiltonian_squared_eigenvalues(&f, &z, &z).unwrap_or_else(|e| panic!("{e}"));
        for mu in &sq.mu {
            assert!((mu - C::new(-w * w, 0.0)).norm() <= 1e-13 * w * w, "{mu}");
        }
    }
}
