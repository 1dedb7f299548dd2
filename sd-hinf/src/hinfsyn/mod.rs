//! H∞ synthesis on a generalized plant, continuous or discrete time: γ-iteration to a stated
//! tolerance, the central controller, and the achieved closed-loop norm checked by the
//! toolkit's own H∞ norm.
//!
//! **Problem.** Given `P` with the partition of [`crate::lft`] (the last `nmeas` outputs are
//! measured, the last `ncon` inputs are controls), find `u = K y` that stabilizes the loop and
//! makes `‖F_l(P, K)‖∞ < γ`, for the least γ we can certify.
//!
//! **Method.** A discrete plant is carried to continuous time by the exact bilinear map, which
//! preserves stability and the H∞ norm of every loop; D₂₂ is removed by a loop shift and
//! D₁₂, D₂₁ scaled to `[0; I]`, `[0 I]` ([`normalize`](self) step); at each γ the Glover–Doyle
//! conditions (D₁₁ ≠ 0 allowed) are tested and the central controller's loop must be stable
//! (`central` step). γ_min is found by bisection in log γ between a level that fails and one
//! that passes until they are within the relative tolerance; the controller is the central one
//! at the passing end (or at the γ the user asks for), mapped back to the plant's time domain.
//! Its loop is then closed with the user's own plant and its norm computed independently
//! ([`sd_model::StateSpace::hinf_norm`]); it must be ≤ γ(1 + [`tol::ACHIEVED`]) with all poles
//! stable, else γ is raised by the tolerance (up to ten times) and the failure reported.
//! Before the full norm, σ̄ of the loop at a few frequencies (where an earlier level's loop
//! failed, DC, and for a discrete loop a log grid up to Nyquist) is compared with that bound:
//! each is a lower bound of the norm, so one above it settles a failure without the level-set
//! search.
//!
//! **Speed.** The existence test's two Riccati equations go through their Cayley-transformed
//! DAREs by doubling (`riccati/cayley.rs`, the ordered Schur method as fallback); on the
//! 64-state mixed-sensitivity plant of `cargo xtask bench --only hinfsyn` (the 60-state stage
//! at 1 kHz) that took the γ-optimal synthesis from 5.7 s to the figure that bench reports.
//!
//! **Why not SLICOT's discrete SB10DD formulas:** the bilinear route reuses one set of
//! continuous formulas and Riccati solver for both domains, and its existence test is the
//! standard one; the result is checked, not trusted (the γ-iteration records every level it
//! tried and why a level failed).
//!
//! **Refused with the reason** (never a silent wrong controller): D₁₂ or D₂₁ without full
//! rank at infinite frequency (for a discrete plant: at z = −1), a pole at z = −1, a plant no
//! controller stabilizes (no γ up to `gamma_max` passes: the report names the condition that
//! failed last), a γ below γ_min.

mod central;
mod normalize;

use crate::error::{HinfError, Result};
use crate::lft::{lft_lower, Partition};
use crate::tol;
use central::Level;
use normalize::Normalized;
use rayon::prelude::*;
use sd_model::linalg::convert::eigenvalues;
use sd_model::{SampleTime, StateSpace};
use serde::{Deserialize, Serialize};

/// Options of [`hinfsyn()`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HinfOptions {
    /// Design at this γ (it must be at least γ_min) instead of at γ_min.
    pub gamma: Option<f64>,
    /// Relative tolerance of the γ iteration: γ_min is certified feasible and
    /// `γ_min/(1 + tolerance)` was found infeasible.
    pub tolerance: f64,
    /// Give up (no controller exists) when no γ up to this passes.
    pub gamma_max: f64,
}

impl Default for HinfOptions {
    fn default() -> Self {
        HinfOptions {
            gamma: None,
            tolerance: tol::GAMMA_TOL,
            gamma_max: 1e12,
        }
    }
}

/// What the test at one γ found.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "result", rename_all = "snake_case")]
pub enum GammaOutcome {
    /// All conditions hold and the central controller's loop is stable.
    Feasible,
    /// γ is at or below the Parrott bound of D₁₁: no controller reaches it.
    BelowParrott {
        /// The bound.
        bound: f64,
    },
    /// The X∞ Riccati equation has no stabilizing solution.
    XRiccati {
        /// Why.
        reason: String,
    },
    /// The Y∞ Riccati equation has no stabilizing solution.
    YRiccati {
        /// Why.
        reason: String,
    },
    /// X∞ is not positive semidefinite.
    XIndefinite {
        /// Its smallest eigenvalue over its 2-norm.
        min_eigenvalue: f64,
    },
    /// Y∞ is not positive semidefinite.
    YIndefinite {
        /// Its smallest eigenvalue over its 2-norm.
        min_eigenvalue: f64,
    },
    /// The coupling condition `ρ(X∞Y∞) < γ²` fails.
    Coupling {
        /// ρ(X∞Y∞).
        spectral_radius: f64,
        /// γ².
        gamma_squared: f64,
    },
    /// A factor of the central controller is singular (γ numerically at the optimum).
    ControllerSingular,
    /// The central controller's loop is not stable (continuous-domain spectral abscissa).
    LoopUnstable {
        /// Largest real part of the closed-loop poles (bilinear domain).
        abscissa: f64,
    },
}

/// One level the γ iteration tried.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GammaStep {
    /// γ.
    pub gamma: f64,
    /// What the test found.
    pub outcome: GammaOutcome,
}

/// The result of [`hinfsyn()`].
#[derive(Debug, Clone, Serialize)]
pub struct HinfSynthesis {
    /// The controller, `u = K y`, in the plant's time domain (serialized by the caller).
    #[serde(skip)]
    pub controller: StateSpace,
    /// The level the controller was built for.
    pub gamma: f64,
    /// The least level found feasible (a stabilizing controller achieving it exists).
    pub gamma_min: f64,
    /// The largest level found infeasible below γ_min (`γ_min/γ_infeasible ≤ 1 + tolerance`).
    pub gamma_infeasible: f64,
    /// The relative tolerance of the iteration.
    pub tolerance: f64,
    /// `‖F_l(P, K)‖∞` computed on the user's plant by the toolkit's H∞ norm.
    pub achieved_norm: f64,
    /// Frequency of the peak (Hz; rad/s/2π for a continuous plant).
    pub peak_hz: f64,
    /// Whether all closed-loop poles are stable.
    pub closed_loop_stable: bool,
    /// Largest closed-loop pole modulus (discrete) or real part (continuous).
    pub closed_loop_extreme_pole: f64,
    /// Controller order.
    pub controller_order: usize,
    /// Relative residuals of the X∞ and Y∞ Riccati equations at γ.
    pub riccati_residuals: [f64; 2],
    /// Their condition estimates.
    pub riccati_conditions: [f64; 2],
    /// Every level tried, in order.
    pub steps: Vec<GammaStep>,
}

/// H∞ synthesis (module documentation).
///
/// # Errors
/// [`HinfError::InvalidArgument`] for a wrong partition, rank-deficient D₁₂/D₂₁, a pole at
/// z = −1, a γ below γ_min, or a bad option; [`HinfError::NoStabilizingSolution`] when no
/// γ up to `gamma_max` passes; [`HinfError::Numerical`] when the controller at the certified γ
/// fails the independent check.
pub fn hinfsyn(p: &StateSpace, part: Partition, opt: &HinfOptions) -> Result<HinfSynthesis> {
    check_options(opt)?;
    stabilizable(p, part)?;
    let nz = normalize::normalize(p, part)?;
    let mut it = Iteration {
        nz: &nz,
        steps: Vec::new(),
    };
    let (gamma_min, gamma_infeasible, best) = it.bisect(opt)?;
    let (gamma, level) = match opt.gamma {
        None => (gamma_min, best),
        Some(g) => match it.test(g)? {
            Some(level) => (g, level),
            None => {
                return Err(HinfError::InvalidArgument(format!(
                    "γ = {g} is below γ_min = {gamma_min:.6e} (the least level at which a \
                     stabilizing controller exists, to relative tolerance {}): choose γ ≥ \
                     γ_min",
                    opt.tolerance
                )))
            }
        },
    };
    it.finish(p, part, gamma, level, opt, (gamma_min, gamma_infeasible))
}

/// Refuses a plant no controller stabilizes: a mode on or outside the stability boundary that
/// the controls cannot move or the measurements do not see (PBH tests at
/// [`tol::PBH_REFUSE`], a rank deficiency at roundoff level; a mode that is only weakly
/// reachable is left to the Riccati test, whose failure is reported per γ).
fn stabilizable(p: &StateSpace, part: Partition) -> Result<()> {
    let bl = part.split(p)?;
    let discrete = p.time().is_discrete();
    let scale = bl.a.norm();
    let place = |z: num_complex::Complex64| {
        format!(
            "the mode at {} = {:.6}{:+.6}i",
            if discrete { "z" } else { "s" },
            z.re,
            z.im
        )
    };
    if let Some(z) = crate::riccati::unmovable_mode(&bl.a, &bl.b2, discrete, scale, tol::PBH_REFUSE)
    {
        return Err(HinfError::InvalidArgument(format!(
            "no controller stabilizes this plant: {} is unstable and the controls cannot move it ((A, B₂) is not stabilizable); check the partition (ncon = {}) or the plant",
            place(z),
            part.ncon
        )));
    }
    let at = bl.a.transpose();
    if let Some(z) =
        crate::riccati::unmovable_mode(&at, &bl.c2.transpose(), discrete, scale, tol::PBH_REFUSE)
    {
        return Err(HinfError::InvalidArgument(format!(
            "no controller stabilizes this plant: {} is unstable and the measurements do not see it ((C₂, A) is not detectable); check the partition (nmeas = {}) or the plant",
            place(z),
            part.nmeas
        )));
    }
    Ok(())
}

fn check_options(opt: &HinfOptions) -> Result<()> {
    let bad = |what: &str, v: f64| {
        HinfError::InvalidArgument(format!("{what} must be a positive finite number, got {v}"))
    };
    if !(opt.tolerance.is_finite() && opt.tolerance > 0.0 && opt.tolerance < 1.0) {
        return Err(bad("the γ tolerance (below 1)", opt.tolerance));
    }
    if !(opt.gamma_max.is_finite() && opt.gamma_max > 0.0) {
        return Err(bad("gamma_max", opt.gamma_max));
    }
    if let Some(g) = opt.gamma {
        if !(g.is_finite() && g > 0.0) {
            return Err(bad("γ", g));
        }
    }
    Ok(())
}

/// The γ iteration's state: the problem and the record of the levels tried.
struct Iteration<'a> {
    nz: &'a Normalized,
    steps: Vec<GammaStep>,
}

impl Iteration<'_> {
    /// Tests one level and records it.
    fn test(&mut self, gamma: f64) -> Result<Option<Level>> {
        let r = central::at_gamma(self.nz, gamma)?;
        let outcome = match &r {
            Ok(_) => GammaOutcome::Feasible,
            Err(o) => o.clone(),
        };
        self.steps.push(GammaStep { gamma, outcome });
        Ok(r.ok())
    }

    /// `(γ_min, the largest infeasible level below it, the level at γ_min)`.
    fn bisect(&mut self, opt: &HinfOptions) -> Result<(f64, f64, Level)> {
        let bound = central::parrott(self.nz);
        let mut g = (2.0 * bound).max(1.0).min(opt.gamma_max);
        let (mut lo, mut hi, mut best);
        match self.test(g)? {
            Some(level) => {
                hi = g;
                best = level;
                lo = bound;
                // search down for a failing level when the Parrott bound gives none > 0
                while lo <= 0.0 {
                    g = hi / 4.0;
                    match self.test(g)? {
                        Some(level) if g > f64::MIN_POSITIVE * 1e10 => {
                            hi = g;
                            best = level;
                        }
                        Some(_) => return Ok((hi, 0.0, best)),
                        None => lo = g,
                    }
                }
            }
            None => {
                lo = g;
                loop {
                    g *= 4.0;
                    if g > opt.gamma_max {
                        return Err(self.no_controller(opt.gamma_max));
                    }
                    if let Some(level) = self.test(g)? {
                        hi = g;
                        best = level;
                        break;
                    }
                    lo = g;
                }
            }
        }
        while hi > lo * (1.0 + opt.tolerance) {
            let mid = (lo * hi).sqrt();
            match self.test(mid)? {
                Some(level) => {
                    hi = mid;
                    best = level;
                }
                None => lo = mid,
            }
        }
        Ok((hi, lo, best))
    }

    fn no_controller(&self, gamma_max: f64) -> HinfError {
        let last = self
            .steps
            .last()
            .map(|s| format!("{:?}", s.outcome))
            .unwrap_or_default();
        HinfError::NoStabilizingSolution {
            equation: "H∞ synthesis".into(),
            reason: format!(
                "no γ up to {gamma_max:e} admits a stabilizing controller (last test: {last}); \
                 check that the controls can stabilize the plant ((A, B₂) stabilizable) and \
                 the measurements see every unstable mode ((C₂, A) detectable), and that P₁₂ \
                 and P₂₁ have no zeros on the stability boundary"
            ),
        }
    }

    /// The controller on the user's plant, checked independently; γ raised by the tolerance
    /// (at most ten times) while the check fails and γ was the iteration's own.
    fn finish(
        mut self,
        p: &StateSpace,
        part: Partition,
        mut gamma: f64,
        mut level: Level,
        opt: &HinfOptions,
        (gamma_min, mut gamma_infeasible): (f64, f64),
    ) -> Result<HinfSynthesis> {
        let mut tries = 0;
        let mut probes = vec![0.0];
        loop {
            let k = self.nz.restore(&level.controller)?;
            let cl = lft_lower(p, &k, part)?;
            let bound = gamma * (1.0 + tol::ACHIEVED);
            let (why, peak_hz) = match probe(&cl, &probes, bound) {
                Some((v, f)) => (format!("σ̄ of the closed loop is {v:.6e} at {f:.6e} Hz"), f),
                None => {
                    let norm = cl.hinf_norm()?;
                    if norm.stable && norm.value <= bound {
                        let bracket = (gamma_min, gamma_infeasible);
                        return Ok(self.result(k, &cl, (gamma, level), opt, bracket, norm));
                    }
                    (
                        format!(
                            "closed loop stable: {}, achieved norm {:.6e}",
                            norm.stable, norm.value
                        ),
                        norm.peak_hz,
                    )
                }
            };
            if peak_hz.is_finite() && !probes.contains(&peak_hz) {
                probes.push(peak_hz);
            }
            tries += 1;
            if opt.gamma.is_some() || tries > 10 {
                return Err(HinfError::Numerical(format!(
                    "the central controller at γ = {gamma:.6e} fails the independent check on \
                     the plant ({why}; the bound is γ(1 + {})): the problem is too \
                     ill-conditioned at this level; try a larger γ",
                    tol::ACHIEVED
                )));
            }
            // the level whose controller failed the check is the new lower end
            gamma_infeasible = gamma;
            gamma *= 1.0 + opt.tolerance;
            match self.test(gamma)? {
                Some(l) => level = l,
                None => continue,
            }
        }
    }

    /// The result for the controller `k` at `(γ, level)` that passed the check with closed
    /// loop `cl` and norm `norm`; `bracket` is the iteration's `(γ_min, γ_infeasible)`.
    fn result(
        self,
        k: StateSpace,
        cl: &StateSpace,
        (gamma, level): (f64, Level),
        opt: &HinfOptions,
        (gamma_min, gamma_infeasible): (f64, f64),
        norm: sd_model::HinfNorm,
    ) -> HinfSynthesis {
        HinfSynthesis {
            controller_order: k.n(),
            controller: k,
            gamma,
            // a level raised by the check is the least one certified
            gamma_min: if opt.gamma.is_none() {
                gamma
            } else {
                gamma_min
            },
            gamma_infeasible,
            tolerance: opt.tolerance,
            achieved_norm: norm.value,
            peak_hz: norm.peak_hz,
            closed_loop_stable: norm.stable,
            closed_loop_extreme_pole: closed_loop_extreme(cl),
            riccati_residuals: [level.x.residual, level.y.residual],
            riccati_conditions: [level.x.condition, level.y.condition],
            steps: self.steps,
        }
    }
}

/// Largest closed-loop pole modulus (discrete) or real part (continuous); NaN when the
/// eigenvalues cannot be computed.
fn closed_loop_extreme(cl: &StateSpace) -> f64 {
    let Ok(ev) = eigenvalues(cl.a()) else {
        return f64::NAN;
    };
    if cl.time().is_discrete() {
        ev.iter().fold(0.0f64, |a, z| a.max(z.norm()))
    } else {
        ev.iter().fold(f64::NEG_INFINITY, |a, z| a.max(z.re))
    }
}

/// A quick proof that a closed loop fails the check: σ̄ of its response (dense solves, the
/// reference evaluation) at the frequencies where earlier controllers failed (DC first) and, for
/// a discrete loop, at the Nyquist frequency and 24 log-spaced frequencies from 10⁻⁶ to 1 times
/// it. Each value is a lower bound of the H∞ norm (of the L∞ norm when the loop is unstable,
/// which fails anyway), so one above `bound` settles it: `Some((σ̄, Hz))` without the full
/// norm; `None` when no probe exceeds it, and the full norm decides. Near γ_min the central
/// controllers of successive levels tend to fail at the same low frequency, where this costs a
/// few dense solves instead of a level-set search.
fn probe(cl: &StateSpace, at_hz: &[f64], bound: f64) -> Option<(f64, f64)> {
    let mut freqs: Vec<f64> = at_hz.to_vec();
    let time = cl.time();
    if let SampleTime::Discrete { ts } = time {
        let nyquist = 0.5 / ts;
        freqs.push(nyquist);
        freqs.extend((0..24).map(|i| nyquist * 10f64.powf(-6.0 + 6.0 * f64::from(i) / 23.0)));
    }
    freqs
        .par_iter()
        .filter_map(|&f| {
            let g = cl.eval_direct(time.point(f)).ok()?;
            let v = g.singular_values().iter().fold(0.0f64, |a, x| a.max(*x));
            (v.is_finite() && v > bound).then_some((v, f))
        })
        .reduce_with(|a, b| if b.0 > a.0 { b } else { a })
}
