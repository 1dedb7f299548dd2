//! Minimal realisation, stable/unstable splitting and balanced truncation.
//!
//! - **Minimal realisation**: orthogonal staircase (Varga, "Minimal realization procedures based
//!   on balancing and related techniques", 1991; Van Dooren 1981): the controllable subspace is
//!   built block by block from SVDs of `B` and the sub-diagonal blocks of A, with rank decisions
//!   at `tol = n·ε·max(‖A‖₁, ‖B‖₁, ‖C‖₁)` unless given; the same on the dual removes unobservable
//!   states. All transformations are orthogonal.
//! - **Stable/unstable split**: complex Schur form reordered so the unstable (or marginal) poles
//!   come first, decoupled by one Sylvester equation; the two invariant subspaces get real
//!   orthonormal bases (from the real and imaginary parts of their complex bases), so both parts
//!   are real models and `G = G_unstable + G_stable`.
//! - **Balanced truncation** (Moore 1981; square-root method of Tombs & Sreeram 1987 / Laub et
//!   al. 1987): Gramians from the Lyapunov equations (CT: `AP + PAᵀ + BBᵀ = 0`,
//!   DT: `APAᵀ − P + BBᵀ = 0`, and duals), factors `P = RRᵀ`, `Q = LLᵀ` from symmetric
//!   eigendecompositions, SVD `LᵀR = UΣVᵀ`, projection `T_l = Σ_r^{-1/2}U_rᵀLᵀ`,
//!   `T_r = RV_rΣ_r^{-1/2}`. Hankel singular values σ_i = Σ; a priori bound
//!   `‖G − G_r‖∞ ≤ 2 Σ_{i>r} σ_i` for stable G (CT and DT).

use crate::error::{ModelError, Result};
use crate::linalg::convert::svd;
use crate::linalg::expm::norm1;
use crate::linalg::lyap::{lyap, LyapKind};
use crate::linalg::schur::{complex_schur, swap_adjacent, to_complex, triangular_sylvester};
use crate::ss::StateSpace;
use crate::time::SampleTime;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// Result of a balanced truncation.
#[derive(Debug, Clone)]
pub struct BalancedTruncation {
    /// The reduced model.
    pub model: StateSpace,
    /// Hankel singular values of the stable part, descending.
    pub hankel_sv: Vec<f64>,
    /// `2 Σ` of the discarded Hankel singular values: the a priori ‖G − G_r‖∞ bound.
    pub error_bound: f64,
    /// States kept unreduced because their poles are unstable or marginal.
    pub n_unstable: usize,
}

fn keep_leading(sys: &StateSpace, k: usize) -> Result<StateSpace> {
    StateSpace::new(
        sys.a().view((0, 0), (k, k)).into_owned(),
        sys.b().rows(0, k).into_owned(),
        sys.c().columns(0, k).into_owned(),
        sys.d().clone(),
        sys.time(),
    )
}

/// Keeps the controllable part (orthogonal staircase). Returns the transformed model whose
/// leading `k` states are controllable, and k.
fn controllable_staircase(sys: &StateSpace, tol: f64) -> Result<(StateSpace, usize)> {
    let n = sys.n();
    let mut a = sys.a().clone();
    let mut b = sys.b().clone();
    let mut c = sys.c().clone();
    let mut k = 0; // dimension found so far
    let mut blk: DMatrix<f64> = b.clone(); // current block: rows k.., in "previous" columns
    loop {
        if k == n {
            break;
        }
        let (u, s, _v) = svd(&blk)?;
        let r = s.iter().filter(|&&x| x > tol).count();
        if r == 0 {
            break;
        }
        // Full orthogonal basis of rows k..n: complete U (thin) to square by QR of [U | I].
        let m = n - k;
        let mut ext = DMatrix::zeros(m, m + u.ncols());
        ext.view_mut((0, 0), u.shape()).copy_from(&u);
        ext.view_mut((0, u.ncols()), (m, m)).fill_with_identity();
        let q = ext.qr().q();
        let uf = q.columns(0, m).into_owned();
        // apply diag(I_k, Ufᵀ): A <- T A Tᵀ, B <- T B, C <- C Tᵀ
        let ar = uf.transpose() * a.rows(k, m);
        a.rows_mut(k, m).copy_from(&ar);
        let ac = a.columns(k, m) * &uf;
        a.columns_mut(k, m).copy_from(&ac);
        let br = uf.transpose() * b.rows(k, m);
        b.rows_mut(k, m).copy_from(&br);
        let cc = c.columns(k, m) * &uf;
        c.columns_mut(k, m).copy_from(&cc);
        let prev = k; // start column of this block: the next block is A[k+r.., prev..prev+r]
        k += r;
        if k < n {
            blk = a.view((k, prev), (n - k, r)).into_owned();
        }
    }
    Ok((StateSpace::new(a, b, c, sys.d().clone(), sys.time())?, k))
}

fn dual(sys: &StateSpace) -> Result<StateSpace> {
    StateSpace::new(
        sys.a().transpose(),
        sys.c().transpose(),
        sys.b().transpose(),
        sys.d().transpose(),
        sys.time(),
    )
}

impl StateSpace {
    /// Removes uncontrollable and unobservable states (orthogonal staircase). `tol` is the
    /// rank threshold on singular values (default `n·ε·max(‖A‖₁, ‖B‖₁, ‖C‖₁)`).
    pub fn minreal(&self, tol: Option<f64>) -> Result<StateSpace> {
        let n = self.n();
        let t = match tol {
            Some(t) if t.is_finite() && t >= 0.0 => t,
            Some(t) => {
                return Err(ModelError::InvalidArgument(format!(
                    "minreal tolerance {t} must be finite and >= 0"
                )))
            }
            None => {
                (n.max(1) as f64)
                    * f64::EPSILON
                    * norm1(self.a())
                        .max(norm1(self.b()))
                        .max(norm1(&self.c().transpose()))
                        .max(1.0)
                    * 10.0
            }
        };
        let (s1, k1) = controllable_staircase(self, t)?;
        let s1 = keep_leading(&s1, k1)?;
        let (s2, k2) = controllable_staircase(&dual(&s1)?, t)?;
        let s2 = keep_leading(&s2, k2)?;
        dual(&s2)
    }

    /// Splits `G = G_u + G_s` where `G_u` holds the poles with `Re s ≥ −margin` (CT) or
    /// `|z| ≥ 1 − margin` (DT) and `G_s` the others; `D` goes to `G_s`.
    pub fn stable_unstable_split(&self, margin: f64) -> Result<(StateSpace, StateSpace)> {
        let n = self.n();
        let unstable = |z: C| match self.time() {
            SampleTime::Continuous => z.re >= -margin,
            SampleTime::Discrete { .. } => z.norm() >= 1.0 - margin,
        };
        let (q, mut t) = complex_schur(&to_complex(self.a()))?;
        let mut qh = q.adjoint();
        // bubble unstable eigenvalues to the front
        let mut k = 0;
        for j in 0..n {
            if unstable(t[(j, j)]) {
                for i in (k..j).rev() {
                    swap_adjacent(&mut t, i, &mut [&mut qh], &mut []);
                }
                k += 1;
            }
        }
        let q = qh.adjoint();
        let zero_d = DMatrix::zeros(self.ny(), self.nu());
        if k == 0 {
            let empty = StateSpace::new(
                DMatrix::zeros(0, 0),
                DMatrix::zeros(0, self.nu()),
                DMatrix::zeros(self.ny(), 0),
                zero_d,
                self.time(),
            )?;
            return Ok((empty, self.clone()));
        }
        if k == n {
            let s = StateSpace::new(
                DMatrix::zeros(0, 0),
                DMatrix::zeros(0, self.nu()),
                DMatrix::zeros(self.ny(), 0),
                self.d().clone(),
                self.time(),
            )?;
            return Ok((
                StateSpace::new(
                    self.a().clone(),
                    self.b().clone(),
                    self.c().clone(),
                    zero_d,
                    self.time(),
                )?,
                s,
            ));
        }
        let t11 = t.view((0, 0), (k, k)).into_owned();
        let t22 = t.view((k, k), (n - k, n - k)).into_owned();
        let r = -t.view((0, k), (k, n - k)).into_owned();
        let x = triangular_sylvester(&t11, &t22, &r).ok_or_else(|| ModelError::Singular {
            what: "the stable/unstable Sylvester equation (a pole on the boundary in both groups)"
                .into(),
        })?;
        let vu = q.columns(0, k).into_owned();
        let vs = q.columns(k, n - k) + q.columns(0, k) * &x;
        let real_basis = |v: &DMatrix<C>, dim: usize| -> Result<DMatrix<f64>> {
            let mut m = DMatrix::zeros(n, 2 * v.ncols());
            m.columns_mut(0, v.ncols()).copy_from(&v.map(|z| z.re));
            m.columns_mut(v.ncols(), v.ncols())
                .copy_from(&v.map(|z| z.im));
            let (u, _s, _) = svd(&m)?;
            Ok(u.columns(0, dim).into_owned())
        };
        let wu = real_basis(&vu, k)?;
        let ws = real_basis(&vs, n - k)?;
        let mut tm = DMatrix::zeros(n, n);
        tm.columns_mut(0, k).copy_from(&wu);
        tm.columns_mut(k, n - k).copy_from(&ws);
        let ti = tm.clone().try_inverse().ok_or_else(|| ModelError::Singular {
            what: "the stable/unstable basis (poles too close to the stability boundary to separate)".into(),
        })?;
        let at = &ti * self.a() * &tm;
        let bt = &ti * self.b();
        let ct = self.c() * &tm;
        let gu = StateSpace::new(
            at.view((0, 0), (k, k)).into_owned(),
            bt.rows(0, k).into_owned(),
            ct.columns(0, k).into_owned(),
            zero_d,
            self.time(),
        )?;
        let gs = StateSpace::new(
            at.view((k, k), (n - k, n - k)).into_owned(),
            bt.rows(k, n - k).into_owned(),
            ct.columns(k, n - k).into_owned(),
            self.d().clone(),
            self.time(),
        )?;
        Ok((gu, gs))
    }

    /// Balanced truncation to `order` states. Unstable and marginal poles (CT `Re s ≥ −1e-9·ρ`,
    /// DT `|z| ≥ 1 − 1e-9`) are kept exactly and only the stable part is reduced; `order` must be
    /// at least their number.
    pub fn balanced_truncation(&self, order: usize) -> Result<BalancedTruncation> {
        self.truncate_stable_part(order, |gs, k| {
            let (gr, hsv) = balanced_truncation_stable(gs, k)?;
            let bound = 2.0 * hsv.iter().skip(k).sum::<f64>();
            Ok((gr, hsv, bound))
        })
    }

    /// Frequency-weighted balanced truncation (Enns 1984) to `order` states: the stable part's
    /// controllability Gramian is the leading block of that of `G_s·V` (input weight `V`), its
    /// observability Gramian the leading block of that of `W·G_s` (output weight `W`), then the
    /// square-root projection of [`Self::balanced_truncation`]. It makes `‖W(G − G_r)V‖∞` small
    /// rather than `‖G − G_r‖∞`: with `V = (I + PK)⁻¹P` for a controller K in a loop with P,
    /// the error the loop sees (Anderson & Liu, *IEEE TAC* 34, 1989). With one weight the
    /// reduced stable part is stable (Enns); with both it is not guaranteed and is checked by
    /// the caller. Unstable and marginal poles are kept exactly, as in balanced truncation. The
    /// returned "Hankel" values are the weighted ones, `√λ(PQ)`; no a priori bound is given
    /// (`error_bound` is NaN).
    ///
    /// # Errors
    /// Order out of range, weights of the wrong size or sample time or not stable.
    pub fn weighted_balanced_truncation(
        &self,
        order: usize,
        input_weight: Option<&StateSpace>,
        output_weight: Option<&StateSpace>,
    ) -> Result<BalancedTruncation> {
        self.truncate_stable_part(order, |gs, k| {
            if gs.n() == 0 {
                return Ok((gs.clone(), Vec::new(), f64::NAN));
            }
            let p = weighted_gramian(gs, input_weight, false)?;
            let q = weighted_gramian(gs, output_weight, true)?;
            let (gr, hsv) = project(gs, factors_of(&p, &q)?, k)?;
            Ok((gr, hsv, f64::NAN))
        })
    }

    /// The same system with its states scaled by powers of two so that the rows of `[A B]` and
    /// the columns of `[A; C]` are balanced ([`crate::linalg::expm::balance_leading`] on
    /// `[A B; C 0]`, MATLAB's `ssbal`): exact (a diagonal similarity of powers of two), and what
    /// a Gramian or Riccati solution needs when the physical units put the entries decades
    /// apart (a position in metres, a force in newtons, a weight of 1e-7).
    pub fn balance_states(&self) -> Result<StateSpace> {
        let (n, m, p) = (self.n(), self.nu(), self.ny());
        let size = n + m.max(p);
        let mut big = DMatrix::<f64>::zeros(size, size);
        big.view_mut((0, 0), (n, n)).copy_from(self.a());
        big.view_mut((0, n), (n, m)).copy_from(self.b());
        big.view_mut((n, 0), (p, n)).copy_from(self.c());
        let (bal, _) = crate::linalg::expm::balance_leading(&big, n);
        StateSpace::new(
            bal.view((0, 0), (n, n)).into_owned(),
            bal.view((0, n), (n, m)).into_owned(),
            bal.view((n, 0), (p, n)).into_owned(),
            self.d().clone(),
            self.time(),
        )
    }

    /// Keeps the unstable and marginal poles (CT `Re s ≥ −1e-9·ρ`, DT `|z| ≥ 1 − 1e-9`) exactly
    /// and reduces the stable part by `reduce(stable part, states left)` →
    /// `(reduced, Hankel values, error bound)`; checks `order` against both.
    fn truncate_stable_part(
        &self,
        order: usize,
        reduce: impl FnOnce(&StateSpace, usize) -> Result<(StateSpace, Vec<f64>, f64)>,
    ) -> Result<BalancedTruncation> {
        if order > self.n() {
            return Err(ModelError::InvalidArgument(format!(
                "order {order} exceeds the model order {}",
                self.n()
            )));
        }
        let margin = match self.time() {
            SampleTime::Continuous => 1e-9 * norm1(self.a()).max(1.0),
            SampleTime::Discrete { .. } => 1e-9,
        };
        let (gu, gs) = self.stable_unstable_split(margin)?;
        let nu_states = gu.n();
        if order < nu_states {
            return Err(ModelError::InvalidArgument(format!(
                "order {order} is below the number of unstable/marginal states ({nu_states}), which are kept"
            )));
        }
        let (gr, hsv, bound) = reduce(&gs, order - nu_states)?;
        let model = if nu_states == 0 {
            gr
        } else {
            crate::connect::parallel(&gu, &gr)?
        };
        Ok(BalancedTruncation {
            model,
            hankel_sv: hsv,
            error_bound: bound,
            n_unstable: nu_states,
        })
    }

    /// Hankel singular values of a stable model (descending).
    pub fn hankel_singular_values(&self) -> Result<Vec<f64>> {
        Ok(gramian_factors(self)?.2)
    }
}

/// The leading n×n block of the controllability Gramian of `G·V` (`observe = false`) or of the
/// observability Gramian of `W·G` (`observe = true`); G's own Gramian without a weight.
fn weighted_gramian(
    g: &StateSpace,
    weight: Option<&StateSpace>,
    observe: bool,
) -> Result<DMatrix<f64>> {
    let kind = if g.time().is_continuous() {
        LyapKind::Continuous
    } else {
        LyapKind::Discrete
    };
    let n = g.n();
    let cascade = match weight {
        None => g.clone(),
        Some(w) => {
            let what = if observe {
                "output weight"
            } else {
                "input weight"
            };
            if w.poles()?.iter().any(|p| match kind {
                LyapKind::Continuous => p.re >= 0.0,
                LyapKind::Discrete => p.norm() >= 1.0,
            }) {
                return Err(ModelError::Unstable {
                    operation: format!("the {what} of a weighted balanced truncation"),
                    detail: "the weight must be stable".into(),
                });
            }
            // G first: [x_G; x_W] with the weight after (W·G) or the weight first, G's
            // states still leading (G·V: ẋ_G = A x_G + B C_V x_V + B D_V u)
            if observe {
                crate::connect::series(g, w)?
            } else {
                let s = crate::connect::series(w, g)?;
                let nw = w.n();
                let perm = |m: &DMatrix<f64>, rows: bool| {
                    let mut out = m.clone();
                    let total = if rows { m.nrows() } else { m.ncols() };
                    let order: Vec<usize> = (nw..total).chain(0..nw).collect();
                    for (new, &old) in order.iter().enumerate() {
                        if rows {
                            out.row_mut(new).copy_from(&m.row(old));
                        } else {
                            out.column_mut(new).copy_from(&m.column(old));
                        }
                    }
                    out
                };
                StateSpace::new(
                    perm(&perm(s.a(), true), false),
                    perm(s.b(), true),
                    perm(s.c(), false),
                    s.d().clone(),
                    s.time(),
                )?
            }
        }
    };
    let full = if observe {
        lyap(
            &cascade.a().transpose(),
            &(cascade.c().transpose() * cascade.c()),
            kind,
        )?
    } else {
        lyap(cascade.a(), &(cascade.b() * cascade.b().transpose()), kind)?
    };
    let block = full.view((0, 0), (n, n)).into_owned();
    Ok((&block + block.transpose()) * 0.5)
}

fn psd_factor(p: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let n = p.nrows();
    let eig = nalgebra::SymmetricEigen::try_new(p.clone(), f64::EPSILON, 100 * n.max(10))
        .ok_or_else(|| ModelError::NotConverged {
            what: "the symmetric eigensolver for a Gramian".into(),
        })?;
    let mut r = eig.eigenvectors.clone();
    for j in 0..n {
        let l = eig.eigenvalues[j].max(0.0).sqrt();
        r.column_mut(j).scale_mut(l);
    }
    Ok(r)
}

/// (R, L, σ, U, V) with P = RRᵀ, Q = LLᵀ, LᵀR = UΣVᵀ.
#[allow(clippy::type_complexity)]
fn gramian_factors(
    sys: &StateSpace,
) -> Result<(
    DMatrix<f64>,
    DMatrix<f64>,
    Vec<f64>,
    DMatrix<f64>,
    DMatrix<f64>,
)> {
    let kind = if sys.time().is_continuous() {
        LyapKind::Continuous
    } else {
        LyapKind::Discrete
    };
    for p in sys.poles()? {
        let bad = match kind {
            LyapKind::Continuous => p.re >= 0.0,
            LyapKind::Discrete => p.norm() >= 1.0,
        };
        if bad {
            return Err(ModelError::Unstable {
                operation: "Gramians".into(),
                detail: format!("pole {p}"),
            });
        }
    }
    let p = lyap(sys.a(), &(sys.b() * sys.b().transpose()), kind)?;
    let q = lyap(&sys.a().transpose(), &(sys.c().transpose() * sys.c()), kind)?;
    factors_of(&p, &q)
}

/// (R, L, σ, U, V) of given Gramians.
#[allow(clippy::type_complexity)]
fn factors_of(
    p: &DMatrix<f64>,
    q: &DMatrix<f64>,
) -> Result<(
    DMatrix<f64>,
    DMatrix<f64>,
    Vec<f64>,
    DMatrix<f64>,
    DMatrix<f64>,
)> {
    let r = psd_factor(p)?;
    let l = psd_factor(q)?;
    let (u, s, v) = svd(&(l.transpose() * &r))?;
    Ok((r, l, s, u, v))
}

fn balanced_truncation_stable(sys: &StateSpace, order: usize) -> Result<(StateSpace, Vec<f64>)> {
    if sys.n() == 0 {
        return Ok((sys.clone(), Vec::new()));
    }
    project(sys, gramian_factors(sys)?, order)
}

/// The square-root projection onto the `order` leading directions of the factors.
#[allow(clippy::type_complexity)]
fn project(
    sys: &StateSpace,
    (r, l, s, u, v): (
        DMatrix<f64>,
        DMatrix<f64>,
        Vec<f64>,
        DMatrix<f64>,
        DMatrix<f64>,
    ),
    order: usize,
) -> Result<(StateSpace, Vec<f64>)> {
    let k = order.min(s.iter().filter(|&&x| x > 0.0).count());
    let mut tl = u.columns(0, k).transpose() * l.transpose();
    let mut tr = &r * v.columns(0, k);
    for i in 0..k {
        let w = 1.0 / s[i].sqrt();
        tl.row_mut(i).scale_mut(w);
        tr.column_mut(i).scale_mut(w);
    }
    let red = StateSpace::new(
        &tl * sys.a() * &tr,
        &tl * sys.b(),
        sys.c() * &tr,
        sys.d().clone(),
        sys.time(),
    )?;
    Ok((red, s))
}
