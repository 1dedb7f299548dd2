//! Controller reduction by a loop-weighted rational fit (`ReductionMethod::LoopFit`).
//!
//! # Math
//!
//! For the SISO loop `u = −K y` around `P`, a reduced `K_r = K + Δ` changes the sensitivities
//! to first order by
//!
//! ```text
//! S_r/S − 1 ≈ −T·Δ/K,        T_r/T − 1 ≈ S·Δ/K
//! ```
//!
//! (`S = 1/(1 + PK)`, `T = PK·S`; Anderson & Liu, "Controller reduction: concepts and
//! approaches", *IEEE TAC* 34, 1989, §III), and the loop stays stable while
//! `|T·Δ/K| < 1` at every frequency (small gain on the multiplicative error of the
//! controller). So `K_r` of `order` states is fitted to K's frequency response by weighted least
//! squares,
//!
//! ```text
//! min Σ_k w_k² |K_r(z_k) − K(z_k)|²,    w_k = E_k · max(|S_k|, |T_k|)/|K_k|,
//! ```
//!
//! on a logarithmic grid of [`FIT_LINES`] frequencies from 0.05 % of the comparison band's top
//! (twice the full loop's crossover) to 0.999 of Nyquist, `E_k = E` inside the band (where
//! |ΔS| and |ΔT| are judged) and 1 above it (where the weight is the stability margin). The
//! fit is the toolkit's rational fitter ([`sd_ident::fit()`]: Sanathanan–Koerner iterations, then
//! Levenberg–Marquardt on the modal parameters, with a feedthrough), K's poles at `z = 1` (an
//! integrator, at most two) kept exactly as its fixed poles. The emphasis `E` trades the band
//! against the margin above it; the fits for `E` ∈ [`EMPHASES`] are judged on the loop with
//! the full-order plant and the stable one with the least `max(|ΔS|, |ΔT|)` in dB in the band is
//! returned.
//!
//! Unlike balanced truncation this has no a-priori error bound: the loop is checked afterwards
//! (eigenvalues), like every method's result.

use crate::closed_loop::ClosedLoop;
use crate::error::{AnalysisError, Result};
use num_complex::Complex64 as C;
use sd_model::{Frd, StateSpace};

/// Frequencies of the fit's grid.
pub const FIT_LINES: usize = 2000;
/// The band's emphases tried (module documentation).
pub const EMPHASES: [f64; 3] = [1.0, 10.0, 100.0];

/// Fitted candidates of `order` states for the SISO loop `full` (plant `p`, controller `k`),
/// one per emphasis in [`EMPHASES`], on the grid up to Nyquist with the band `band_hz`
/// (module documentation). Candidates whose fit failed are left out.
///
/// # Errors
/// A loop that is not SISO or not discrete, a controller with more than two poles at
/// `z = 1`, an order below its poles at `z = 1`, or no candidate fitted.
pub fn loop_fit(
    k: &StateSpace,
    full: &ClosedLoop,
    order: usize,
    band_hz: f64,
) -> Result<Vec<StateSpace>> {
    if (k.ny(), k.nu()) != (1, 1) {
        return Err(AnalysisError::InvalidArgument(format!(
            "the loop-weighted fit reduces a SISO controller; this one is {}x{}: use \
             `weighted` or `coprime`",
            k.ny(),
            k.nu()
        )));
    }
    let ts = k.ts().ok_or_else(|| {
        AnalysisError::InvalidArgument(
            "the loop-weighted fit needs a discrete-time loop; discretize plant and controller \
             first"
                .into(),
        )
    })?;
    let integrators = k
        .poles()?
        .iter()
        .filter(|l| (*l - C::new(1.0, 0.0)).norm() <= 1e-8)
        .count();
    if integrators > 2 || order < integrators {
        return Err(AnalysisError::InvalidArgument(format!(
            "the controller has {integrators} unstable/marginal poles at z = 1 and the \
             loop-weighted fit keeps them exactly: at most two, in an order of at least their \
             number (asked {order})"
        )));
    }
    let nyquist = 0.5 / ts;
    let lo = (5e-4 * band_hz).min(0.5 * nyquist);
    let hi = 0.999 * nyquist;
    let f: Vec<f64> = (0..FIT_LINES)
        .map(|i| lo * (hi / lo).powf(i as f64 / (FIT_LINES - 1) as f64))
        .collect();
    let kf = k.freqresp(&f)?;
    // max(|S|, |T|)/|K| per line: the first-order relative change of S and T per unit Δ
    let mut base = Vec::with_capacity(f.len());
    for (i, &fi) in f.iter().enumerate() {
        let r = full.responses(fi)?;
        let kk = kf.response()[i][(0, 0)].norm();
        let st = r.s[(0, 0)].norm().max(r.t[(0, 0)].norm());
        base.push(st / kk.max(f64::MIN_POSITIVE));
    }
    let candidates: Vec<StateSpace> = EMPHASES
        .iter()
        .filter_map(|&e| {
            let var = f
                .iter()
                .zip(&base)
                .map(|(&fi, &w)| {
                    let w = w * if fi <= band_hz { e } else { 1.0 };
                    nalgebra::DMatrix::from_element(1, 1, 1.0 / (w * w).max(f64::MIN_POSITIVE))
                })
                .collect();
            let frd = Frd::new(f.clone(), kf.response().to_vec(), Some(var), kf.time()).ok()?;
            let opt = sd_ident::FitOptions {
                order,
                rigid_body: integrators,
                feedthrough: true,
                ..Default::default()
            };
            sd_ident::fit(&frd, &opt).ok().map(|r| r.model)
        })
        .collect();
    if candidates.is_empty() {
        return Err(AnalysisError::ReductionFailed(format!(
            "no loop-weighted fit of order {order} converged; try another order or method"
        )));
    }
    Ok(candidates)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::{reduce_controller, ReductionMethod};
    use sd_model::{c2d, Discretization};

    /// A damped double integrator at 1 kHz and its loopshaping controller (6 states).
    fn siso_loop() -> (StateSpace, StateSpace) {
        let g = StateSpace::new(
            nalgebra::dmatrix![0.0, 1.0; 0.0, -0.1],
            nalgebra::dmatrix![0.0; 1.0],
            nalgebra::dmatrix![1.0, 0.0],
            nalgebra::dmatrix![0.0],
            sd_model::SampleTime::Continuous,
        )
        .unwrap();
        let p = c2d(&g, 1e-3, Discretization::Zoh).unwrap();
        let w = sd_hinf::weights::pid(20.0, 1.0, Some(1e-3), &Default::default()).unwrap();
        let k = sd_hinf::loopshape(&p, Some(&w), None, &Default::default())
            .unwrap()
            .controller;
        (p, k)
    }

    #[test]
    fn keeps_a_siso_loop_and_refuses_what_it_cannot_fit() {
        let (p, k) = siso_loop();
        let r = reduce_controller(&p, &k, 3, ReductionMethod::LoopFit).unwrap();
        assert!(r.after.stable && r.orders == (k.n(), 3));
        assert!(r.max_delta_s_db <= 0.1 && r.max_delta_t_db <= 0.1, "{r:?}");
        assert!(r.hankel_sv.is_empty());
        // a two-channel controller
        let full = ClosedLoop::new(&p, &k).unwrap();
        let k2 = sd_model::append(&k, &k).unwrap();
        let e = loop_fit(&k2, &full, 3, 40.0).unwrap_err();
        assert!(e.to_string().contains("SISO"), "{e}");
        // an order below the controller's poles at z = 1 (three integrators)
        let i3 = StateSpace::new(
            nalgebra::DMatrix::identity(3, 3),
            nalgebra::DMatrix::from_element(3, 1, 1.0),
            nalgebra::DMatrix::from_element(1, 3, 1.0),
            nalgebra::dmatrix![0.0],
            k.time(),
        )
        .unwrap();
        let e = loop_fit(&i3, &full, 4, 40.0).unwrap_err();
        assert!(e.to_string().contains("3 unstable/marginal poles"), "{e}");
    }
}
