//! Mixed-sensitivity H∞ design: the generalized plant of `[W₁S; W₂KS; W₃T]` (MATLAB's
//! `augw`), optionally with an input-disturbance channel, and its H∞ synthesis (`mixsyn`).
//!
//! **Loop.** `e = r − y`, `u = K e`, `y = G(u + W_d d)` (negative feedback, the controller
//! returned is used as `u = K e`): `S = (I + GK)⁻¹`, `T = GKS`. The generalized plant has
//! inputs `[r; d; u]` (`d` only with `W_d`) and outputs `[z₁; z₂; z₃; e]`, each `z` present only
//! with its weight: `z₁ = W₁e`, `z₂ = W₂u`, `z₃ = W₃y`, measurement `e`. From `r` the closed
//! loop is `[W₁S; W₂KS; W₃T]`; from `d` it is `[−W₁SG; −W₂KSG; W₃SG]·W_d` — the process
//! sensitivity `SG` (force disturbance to error), the motion-control performance measure. A
//! `W_d` also makes every plant mode reachable from the exogenous inputs, which the Riccati
//! formulas need when `G` has poles on the stability boundary (a rigid body at z = 1: without
//! `W_d` it is reachable from `u` only and no γ passes).
//!
//! **Assembly.** Every signal is written as `c·X + d·[r; d; u]` over the stacked state
//! `X = [x_G; x_{W_d}; x_{W₁}; x_{W₂}; x_{W₃}]`; a block with input signal σ adds `B·σ` to its
//! state equation and `C x + D·σ` to its output — the state-space formulas of
//! Zhou, Doyle & Glover (1996), ch. 10, written once for all blocks.

use crate::error::{HinfError, Result};
use crate::hinfsyn::{hinfsyn, HinfOptions, HinfSynthesis};
use crate::lft::Partition;
use nalgebra::DMatrix;
use sd_model::{ModelError, StateSpace};

/// The weights of a mixed-sensitivity problem (each optional; at least one of W₁, W₂, W₃).
#[derive(Debug, Clone, Copy, Default)]
pub struct MixsynWeights<'a> {
    /// On the sensitivity S (ny×ny).
    pub w1: Option<&'a StateSpace>,
    /// On the control sensitivity KS (nu×nu).
    pub w2: Option<&'a StateSpace>,
    /// On the complementary sensitivity T (ny×ny).
    pub w3: Option<&'a StateSpace>,
    /// Input disturbance shaping (nu×nu): adds the process-sensitivity channel.
    pub wd: Option<&'a StateSpace>,
}

/// A signal as a linear map of the stacked state and the inputs.
#[derive(Clone)]
struct Sig {
    c: DMatrix<f64>,
    d: DMatrix<f64>,
}

impl Sig {
    fn zero(rows: usize, nx: usize, ni: usize) -> Sig {
        Sig {
            c: DMatrix::zeros(rows, nx),
            d: DMatrix::zeros(rows, ni),
        }
    }
    /// `m·self`.
    fn times(&self, m: &DMatrix<f64>) -> Sig {
        Sig {
            c: m * &self.c,
            d: m * &self.d,
        }
    }
    fn plus(&self, o: &Sig) -> Sig {
        Sig {
            c: &self.c + &o.c,
            d: &self.d + &o.d,
        }
    }
}

/// The stacked model under construction.
struct Build {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    next: usize,
}

impl Build {
    /// Places block `s` driven by `input`; returns its output signal.
    fn block(&mut self, s: &StateSpace, input: &Sig) -> Sig {
        let (o, n) = (self.next, s.n());
        self.next += n;
        let bc = s.b() * &input.c;
        let mut rows = self.a.rows_mut(o, n);
        rows += &bc;
        let mut diag = self.a.view_mut((o, o), (n, n));
        diag += s.a();
        let mut brows = self.b.rows_mut(o, n);
        brows += &(s.b() * &input.d);
        let mut out = input.times(s.d());
        let mut cols = out.c.columns_mut(o, n);
        cols += s.c();
        out
    }
}

fn check_weight(w: &StateSpace, size: usize, what: &str, g: &StateSpace) -> Result<()> {
    if w.nu() != size || w.ny() != size {
        return Err(ModelError::dim(
            what,
            format!("{size}x{size}"),
            format!("{}x{}", w.ny(), w.nu()),
        )
        .into());
    }
    if !w.time().compatible(&g.time()) {
        return Err(HinfError::InvalidArgument(format!(
            "{what} and the plant have different sample times: discretize the weight at the \
             plant's period"
        )));
    }
    Ok(())
}

/// The generalized plant (module documentation) and its partition (`nmeas = ny`,
/// `ncon = nu`).
///
/// # Errors
/// No weight on S, KS or T; a weight of the wrong size or sample time.
pub fn augw(g: &StateSpace, w: &MixsynWeights<'_>) -> Result<(StateSpace, Partition)> {
    let (ny, nu) = (g.ny(), g.nu());
    if w.w1.is_none() && w.w2.is_none() && w.w3.is_none() {
        return Err(HinfError::InvalidArgument(
            "mixed sensitivity needs at least one of W1 (on S), W2 (on KS), W3 (on T)".into(),
        ));
    }
    for (wt, size, what) in [
        (w.w1, ny, "W1 (on S, ny×ny)"),
        (w.w2, nu, "W2 (on KS, nu×nu)"),
        (w.w3, ny, "W3 (on T, ny×ny)"),
        (w.wd, nu, "Wd (input disturbance, nu×nu)"),
    ] {
        if let Some(wt) = wt {
            check_weight(wt, size, what, g)?;
        }
    }
    let nd = if w.wd.is_some() { nu } else { 0 };
    let ni = ny + nd + nu;
    let nx = g.n()
        + [w.wd, w.w1, w.w2, w.w3]
            .iter()
            .flatten()
            .map(|s| s.n())
            .sum::<usize>();
    let pick = |at: usize, k: usize| {
        let mut s = Sig::zero(k, nx, ni);
        s.d.view_mut((0, at), (k, k)).fill_with_identity();
        s
    };
    let (r, d, u) = (pick(0, ny), pick(ny, nd), pick(ny + nd, nu));
    let mut bld = Build {
        a: DMatrix::zeros(nx, nx),
        b: DMatrix::zeros(nx, ni),
        next: 0,
    };
    // the plant first (its states at the top), its input v = u + W_d d placed after
    let g_at = bld.next;
    bld.next += g.n();
    let v = match w.wd {
        Some(wd) => u.plus(&bld.block(wd, &d)),
        None => u.clone(),
    };
    let gb = g.b() * &v.c;
    let mut rows = bld.a.rows_mut(g_at, g.n());
    rows += &gb;
    let mut diag = bld.a.view_mut((g_at, g_at), (g.n(), g.n()));
    diag += g.a();
    let mut brows = bld.b.rows_mut(g_at, g.n());
    brows += &(g.b() * &v.d);
    let mut y = v.times(g.d());
    let mut cols = y.c.columns_mut(g_at, g.n());
    cols += g.c();
    let e = r.plus(&y.times(&-DMatrix::<f64>::identity(ny, ny)));
    let mut outs: Vec<Sig> = Vec::new();
    if let Some(w1) = w.w1 {
        outs.push(bld.block(w1, &e));
    }
    if let Some(w2) = w.w2 {
        outs.push(bld.block(w2, &u));
    }
    if let Some(w3) = w.w3 {
        outs.push(bld.block(w3, &y));
    }
    outs.push(e);
    let rows: usize = outs.iter().map(|s| s.c.nrows()).sum();
    let mut c = DMatrix::zeros(rows, nx);
    let mut dm = DMatrix::zeros(rows, ni);
    let mut at = 0;
    for s in &outs {
        c.rows_mut(at, s.c.nrows()).copy_from(&s.c);
        dm.rows_mut(at, s.d.nrows()).copy_from(&s.d);
        at += s.c.nrows();
    }
    let p = StateSpace::new(bld.a, bld.b, c, dm, g.time())?;
    Ok((
        p,
        Partition {
            nmeas: ny,
            ncon: nu,
        },
    ))
}

/// Mixed-sensitivity synthesis: [`augw`], then [`hinfsyn()`]. The controller is used as
/// `u = K e` with `e = r − y` (negative feedback).
///
/// # Errors
/// As [`augw`] and [`hinfsyn()`].
pub fn mixsyn(
    g: &StateSpace,
    w: &MixsynWeights<'_>,
    opt: &HinfOptions,
) -> Result<(HinfSynthesis, StateSpace)> {
    let (p, part) = augw(g, w)?;
    let r = hinfsyn(&p, part, opt)?;
    Ok((r, p))
}
