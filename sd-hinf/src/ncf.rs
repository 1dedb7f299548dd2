//! Normalized coprime factors and their balanced truncation: model (or controller) reduction
//! that handles unstable and marginal poles and keeps what a loop needs.
//!
//! # Math
//!
//! A continuous `G = (A, B, C, D)` has the normalized left coprime factorization
//! `G = M̃⁻¹Ñ`, `ÑÑ* + M̃M̃* = I` on the imaginary axis (Vidyasagar 1988; Zhou, Doyle & Glover,
//! *Robust and Optimal Control*, 1996, §13.8): with `R̃ = I + DDᵀ` and `Y` the stabilizing
//! solution of the filter Riccati equation
//!
//! ```text
//! AY + YAᵀ − (YCᵀ + BDᵀ) R̃⁻¹ (CY + DBᵀ) + BBᵀ = 0,    L = −(YCᵀ + BDᵀ) R̃⁻¹,
//! [Ñ M̃] = (A + LC, [B + LD, L], R̃^{-1/2} C, R̃^{-1/2} [D, I]).
//! ```
//!
//! `[Ñ M̃]` is stable with the states of `G` and Hankel singular values below 1. Its balanced
//! truncation to r states gives `[Ñ_r M̃_r]` with
//! `‖[Ñ − Ñ_r, M̃ − M̃_r]‖∞ ≤ 2 Σ_{i>r} σ_i` (Meyer, "Fractional balanced reduction", *IEEE
//! TAC* 35(12), 1990; McFarlane & Glover 1990), and `G_r = M̃_r⁻¹Ñ_r`:
//! `A_r − B_m D_m⁻¹ C_r`, `B_n − B_m D_m⁻¹ D_n`, `D_m⁻¹ C_r`, `D_m⁻¹ D_n`. A controller `K`
//! with normalized coprime factor stability margin `b(P, K)` keeps the loop stable when the
//! bound is below it.
//!
//! A discrete model goes through the exact bilinear map ([`crate::bilinear`]): it preserves
//! the H∞ norm, stability and every interconnection, so the factorization, the bound and the
//! loop statement hold in discrete time as they do in the continuous domain.

use crate::bilinear::{bilinear_to_continuous, bilinear_to_discrete};
use crate::error::{HinfError, Result};
use crate::riccati::care;
use nalgebra::DMatrix;
use sd_model::StateSpace;

/// The result of [`coprime_reduce`].
#[derive(Debug, Clone)]
pub struct CoprimeReduction {
    /// The reduced model `M̃_r⁻¹Ñ_r`, in the input's time domain.
    pub model: StateSpace,
    /// Hankel singular values of `[Ñ M̃]`, descending (all below 1).
    pub hankel_sv: Vec<f64>,
    /// `2 Σ` of the discarded ones: the bound on the factors' error `‖[ΔÑ ΔM̃]‖∞`.
    pub error_bound: f64,
}

/// `[Ñ M̃]` of a continuous model (module documentation).
///
/// # Errors
/// A discrete model; a filter Riccati equation without a stabilizing solution (a mode on the
/// imaginary axis that `B` does not reach, or an undetectable unstable mode).
pub fn normalized_lcf(g: &StateSpace) -> Result<StateSpace> {
    if g.time().is_discrete() {
        return Err(HinfError::InvalidArgument(
            "normalized_lcf takes a continuous model (map a discrete one with \
             bilinear_to_continuous, or call coprime_reduce)"
                .into(),
        ));
    }
    let (a, b, c, d) = (g.a(), g.b(), g.c(), g.d());
    let (n, ny) = (g.n(), g.ny());
    let rt = DMatrix::identity(ny, ny) + d * d.transpose();
    let q = b * b.transpose();
    let s = b * d.transpose();
    let y = care(&a.transpose(), &c.transpose(), &q, &rt, Some(&s))?;
    // care's gain is R̃⁻¹(CY + DBᵀ): L = −gainᵀ
    let l = -y.gain.transpose();
    let ri = inv_sqrt(&rt)?;
    let mut bn = DMatrix::zeros(n, g.nu() + ny);
    bn.columns_mut(0, g.nu()).copy_from(&(b + &l * d));
    bn.columns_mut(g.nu(), ny).copy_from(&l);
    let mut dn = DMatrix::zeros(ny, g.nu() + ny);
    dn.columns_mut(0, g.nu()).copy_from(&(&ri * d));
    dn.columns_mut(g.nu(), ny).copy_from(&ri);
    Ok(StateSpace::new(a + &l * c, bn, &ri * c, dn, g.time())?)
}

/// `R^{-1/2}` of a symmetric positive definite `R`.
fn inv_sqrt(r: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let e = r.clone().symmetric_eigen();
    if e.eigenvalues.iter().any(|v| *v <= 0.0) {
        return Err(HinfError::Numerical(
            "I + DDᵀ is not positive definite".into(),
        ));
    }
    let s = DMatrix::from_diagonal(&e.eigenvalues.map(|v| 1.0 / v.sqrt()));
    Ok(&e.eigenvectors * s * e.eigenvectors.transpose())
}

/// Balanced truncation of the normalized coprime factors to `order` states (module
/// documentation), continuous or discrete.
///
/// # Errors
/// An order above the model's; a discrete model with a pole at z = −1 (the bilinear map);
/// as [`normalized_lcf`].
pub fn coprime_reduce(g: &StateSpace, order: usize) -> Result<CoprimeReduction> {
    if order > g.n() {
        return Err(HinfError::InvalidArgument(format!(
            "order {order} is above the model's {} states",
            g.n()
        )));
    }
    let ts = g.ts();
    let gc = match ts {
        Some(_) => bilinear_to_continuous(g)?,
        None => g.clone(),
    };
    let f = normalized_lcf(&gc)?;
    let bt = f.balanced_truncation(order)?;
    let (nu, ny) = (g.nu(), g.ny());
    let fr = &bt.model;
    let bm = fr.b().columns(nu, ny).into_owned();
    let dm = fr.d().columns(nu, ny).into_owned();
    let dmi = dm.try_inverse().ok_or_else(|| {
        HinfError::Numerical("the reduced factor M̃_r has a singular feedthrough".into())
    })?;
    let (bn, dn) = (fr.b().columns(0, nu), fr.d().columns(0, nu));
    let gr = StateSpace::new(
        fr.a() - &bm * &dmi * fr.c(),
        bn - &bm * &dmi * dn,
        &dmi * fr.c(),
        &dmi * dn,
        gc.time(),
    )?;
    let model = match ts {
        Some(t) => bilinear_to_discrete(&gr, t)?,
        None => gr,
    };
    Ok(CoprimeReduction {
        model,
        hankel_sv: bt.hankel_sv,
        error_bound: bt.error_bound,
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use num_complex::Complex64 as C;
    use sd_model::{c2d, stage::paper_stage, Discretization};

    /// A loopshaping controller of the paper's stage (an integrator at z = 1 included),
    /// scaled by 1e-7 m/N so that its gain is near 1 at the crossover: the factors of a
    /// controller in N/m would be a pure gain to rounding.
    fn controller() -> StateSpace {
        let p = c2d(&paper_stage(0.01).unwrap(), 1e-3, Discretization::Zoh).unwrap();
        let w = crate::weights::pid(65.0, 20.0, Some(1e-3), &Default::default()).unwrap();
        let k = crate::loopshape(&p, Some(&w), None, &Default::default())
            .unwrap()
            .controller;
        StateSpace::new(
            k.a().clone(),
            k.b().clone(),
            k.c() * 1e-7,
            k.d() * 1e-7,
            k.time(),
        )
        .unwrap()
    }

    /// `ÑÑ* + M̃M̃* = I` on the axis, the factors are stable with Hankel singular values
    /// below 1, and `M̃⁻¹Ñ` is the model (checked at points of the axis against its own
    /// response).
    #[test]
    fn factors_are_normalized_and_reproduce_the_model() {
        let k = bilinear_to_continuous(&controller()).unwrap();
        let f = normalized_lcf(&k).unwrap();
        assert!(f.hinf_norm().unwrap().stable);
        let (nu, ny) = (k.nu(), k.ny());
        for w in [1e-4, 1e-2, 0.3, 1.0, 7.0, 100.0] {
            let s = C::new(0.0, w);
            let fv = f.eval_direct(s).unwrap();
            let gram = &fv * fv.adjoint();
            assert!(
                (gram[(0, 0)] - C::new(1.0, 0.0)).norm() < 1e-9,
                "{w}: {gram}"
            );
            let n = fv.columns(0, nu).into_owned();
            let m = fv.columns(nu, ny).into_owned();
            let g = m.try_inverse().unwrap() * n;
            let want = k.eval_direct(s).unwrap();
            assert!((g[(0, 0)] - want[(0, 0)]).norm() <= 1e-8 * want[(0, 0)].norm());
        }
        let r = coprime_reduce(&controller(), k.n()).unwrap();
        assert!(r.hankel_sv.iter().all(|v| *v < 1.0));
        assert_eq!(r.error_bound, 0.0);
    }

    /// The reduced factors stay within the a priori bound of the full ones: the reduced
    /// model's factorization error, measured on a grid of the unit circle, is below
    /// `2 Σ σ_discarded`.
    #[test]
    fn reduction_error_is_within_the_bound() {
        let k = controller();
        let fk = normalized_lcf(&bilinear_to_continuous(&k).unwrap()).unwrap();
        for order in [3, 5] {
            let r = coprime_reduce(&k, order).unwrap();
            assert_eq!(r.model.n(), order);
            assert_eq!(r.model.ts(), Some(1e-3));
            let fr = normalized_lcf(&bilinear_to_continuous(&r.model).unwrap()).unwrap();
            // the pointwise chordal distance of the responses is below the ν-gap, which is
            // below the gap, which the factor error bounds (Vinnicombe 2001, ch. 3)
            let mut worst = 0.0f64;
            for i in 0..400 {
                let w = 10f64.powf(-4.0 + 7.0 * i as f64 / 399.0);
                let s = C::new(0.0, w);
                let (a, b) = (fk.eval_direct(s).unwrap(), fr.eval_direct(s).unwrap());
                let ga = a[(0, 1)].inv() * a[(0, 0)];
                let gb = b[(0, 1)].inv() * b[(0, 0)];
                let chordal = (ga - gb).norm()
                    / ((1.0 + ga.norm_sqr()).sqrt() * (1.0 + gb.norm_sqr()).sqrt());
                worst = worst.max(chordal);
            }
            assert!(
                worst <= r.error_bound * (1.0 + 1e-6),
                "order {order}: chordal distance {worst:e}, bound {:e}",
                r.error_bound
            );
        }
        assert!(coprime_reduce(&k, k.n() + 1).is_err());
    }
}
