//! Controller reduction that keeps the loop: frequency-weighted balanced truncation with the
//! closed-loop weight, judged on the loop it is meant for.
//!
//! **Method.** For the loop `u = −K y` around P, a reduced `K_r = K + Δ` sees the loop through
//! `V = (I + PK)⁻¹P` (= PS, the process sensitivity): the loop stays stable while
//! `‖Δ·V‖∞ < 1` (small gain; Anderson & Liu, "Controller reduction: concepts and approaches",
//! *IEEE TAC* 34, 1989). So K's stable part is truncated with `V` as its input weight
//! ([`sd_model::StateSpace::weighted_balanced_truncation`], Enns 1984: one-sided weighting keeps
//! the reduced part stable); its unstable and marginal poles (an integrator) are kept exactly.
//! `CoprimeFactor` truncates the balanced normalized coprime factors of the loop-scaled
//! controller `αK`, `α = 1/|K(f_c)|` at the full loop's crossover (where `|PK| = 1`, so `αK`
//! and `P/α` have unit gain there and the factors weigh plant and controller alike):
//! [`sd_hinf::coprime_reduce`], Meyer 1990; unstable and marginal poles need no special
//! treatment, and the loop stays stable when the factors' error bound `2Σσ_discarded` is below
//! the loop's normalized coprime stability margin. `Plain` is unweighted balanced truncation,
//! for comparison.
//!
//! **Judged** on the loop with the full-order plant: internal stability (eigenvalues), the
//! largest change of |S| and |T| in dB below twice the full loop's crossover on a 400-point log
//! grid from 0.1 % of it, and the margins before and after. A loop that the reduced controller
//! does not stabilize is an error ([`AnalysisError::ReductionFailed`]) naming the order and the
//! closed-loop pole.

use crate::closed_loop::{ClosedLoop, Summary};
use crate::error::{AnalysisError, Result};
use sd_model::{grid, StateSpace};
use serde::{Deserialize, Serialize};

/// How the controller is reduced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReductionMethod {
    /// Balanced truncation with the closed-loop input weight `(I + PK)⁻¹P`.
    ClosedLoopWeighted,
    /// Unweighted balanced truncation.
    Plain,
    /// Balanced truncation of the loop-scaled controller's normalized coprime factors.
    CoprimeFactor,
}

impl std::str::FromStr for ReductionMethod {
    type Err = AnalysisError;
    /// The names `sdctl reduce --method` and Python take: `weighted`, `plain`, `coprime`.
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "weighted" => Ok(ReductionMethod::ClosedLoopWeighted),
            "plain" => Ok(ReductionMethod::Plain),
            "coprime" => Ok(ReductionMethod::CoprimeFactor),
            other => Err(AnalysisError::InvalidArgument(format!(
                "reduction method {other:?}: use `weighted` (closed-loop weight), `coprime` \
                 (normalized coprime factors) or `plain`"
            ))),
        }
    }
}

/// A reduced controller and what it does to the loop.
#[derive(Debug, Clone)]
pub struct ControllerReduction {
    /// The reduced controller (same sample time and convention as the full one).
    pub controller: StateSpace,
    /// The method used.
    pub method: ReductionMethod,
    /// Orders before and after.
    pub orders: (usize, usize),
    /// The (weighted) Hankel singular values of the stable part, descending.
    pub hankel_sv: Vec<f64>,
    /// Upper end of the comparison band: twice the full loop's crossover (Hz).
    pub band_hz: f64,
    /// Largest |ΔS| and |ΔT| (dB) in the band.
    pub max_delta_s_db: f64,
    /// See `max_delta_s_db`.
    pub max_delta_t_db: f64,
    /// The loop with the full controller.
    pub before: Summary,
    /// The loop with the reduced controller.
    pub after: Summary,
}

/// Reduces `k` (for `u = −K y` around `p`) to `order` states (module documentation).
///
/// # Errors
/// A loop that is not stable with the full controller, an order out of range (below the
/// controller's unstable/marginal states), and [`AnalysisError::ReductionFailed`] when the
/// reduced controller does not stabilize the loop.
pub fn reduce_controller(
    p: &StateSpace,
    k: &StateSpace,
    order: usize,
    method: ReductionMethod,
) -> Result<ControllerReduction> {
    let full = ClosedLoop::new(p, k)?;
    let before = full.summary()?;
    if !before.stable {
        return Err(AnalysisError::InvalidArgument(format!(
            "the loop with the full controller is not stable (closed-loop pole radius/abscissa \
             {:.6}): there is no loop to keep",
            before.closed_loop_radius
        )));
    }
    let red = match method {
        ReductionMethod::ClosedLoopWeighted => {
            // PS realized by the closed loop itself (its states are the loop's: stable), not
            // as P in series with S, which carries P's rigid-body poles uncancelled
            k.weighted_balanced_truncation(order, Some(full.closed_loop()), None)?
        }
        ReductionMethod::Plain => k.balanced_truncation(order)?,
        ReductionMethod::CoprimeFactor => coprime(k, order, &before)?,
    };
    let kr = red.model;
    let reduced = ClosedLoop::new(p, &kr)?;
    let after = reduced.summary()?;
    if !after.stable {
        return Err(AnalysisError::ReductionFailed(format!(
            "the controller reduced to {} states by {method:?} does not stabilize the loop \
             (closed-loop pole radius/abscissa {:.6}); keep more states",
            kr.n(),
            after.closed_loop_radius
        )));
    }
    let cross = if before.crossover_hz.is_finite() {
        before.crossover_hz
    } else {
        before.bandwidth_hz
    };
    let nyquist = p.ts().map_or(f64::INFINITY, |ts| 0.5 / ts);
    let band_hz = (2.0 * cross).min(0.999 * nyquist);
    let (ds, dt) = if band_hz.is_finite() && band_hz > 0.0 {
        let freqs = grid(band_hz * 1e-3 / 2.0, band_hz, 400, true)?;
        let mut worst = (0.0f64, 0.0f64);
        for f in freqs {
            let (a, b) = (full.responses(f)?, reduced.responses(f)?);
            let db = |x: f64, y: f64| (20.0 * (y / x).log10()).abs();
            worst.0 = worst.0.max(db(sigma(&a.s), sigma(&b.s)));
            worst.1 = worst.1.max(db(sigma(&a.t), sigma(&b.t)));
        }
        worst
    } else {
        (f64::NAN, f64::NAN)
    };
    Ok(ControllerReduction {
        orders: (k.n(), kr.n()),
        controller: kr,
        method,
        hankel_sv: red.hankel_sv,
        band_hz,
        max_delta_s_db: ds,
        max_delta_t_db: dt,
        before,
        after,
    })
}

/// The coprime-factor reduction of the loop-scaled controller, unscaled again.
fn coprime(k: &StateSpace, order: usize, before: &Summary) -> Result<sd_model::BalancedTruncation> {
    let fc = if before.crossover_hz.is_finite() && before.crossover_hz > 0.0 {
        before.crossover_hz
    } else {
        before.bandwidth_hz
    };
    let gain = if fc.is_finite() && fc > 0.0 {
        sigma(&k.freqresp(&[fc])?.response()[0])
    } else {
        1.0
    };
    let alpha = if gain.is_finite() && gain > 0.0 {
        1.0 / gain
    } else {
        1.0
    };
    let scaled = StateSpace::new(
        k.a().clone(),
        k.b().clone(),
        k.c() * alpha,
        k.d() * alpha,
        k.time(),
    )?;
    let r = sd_hinf::coprime_reduce(&scaled, order)?;
    let m = &r.model;
    let model = StateSpace::new(
        m.a().clone(),
        m.b().clone(),
        m.c() / alpha,
        m.d() / alpha,
        m.time(),
    )?;
    Ok(sd_model::BalancedTruncation {
        model,
        hankel_sv: r.hankel_sv,
        error_bound: r.error_bound,
        n_unstable: 0,
    })
}

fn sigma(m: &nalgebra::DMatrix<num_complex::Complex64>) -> f64 {
    crate::closed_loop::sigma_max(m)
}
