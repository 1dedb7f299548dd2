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
//! (ρ(A_cl) the closed loop's spectral radius), so a stage with ρ = 1 − 3·10⁻⁵ needs about 21
//! steps. A step costs 16⅔ n³ flops: `G_k H_k` (2n³), the LU of W (⅔n³), the solves for
//! `V₁ = W⁻¹A_k` and `V₂ = W⁻¹G_k` (2n³ each) and five products (2n³ each).
//!
//! **Two cores.** After the LU the step splits into `V₁, H_{k+1} = H + Aᵀ(H V₁), A_{k+1} = A V₁`
//! (8n³) and `V₂, G_{k+1} = G + A(V₂ Aᵀ)` (6n³). The second half is *posted* to a helper
//! running beside the loop on the rayon pool; whichever thread claims it first computes it
//! (the loop itself when the helper has not started: inside a busy pool, e.g. the two Riccati
//! equations of loopshaping solved in parallel, the steps simply run on one thread). The
//! helper spins between steps, yielding its core every few hundred spins: a step of a 60-state
//! problem is a few tens of microseconds, the order of what waking a sleeping pool thread
//! costs, so a `rayon::join` per step (which lets the other thread sleep between steps) lost
//! more than it gained. The arithmetic does not depend on which thread computes a half: the
//! result is bit-identical either way (test). `cargo xtask bench` reports the 60-state DARE's
//! time, steps and share of one core's peak (`dare`).

use crate::error::{HinfError, Result};
use crate::riccati::{all_finite, fsym, mm};
use crate::tol;
use faer::linalg::solvers::{PartialPivLu, Solve};
use faer::Mat;
use nalgebra::DMatrix;
use sd_model::linalg::convert::{from_faer, to_faer};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// Below this order one thread does every step (the halves are too small to share).
const TWO_CORES_FROM: usize = 24;

/// Spins between two yields of a waiting thread.
const SPINS_PER_YIELD: usize = 256;

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
    mm(&mut work.next, true, a.as_ref().as_ref(), work.t.as_ref());
    fsym(&mut work.next);
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
    mm(&mut work.next, true, a.transpose(), work.t.as_ref());
    fsym(&mut work.next);
    mm(an, false, a.as_ref(), work.v.as_ref());
    all_finite(&work.v)
}

/// What the loop and the helper share: the posted half, its result, and counters.
#[derive(Default)]
struct Board {
    posted: Mutex<Option<GJob>>,
    result: Mutex<Option<(Work, bool)>>,
    /// Steps posted so far.
    seq: AtomicUsize,
    /// Steps whose posted half the helper has finished.
    done: AtomicUsize,
    finished: AtomicBool,
}

impl Board {
    /// The helper: claims every posted half until the loop has finished.
    fn help(&self) {
        let mut seen = 0;
        let mut spins = 0;
        while !self.finished.load(Ordering::Acquire) {
            let p = self.seq.load(Ordering::Acquire);
            if p > seen {
                seen = p;
                let job = self.posted.lock().ok().and_then(|mut j| j.take());
                if let Some(job) = job {
                    let r = g_half(job);
                    if let Ok(mut slot) = self.result.lock() {
                        *slot = Some(r);
                    }
                    self.done.store(p, Ordering::Release);
                }
                continue;
            }
            pause(&mut spins);
        }
    }

    /// Posts step `k`'s second half (numbered from 1).
    fn post(&self, job: GJob, k: usize) -> Result<()> {
        *self.posted.lock().map_err(|_| poisoned())? = Some(job);
        self.seq.store(k, Ordering::Release);
        Ok(())
    }

    /// Step `k`'s second half: computed here when the helper has not claimed it, else the
    /// helper's result once it is there.
    fn collect(&self, k: usize) -> Result<(Work, bool)> {
        let unclaimed = self.posted.lock().map_err(|_| poisoned())?.take();
        if let Some(job) = unclaimed {
            return Ok(g_half(job));
        }
        let mut spins = 0;
        while self.done.load(Ordering::Acquire) < k {
            pause(&mut spins);
        }
        self.result
            .lock()
            .map_err(|_| poisoned())?
            .take()
            .ok_or_else(|| HinfError::Numerical("a doubling step's half went missing".into()))
    }
}

fn poisoned() -> HinfError {
    HinfError::Numerical("the doubling's helper thread failed".into())
}

/// One spin, and a yield of the core every [`SPINS_PER_YIELD`].
fn pause(spins: &mut usize) {
    *spins += 1;
    if *spins % SPINS_PER_YIELD == 0 {
        std::thread::yield_now();
    } else {
        std::hint::spin_loop();
    }
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
            board.finished.store(true, Ordering::Release);
            r
        },
        || board.help(),
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
    board: Option<&Board>,
) -> Result<(DMatrix<f64>, usize)> {
    let n = a.nrows();
    let (mut ak, mut gk, mut hk) = (Arc::new(to_faer(a)), Arc::new(to_faer(g)), to_faer(h));
    let (mut w, mut an) = (Mat::<f64>::zeros(n, n), Mat::<f64>::zeros(n, n));
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
                (ok, b.collect(it + 1)?)
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
        if dh <= tol::DOUBLING_STOP * hnorm.max(f64::MIN_POSITIVE) {
            return Ok((from_faer(hk.as_ref()), it + 1));
        }
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

/// `(‖new − old‖_F, ‖new‖_F)` without a temporary.
fn change_and_norm(new: &Mat<f64>, old: &Mat<f64>) -> (f64, f64) {
    let (mut d2, mut n2) = (0.0, 0.0);
    for j in 0..new.ncols() {
        for i in 0..new.nrows() {
            let (x, y) = (new[(i, j)], old[(i, j)]);
            d2 += (x - y) * (x - y);
            n2 += x * x;
        }
    }
    (d2.sqrt(), n2.sqrt())
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
