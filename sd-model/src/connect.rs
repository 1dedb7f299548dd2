//! Interconnections: series, parallel, feedback, append.
//!
//! Standard state-space formulas (e.g. Zhou, Doyle & Glover, *Robust and Optimal Control*, §3.6).
//! All check equal sample times and compatible dimensions, and return errors otherwise.

use crate::error::{ModelError, Result};
use crate::ss::StateSpace;
use nalgebra::DMatrix;

fn blockdiag(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(a.nrows() + b.nrows(), a.ncols() + b.ncols());
    m.view_mut((0, 0), a.shape()).copy_from(a);
    m.view_mut(a.shape(), b.shape()).copy_from(b);
    m
}

fn vstack(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(a.nrows() + b.nrows(), a.ncols());
    m.view_mut((0, 0), a.shape()).copy_from(a);
    m.view_mut((a.nrows(), 0), b.shape()).copy_from(b);
    m
}

fn hstack(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(a.nrows(), a.ncols() + b.ncols());
    m.view_mut((0, 0), a.shape()).copy_from(a);
    m.view_mut((0, a.ncols()), b.shape()).copy_from(b);
    m
}

/// `first` then `second`: `y = G₂ G₁ u` (the output of `first` drives `second`).
pub fn series(first: &StateSpace, second: &StateSpace) -> Result<StateSpace> {
    first.time().check_same(&second.time(), "series")?;
    if first.ny() != second.nu() {
        return Err(ModelError::dim(
            "series (outputs of the first = inputs of the second)",
            first.ny(),
            second.nu(),
        ));
    }
    let (a1, b1, c1, d1) = (first.a(), first.b(), first.c(), first.d());
    let (a2, b2, c2, d2) = (second.a(), second.b(), second.c(), second.d());
    let mut a = blockdiag(a1, a2);
    a.view_mut((a1.nrows(), 0), (a2.nrows(), a1.ncols()))
        .copy_from(&(b2 * c1));
    let b = vstack(b1, &(b2 * d1));
    let c = hstack(&(d2 * c1), c2);
    StateSpace::new(a, b, c, d2 * d1, first.time())
}

/// `y = (G₁ + G₂) u`.
pub fn parallel(g1: &StateSpace, g2: &StateSpace) -> Result<StateSpace> {
    g1.time().check_same(&g2.time(), "parallel")?;
    if g1.d().shape() != g2.d().shape() {
        return Err(ModelError::dim(
            "parallel (equal input/output counts)",
            format!("{}x{}", g1.ny(), g1.nu()),
            format!("{}x{}", g2.ny(), g2.nu()),
        ));
    }
    StateSpace::new(
        blockdiag(g1.a(), g2.a()),
        vstack(g1.b(), g2.b()),
        hstack(g1.c(), g2.c()),
        g1.d() + g2.d(),
        g1.time(),
    )
}

/// Block-diagonal stacking: inputs `[u₁; u₂]`, outputs `[y₁; y₂]`.
pub fn append(g1: &StateSpace, g2: &StateSpace) -> Result<StateSpace> {
    g1.time().check_same(&g2.time(), "append")?;
    StateSpace::new(
        blockdiag(g1.a(), g2.a()),
        blockdiag(g1.b(), g2.b()),
        blockdiag(g1.c(), g2.c()),
        blockdiag(g1.d(), g2.d()),
        g1.time(),
    )
}

/// Closed loop `y = G (r + σ K y)` from r to y, σ = −1 (negative feedback, the default meaning
/// `u = r − K y`) or +1. Requires `I − σ D_G D_K` invertible (a well-posed loop).
pub fn feedback(g: &StateSpace, k: &StateSpace, sign: f64) -> Result<StateSpace> {
    g.time().check_same(&k.time(), "feedback")?;
    if sign != 1.0 && sign != -1.0 {
        return Err(ModelError::InvalidArgument(format!(
            "feedback sign must be +1 or -1, got {sign}"
        )));
    }
    if k.nu() != g.ny() || k.ny() != g.nu() {
        return Err(ModelError::dim(
            "feedback (K must be nu(G) x ny(G))",
            format!("{}x{}", g.nu(), g.ny()),
            format!("{}x{}", k.ny(), k.nu()),
        ));
    }
    let (a1, b1, c1, d1) = (g.a(), g.b(), g.c(), g.d());
    let (a2, b2, c2, d2) = (k.a(), k.b(), k.c(), k.d());
    let ny = g.ny();
    let m = DMatrix::<f64>::identity(ny, ny) - d1 * d2 * sign;
    let e = m.try_inverse().ok_or_else(|| ModelError::Singular {
        what: "I − σ·D_G·D_K: the feedback loop is ill-posed (algebraic loop)".into(),
    })?;
    let nu = g.nu();
    // y = E C1 x1 + σ E D1 C2 x2 + E D1 r
    let yx1 = &e * c1;
    let yx2 = &e * d1 * c2 * sign;
    let yr = &e * d1;
    // u = r + σ (C2 x2 + D2 y)
    let ux1 = d2 * &yx1 * sign;
    let ux2 = (c2 + d2 * &yx2) * sign;
    let ur = DMatrix::<f64>::identity(nu, nu) + d2 * &yr * sign;
    let top = hstack(&(a1 + b1 * &ux1), &(b1 * &ux2));
    let bot = hstack(&(b2 * &yx1), &(a2 + b2 * &yx2));
    let a = vstack(&top, &bot);
    let b = vstack(&(b1 * &ur), &(b2 * &yr));
    let c = hstack(&yx1, &yx2);
    StateSpace::new(a, b, c, yr, g.time())
}
