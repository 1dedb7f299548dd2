//! The structure-preserving doubling algorithm (SDA) of the DARE, with each step's two
//! independent halves on two cores.
//!
//! For the DARE `X = AᵀX(I + GX)⁻¹A + H` (G, H symmetric positive semidefinite) the SDA of
//! Chu, Fan, Lin & Wang (*Linear Algebra Appl.* 396, 2005) iterates, with `W = I + G_k H_k`,
//!
//! ```text
//! A_{k+1} = A_k W⁻¹ A_k,   G_{k+1} = G_k + A_k W⁻¹ G_k A_kᵀ,   H_{k+1} = H_k + A_kᵀ H_k W⁻¹ A_k,
//! ```
//!
//! and `H_k → X` quadratically: the error after k steps is of order `ρ(A_cl)^{2^{k+1}}`
//! (ρ(A_cl) the closed loop's spectral radius), so a stage with ρ = 1 − 3·10⁻⁵ needs about 20
//! steps. The loop stops when a step changes H by less than 10⁻¹⁵ relative, or, once the
//! convergence is visibly quadratic (the change at most the 1.5th power of the previous one),
//! by less than 10⁻¹⁰: the next step's change would be of the order of its square, below ε
//! (on the 60-state stage this saves the 21st step, which changed nothing: `cargo xtask
//! bench`'s `dare` entry reports the steps and the residual).
//!
//! A step costs 14⅔ n³ flops: `G_k H_k` (2n³), the LU of W (⅔n³), the solves for
//! `V₁ = W⁻¹A_k` and `V₂ = W⁻¹G_k` (2n³ each), three general products (2n³ each) and the
//! two symmetric ones of `H_{k+1}`, `G_{k+1}` as lower triangles (n³ each, mirrored).
//!
//! **Two cores.** After the LU the step splits into `V₁, H_{k+1} = H + Aᵀ(H V₁), A_{k+1} = A V₁`
//! (7n³) and `V₂, G_{k+1} = G + A(V₂ Aᵀ)` (5n³). (Moving half of `A V₁` into the second half
//! to balance them was tried and measured no faster.) The second half is *posted* to a helper
//! running beside the loop on the rayon pool (`board.rs`: whichever thread claims it first
//! computes it; inside a busy pool, e.g. the two Riccati equations of loopshaping solved in
//! parallel, the steps simply run on one thread). The result is bit-identical either way
//! (test). `cargo xtask bench` reports the 60-state DARE's time, steps and share of one
//! core's peak (`dare`).

use crate::board::Board;
use crate::error::{HinfError, Result};
use crate::riccati::{all_finite, mm, mm_sym};
use crate::tol;
use faer::linalg::solvers::{PartialPivLu, Solve};
use faer::Mat;
use nalgebra::DMatrix;
use sd_model::linalg::convert::{from_faer, to_faer};
use std::sync::Arc;

/// Below this order one thread does every step (the halves are too small to share).
const TWO_CORES_FROM: usize = 24;

/// The work matrices of one half of a step: `W⁻¹A` or `W⁻¹G`, a product's intermediate, and
/// the next `H` or `G` (allocated once, handed back and forth with the job).
struct Work {
    v: Mat<f64>,
    t: Mat<f64>,
    next: Mat<f64>,
}

impl Work {
    fn new(n: usize) -> Self {
        let z = || Mat::<f64>::zeros(n, n);
        Work {
            v: z(),
            t: z(),
            next: z(),
        }
    }
}

/// The second half of a step, as posted: its inputs (shared) and its work matrices.
struct GJob {
    lu: Arc<PartialPivLu<f64>>,
    a: Arc<Mat<f64>>,
    g: Arc<Mat<f64>>,
    work: Work,
}

/// `V₂ = W⁻¹G`, `G⁺ = G + A(V₂ Aᵀ)` (in `work.next`); whether V₂ is finite.
fn g_half(job: GJob) -> (Work, bool) {
    let GJob { lu, a, g, mut work } = job;
    work.v.copy_from(g.as_ref());
    lu.solve_in_place(work.v.as_mut());
    mm(&mut work.t, false, work.v.as_ref(), a.transpose());
    work.next.copy_from(g.as_ref());
    mm_sym(&mut work.next, true, a.as_ref().as_ref(), work.t.as_ref());
    let ok = all_finite(&work.v);
    (work, ok)
}

/// `V₁ = W⁻¹A`, `H⁺ = H + Aᵀ(H V₁)` (in `work.next`), `A⁺ = A V₁` (in `an`); whether V₁ is
/// finite.
fn h_half(
    lu: &PartialPivLu<f64>,
    a: &Mat<f64>,
    h: &Mat<f64>,
    work: &mut Work,
    an: &mut Mat<f64>,
) -> bool {
    work.v.copy_from(a);
    lu.solve_in_place(work.v.as_mut());
    mm(&mut work.t, false, h.as_ref(), work.v.as_ref());
    work.next.copy_from(h);
    mm_sym(&mut work.next, true, a.transpose(), work.t.as_ref());
    mm(an, false, a.as_ref(), work.v.as_ref());
    all_finite(&work.v)
}

/// SDA on `(A, G, H)`; returns `(X, iterations)` (module documentation).
///
/// # Errors
/// A singular `I + G_k H_k`, divergence, or no convergence within [`tol::MAX_DOUBLING`] steps.
pub(crate) fn doubling(
    a: &DMatrix<f64>,
    g: &DMatrix<f64>,
    h: &DMatrix<f64>,
) -> Result<(DMatrix<f64>, usize)> {
    if a.nrows() < TWO_CORES_FROM {
        return steps(a, g, h, None);
    }
    let board = Board::default();
    let (r, ()) = rayon::join(
        || {
            let r = steps(a, g, h, Some(&board));
            board.close();
            r
        },
        || board.help(g_half),
    );
    r
}

/// The doubling loop; the second halves through `board` when there is one. The matrices are
/// allocated once: each step's results are swapped into place (`A_k`, `G_k` are shared with
/// the posted half through `Arc`s, which are the loop's alone again once the half is back).
fn steps(
    a: &DMatrix<f64>,
    g: &DMatrix<f64>,
    h: &DMatrix<f64>,
    board: Option<&Board<GJob, (Work, bool)>>,
) -> Result<(DMatrix<f64>, usize)> {
    let n = a.nrows();
    let (mut ak, mut gk, mut hk) = (Arc::new(to_faer(a)), Arc::new(to_faer(g)), to_faer(h));
    let (mut w, mut an) = (Mat::<f64>::zeros(n, n), Mat::<f64>::zeros(n, n));
    let mut last_change = f64::INFINITY;
    let (mut hw, mut gw) = (Work::new(n), Some(Work::new(n)));
    for it in 0..tol::MAX_DOUBLING {
        mm(&mut w, false, gk.as_ref().as_ref(), hk.as_ref());
        for i in 0..n {
            w[(i, i)] += 1.0;
        }
        let lu = Arc::new(w.partial_piv_lu());
        let job = GJob {
            lu: lu.clone(),
            a: ak.clone(),
            g: gk.clone(),
            work: gw.take().unwrap_or_else(|| Work::new(n)),
        };
        let (ok_h, (mut gdone, ok_g)) = match board {
            Some(b) => {
                b.post(job, it + 1)?;
                let ok = h_half(&lu, &ak, &hk, &mut hw, &mut an);
                (ok, b.collect(it + 1, g_half)?)
            }
            None => (h_half(&lu, &ak, &hk, &mut hw, &mut an), g_half(job)),
        };
        if !(ok_h && ok_g) {
            return Err(HinfError::Numerical(
                "I + G_k H_k is singular in the doubling".into(),
            ));
        }
        let (dh, hnorm) = change_and_norm(&hw.next, &hk);
        if !hnorm.is_finite() {
            return Err(HinfError::Numerical(
                "the doubling iteration diverged".into(),
            ));
        }
        std::mem::swap(&mut hk, &mut hw.next);
        swap_into(&mut gk, &mut gdone.next);
        swap_into(&mut ak, &mut an);
        gw = Some(gdone);
        let change = dh / hnorm.max(f64::MIN_POSITIVE);
        let quadratic = change <= tol::DOUBLING_QUADRATIC && change <= last_change.powf(1.5);
        if change <= tol::DOUBLING_STOP || quadratic {
            return Ok((from_faer(hk.as_ref()), it + 1));
        }
        last_change = change;
    }
    Err(HinfError::Numerical(format!(
        "the doubling iteration did not converge in {} steps",
        tol::MAX_DOUBLING
    )))
}

/// Makes `m` the shared matrix and leaves the old one in `m` for reuse (a copy only if the
/// `Arc` is still shared, which it is not once the step's half is back).
fn swap_into(shared: &mut Arc<Mat<f64>>, m: &mut Mat<f64>) {
    match Arc::get_mut(shared) {
        Some(s) => std::mem::swap(s, m),
        None => {
            let (r, c) = (m.nrows(), m.ncols());
            *shared = Arc::new(std::mem::replace(m, Mat::<f64>::zeros(r, c)));
        }
    }
}

/// `(‖new − old‖_F, ‖new‖_F)` without a temporary (column slices, vectorised).
fn change_and_norm(new: &Mat<f64>, old: &Mat<f64>) -> (f64, f64) {
    let (mut d2, mut n2) = ([0.0f64; 4], [0.0f64; 4]);
    for j in 0..new.ncols() {
        let (x, y) = (new.col_as_slice(j), old.col_as_slice(j));
        for (k, (a, b)) in x.iter().zip(y).enumerate() {
            d2[k % 4] += (a - b) * (a - b);
            n2[k % 4] += a * a;
        }
    }
    let sum = |v: [f64; 4]| ((v[0] + v[1]) + (v[2] + v[3])).sqrt();
    (sum(d2), sum(n2))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random stable-ish 40-state problem: the two-core loop and the one-thread loop give
    /// bit-identical X and the same number of steps.
    #[test]
    fn two_cores_and_one_give_the_same_bits() {
        let n = 40;
        let mut s = 1u64;
        let mut rnd = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let a = DMatrix::from_fn(n, n, |_, _| rnd() * 0.3);
        let b = DMatrix::from_fn(n, 2, |_, _| rnd());
        let c = DMatrix::from_fn(3, n, |_, _| rnd());
        let g = &b * b.transpose();
        let h = c.transpose() * &c;
        let (x1, k1) = steps(&a, &g, &h, None).unwrap_or_else(|e| panic!("{e}"));
        let (x2, k2) = doubling(&a, &g, &h).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(k1, k2);
        assert_eq!(x1, x2);
    }
}
