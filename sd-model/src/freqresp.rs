//! Frequency response of state-space models at many frequencies.
//!
//! `G(s) = C (sI − A)⁻¹ B + D` with `s = j2πf` (continuous) or `s = e^{j2πf·ts}` (discrete).
//! A dense O(n³) solve per frequency is never used: A is reduced **once** to block-diagonal
//! form `V⁻¹AV = diag(T₁, …, T_k)` with upper-triangular blocks ([`crate::linalg::schur`]:
//! complex Schur, then Bavely–Stewart decoupling with `‖X‖ ≤ 10⁴`); then per frequency
//! `G(s) = D + Σ_b C̃_b (sI − T_b)⁻¹ B̃_b`, a back-substitution per block. Cost per frequency
//! O(Σ m_b²·nu + n·ny·nu) — O(n) for distinct poles. Close or defective poles (the rigid-body
//! Jordan block at z = 1) stay together in one triangular block, so nothing is inverted that is
//! ill-conditioned. Accuracy: within 1e-10 relative of LU solves of `sI − A` on the 60-state
//! stage test (`tests/freqresp_stage.rs`). When the block form fails its accuracy check (a
//! defective multiple pole formed by a series connection), the evaluator uses the Hessenberg
//! form instead, O(n²) per point, and dense solves only when that fails the same check
//! ([`EvalPath`]). Frequencies are evaluated in parallel (rayon), four at a time on the
//! block-diagonal path: one SIMD lane per point (AVX2/FMA where the processor has them), the
//! simple poles' conjugate pairs summed with one division per pair (`pole_sum.rs`: same
//! rounding bound as the terms one by one), then the small clusters in the same lanes.

use crate::error::{ModelError, Result};
use crate::frd::Frd;
use crate::linalg::schur::{block_diagonalize, to_complex, BlockDiagonal, SPLIT_BOUND};
use crate::pole_guard::{AtPole, PoleGuard};
use crate::pole_sum::{offsets, PoleSum, LANES};
use crate::ss::StateSpace;
use crate::time::SampleTime;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use rayon::prelude::*;

/// A cluster of the reduced form: upper-triangular `t` (m×m) with its input map `b` (m×nu)
/// and output map `c` (ny×m).
#[derive(Debug, Clone)]
struct Cluster {
    t: DMatrix<C>,
    b: DMatrix<C>,
    c: DMatrix<C>,
}

/// Clusters up to this size are solved in a stack buffer.
const SMALL_CLUSTER: usize = 8;

/// The simple poles of the block-diagonal form with their residues `R_k = c_k b_kᵀ`
/// (`r[e·n + k]` for entry `e` of the column-major ny×nu response), summed by [`PoleSum`].
fn pole_sum(bd: &BlockDiagonal) -> PoleSum {
    let (ny, nu) = (bd.ct.nrows(), bd.bt.ncols());
    let simple: Vec<usize> = bd.blocks.iter().filter(|b| b.1 == 1).map(|b| b.0).collect();
    let n = simple.len();
    let t: Vec<C> = simple.iter().map(|&k| bd.t[(k, k)]).collect();
    let mut r = vec![C::new(0.0, 0.0); n * ny * nu];
    for (k, &st) in simple.iter().enumerate() {
        for j in 0..nu {
            for i in 0..ny {
                r[(j * ny + i) * n + k] = bd.ct[(i, st)] * bd.bt[(st, j)];
            }
        }
    }
    PoleSum::new(&t, &r, ny * nu)
}

/// A model prepared for fast evaluation at many points.
#[derive(Debug, Clone)]
pub struct FreqRespEvaluator {
    /// The size-one blocks, conjugate pairs combined (what the per-point sum runs on).
    poles: PoleSum,
    /// The larger blocks.
    clusters: Vec<Cluster>,
    d: DMatrix<C>,
    time: SampleTime,
    /// The Hessenberg form when the block form failed its accuracy check.
    hess: Option<HessenbergForm>,
    /// `(A, B, C)` when the Hessenberg form failed it too: dense solves per point.
    dense: Option<(DMatrix<C>, DMatrix<C>, DMatrix<C>)>,
    /// Marks the entries at a pole as infinite ([`crate::pole_guard`]).
    guard: PoleGuard,
}

/// `A = Q H Qᵀ` (real, orthogonal `Q`, upper Hessenberg `H`) with `B̃ = QᵀB`, `C̃ = CQ`: per
/// point `G(s) = C̃ (sI − H)⁻¹ B̃ + D` by Gaussian elimination with partial pivoting between
/// adjacent rows, O(n²·nu) — backward stable like a dense LU (Golub & Van Loan, *Matrix
/// Computations*, 4th ed., §3.5.5 and Laub's frequency-response algorithm, IEEE TAC 1981).
#[derive(Debug, Clone)]
pub(crate) struct HessenbergForm {
    h: DMatrix<f64>,
    b: DMatrix<C>,
    c: DMatrix<C>,
}

/// `(D⁻¹AD, D⁻¹B, CD)` for the exact power-of-two diagonal balancing `D` of A
/// ([`crate::linalg::expm::balance_diag`]): the same response.
fn balanced(sys: &StateSpace) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let (ab, d) = crate::linalg::expm::balance_diag(sys.a());
    let bb = DMatrix::from_fn(sys.n(), sys.nu(), |i, j| sys.b()[(i, j)] / d[i]);
    let cb = DMatrix::from_fn(sys.ny(), sys.n(), |i, j| sys.c()[(i, j)] * d[j]);
    (ab, bb, cb)
}

/// Simple poles the reduced form is checked next to ([`FreqRespEvaluator::new`]).
const CHECKED_SIMPLE: usize = 64;

/// A point near eigenvalue `lam` on the stability boundary (`delta` away, relative) where the
/// reduced forms are checked against dense solves.
pub(crate) fn check_point(time: SampleTime, lam: C, delta: f64) -> C {
    match time {
        SampleTime::Continuous => {
            C::new(0.0, lam.im) + C::new(1.0, 1.0) * (delta * lam.norm().max(1.0))
        }
        SampleTime::Discrete { .. } => {
            let ang = if lam.norm() > 0.0 { lam.arg() } else { 0.0 };
            C::from_polar(1.0, ang + delta)
        }
    }
}

/// Which algorithm evaluates a model's frequency response.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EvalPath {
    /// Block-diagonal (modal) form: O(n) per point for distinct poles.
    BlockDiagonal,
    /// Hessenberg form: O(n²) per point (the block form failed its accuracy check).
    Hessenberg,
    /// Dense LU solves, O(n³) per point (both forms failed it: a defective multiple
    /// eigenvalue, which an orthogonal reduction moves by `(ε‖A‖)^(1/k)`).
    Dense,
}

impl HessenbergForm {
    /// From the diagonally balanced `(D⁻¹AD, D⁻¹B, CD)` ([`FreqRespEvaluator::new`]): an
    /// orthogonal reduction of states of very different scales would mix them.
    fn new(ab: &DMatrix<f64>, bb: &DMatrix<f64>, cb: &DMatrix<f64>) -> Self {
        if ab.nrows() == 0 {
            // a static gain: nothing to reduce (nalgebra refuses an empty matrix)
            return HessenbergForm {
                h: ab.clone(),
                b: to_complex(bb),
                c: to_complex(cb),
            };
        }
        let (q, h) = ab.clone().hessenberg().unpack();
        HessenbergForm {
            b: to_complex(&(q.transpose() * bb)),
            c: to_complex(&(cb * &q)),
            h,
        }
    }

    /// The form of `sys` after the exact power-of-two diagonal balancing that
    /// [`FreqRespEvaluator::new`] applies first.
    pub(crate) fn of_model(sys: &StateSpace) -> Self {
        let (ab, bb, cb) = balanced(sys);
        HessenbergForm::new(&ab, &bb, &cb)
    }

    /// `C̃ (sI − H)⁻¹ B̃ + d` at `s`; `None` when `sI − H` is singular.
    pub(crate) fn eval(&self, s: C, d: &DMatrix<C>) -> Option<DMatrix<C>> {
        let mut g = d.clone();
        let ny = g.nrows();
        self.accumulate(s, g.as_mut_slice(), ny).then_some(g)
    }

    /// `C̃ (sI − H)⁻¹ B̃` into `g` (added; column-major ny×nu); `false` when `sI − H` is
    /// singular.
    fn accumulate(&self, s: C, g: &mut [C], ny: usize) -> bool {
        let n = self.h.nrows();
        let nu = self.b.ncols();
        // M = sI − H, row-major for the row operations
        let mut m: Vec<C> = vec![C::new(0.0, 0.0); n * n];
        for i in 0..n {
            for j in i.saturating_sub(1)..n {
                m[i * n + j] = C::new(-self.h[(i, j)], 0.0);
            }
            m[i * n + i] += s;
        }
        let mut x: Vec<C> = (0..n)
            .flat_map(|i| (0..nu).map(move |j| (i, j)))
            .map(|(i, j)| self.b[(i, j)])
            .collect();
        for k in 0..n.saturating_sub(1) {
            if m[(k + 1) * n + k].norm() > m[k * n + k].norm() {
                for j in k..n {
                    m.swap(k * n + j, (k + 1) * n + j);
                }
                for j in 0..nu {
                    x.swap(k * nu + j, (k + 1) * nu + j);
                }
            }
            let piv = m[k * n + k];
            if piv.norm() == 0.0 {
                return false;
            }
            let l = m[(k + 1) * n + k] / piv;
            if l.norm() != 0.0 {
                for j in k..n {
                    let v = m[k * n + j];
                    m[(k + 1) * n + j] -= l * v;
                }
                for j in 0..nu {
                    let v = x[k * nu + j];
                    x[(k + 1) * nu + j] -= l * v;
                }
            }
        }
        for k in (0..n).rev() {
            let piv = m[k * n + k];
            if piv.norm() == 0.0 {
                return false;
            }
            for j in 0..nu {
                let mut v = x[k * nu + j];
                for i in k + 1..n {
                    v -= m[k * n + i] * x[i * nu + j];
                }
                x[k * nu + j] = v / piv;
            }
        }
        for j in 0..nu {
            for r in 0..ny {
                let mut v = C::new(0.0, 0.0);
                for i in 0..n {
                    v += self.c[(r, i)] * x[i * nu + j];
                }
                g[j * ny + r] += v;
            }
        }
        true
    }
}

impl FreqRespEvaluator {
    /// Reduces the model once (O(n³)).
    pub fn new(sys: &StateSpace) -> Result<Self> {
        // exact power-of-two diagonal balancing first (as LAPACK does before an eigenvalue
        // problem): D⁻¹AD, D⁻¹B, CD leave G unchanged and keep the split bound meaningful for
        // models whose states have very different scales (registers next to positions)
        let (ab, bb, cb) = balanced(sys);
        let bd: BlockDiagonal = block_diagonalize(
            &to_complex(&ab),
            &to_complex(&bb),
            &to_complex(&cb),
            SPLIT_BOUND,
        )?;
        let clusters: Vec<Cluster> = bd
            .blocks
            .iter()
            .filter(|b| b.1 > 1)
            .map(|&(st, sz)| Cluster {
                t: bd.t.view((st, st), (sz, sz)).into_owned(),
                b: bd.bt.rows(st, sz).into_owned(),
                c: bd.ct.columns(st, sz).into_owned(),
            })
            .collect();
        let eig: Vec<(C, usize)> = bd
            .blocks
            .iter()
            .enumerate()
            .flat_map(|(k, &(st, sz))| (st..st + sz).map(move |i| (i, k)))
            .map(|(i, k)| (bd.t[(i, i)], k))
            .collect();
        let mut ev = FreqRespEvaluator {
            poles: pole_sum(&bd),
            clusters,
            d: to_complex(sys.d()),
            time: sys.time(),
            hess: None,
            dense: None,
            guard: PoleGuard::new((sys.a(), sys.b(), sys.c()), &eig, bd.t.norm(), sys.time()),
        };
        // Accuracy check against dense LU solves next to every eigenvalue, on the stability
        // boundary where responses are evaluated. A defective multiple pole formed by a series
        // connection (a rigid body times an integrator) can make the reduced form lose accuracy
        // there; the evaluator then falls back to the Hessenberg form (O(n²) per point,
        // backward stable), and when that fails the same check, to dense solves, rather than
        // return a wrong response.
        // The references: dense LU solves of `sI − A` next to every eigenvalue of a cluster
        // (close or defective poles, where reduced forms lose accuracy) and next to the
        // [`CHECKED_SIMPLE`] simple poles nearest the stability boundary (those dominate the
        // response): every pole of a model up to that size, O(n³) in all above it (checking
        // every pole of a 240-state model took 3 s, O(n⁴)).
        let time = ev.time;
        let margin = |lam: C| match time {
            SampleTime::Continuous => lam.re.abs(),
            SampleTime::Discrete { .. } => (1.0 - lam.norm()).abs(),
        };
        let mut simple: Vec<C> = Vec::new();
        let mut clustered: Vec<C> = Vec::new();
        for &(st, sz) in &bd.blocks {
            let target = if sz > 1 { &mut clustered } else { &mut simple };
            target.extend((st..st + sz).map(|i| bd.t[(i, i)]));
        }
        simple.sort_by(|a, b| margin(*a).total_cmp(&margin(*b)));
        simple.truncate(CHECKED_SIMPLE);
        // the dense solves (O(n³) each, most of the set-up's time) on every core
        let points: Vec<C> = clustered
            .iter()
            .chain(&simple)
            .flat_map(|&lam| [1e-3, 1e-2].map(|delta| check_point(time, lam, delta)))
            .collect();
        let refs: Vec<(C, DMatrix<C>, f64)> = points
            .into_par_iter()
            .filter_map(|sp| {
                let r = sys.eval_direct(sp).ok()?;
                let rn = r.norm();
                (rn.is_finite() && rn > 0.0).then_some((sp, r, rn))
            })
            .collect();
        let fails = |ev: &Self, tol: f64| {
            let worst = refs
                .iter()
                .map(|(sp, r, rn)| (ev.eval_at(*sp) - r).norm() / rn)
                .fold(
                    0.0,
                    |a: f64, b| if b.is_nan() { f64::NAN } else { a.max(b) },
                );
            worst.is_nan() || worst > tol
        };
        if fails(&ev, 1e-8) {
            // the fallback must be as good as the dense solves it replaces: a rigid body's
            // Jordan block at z = 1 costs an orthogonal reduction about √ε
            ev.hess = Some(HessenbergForm::new(&ab, &bb, &cb));
            if fails(&ev, 1e-11) {
                // an orthogonal reduction moves a defective multiple eigenvalue by
                // (ε‖A‖)^(1/k): dense solves of the structured matrix keep it
                ev.hess = None;
                ev.dense = Some((
                    to_complex(sys.a()),
                    to_complex(sys.b()),
                    to_complex(sys.c()),
                ));
            }
        }
        Ok(ev)
    }

    /// Which form evaluates the response (see [`FreqRespEvaluator::new`]).
    pub fn path(&self) -> EvalPath {
        match (&self.hess, &self.dense) {
            (Some(_), _) => EvalPath::Hessenberg,
            (None, Some(_)) => EvalPath::Dense,
            (None, None) => EvalPath::BlockDiagonal,
        }
    }

    /// Adds `Σ_b C̃_b (sI − T_b)⁻¹ B̃_b` to `g` (column-major ny×nu) at one point: the lane
    /// routines ([`PoleSum::accumulate`], [`Self::add_clusters`]) with a single lane.
    fn accumulate(&self, s: C, g: &mut [C], ny: usize) {
        let mut gr: Vec<[f64; 1]> = g.iter().map(|z| [z.re]).collect();
        let mut gi: Vec<[f64; 1]> = g.iter().map(|z| [z.im]).collect();
        self.poles.accumulate(&[s.re], &[s.im], &mut gr, &mut gi);
        self.add_clusters(&[s.re], &[s.im], &mut gr, &mut gi, ny);
        for (e, ge) in g.iter_mut().enumerate() {
            *ge = C::new(gr[e][0], gi[e][0]);
        }
    }

    /// `G(s)` at a point of the complex plane (s for CT, z for DT). At a pole the value is
    /// whatever rounding makes of the division (a huge finite number, or a non-finite one):
    /// internal computations take limits through it (a type-2 loop's sensitivity at DC);
    /// [`FreqRespEvaluator::mark_poles`] turns the entries at a pole into `+∞` for a user.
    pub fn eval_at(&self, s: C) -> DMatrix<C> {
        if let Some((a, b, c)) = &self.dense {
            return match dense_solve(a, b, s) {
                Some(x) => c * x + &self.d,
                None => DMatrix::from_element(
                    self.d.nrows(),
                    self.d.ncols(),
                    C::new(f64::INFINITY, 0.0),
                ),
            };
        }
        let mut g = self.d.clone();
        let ny = g.nrows();
        if let Some(hf) = &self.hess {
            if !hf.accumulate(s, g.as_mut_slice(), ny) {
                g.fill(C::new(f64::INFINITY, 0.0));
            }
            return g;
        }
        self.accumulate(s, g.as_mut_slice(), ny);
        g
    }

    /// The entries of `flat` (as [`FreqRespEvaluator::eval_many_flat`] wrote them for
    /// `freq_hz`) at a pole of the model set to `+∞`: the point within `100·n·ε·max(|λ|, ‖T‖)`
    /// of a computed eigenvalue (a defective one's copies as their mean) and the mode reaching
    /// that entry's input and output (`pole_guard.rs`; an
    /// uncontrollable or unobservable mode's entry is evaluated around the point instead).
    /// Returns whether any point was at an eigenvalue.
    pub fn mark_poles(&self, freq_hz: &[f64], flat: &mut [C]) -> bool {
        let m = self.d.nrows() * self.d.ncols();
        if m == 0 {
            return false;
        }
        let mut any = false;
        for (o, &f) in flat.chunks_mut(m).zip(freq_hz) {
            any |= self.guarded(self.point(f), o);
        }
        any
    }

    /// Marks the entries of `g` at `s` that `s` is a pole of as `+∞`, and evaluates the others
    /// around an eigenvalue that is no pole of theirs (`pole_guard.rs`).
    fn guarded(&self, s: C, g: &mut [C]) -> bool {
        if self.guard.mark(s, g) == AtPole::No {
            return false;
        }
        let d = self.guard.circle(s);
        let around: Vec<DMatrix<C>> = [
            C::new(d, 0.0),
            C::new(0.0, d),
            C::new(-d, 0.0),
            C::new(0.0, -d),
        ]
        .iter()
        .map(|&o| self.eval_at(s + o))
        .collect();
        for (e, v) in g.iter_mut().enumerate() {
            if !v.re.is_infinite() {
                *v = around.iter().map(|m| m.as_slice()[e]).sum::<C>() / 4.0;
            }
        }
        true
    }

    /// The point of the complex plane for a frequency in Hz.
    pub fn point(&self, f_hz: f64) -> C {
        self.time.point(f_hz)
    }

    /// `G` at a frequency in Hz written column-major into `out` (length ny·nu), without
    /// allocating where the reduced form has simple poles only.
    pub fn eval_hz_into(&self, f_hz: f64, out: &mut [C]) {
        let s = self.point(f_hz);
        if self.dense.is_some() {
            let g = self.eval_at(s);
            out.copy_from_slice(g.as_slice());
            return;
        }
        if let Some(hf) = &self.hess {
            out.copy_from_slice(self.d.as_slice());
            if !hf.accumulate(s, out, self.d.nrows()) {
                out.fill(C::new(f64::INFINITY, 0.0));
            }
            return;
        }
        out.copy_from_slice(self.d.as_slice());
        self.accumulate(s, out, self.d.nrows());
    }

    /// `G` at a frequency in Hz.
    pub fn eval_hz(&self, f_hz: f64) -> DMatrix<C> {
        self.eval_at(self.point(f_hz))
    }

    /// `G` at many frequencies (parallel).
    pub fn eval_many(&self, freq_hz: &[f64]) -> Vec<DMatrix<C>> {
        let (ny, nu) = self.d.shape();
        let flat = self.eval_many_flat(freq_hz);
        if ny * nu == 0 {
            return vec![DMatrix::zeros(ny, nu); freq_hz.len()];
        }
        flat.par_chunks(ny * nu)
            .with_min_len(1024)
            .map(|g| DMatrix::from_column_slice(ny, nu, g))
            .collect()
    }

    /// Up to [`LANES`] frequencies of the block-diagonal path into `out` (their ny·nu entries
    /// each), all of them at once (one SIMD lane per point). `gr`, `gi`: work rows, one per
    /// entry.
    fn eval_batch(
        &self,
        f: &[f64],
        out: &mut [C],
        gr: &mut [[f64; LANES]],
        gi: &mut [[f64; LANES]],
    ) {
        let m = self.d.len();
        let (mut sr, mut si) = ([0.0; LANES], [0.0; LANES]);
        for l in 0..LANES {
            // a short last batch repeats its last point in the spare lanes
            let p = self.point(f[l.min(f.len() - 1)]);
            (sr[l], si[l]) = (p.re, p.im);
        }
        for (e, d) in self.d.iter().enumerate() {
            gr[e] = [d.re; LANES];
            gi[e] = [d.im; LANES];
        }
        self.poles.accumulate(&sr, &si, gr, gi);
        self.add_clusters(&sr, &si, gr, gi, self.d.nrows());
        for (l, o) in out.chunks_mut(m).enumerate() {
            for (e, oe) in o.iter_mut().enumerate() {
                *oe = C::new(gr[e][l], gi[e][l]);
            }
        }
    }

    /// Adds the clusters' share `Σ_b C̃_b (sI − T_b)⁻¹ B̃_b` at `L` points at once (one lane per
    /// point; rows `gr`/`gi` per entry, column-major ny×nu): per cluster the diagonal's
    /// reciprocals (one real division each), the back substitution per input column and the
    /// output product, in plain loops over the lanes. Work rows on the stack up to
    /// [`SMALL_CLUSTER`] poles, so the usual small clusters allocate nothing.
    fn add_clusters<const L: usize>(
        &self,
        sr: &[f64; L],
        si: &[f64; L],
        gr: &mut [[f64; L]],
        gi: &mut [[f64; L]],
        ny: usize,
    ) {
        for Cluster { t, b, c } in &self.clusters {
            let m = t.nrows();
            // x (real, imaginary) and the reciprocals (real, imaginary), m rows each
            let mut stack = [[0.0; L]; 4 * SMALL_CLUSTER];
            let mut heap = Vec::new();
            let buf: &mut [[f64; L]] = if m <= SMALL_CLUSTER {
                &mut stack[..4 * m]
            } else {
                heap.resize(4 * m, [0.0; L]);
                &mut heap
            };
            let (x, v) = buf.split_at_mut(2 * m);
            let (xr, xi) = x.split_at_mut(m);
            let (vr, vi) = v.split_at_mut(m);
            for i in 0..m {
                let (dr, di, inv) = offsets(sr, si, t[(i, i)]);
                for l in 0..L {
                    vr[i][l] = dr[l] * inv[l];
                    vi[i][l] = -di[l] * inv[l];
                }
            }
            for j in 0..b.ncols() {
                for i in (0..m).rev() {
                    let bij = b[(i, j)];
                    let (mut ar, mut ai) = ([bij.re; L], [bij.im; L]);
                    for k in (i + 1)..m {
                        let tik = t[(i, k)];
                        for l in 0..L {
                            ar[l] += tik.re * xr[k][l] - tik.im * xi[k][l];
                            ai[l] += tik.re * xi[k][l] + tik.im * xr[k][l];
                        }
                    }
                    for l in 0..L {
                        xr[i][l] = ar[l] * vr[i][l] - ai[l] * vi[i][l];
                        xi[i][l] = ar[l] * vi[i][l] + ai[l] * vr[i][l];
                    }
                }
                for r in 0..ny {
                    let e = j * ny + r;
                    for i in 0..m {
                        let cri = c[(r, i)];
                        for l in 0..L {
                            gr[e][l] += cri.re * xr[i][l] - cri.im * xi[i][l];
                            gi[e][l] += cri.re * xi[i][l] + cri.im * xr[i][l];
                        }
                    }
                }
            }
        }
    }

    /// `G` at many frequencies into one flat buffer (parallel): point `k`'s ny·nu entries at
    /// `k·ny·nu`, column-major as [`Self::eval_hz_into`]; no allocation per point.
    pub fn eval_many_flat(&self, freq_hz: &[f64]) -> Vec<C> {
        let m = self.d.nrows() * self.d.ncols();
        let mut out = vec![C::new(0.0, 0.0); freq_hz.len() * m];
        if m == 0 {
            return out;
        }
        if self.hess.is_some() || self.dense.is_some() {
            out.par_chunks_mut(m)
                .with_min_len(1024)
                .zip(freq_hz.par_iter())
                .for_each(|(o, &f)| self.eval_hz_into(f, o));
            return out;
        }
        out.par_chunks_mut(LANES * m)
            .zip(freq_hz.par_chunks(LANES))
            .with_min_len(256)
            .for_each_init(
                || (vec![[0.0; LANES]; m], vec![[0.0; LANES]; m]),
                |(gr, gi), (o, f)| self.eval_batch(f, o, gr, gi),
            );
        out
    }

    /// `(conjugate pairs, poles summed one by one)` among the simple poles (the pairs cost one
    /// division per point for two poles).
    pub fn pole_counts(&self) -> (usize, usize) {
        self.poles.counts()
    }

    /// Block sizes of the reduced form: 1 for each simple pole, then each cluster's size.
    pub fn block_sizes(&self) -> Vec<usize> {
        std::iter::repeat_n(1, self.poles.count())
            .chain(self.clusters.iter().map(|c| c.t.nrows()))
            .collect()
    }
}

fn check_freqs(freq_hz: &[f64]) -> Result<()> {
    if let Some(f) = freq_hz.iter().find(|f| !f.is_finite()) {
        return Err(ModelError::InvalidArgument(format!(
            "frequency {f} is not finite"
        )));
    }
    Ok(())
}

impl StateSpace {
    /// Frequency response at `freq_hz` (Hz) as an [`Frd`]. Discrete models are evaluated on
    /// the unit circle; frequencies above Nyquist are allowed here (the response is periodic)
    /// — the command line refuses them.
    ///
    /// # Errors
    /// A frequency that is a pole of the model (an integrator at 0 Hz, an undamped mode at its
    /// frequency: the response is infinite there, [`FreqRespEvaluator::eval_at`]).
    pub fn freqresp(&self, freq_hz: &[f64]) -> Result<Frd> {
        check_freqs(freq_hz)?;
        let ev = FreqRespEvaluator::new(self)?;
        let (ny, nu) = (self.ny(), self.nu());
        let mut flat = ev.eval_many_flat(freq_hz);
        ev.mark_poles(freq_hz, &mut flat);
        let m = (ny * nu).max(1);
        if let Some(k) = flat
            .iter()
            .position(|v| !(v.re.is_finite() && v.im.is_finite()))
            .map(|e| e / m)
        {
            return Err(ModelError::InvalidArgument(format!(
                "{} Hz is a pole of the model (its response is infinite there); leave that \
                 frequency out",
                freq_hz[k]
            )));
        }
        let g: Vec<DMatrix<C>> = if ny * nu == 0 {
            vec![DMatrix::zeros(ny, nu); freq_hz.len()]
        } else {
            flat.chunks(m)
                .map(|c| DMatrix::from_column_slice(ny, nu, c))
                .collect()
        };
        Frd::new(freq_hz.to_vec(), g, None, self.time())
    }

    /// `G(s)` at one point by a dense LU solve of `(sI − A) X = B` — the O(n³) reference.
    pub fn eval_direct(&self, s: C) -> Result<DMatrix<C>> {
        let n = self.n();
        if n == 0 {
            // a static gain (nalgebra's LU of a 0×0 matrix panics)
            return Ok(to_complex(self.d()));
        }
        // faer's blocked partial-pivoting LU: the evaluator's accuracy check makes up to
        // 2·(clusters + 64) of these references, the set-up cost that `cargo xtask bench`
        // reports as the scaling row `freqresp_setup`
        use faer::linalg::solvers::Solve;
        let (a, b) = (self.a(), self.b());
        let m = faer::Mat::<C>::from_fn(n, n, |i, j| {
            let v = C::new(-a[(i, j)], 0.0);
            if i == j {
                v + s
            } else {
                v
            }
        });
        let rhs = faer::Mat::<C>::from_fn(n, b.ncols(), |i, j| C::new(b[(i, j)], 0.0));
        let x = m.partial_piv_lu().solve(&rhs);
        let x = DMatrix::<C>::from_fn(n, b.ncols(), |i, j| x[(i, j)]);
        if x.iter().any(|v| !(v.re.is_finite() && v.im.is_finite())) {
            return Err(ModelError::Singular {
                what: format!("sI − A at s = {s} (a pole)"),
            });
        }
        Ok(to_complex(self.c()) * x + to_complex(self.d()))
    }
}

/// `(sI − A)⁻¹B` by faer's blocked partial-pivoting LU (nalgebra's unblocked one took 84 % of
/// an H∞ norm of a 128-state loop that needs this path); `None` at a pole (a non-finite
/// solution).
fn dense_solve(a: &DMatrix<C>, b: &DMatrix<C>, s: C) -> Option<DMatrix<C>> {
    use faer::linalg::solvers::Solve;
    let n = a.nrows();
    let m = faer::Mat::<C>::from_fn(n, n, |i, j| if i == j { s - a[(i, j)] } else { -a[(i, j)] });
    let rhs = faer::Mat::<C>::from_fn(n, b.ncols(), |i, j| b[(i, j)]);
    let x = m.partial_piv_lu().solve(&rhs);
    let x = DMatrix::<C>::from_fn(n, b.ncols(), |i, j| x[(i, j)]);
    x.iter()
        .all(|v| v.re.is_finite() && v.im.is_finite())
        .then_some(x)
}

/// A frequency grid: `n` points from `fmin` to `fmax` Hz, linear or logarithmic.
pub fn grid(fmin: f64, fmax: f64, n: usize, log: bool) -> Result<Vec<f64>> {
    if !(fmin.is_finite() && fmax.is_finite() && fmin <= fmax && fmin >= 0.0) || n == 0 {
        return Err(ModelError::InvalidArgument(format!(
            "grid {fmin}:{fmax}:{n} must have 0 <= FMIN <= FMAX and N >= 1"
        )));
    }
    if log && fmin <= 0.0 {
        return Err(ModelError::InvalidArgument(
            "a logarithmic grid needs FMIN > 0".into(),
        ));
    }
    if n == 1 {
        return Ok(vec![fmin]);
    }
    Ok((0..n)
        .map(|i| {
            let t = i as f64 / (n - 1) as f64;
            if log {
                (fmin.ln() + t * (fmax.ln() - fmin.ln())).exp()
            } else {
                fmin + t * (fmax - fmin)
            }
        })
        .collect())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// The Hessenberg path against dense LU solves on a random 12-state MIMO model.
    #[test]
    fn hessenberg_path_matches_dense_solves() {
        let n = 12;
        let mut seed = 7u64;
        let mut r = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let a = DMatrix::from_fn(n, n, |_, _| 0.4 * r());
        let b = DMatrix::from_fn(n, 2, |_, _| r());
        let c = DMatrix::from_fn(3, n, |_, _| r());
        let d = DMatrix::from_fn(3, 2, |_, _| r());
        let sys = StateSpace::new(a, b, c, d, SampleTime::discrete(1e-3).unwrap()).unwrap();
        // a static gain has nothing to reduce
        let gain = StateSpace::gain(
            DMatrix::from_element(1, 1, 2.0),
            SampleTime::discrete(1e-3).unwrap(),
        )
        .unwrap();
        let ev = FreqRespEvaluator::new(&gain).unwrap();
        assert_eq!(ev.eval_hz(10.0)[(0, 0)], C::new(2.0, 0.0));
        let hf = HessenbergForm::new(sys.a(), sys.b(), sys.c());
        for f in [1.0, 37.0, 250.0, 499.0] {
            let z = C::from_polar(1.0, 2.0 * std::f64::consts::PI * f * 1e-3);
            let reference = sys.eval_direct(z).unwrap();
            let mut g = to_complex(sys.d());
            assert!(hf.accumulate(z, g.as_mut_slice(), 3));
            let err = (g - &reference).norm() / reference.norm();
            assert!(err < 1e-12, "f {f}: {err}");
        }
    }
}
