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
//! the loop's normalized coprime stability margin. `LoopFit` (SISO, discrete) fits the
//! reduced controller to K's frequency response with the loop's first-order weights
//! `max(|S|, |T|)/|K|` by the toolkit's rational fitter (the `reduce_fit` module's
//! documentation): no a-priori bound, but on the 60-state stage's loopshaping controller 5
//! states within 0.5 dB of |S| and |T| and of ‖S‖∞ where the truncations need 16 and 18
//! (`tests/tests/controller_reduction.rs`). `Auto` takes `LoopFit` for a SISO discrete loop,
//! else `ClosedLoopWeighted`. `Plain` is unweighted balanced truncation, for comparison.
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
    /// The rational fit of K's response weighted by the loop's sensitivities (SISO).
    LoopFit,
    /// `LoopFit` for a SISO discrete loop, else `ClosedLoopWeighted` (the result names the
    /// one used).
    Auto,
}

impl ReductionMethod {
    /// `Auto` made concrete for controller `k`: `LoopFit` for a SISO discrete controller,
    /// else `ClosedLoopWeighted`; the other methods as they are.
    pub fn resolved(self, k: &StateSpace) -> ReductionMethod {
        match self {
            ReductionMethod::Auto if (k.ny(), k.nu()) == (1, 1) && k.ts().is_some() => {
                ReductionMethod::LoopFit
            }
            ReductionMethod::Auto => ReductionMethod::ClosedLoopWeighted,
            m => m,
        }
    }
}

impl std::str::FromStr for ReductionMethod {
    type Err = AnalysisError;
    /// The names `sdctl reduce --method` and Python take: `weighted`, `plain`, `coprime`,
    /// `fit`, `auto`.
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "weighted" => Ok(ReductionMethod::ClosedLoopWeighted),
            "plain" => Ok(ReductionMethod::Plain),
            "coprime" => Ok(ReductionMethod::CoprimeFactor),
            "fit" => Ok(ReductionMethod::LoopFit),
            "auto" => Ok(ReductionMethod::Auto),
            other => Err(AnalysisError::InvalidArgument(format!(
                "reduction method {other:?}: use `weighted` (closed-loop weight), `coprime` \
                 (normalized coprime factors), `fit` (loop-weighted rational fit, SISO), \
                 `auto` (`fit` where it applies, else `weighted`) or `plain`"
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
    let cross = if before.crossover_hz.is_finite() {
        before.crossover_hz
    } else {
        before.bandwidth_hz
    };
    let nyquist = p.ts().map_or(f64::INFINITY, |ts| 0.5 / ts);
    let band_hz = (2.0 * cross).min(0.999 * nyquist);
    let method = method.resolved(k);
    let (kr, hankel_sv) = match method {
        ReductionMethod::ClosedLoopWeighted => {
            // PS realized by the closed loop itself (its states are the loop's: stable), not
            // as P in series with S, which carries P's rigid-body poles uncancelled
            let r = k.weighted_balanced_truncation(order, Some(full.closed_loop()), None)?;
            (r.model, r.hankel_sv)
        }
        ReductionMethod::Plain => {
            let r = k.balanced_truncation(order)?;
            (r.model, r.hankel_sv)
        }
        ReductionMethod::CoprimeFactor => {
            let r = coprime(k, order, &before)?;
            (r.model, r.hankel_sv)
        }
        // `Auto` is resolved above
        ReductionMethod::LoopFit | ReductionMethod::Auto => {
            let fits = crate::reduce_fit::loop_fit(k, &full, order, band_hz)?;
            let margin = before.modulus_margin;
            (best_fit(p, (&full, margin), fits, band_hz)?, Vec::new())
        }
    };
    let (after, ds, dt) = judge(p, &full, &kr, band_hz)?;
    if !after.stable {
        return Err(AnalysisError::ReductionFailed(format!(
            "the controller reduced to {} states by {method:?} does not stabilize the loop \
             (closed-loop pole radius/abscissa {:.6}); keep more states",
            kr.n(),
            after.closed_loop_radius
        )));
    }
    Ok(ControllerReduction {
        orders: (k.n(), kr.n()),
        controller: kr,
        method,
        hankel_sv,
        band_hz,
        max_delta_s_db: ds,
        max_delta_t_db: dt,
        before,
        after,
    })
}

/// The loop with the reduced controller `kr`: its summary and the largest |ΔS|, |ΔT| (dB)
/// against the full loop below `band_hz` on a 400-point log grid from 0.05 % of it (NaN
/// without a finite band).
fn judge(
    p: &StateSpace,
    full: &ClosedLoop,
    kr: &StateSpace,
    band_hz: f64,
) -> Result<(Summary, f64, f64)> {
    let reduced = ClosedLoop::new(p, kr)?;
    let after = reduced.summary()?;
    if !(band_hz.is_finite() && band_hz > 0.0) {
        return Ok((after, f64::NAN, f64::NAN));
    }
    let mut worst = (0.0f64, 0.0f64);
    for f in grid(band_hz * 1e-3 / 2.0, band_hz, 400, true)? {
        let (a, b) = (full.responses(f)?, reduced.responses(f)?);
        let db = |x: f64, y: f64| (20.0 * (y / x).log10()).abs();
        worst.0 = worst.0.max(db(sigma(&a.s), sigma(&b.s)));
        worst.1 = worst.1.max(db(sigma(&a.t), sigma(&b.t)));
    }
    Ok((after, worst.0, worst.1))
}

/// Among the loop-weighted fits, the one whose loop is stable with the least
/// `max(|ΔS|, |ΔT|)` in the band ([`judge`]) and rise of `‖S‖∞` (dB; the modulus margin's
/// loss anywhere, above the band too) against the full loop `full` of modulus margin
/// `full_margin`.
///
/// # Errors
/// [`AnalysisError::ReductionFailed`] when no fit stabilizes the loop.
fn best_fit(
    p: &StateSpace,
    (full, full_margin): (&ClosedLoop, f64),
    fits: Vec<StateSpace>,
    band_hz: f64,
) -> Result<StateSpace> {
    let mut best: Option<(f64, StateSpace)> = None;
    let mut least_radius = f64::INFINITY;
    let n = fits.first().map_or(0, StateSpace::n);
    for kr in fits {
        let Ok((after, ds, dt)) = judge(p, full, &kr, band_hz) else {
            continue;
        };
        least_radius = least_radius.min(after.closed_loop_radius);
        // the band's changes, and a peak of |S| anywhere that rose (a margin lost above the
        // band, where |ΔS| is not judged)
        let peak_rise = 20.0 * (full_margin / after.modulus_margin).log10();
        let worst = if ds.is_nan() { 0.0 } else { ds.max(dt) }.max(peak_rise);
        if after.stable && best.as_ref().is_none_or(|b| worst < b.0) {
            best = Some((worst, kr));
        }
    }
    best.map(|b| b.1).ok_or_else(|| {
        AnalysisError::ReductionFailed(format!(
            "the controller reduced to {n} states by LoopFit does not stabilize the loop \
             with any of its emphases (least closed-loop pole radius {least_radius:.6}); keep \
             more states"
        ))
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
