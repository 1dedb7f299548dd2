//! Invariant zeros: the finite values `λ` where the Rosenbrock system pencil
//! `P(λ) = [[A − λI, B], [C, D]]` loses rank below its normal rank.
//!
//! **Method** (Emami-Naeini & Van Dooren, "Computation of zeros of linear multivariable
//! systems", Automatica 18(4), 1982; the reduction SLICOT's `AB08ND` performs). Orthogonal
//! transformations strip the infinite and the non-square structure first, so no eigenvalue
//! solver sees the pencil's defective infinite eigenvalues, and the last step is a standard
//! eigenvalue problem. (The earlier implementation ran faer's QZ on the whole pencil and
//! squared non-square systems by random output or input combinations: faer 0.24's real QZ
//! scales the second member of a complex pair wrongly — zeros without their conjugates — and
//! returns `(0, 0)` for most eigenvalues of some pencils of a few dozen states, and the random
//! combinations let spurious zeros through.)
//!
//! 1. *Reduce* (`reduce`): while `D` (p×m) lacks full row rank, compress its rows
//!    (`UᵀD = [D_σ; 0]`, rank σ, `UᵀC = [C_σ; C_0]`) and the columns of `C_0`
//!    (`C_0 V = [0, C̄_0]`, `C̄_0` of full column rank ρ). In the coordinates `x = V[x₁; x₂]`
//!    the rows `[0, C̄_0, 0]` fix `x₂` whatever λ: the pencil's rank is ρ plus the rank of the
//!    smaller pencil of `A' = A₁₁`, `B' = B₁`, `C' = [A₂₁; C_σ₁]`, `D' = [B₂; D_σ]` (n − ρ
//!    states), by a unimodular row elimination that keeps the rank at every λ. Zero rows
//!    (ρ = 0) are dropped. Each step removes states or rows, so it ends with `D` of full row
//!    rank.
//! 2. The same on the dual system `(Aᵀ, Cᵀ, Bᵀ, Dᵀ)` (the transposed pencil has the same rank
//!    at every λ): `D` then also has full column rank — square and invertible.
//! 3. Compress the columns of `[C D]`: `[C D]W = [0, D_f]`, `D_f` invertible; the zeros are the
//!    eigenvalues of the square pencil `[A B]W₁ − λ[I 0]W₁` (`W₁` the first `n_r` columns of
//!    `W`), whose `[I 0]W₁` is invertible: those of `([I 0]W₁)⁻¹[A B]W₁` by the real QR
//!    algorithm (conjugate pairs come out exactly conjugate).
//!
//! The system is first balanced by powers of two (`balanced`: xGEBAL's diagonal scaling of the
//! system matrix, which keeps the zeros), and rank decisions count singular values above
//! `tol = (n + p)(n + m)·ε·‖[A B; C D]‖_F` of the balanced matrix (AB08ND's default). The normal rank is the sum of the ρ plus `n_r + p_r` of the final system; below
//! `n + min(p, m)` the zeros are undefined (an identically rank-deficient transfer matrix,
//! e.g. a zero channel) and an error says so.
//!
//! **Accuracy**: orthogonal transformations, then one LU solve with the reduced `E`; on well-conditioned
//! systems the zeros agree with the pencil's roots to ~1e-12 relative (tests:
//! `tests/tests/zeros.rs`, systems built with known zeros, and the pencil's smallest singular
//! value at each zero).

use crate::error::{ModelError, Result};
use crate::linalg::convert::{eigenvalues, svd};
use crate::linalg::expm::balance_diag;
use crate::ss::StateSpace;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

impl StateSpace {
    /// Invariant zeros (finite), sorted by modulus (module docs: the Emami-Naeini–Van Dooren
    /// reduction, then the eigenvalues of the reduced pencil). Continuous or discrete alike (the pencil does not depend on the
    /// sampling). An error when the system pencil is normal-rank deficient.
    pub fn zeros(&self) -> Result<Vec<C>> {
        let (n, nu, ny) = (self.n(), self.nu(), self.ny());
        let (mut sys, norm) = balanced(self);
        let tol = ((n + ny) * (n + nu)).max(1) as f64 * f64::EPSILON * norm;
        let mut rank = 0;
        // the passes alternate until D is square; two suffice in exact arithmetic
        for _ in 0..2 * (n + 2) {
            let (r, rho) = reduce(sys, tol)?;
            let (dual, rho_d) = reduce(r.dual(), tol)?;
            sys = dual.dual();
            rank += rho + rho_d;
            if sys.d.nrows() == sys.d.ncols() && (rho + rho_d == 0 || sys.a.nrows() == 0) {
                break;
            }
        }
        let (nr, pr) = (sys.a.nrows(), sys.d.nrows());
        if sys.d.ncols() != pr || rank + nr + pr < n + ny.min(nu) {
            return Err(ModelError::Singular {
                what: "the system pencil [A − λI, B; C, D] (normal rank deficient: the \
                       transfer matrix is rank deficient at every frequency, e.g. a zero \
                       channel, so its invariant zeros are undefined)"
                    .into(),
            });
        }
        let mut z = finite_eigenvalues(&sys, tol)?;
        z.sort_by(|a, b| a.norm().total_cmp(&b.norm()));
        Ok(z)
    }
}

/// The system scaled by powers of two (no rounding) so that its system matrix is balanced,
/// and the Frobenius norm of `[A B; C D]`: `diag(T⁻¹, S_y)·[A B; C D]·diag(T, S_u)`, `T`, `S_u`,
/// `S_y` diagonal (LAPACK xGEBAL's scaling of `[[A, B], [C, D]]` padded square). Constant
/// nonsingular factors on both sides keep the pencil's rank at every λ (the `λ[I 0; 0 0]` term
/// is unchanged), so the zeros are the same; the rank decisions then see entries of comparable
/// size (a stage model's entries span 0.05 to 1e9, and a tolerance relative to its largest
/// entry would take its input and output couplings for zero).
fn balanced(sys: &StateSpace) -> (Quad, f64) {
    let (n, m, p) = (sys.n(), sys.nu(), sys.ny());
    let k = n + m.max(p);
    let mut full = DMatrix::zeros(k, k);
    full.view_mut((0, 0), (n, n)).copy_from(sys.a());
    full.view_mut((0, n), (n, m)).copy_from(sys.b());
    full.view_mut((n, 0), (p, n)).copy_from(sys.c());
    full.view_mut((n, n), (p, m)).copy_from(sys.d());
    let (s, _) = balance_diag(&full);
    let q = Quad {
        a: s.view((0, 0), (n, n)).into_owned(),
        b: s.view((0, n), (n, m)).into_owned(),
        c: s.view((n, 0), (p, n)).into_owned(),
        d: s.view((n, n), (p, m)).into_owned(),
    };
    (q, s.norm())
}

/// A state-space quadruple being reduced.
struct Quad {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    d: DMatrix<f64>,
}

impl Quad {
    /// The dual system `(Aᵀ, Cᵀ, Bᵀ, Dᵀ)`.
    fn dual(self) -> Quad {
        Quad {
            a: self.a.transpose(),
            b: self.c.transpose(),
            c: self.b.transpose(),
            d: self.d.transpose(),
        }
    }
}

/// Singular values above `tol`.
fn rank_of(s: &[f64], tol: f64) -> usize {
    s.iter().filter(|v| **v > tol).count()
}

/// An orthogonal `U` (p×p) with `UᵀD = [D_σ; 0]` and the rank σ: the left singular vectors of
/// `[D 0]` (padded so that the thin factor is square).
fn row_compression(d: &DMatrix<f64>, tol: f64) -> Result<(DMatrix<f64>, usize)> {
    let (p, m) = d.shape();
    let mut padded = DMatrix::zeros(p, m + p);
    padded.view_mut((0, 0), (p, m)).copy_from(d);
    let (u, s, _) = svd(&padded)?;
    Ok((u, rank_of(&s, tol)))
}

/// An orthogonal `V` (n×n) with `C V = [0, C̄]`, `C̄` of full column rank ρ (the last ρ
/// columns), and ρ: the right singular vectors of `[C; 0]`, the row space's last.
fn column_compression(c: &DMatrix<f64>, tol: f64) -> Result<(DMatrix<f64>, usize)> {
    let (q, n) = c.shape();
    let mut padded = DMatrix::zeros(q + n, n);
    padded.view_mut((0, 0), (q, n)).copy_from(c);
    let (_, s, v) = svd(&padded)?;
    let rho = rank_of(&s, tol);
    let mut out = DMatrix::zeros(n, n);
    for j in 0..n {
        // null space first (columns ρ..n of V), then the row space (columns 0..ρ)
        let src = if j < n - rho { rho + j } else { j - (n - rho) };
        out.set_column(j, &v.column(src));
    }
    Ok((out, rho))
}

/// Step 1 (module docs): the system with `D` of full row rank and the same finite zeros, and
/// the pencil rank the reduction removed (the sum of the ρ).
fn reduce(mut s: Quad, tol: f64) -> Result<(Quad, usize)> {
    let mut removed = 0;
    loop {
        let (n, p) = (s.a.nrows(), s.d.nrows());
        if p == 0 {
            return Ok((s, removed));
        }
        let (u, sigma) = row_compression(&s.d, tol)?;
        if sigma == p {
            return Ok((s, removed));
        }
        let (cu, du) = (u.transpose() * &s.c, u.transpose() * &s.d);
        let (c_sig, d_sig) = (
            cu.rows(0, sigma).into_owned(),
            du.rows(0, sigma).into_owned(),
        );
        let c0 = cu.rows(sigma, p - sigma).into_owned();
        let (v, rho) = if n == 0 {
            (DMatrix::zeros(0, 0), 0)
        } else {
            column_compression(&c0, tol)?
        };
        if rho == 0 {
            // the rows beyond σ are zero: they carry no rank
            s.c = c_sig;
            s.d = d_sig;
            continue;
        }
        let k = n - rho;
        let at = v.transpose() * &s.a * &v;
        let bt = v.transpose() * &s.b;
        let ct = c_sig * &v;
        let m = s.b.ncols();
        let mut c_new = DMatrix::zeros(rho + sigma, k);
        c_new
            .view_mut((0, 0), (rho, k))
            .copy_from(&at.view((k, 0), (rho, k)));
        c_new
            .view_mut((rho, 0), (sigma, k))
            .copy_from(&ct.view((0, 0), (sigma, k)));
        let mut d_new = DMatrix::zeros(rho + sigma, m);
        d_new
            .view_mut((0, 0), (rho, m))
            .copy_from(&bt.view((k, 0), (rho, m)));
        d_new.view_mut((rho, 0), (sigma, m)).copy_from(&d_sig);
        s = Quad {
            a: at.view((0, 0), (k, k)).into_owned(),
            b: bt.view((0, 0), (k, m)).into_owned(),
            c: c_new,
            d: d_new,
        };
        removed += rho;
    }
}

/// Step 3 (module docs): the eigenvalues of the pencil `[A B]W₁ − λ[I 0]W₁` for a system whose
/// `D` is square and invertible. `W₁` spans the null space `{[x; −D⁻¹Cx]}` of `[C D]`, so
/// `E = [I 0]W₁` is invertible and every eigenvalue is finite: they are the eigenvalues of
/// `E⁻¹·[A B]W₁` (LU solve, then faer's QR algorithm; faer 0.24's real QZ returns `(0, 0)` for
/// most eigenvalues of some pencils of a few dozen states, so it is not used here).
fn finite_eigenvalues(s: &Quad, tol: f64) -> Result<Vec<C>> {
    let (n, p) = (s.a.nrows(), s.d.nrows());
    if n == 0 {
        return Ok(Vec::new());
    }
    let mut cd = DMatrix::zeros(p, n + p);
    cd.view_mut((0, 0), (p, n)).copy_from(&s.c);
    cd.view_mut((0, n), (p, p)).copy_from(&s.d);
    let (w, _) = column_compression(&cd, tol)?;
    let mut ab = DMatrix::zeros(n, n + p);
    ab.view_mut((0, 0), (n, n)).copy_from(&s.a);
    ab.view_mut((0, n), (n, p)).copy_from(&s.b);
    let w1 = w.columns(0, n);
    let af = &ab * w1;
    let e = w1.rows(0, n).into_owned();
    let m = e.lu().solve(&af).ok_or_else(|| ModelError::Singular {
        what: "the reduced pencil's E (the feedthrough D of the reduced system is singular \
               to working precision)"
            .into(),
    })?;
    eigenvalues(&m)
}
