//! H2 and H∞ norms.
//!
//! - **H2**: `‖G‖₂² = tr(C P Cᵀ)` (CT, D must be 0) or `tr(C P Cᵀ + D Dᵀ)` (DT) with P the
//!   controllability Gramian; the model must be stable.
//! - **H∞** (L∞ when there are no poles on the stability boundary): the level-set algorithm of
//!   Boyd & Balakrishnan (1990) / Bruinsma & Steinbuch (Syst. Control Lett. 14, 1990). For a level
//!   γ (not a singular value of D), the frequencies where a singular value of G(jω) equals γ
//!   are the imaginary eigenvalues of the Hamiltonian, with `R = DᵀD − γ²I`, `S = DDᵀ − γ²I`,
//!   `F = A − BR⁻¹DᵀC`: `H(γ) = [[F, −γBR⁻¹Bᵀ], [γCᵀS⁻¹C, −Fᵀ]]`, found as the negative real
//!   eigenvalues `μ = −ω²` of `H²` at half the order ([`crate::linalg::hamiltonian`]: the QR
//!   iteration runs on order n instead of 2n; a μ too close to zero for √μ to be resolved
//!   gives a bracket from ω = 0); the level rises to the largest σ_max at the midpoints of those intervals until no crossing remains. The lower bound starts from the
//!   poles' frequencies and a grid; the final peak is polished by golden-section search, and the
//!   result is always a value actually attained at the reported peak frequency (tests: 5e-15
//!   relative to the closed form of a resonance; DT within 1e-8 of a dense local search). Discrete models are mapped exactly to continuous ones by the bilinear map
//!   `z = (1 + s)/(1 − s)` (H∞ norm invariant; ωh = 2 atan ν).

use crate::error::{ModelError, Result};
use crate::freqresp::{check_point, HessenbergForm};
use crate::linalg::expm::norm1;
use crate::linalg::hamiltonian::hamiltonian_squared_eigenvalues;
use crate::linalg::lyap::{lyap, LyapKind};
use crate::pole_sum::PoleSum;
use crate::ss::StateSpace;
use crate::time::SampleTime;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use rayon::prelude::*;
use std::f64::consts::PI;

/// The H∞ (or L∞) norm with its peak frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HinfNorm {
    /// `sup_ω σ_max(G(jω))` (infinite with a pole on the boundary).
    pub value: f64,
    /// Frequency of the peak in Hz (for DT in [0, Nyquist]).
    pub peak_hz: f64,
    /// True when every pole is strictly stable (then this is the H∞ norm, else the L∞ norm).
    pub stable: bool,
}

fn sigma_max(g: &DMatrix<C>) -> f64 {
    if g.nrows() == 1 && g.ncols() == 1 {
        return g[(0, 0)].norm();
    }
    g.clone()
        .singular_values()
        .iter()
        .cloned()
        .fold(0.0, f64::max)
}

impl StateSpace {
    /// H2 norm (stable models; a continuous model needs D = 0).
    pub fn h2_norm(&self) -> Result<f64> {
        let kind = if self.time().is_continuous() {
            LyapKind::Continuous
        } else {
            LyapKind::Discrete
        };
        for p in self.poles()? {
            let bad = if kind == LyapKind::Continuous {
                p.re >= 0.0
            } else {
                p.norm() >= 1.0
            };
            if bad {
                return Err(ModelError::Unstable {
                    operation: "the H2 norm".into(),
                    detail: format!("pole {p} (the norm is infinite)"),
                });
            }
        }
        if kind == LyapKind::Continuous && self.d().iter().any(|v| *v != 0.0) {
            return Err(ModelError::InvalidArgument(
                "the H2 norm of a continuous model with D ≠ 0 is infinite".into(),
            ));
        }
        // balanced states: the Gramian of a badly scaled realization (entries decades apart)
        // has huge entries in directions C does not see, and C·P·Cᵀ then cancels to noise
        let bal = self.balance_states()?;
        let p = lyap(bal.a(), &(bal.b() * bal.b().transpose()), kind)?;
        let mut m = bal.c() * p * bal.c().transpose();
        if kind == LyapKind::Discrete {
            m += bal.d() * bal.d().transpose();
        }
        Ok(m.trace().max(0.0).sqrt())
    }

    /// H∞ norm and its peak frequency (L∞ for unstable models without boundary poles).
    pub fn hinf_norm(&self) -> Result<HinfNorm> {
        // one eigendecomposition gives the poles and the basis σ_max is evaluated in
        let eig = Eigen::of(self.a());
        let poles = match &eig {
            Some(e) => e.lam.clone(),
            None => self.poles()?,
        };
        let scale = norm1(self.a()).max(1.0);
        let (on_boundary, stable, h) = match self.time() {
            SampleTime::Continuous => (
                poles.iter().find(|p| p.re.abs() <= 1e-12 * scale),
                poles.iter().all(|p| p.re < 0.0),
                None,
            ),
            SampleTime::Discrete { ts } => (
                poles.iter().find(|p| (p.norm() - 1.0).abs() <= 1e-12),
                poles.iter().all(|p| p.norm() < 1.0),
                Some(ts),
            ),
        };
        if let Some(p) = on_boundary {
            let f = match h {
                None => p.im.abs() / (2.0 * PI),
                Some(ts) => p.arg().abs() / (2.0 * PI * ts),
            };
            return Ok(HinfNorm {
                value: f64::INFINITY,
                peak_hz: f,
                stable: false,
            });
        }
        // σ̄ is evaluated on the model itself, in its own domain (a discrete one at
        // z = (1 + jω)/(1 − jω)); the bilinear image serves only the Hamiltonian test
        let modal = eig.and_then(|e| Modal::new(self, &e, poles.clone()));
        let (ct, ct_poles) = match h {
            None => (self.clone(), poles),
            // the bilinear map sends each pole z to s = (z − 1)/(z + 1) (candidates only)
            Some(_) => (
                bilinear_to_ct(self)?,
                poles.iter().map(|z| (z - 1.0) / (z + 1.0)).collect(),
            ),
        };
        let (val, w) = hinf_ct(&ct, &ct_poles, self, modal)?;
        let peak_hz = match h {
            None => w / (2.0 * PI),
            Some(ts) => 2.0 * w.atan() / (2.0 * PI * ts),
        };
        Ok(HinfNorm {
            value: val,
            peak_hz,
            stable,
        })
    }
}

/// Exact bilinear map of a DT model to CT with `G_c(s) = G_d((1+s)/(1−s))`.
fn bilinear_to_ct(sys: &StateSpace) -> Result<StateSpace> {
    let n = sys.n();
    let ip = sys.a() + DMatrix::<f64>::identity(n, n);
    let inv = ip.try_inverse().ok_or_else(|| ModelError::Singular {
        what: "A + I (a pole at z = −1, the Nyquist frequency): the norm there is infinite".into(),
    })?;
    let s2 = 2f64.sqrt();
    let ac = &inv * (sys.a() - DMatrix::<f64>::identity(n, n));
    let bc = &inv * sys.b() * s2;
    let cc = sys.c() * &inv * s2;
    let dc = sys.d() - sys.c() * &inv * sys.b();
    StateSpace::new(ac, bc, cc, dc, SampleTime::Continuous)
}

/// (norm, peak ω in rad/s) of a CT model without imaginary-axis poles, given its poles; `own`
/// is the model whose norm is sought, in its own domain: `ct` itself, or the discrete model
/// whose bilinear image `ct` is.
///
/// σ_max at ω is evaluated on `own` at [`own_point`] — for a discrete model at
/// `z = (1 + jω)/(1 − jω)`, never on the bilinear image: that image's A is as large as the
/// discrete poles are close to z = −1 (‖A‖_F = 1.6·10⁷ for a 128-state H∞ loop at 1 kHz,
/// against 4.7·10⁴ for its discrete A), and dense solves of `jωI − A` near DC then lose digits that the
/// discrete solves keep (`tests/tests/hinf_norm_reference.rs` prints both errors against
/// 30-digit arithmetic and requires the image's to be the larger by 100×; the norm came out
/// too high there, at a frequency near DC instead of the peak). The image serves the
/// Hamiltonian level-set test only.
///
/// The search runs on a fast evaluation: the eigenvector basis ([`Modal`]) when that basis
/// passes its accuracy check, else the Hessenberg form of the balanced model (O(n²) per
/// point, backward stable, but an orthogonal reduction moves a nearly defective pole pair by
/// about √ε, so the response next to it can lose digits that dense solves of the model's own
/// matrices keep). Its result is accepted when a dense solve at the peak agrees with it
/// within [`FAST_AGREE`]: the level-set step ended where the Hamiltonian, which does not
/// depend on the evaluation, showed no crossing `2·10⁻¹²` above the fast value (or where the
/// polishes between its crossings found nothing higher), and the dense value is attained.
/// Otherwise the dense solves take over from that peak ([`level_set`] with dense σ̄, which
/// searches every interval the Hamiltonian test leaves above the level, wherever the fast
/// form erred).
fn hinf_ct(
    sys: &StateSpace,
    poles: &[C],
    own: &StateSpace,
    modal: Option<Modal>,
) -> Result<(f64, f64)> {
    let time = own.time();
    let dense = |w: f64| match own.eval_direct(own_point(time, w)) {
        // a failed solve (a point at a pole) leaves the lower bound where it was
        Ok(g) => sigma_max(&g),
        Err(_) => 0.0,
    };
    match modal {
        Some(m) => {
            let fast = |w: f64| sigma_max(&m.eval(own_point(time, w)));
            checked_search(sys, poles, &fast, &dense)
        }
        None => {
            let hess = HessenbergForm::of_model(own);
            let d = crate::linalg::schur::to_complex(own.d());
            let fast = |w: f64| match hess.eval(own_point(time, w), &d) {
                Some(g) => sigma_max(&g),
                None => 0.0,
            };
            checked_search(sys, poles, &fast, &dense)
        }
    }
}

/// The level-set search on the fast σ̄ `fast`, its peak checked by the reference σ̄ `dense`:
/// the reference value when the two agree within [`FAST_AGREE`], else the level-set search
/// continued on reference values from there ([`hinf_ct`]).
fn checked_search(
    sys: &StateSpace,
    poles: &[C],
    fast: &(impl Fn(f64) -> f64 + Sync),
    dense: &(impl Fn(f64) -> f64 + Sync),
) -> Result<(f64, f64)> {
    let (v, w) = hinf_search(sys, poles, fast)?;
    if !w.is_finite() {
        return Ok((v, w));
    }
    let vd = dense(w);
    if (vd - v).abs() <= FAST_AGREE * vd {
        return Ok((vd, w));
    }
    level_set(sys, dense, (vd, w))
}

/// The point of `time`'s domain at the bilinear-domain frequency ω: `jω` (continuous) or
/// `z = (1 + jω)/(1 − jω)` (discrete; |z| = 1, arg z = 2·atan ω).
fn own_point(time: SampleTime, w: f64) -> C {
    match time {
        SampleTime::Continuous => C::new(0.0, w),
        SampleTime::Discrete { .. } => C::from_polar(1.0, 2.0 * w.atan()),
    }
}

/// Relative agreement required of the eigenvector basis with dense solves at its check points,
/// and of the fast evaluation with a dense solve at the peak it found.
const FAST_AGREE: f64 = 1e-9;

/// `G(s) = D + Σ_k (C v_k)(w_kᵀ B)/(s − λ_k)` from `A = V Λ V⁻¹` (faer's eigendecomposition of
/// the diagonally balanced A; O(n³) once, O(n·ny·nu) per point). Accurate when V is well
/// conditioned; checked against dense solves next to the 8 poles with the largest eigenvalue
/// condition `‖v_k‖‖w_k‖` and the 8 nearest the stability boundary. In the model's own
/// domain (s or z).
/// The sum runs through [`PoleSum`], as the frequency-response evaluator's does.
struct Modal {
    lam: Vec<C>,
    poles: PoleSum,
    d: DMatrix<C>,
}

/// `D⁻¹AD = VΛV⁻¹` for the diagonal balancing D of A (faer's eigendecomposition, V⁻¹ by LU).
struct Eigen {
    lam: Vec<C>,
    v: faer::Mat<C>,
    vinv: faer::Mat<C>,
    dv: Vec<f64>,
}

impl Eigen {
    /// `None` for an empty matrix or when the decomposition fails.
    fn of(a: &DMatrix<f64>) -> Option<Self> {
        use faer::linalg::solvers::Solve;
        let n = a.nrows();
        if n == 0 {
            return None;
        }
        let (ab, dv) = crate::linalg::expm::balance_diag(a);
        let e = crate::linalg::convert::to_faer(&ab).eigen().ok()?;
        let v = e.U().to_owned();
        let lam: Vec<C> = (0..n).map(|i| e.S()[i]).collect();
        let vinv = v.partial_piv_lu().solve(faer::Mat::<C>::identity(n, n));
        Some(Eigen { lam, v, vinv, dv })
    }
}

impl Modal {
    /// The basis of `e` (an eigendecomposition of `sys`'s A, or of a matrix with the same
    /// eigenvectors) with `sys`'s eigenvalues `lam`; `None` when it fails its check.
    fn new(sys: &StateSpace, e: &Eigen, lam: Vec<C>) -> Option<Self> {
        let n = sys.n();
        let (v, vinv, dv) = (&e.v, &e.vinv, &e.dv);
        let (ny, nu) = (sys.ny(), sys.nu());
        let cv = DMatrix::from_fn(ny, n, |r, k| {
            (0..n)
                .map(|i| v[(i, k)] * (sys.c()[(r, i)] * dv[i]))
                .sum::<C>()
        });
        let wb = DMatrix::from_fn(n, nu, |k, j| {
            (0..n)
                .map(|i| vinv[(k, i)] * (sys.b()[(i, j)] / dv[i]))
                .sum::<C>()
        });
        if cv
            .iter()
            .chain(wb.iter())
            .any(|z| !(z.re.is_finite() && z.im.is_finite()))
        {
            return None;
        }
        // residues R_k = (C v_k)(w_kᵀ B), entry e = j·ny + i at [e·n + k]
        let mut r = vec![C::new(0.0, 0.0); n * ny * nu];
        for k in 0..n {
            for j in 0..nu {
                for i in 0..ny {
                    r[(j * ny + i) * n + k] = cv[(i, k)] * wb[(k, j)];
                }
            }
        }
        let m = Modal {
            poles: PoleSum::new(&lam, &r, ny * nu),
            lam,
            d: crate::linalg::schur::to_complex(sys.d()),
        };
        let cond: Vec<f64> = (0..n)
            .map(|k| {
                let vk: f64 = (0..n).map(|i| v[(i, k)].norm_sqr()).sum();
                let wk: f64 = (0..n).map(|i| vinv[(k, i)].norm_sqr()).sum();
                (vk * wk).sqrt()
            })
            .collect();
        let mut by_cond: Vec<usize> = (0..n).collect();
        by_cond.sort_by(|&a, &b| cond[b].total_cmp(&cond[a]));
        let mut by_axis: Vec<usize> = (0..n).collect();
        let time = sys.time();
        let margin = |z: C| match time {
            SampleTime::Continuous => z.re.abs(),
            SampleTime::Discrete { .. } => (1.0 - z.norm()).abs(),
        };
        by_axis.sort_by(|&a, &b| margin(m.lam[a]).total_cmp(&margin(m.lam[b])));
        // the 16 dense solves (most of this check's time) on every core
        let checks: Vec<usize> = by_cond
            .iter()
            .take(8)
            .chain(by_axis.iter().take(8))
            .copied()
            .collect();
        let ok = checks.into_par_iter().all(|k| {
            let s = check_point(time, m.lam[k], 1e-3);
            match sys.eval_direct(s) {
                Ok(g) => {
                    let gn = g.norm();
                    (m.eval(s) - &g).norm() <= FAST_AGREE * gn
                }
                Err(_) => false,
            }
        });
        ok.then_some(m)
    }

    fn eval(&self, s: C) -> DMatrix<C> {
        let mut gr: Vec<[f64; 1]> = self.d.iter().map(|z| [z.re]).collect();
        let mut gi: Vec<[f64; 1]> = self.d.iter().map(|z| [z.im]).collect();
        self.poles.accumulate(&[s.re], &[s.im], &mut gr, &mut gi);
        DMatrix::from_fn(self.d.nrows(), self.d.ncols(), |i, j| {
            let e = j * self.d.nrows() + i;
            C::new(gr[e][0], gi[e][0])
        })
    }
}

/// The level-set search for the peak of `sig` (σ_max at ω) of a CT model with poles `poles`.
///
/// The grid and the polishes between the crossings of one level are independent: they run on
/// every core (an H∞-optimal closed loop is nearly flat, with many crossings per level).
fn hinf_search(
    sys: &StateSpace,
    poles: &[C],
    sig: &(impl Fn(f64) -> f64 + Sync),
) -> Result<(f64, f64)> {
    let n = sys.n();
    let dmax = sigma_max(&crate::linalg::schur::to_complex(sys.d()));
    if n == 0 {
        return Ok((dmax, 0.0));
    }
    // Initial lower bound: ω = 0, the poles' natural frequencies, and a log grid.
    let mut best = (sig(0.0), 0.0);
    let mut cands: Vec<f64> = poles
        .iter()
        .map(|p| p.norm())
        .filter(|w| *w > 0.0)
        .collect();
    cands.extend(poles.iter().map(|p| p.im.abs()).filter(|w| *w > 0.0));
    let (wlo, whi) = cands
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &w| (a.min(w), b.max(w)));
    if wlo.is_finite() {
        let m = 400;
        for i in 0..m {
            let t = i as f64 / (m - 1) as f64;
            cands.push(
                (wlo * 0.01)
                    .ln()
                    .mul_add(1.0 - t, (whi * 100.0).ln() * t)
                    .exp(),
            );
        }
    }
    cands.sort_by(f64::total_cmp);
    let vals: Vec<f64> = cands.par_iter().map(|&w| sig(w)).collect();
    let mut at = None;
    for (i, (&w, &v)) in cands.iter().zip(&vals).enumerate() {
        if v > best.0 {
            best = (v, w);
            at = Some(i);
        }
    }
    // The grid's best point polished first, between its neighbours: the level set at the
    // polished value then usually has no crossing (one Hamiltonian eigenvalue problem of order
    // 2n instead of several).
    if let Some(i) = at {
        let lo = cands[i.saturating_sub(1)];
        let hi = cands.get(i + 1).copied().unwrap_or(cands[i] * 1.001);
        polish(sig, &mut best, lo, hi);
    }
    if dmax > best.0 {
        best = (dmax, f64::INFINITY);
    }
    level_set(sys, sig, best)
}

/// The level-set iterations from the lower bound `best = (σ̄, ω)`: the level rises to the
/// largest σ̄ between the Hamiltonian's crossings until none remains, then the peak is
/// polished (module documentation).
fn level_set(
    sys: &StateSpace,
    sig: &(impl Fn(f64) -> f64 + Sync),
    mut best: (f64, f64),
) -> Result<(f64, f64)> {
    let tol = 1e-12;
    for _iter in 0..60 {
        let gamma = best.0 * (1.0 + 2.0 * tol);
        let ws = imaginary_crossings(sys, gamma)?;
        if ws.len() < 2 {
            break;
        }
        // the peak between each two crossings (the midpoint, polished), so that the next
        // level usually certifies it. Between two consecutive crossings σ̄ − γ keeps its sign
        // (every frequency where a singular value equals γ is a crossing), so an interval
        // whose midpoint is not above γ holds no higher peak and is not polished: a nearly
        // flat H∞-optimal loop has dozens of crossings at a level just above its peak, half
        // of them bounding intervals below it (the polishes were most of such a norm's time)
        let found: Vec<(f64, f64)> = ws
            .par_windows(2)
            .filter_map(|pair| {
                let m = 0.5 * (pair[0] + pair[1]);
                let mut here = (sig(m), m);
                if here.0.partial_cmp(&gamma) != Some(std::cmp::Ordering::Greater) {
                    return (here.0 > best.0).then_some(here);
                }
                polish(sig, &mut here, pair[0], pair[1]);
                Some(here)
            })
            .collect();
        let before = best.0;
        for f in found {
            if f.0 > best.0 {
                best = f;
            }
        }
        if best.0 <= before {
            break;
        }
    }
    if best.1.is_finite() && best.1 > 0.0 {
        let w = best.1;
        polish(sig, &mut best, w * (1.0 - 1e-3), w * (1.0 + 1e-3));
    }
    let w = if best.1.is_finite() {
        best.1
    } else {
        f64::INFINITY
    };
    Ok((best.0, w))
}

/// Raises `best = (σ, ω)` to the golden-section maximum of σ on `[lo, hi]` when higher. The
/// bracket is shrunk to `1e-10·hi` (at most 80 steps): a smooth peak's value is then exact to
/// rounding for any peak wider than `1e-3·ω`, and the level-set step certifies what the
/// polish leaves (where the evaluation itself is ill-conditioned — a flat peak next to a
/// defective pole at the boundary — the value is as good as the evaluations, not better).
fn polish(sig: &impl Fn(f64) -> f64, best: &mut (f64, f64), lo: f64, hi: f64) {
    if lo.is_finite() && hi.is_finite() && hi > lo {
        let shrink = (1e-10 * hi / (hi - lo)).clamp(1e-17, 1.0);
        let steps = (shrink.ln() / 0.618_033_988_749_895f64.ln()).ceil() as usize;
        let (x, f) = crate::linalg::golden_min(|x| -sig(x), lo, hi, steps.clamp(8, 80));
        if -f > best.0 {
            *best = (-f, x);
        }
    }
}

/// Frequencies ω ≥ 0 where σ(G(jω)) = γ: imaginary eigenvalues of the Hamiltonian.
///
/// From the squares `μ = λ²` of its eigenvalues at half the order
/// ([`hamiltonian_squared_eigenvalues`]): a crossing `λ = jω` is a negative real μ. A μ within
/// its error of the negative real axis counts too (two crossings the rounding merged into a
/// complex pair `μ, μ̄`: both ends `ω² = −Re μ ± |Im μ|` are returned, so the level-set step
/// looks between them). A μ within 1000 times its error of zero leaves `λ = √μ` unresolved:
/// the frequencies it could cross at, `[0, √(|μ| + 1000·error)]`, are returned as a bracket.
/// A spurious crossing costs the level-set step one σ evaluation and a polish; a missed one
/// would cost accuracy.
fn imaginary_crossings(sys: &StateSpace, gamma: f64) -> Result<Vec<f64>> {
    let (a11, a12, a21) = hamiltonian_blocks(sys, gamma)?;
    let sq = hamiltonian_squared_eigenvalues(&a11, &a12, &a21)?;
    let e = sq.mu_error();
    let unresolved = 1e3 * e;
    let mut ws = Vec::new();
    for m in &sq.mu {
        if m.norm() <= unresolved {
            ws.push(0.0);
            ws.push((m.norm() + unresolved).sqrt());
            continue;
        }
        if m.re >= 0.0 || m.im.abs() > (2e-8 * m.norm()).max(e) {
            continue;
        }
        ws.push((-m.re - m.im.abs()).max(0.0).sqrt());
        ws.push((-m.re + m.im.abs()).sqrt());
    }
    Ok(sorted_unique(ws))
}

/// `(F, G, Q)` of the Hamiltonian `[[F, G], [Q, −Fᵀ]]` at level γ (module documentation).
fn hamiltonian_blocks(
    sys: &StateSpace,
    gamma: f64,
) -> Result<(DMatrix<f64>, DMatrix<f64>, DMatrix<f64>)> {
    let (a, b, c, d) = (sys.a(), sys.b(), sys.c(), sys.d());
    let (ny, nu) = (sys.ny(), sys.nu());
    let r = d.transpose() * d - DMatrix::<f64>::identity(nu, nu) * gamma * gamma;
    let s = d * d.transpose() - DMatrix::<f64>::identity(ny, ny) * gamma * gamma;
    let ri = r.try_inverse().ok_or_else(|| ModelError::Singular {
        what: "DᵀD − γ²I in the H∞ Hamiltonian".into(),
    })?;
    let si = s.try_inverse().ok_or_else(|| ModelError::Singular {
        what: "DDᵀ − γ²I in the H∞ Hamiltonian".into(),
    })?;
    let a11 = a - b * &ri * d.transpose() * c;
    let a12 = -(b * &ri * b.transpose()) * gamma;
    let a21 = c.transpose() * &si * c * gamma;
    Ok((a11, a12, a21))
}

/// The crossings from the eigenvalues of the 2n×2n Hamiltonian: those within `10⁻⁸|λ|` of
/// the imaginary axis (an absolute floor of `10⁻¹⁴‖H‖₁` near zero). The method before
/// [`imaginary_crossings`]; kept as its reference in the tests.
#[cfg(test)]
fn direct_crossings(
    a11: &DMatrix<f64>,
    a12: &DMatrix<f64>,
    a21: &DMatrix<f64>,
) -> Result<Vec<f64>> {
    use crate::linalg::convert::eigenvalues;
    let n = a11.nrows();
    let mut h = DMatrix::zeros(2 * n, 2 * n);
    h.view_mut((0, 0), (n, n)).copy_from(a11);
    h.view_mut((0, n), (n, n)).copy_from(a12);
    h.view_mut((n, 0), (n, n)).copy_from(a21);
    h.view_mut((n, n), (n, n)).copy_from(&(-a11.transpose()));
    let ev = eigenvalues(&h)?;
    let scale = norm1(&h).max(1.0);
    let ws: Vec<f64> = ev
        .iter()
        .filter(|z| z.im >= 0.0 && z.re.abs() <= 1e-8 * z.norm().max(1e-6 * scale))
        .map(|z| z.im)
        .collect();
    Ok(sorted_unique(ws))
}

/// Sorted, with values within `10⁻¹²` (relative) merged.
fn sorted_unique(mut ws: Vec<f64>) -> Vec<f64> {
    ws.sort_by(f64::total_cmp);
    ws.dedup_by(|x, y| (*x - *y).abs() <= 1e-12 * y.abs().max(1.0));
    ws
}

#[cfg(test)]
mod tests {
    use super::*;

    fn resonance(zeta: f64, w: f64) -> StateSpace {
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * zeta * w]);
        let b = DMatrix::from_row_slice(2, 1, &[0.0, w * w]);
        let c = DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
        StateSpace::new(a, b, c, DMatrix::zeros(1, 1), SampleTime::Continuous)
            .unwrap_or_else(|e| panic!("{e}"))
    }

    /// Below the peak of a resonance (ζ = 0.05, ω = 3 rad/s; peak 1/(2ζ√(1−ζ²))), the crossings
    /// from the squared eigenvalues are the two frequencies where |G(jω)| = γ in closed form,
    /// and agree with those from H's own eigenvalues.
    #[test]
    fn crossings_from_the_square_match_the_closed_form() {
        let (zeta, w) = (0.05, 3.0);
        let sys = resonance(zeta, w);
        let peak = 1.0 / (2.0 * zeta * (1.0 - zeta * zeta).sqrt());
        let gamma = 0.8 * peak;
        // |G|² = w⁴ / ((w² − ω²)² + 4ζ²w²ω²) = γ²: a quadratic in x = ω²
        let (a2, a1, a0) = (
            1.0,
            -2.0 * w * w + 4.0 * zeta * zeta * w * w,
            w.powi(4) - w.powi(4) / (gamma * gamma),
        );
        let disc = (a1 * a1 - 4.0 * a2 * a0).sqrt();
        let exact = [((-a1 - disc) / 2.0).sqrt(), ((-a1 + disc) / 2.0).sqrt()];
        let ws = imaginary_crossings(&sys, gamma).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(ws.len(), 2, "{ws:?}");
        for (x, y) in ws.iter().zip(exact) {
            assert!((x - y).abs() <= 1e-12 * y, "{x} vs {y}");
        }
        let (f, g, q) = hamiltonian_blocks(&sys, gamma).unwrap_or_else(|e| panic!("{e}"));
        let direct = direct_crossings(&f, &g, &q).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(direct.len(), 2);
        for (x, y) in ws.iter().zip(&direct) {
            assert!((x - y).abs() <= 1e-12 * y, "{x} vs {y}");
        }
    }

    /// A low-pass peaks at ω = 0: at a level just above it μ is near zero, the crossings are
    /// bracketed from 0, and the norm is the DC gain.
    #[test]
    fn a_peak_at_zero_frequency_is_bracketed() {
        let sys = StateSpace::new(
            DMatrix::from_element(1, 1, -2.0),
            DMatrix::from_element(1, 1, 3.0),
            DMatrix::from_element(1, 1, 1.0),
            DMatrix::zeros(1, 1),
            SampleTime::Continuous,
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let (f, g, q) =
            hamiltonian_blocks(&sys, 1.5 * (1.0 + 1e-12)).unwrap_or_else(|e| panic!("{e}"));
        let sq = hamiltonian_squared_eigenvalues(&f, &g, &q).unwrap_or_else(|e| panic!("{e}"));
        assert!(sq.mu.iter().any(|m| m.norm() <= 1e3 * sq.mu_error()));
        let ws = imaginary_crossings(&sys, 1.5 * (1.0 + 1e-12)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(ws.first(), Some(&0.0), "{ws:?}");
        let n = sys.hinf_norm().unwrap_or_else(|e| panic!("{e}"));
        assert!((n.value - 1.5).abs() <= 1e-14 * 1.5, "{}", n.value);
    }

    /// On 30 seeded random stable 2×2 systems (n = 4…40, D ≠ 0 for half of them) at 0.3, 0.6
    /// and 0.9 of their norm, the crossings from the squared eigenvalues and those from H's own
    /// eigenvalues agree: the same count, each within 10⁻⁸ relative.
    #[test]
    fn square_and_direct_crossings_agree_on_random_systems() {
        use crate::linalg::convert::eigenvalues;
        use crate::linalg::schur::tests::rand_mat;
        for seed in 0..30u64 {
            let n = 4 + (seed as usize * 7) % 37;
            let r = rand_mat(n, 100 + seed);
            let shift = eigenvalues(&r)
                .unwrap_or_else(|e| panic!("{e}"))
                .iter()
                .map(|z| z.re)
                .fold(f64::NEG_INFINITY, f64::max);
            let a = &r - DMatrix::<f64>::identity(n, n) * (shift + 0.05);
            let b = rand_mat(n, 200 + seed).columns(0, 2).into_owned();
            let c = rand_mat(n, 300 + seed).rows(0, 2).into_owned();
            let d = rand_mat(2, 400 + seed) * if seed % 2 == 0 { 0.0 } else { 0.1 };
            let sys = StateSpace::new(a, b, c, d, SampleTime::Continuous)
                .unwrap_or_else(|e| panic!("{e}"));
            let norm = sys.hinf_norm().unwrap_or_else(|e| panic!("{e}")).value;
            for frac in [0.3, 0.6, 0.9] {
                let gamma = frac * norm;
                let ws = imaginary_crossings(&sys, gamma).unwrap_or_else(|e| panic!("{e}"));
                let (f, g, q) = hamiltonian_blocks(&sys, gamma).unwrap_or_else(|e| panic!("{e}"));
                let direct = direct_crossings(&f, &g, &q).unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(
                    ws.len(),
                    direct.len(),
                    "seed {seed}, {frac}: {ws:?} vs {direct:?}"
                );
                for (x, y) in ws.iter().zip(&direct) {
                    assert!(
                        (x - y).abs() <= 1e-8 * y.abs().max(1e-3),
                        "seed {seed}: {x} vs {y}"
                    );
                }
            }
        }
    }

    /// The fast evaluation decides nothing alone: given one that is wrong (a bump of 10 % near
    /// the lower of two resonance peaks, so that it ranks them the wrong way round, or 10⁻⁶ low
    /// everywhere), the dense check at its peak disagrees and the level-set search on dense
    /// values finds the true norm — the higher resonance's peak near 1 rad/s, polished on
    /// dense values by golden section — to 10⁻¹² relative, at its frequency.
    #[test]
    fn a_wrong_fast_evaluation_is_overruled_by_dense_values() {
        let hi = resonance(0.05, 1.0);
        let lo = resonance(0.052, 5.0);
        let sys = crate::connect::parallel(&hi, &lo).unwrap_or_else(|e| panic!("{e}"));
        let poles = sys.poles().unwrap_or_else(|e| panic!("{e}"));
        let dense = |w: f64| sigma_max(&sys.eval_direct(C::new(0.0, w)).unwrap());
        let bumped = |w: f64| dense(w) * (1.0 + 0.1 * (-((w - 5.0) / 0.2).powi(2)).exp());
        let low = |w: f64| dense(w) * (1.0 - 1e-6);
        // the resonance at 1 rad/s, the other one's tail included: polished densely
        let mut truth = (dense(1.0), 1.0);
        polish(&dense, &mut truth, 0.9, 1.1);
        let wrong = hinf_search(&sys, &poles, &bumped).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            wrong.1 > 4.0,
            "the bump must mislead the fast search: {wrong:?}"
        );
        for (name, (v, w)) in [
            ("bumped", checked_search(&sys, &poles, &bumped, &dense)),
            ("low", checked_search(&sys, &poles, &low, &dense)),
        ]
        .map(|(n, r)| (n, r.unwrap_or_else(|e| panic!("{e}"))))
        {
            assert!(
                (v - truth.0).abs() <= 1e-12 * truth.0 && (w - truth.1).abs() <= 1e-3,
                "{name}: {v} at {w} vs {truth:?}"
            );
            assert_eq!(v, dense(w), "{name}");
        }
    }
}
