//! Robust stability of a loop against a data-derived uncertainty bound.
//!
//! **Math.** Negative feedback `u = −K y`. Additive uncertainty `P = P̂ + Δ`: the perturbed
//! return difference is `1 + (P̂ + Δ)K = (1 + P̂K)(1 + Δ·KS)`; multiplicative `P = P̂(1 + Δ)`:
//! `(1 + P̂K)(1 + Δ·T)`. With the nominal loop stable, every stable `Δ` with
//! `|Δ(e^{jωT})| ≤ β·w(ω)` keeps the loop stable if and only if `β·w(ω)|M(e^{jωT})| < 1` at
//! every ω, `M = KS` (additive) or `T` (multiplicative): the small-gain theorem, necessary and
//! sufficient for an unstructured complex SISO perturbation (Zhou, Doyle & Glover, *Robust and
//! Optimal Control*, 1996, Thm. 9.1; Skogestad & Postlethwaite, *Multivariable Feedback
//! Control*, 2005, §7.5). The **robust stability margin** `β* = 1/max_ω w|M|` is the largest
//! scaling of the uncertainty the loop tolerates; above 1 the loop is robustly stable.
//!
//! - On the bound's lines (`w = b_k`, what the data say): [`Robust::margin_lines`].
//! - Between the lines the bound says nothing; an overbounding weight `W(z)` with `|W| ≥ b` on
//!   every line ([`crate::overbound`]) does: `β_W = 1/‖W·M‖∞` ([`Robust::margin_weight`];
//!   the peak from dense logarithmic and linear grids refined by golden section, relative
//!   accuracy about 1e-6 for peaks wider than the grid spacing). `β_W ≤ β_lines` up to the
//!   weight's conservatism.
//! - **Worst-case sensitivity** (the robust-performance peak): `S_Δ = S/(1 + Δ·M)`, so
//!   `|S_Δ| ≤ |S|/(1 − b|M|)` with equality for the worst phase of `Δ`; its largest value over
//!   the lines ([`Robust::worst_sensitivity_db`]; infinite when `β_lines ≤ 1`).
//! - **A destabilising plant** when `β_lines < 1` ([`destabilising`]): at the line `f₀` of the
//!   largest `b|M|`, `Δ(f₀) = −(1 + ε)/M(f₀)` (within the bound there) is realised as
//!   `Δ(z) = ±g·A_a(z)·N(z)`, a second-order resonator `N` peaking at `f₀` (zeros at DC and
//!   Nyquist) times a first-order all-pass `A_a(z) = (1 − az)/(z − a)` whose phase at `f₀`
//!   sweeps a half-turn as `a` runs over (−1, 1) (the sign gives the other half). The
//!   resonator is narrowed until `|Δ| ≤ b` holds on every line; the perturbed loop's
//!   closed-loop poles are then computed, not assumed: `1 + Δ·M = −ε` at `f₀` moves the
//!   Nyquist curve across −1.
//!
//! Discrete SISO loops at the bound's sample time.

use crate::bound::{Bound, Form};
use crate::error::{Result, UncertaintyError};
use num_complex::Complex64 as C;
use sd_analysis::ClosedLoop;
use sd_model::{SampleTime, StateSpace, TransferFunction};
use std::f64::consts::{PI, TAU};

/// The robust stability of a loop against a bound.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Robust {
    /// The bound's form (what `Δ` perturbs).
    pub form: Form,
    /// Whether the nominal loop is stable (the margins assume it).
    pub nominal_stable: bool,
    /// `1/max_k b_k|M(f_k)|` over the bound's lines (0 when the nominal loop is unstable).
    pub margin_lines: f64,
    /// The line where `b|M|` is largest (Hz).
    pub worst_line_hz: f64,
    /// `1/‖W·M‖∞` with the overbounding weight, where one is given (0 when the nominal loop
    /// is unstable).
    pub margin_weight: Option<f64>,
    /// Where `|W·M|` peaks (Hz).
    pub weight_peak_hz: Option<f64>,
    /// Largest worst-case `|S|` over the lines, `|S|/(1 − b|M|)`, in dB (infinite when
    /// `margin_lines ≤ 1`).
    pub worst_sensitivity_db: f64,
    /// Its line (Hz).
    pub worst_sensitivity_hz: f64,
    /// A plant inside the bound that the controller does not stabilise (when
    /// `margin_lines < 1`).
    pub destabilising: Option<Destabilising>,
}

/// A perturbation inside the bound that destabilises the loop.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Destabilising {
    /// Where it acts (Hz).
    pub freq_hz: f64,
    /// `|Δ(f₀)|` (the form's units).
    pub magnitude: f64,
    /// The bound there.
    pub bound_at: f64,
    /// Largest `|Δ(f_k)|/b_k` over the lines (≤ 1: inside the bound).
    pub max_ratio_to_bound: f64,
    /// Spectral radius of the perturbed closed loop (> 1: unstable).
    pub closed_loop_radius: f64,
    /// `Δ(z)`.
    #[serde(skip)]
    pub perturbation: StateSpace,
    /// The perturbed plant `P̂ + Δ` or `P̂(1 + Δ)`.
    #[serde(skip)]
    pub plant: StateSpace,
}

/// `M = KS` (additive) or `T` (multiplicative) of a loop's responses.
fn m_of(r: &sd_analysis::Responses, form: Form) -> C {
    match form {
        Form::Additive => r.ks[(0, 0)],
        Form::Multiplicative => r.t[(0, 0)],
    }
}

/// `M` at `f` Hz.
fn m_at(cl: &ClosedLoop, form: Form, f: f64) -> Result<C> {
    Ok(m_of(&cl.responses(f)?, form))
}

/// Checks the loop and the bound belong together: discrete SISO at the bound's sample time,
/// and the bound's nominal is the plant's response (to 1e-6 of its largest value).
fn check(plant: &StateSpace, controller: &StateSpace, bound: &Bound) -> Result<()> {
    for (what, m) in [("plant", plant), ("controller", controller)] {
        if m.nu() != 1 || m.ny() != 1 {
            return Err(UncertaintyError::Input(format!(
                "the {what} is {}x{}: robust analysis with a scalar bound needs SISO models",
                m.ny(),
                m.nu()
            )));
        }
        match m.time() {
            SampleTime::Discrete { ts } if (ts - bound.ts).abs() <= 1e-9 * bound.ts => {}
            _ => {
                return Err(UncertaintyError::Input(format!(
                    "the {what} must be discrete at the bound's sample time {} s (use `sdctl \
                     downsample --uncertainty` for a bound at a slower rate)",
                    bound.ts
                )))
            }
        }
    }
    let resp = plant.freqresp(&bound.freq_hz)?;
    let scale = bound.nominal.iter().map(|c| c.norm()).fold(0.0, f64::max);
    let worst = resp
        .response()
        .iter()
        .zip(&bound.nominal)
        .map(|(p, n)| (p[(0, 0)] - n).norm())
        .fold(0.0, f64::max);
    if worst > 1e-6 * scale.max(f64::MIN_POSITIVE) {
        return Err(UncertaintyError::Input(format!(
            "the bound was made for another model: its nominal differs from the plant's \
             response by {worst:.3e} (largest |P̂| {scale:.3e}); give the plant the bound came from"
        )));
    }
    Ok(())
}

/// `b_k·|M(f_k)|` on every line of `bound` (`M = KS` or `T` by the bound's form): where the
/// loop is closest to instability under the bound (`1/max` is the margin; a band's `1/max`
/// the margin that band alone leaves).
///
/// # Errors
/// As [`robust_stability`].
pub fn loading_per_line(
    plant: &StateSpace,
    controller: &StateSpace,
    bound: &Bound,
) -> Result<Vec<(f64, f64)>> {
    check(plant, controller, bound)?;
    let cl = ClosedLoop::new(plant, controller)?;
    bound
        .freq_hz
        .iter()
        .zip(bound.values())
        .map(|(&f, b)| Ok((f, b * m_at(&cl, bound.form, f)?.norm())))
        .collect()
}

/// The robust stability of the loop `(plant, controller)` against `bound`, with the margin
/// of the overbounding `weight` where given (module documentation).
///
/// # Errors
/// Models that are not SISO or not at the bound's sample time; a bound made for another
/// plant; a weight at another sample time; numerical failures of the loop.
pub fn robust_stability(
    plant: &StateSpace,
    controller: &StateSpace,
    bound: &Bound,
    weight: Option<&StateSpace>,
) -> Result<Robust> {
    check(plant, controller, bound)?;
    let cl = ClosedLoop::new(plant, controller)?;
    let (_, nominal_stable) = cl.stability()?;
    let b = bound.values();
    let mut worst = (0.0f64, bound.freq_hz.first().copied().unwrap_or(0.0));
    let mut ws = (0.0f64, worst.1);
    for (&f, &bk) in bound.freq_hz.iter().zip(&b) {
        let r = cl.responses(f)?;
        let x = bk * m_of(&r, bound.form).norm();
        if x > worst.0 {
            worst = (x, f);
        }
        let s = r.s[(0, 0)].norm();
        let w = if x < 1.0 {
            s / (1.0 - x)
        } else {
            f64::INFINITY
        };
        if w > ws.0 {
            ws = (w, f);
        }
    }
    let (margin_weight, weight_peak_hz) = match weight {
        Some(w) => {
            if w.nu() != 1 || w.ny() != 1 || !w.time().compatible(&plant.time()) {
                return Err(UncertaintyError::Input(
                    "the weight must be a SISO model at the bound's sample time".into(),
                ));
            }
            let (peak, f) = weighted_peak(&cl, bound.form, w, bound.ts)?;
            (Some(1.0 / peak), Some(f))
        }
        None => (None, None),
    };
    // a loop unstable without uncertainty tolerates none
    let margin_lines = if nominal_stable { 1.0 / worst.0 } else { 0.0 };
    let margin_weight = margin_weight.map(|m| if nominal_stable { m } else { 0.0 });
    let destabilising = if nominal_stable && margin_lines < 1.0 {
        destabilising(plant, controller, bound, &cl, worst.1)?
    } else {
        None
    };
    Ok(Robust {
        form: bound.form,
        nominal_stable,
        margin_lines,
        worst_line_hz: worst.1,
        margin_weight,
        weight_peak_hz,
        worst_sensitivity_db: 20.0 * ws.0.log10(),
        worst_sensitivity_hz: ws.1,
        destabilising,
    })
}

/// Points of each of the two grids (logarithmic and linear) [`weighted_peak`] scans.
const PEAK_GRID: usize = 4000;

/// `sup_ω |W(e^{jωT})·M(e^{jωT})|` and where: the largest of a logarithmic grid (from 10⁻⁵ of
/// Nyquist) and a linear one, each of [`PEAK_GRID`] points below Nyquist, refined by
/// golden-section search between the best point's neighbours. `M` comes from the loop's
/// separately evaluated `P` and `K` ([`ClosedLoop::responses`]), which stays accurate where a
/// state-space realisation of `KS` keeps the controller's integrator as an uncancelled pole
/// on the unit circle (its H∞ norm would read infinite).
fn weighted_peak(cl: &ClosedLoop, form: Form, w: &StateSpace, ts: f64) -> Result<(f64, f64)> {
    let nyq = 0.5 / ts;
    let ev = sd_model::FreqRespEvaluator::new(w)?;
    let g =
        |f: f64| -> Result<f64> { Ok(ev.eval_hz(f)[(0, 0)].norm() * m_at(cl, form, f)?.norm()) };
    let mut grid: Vec<f64> = (0..PEAK_GRID)
        .map(|i| nyq * 1e-5f64.powf(1.0 - i as f64 / PEAK_GRID as f64))
        .chain((1..PEAK_GRID).map(|i| nyq * i as f64 / PEAK_GRID as f64))
        .collect();
    grid.sort_by(f64::total_cmp);
    let vals: Vec<f64> = grid.iter().map(|&f| g(f)).collect::<Result<_>>()?;
    let i = (0..vals.len())
        .max_by(|a, b| vals[*a].total_cmp(&vals[*b]))
        .unwrap_or(0);
    let (mut a, mut b) = (grid[i.saturating_sub(1)], grid[(i + 1).min(grid.len() - 1)]);
    let r = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..60 {
        let (c, d) = (b - r * (b - a), a + r * (b - a));
        if g(c)? > g(d)? {
            b = d;
        } else {
            a = c;
        }
    }
    let f = 0.5 * (a + b);
    let v = g(f)?;
    Ok(if v >= vals[i] {
        (v, f)
    } else {
        (vals[i], grid[i])
    })
}

/// The resonator `N(z) = (z² − 1)/(z² − 2r cos θ z + r²)` at `θ = 2πf₀T`.
fn resonator(theta: f64, r: f64, ts: f64) -> Result<StateSpace> {
    Ok(TransferFunction::new(
        vec![1.0, 0.0, -1.0],
        vec![1.0, -2.0 * r * theta.cos(), r * r],
        SampleTime::discrete(ts)?,
    )?
    .to_ss()?)
}

/// The phase of the all-pass `A_a(e^{jθ}) = (1 − a e^{jθ})/(e^{jθ} − a)`, in `[−π, 0]`
/// (continuous in `a`, from 0 at `a → −1` to −π at `a → 1`).
fn allpass_phase(a: f64, theta: f64) -> f64 {
    let z = C::from_polar(1.0, theta);
    let p = ((1.0 - a * z) / (z - a)).arg();
    // arg is in (−π, π]; the branch runs in [−π, 0]
    if p > 1e-12 {
        p - TAU
    } else {
        p
    }
}

/// The all-pass parameter whose phase at `theta` is `phi ∈ [−π, 0]` (bisection).
fn allpass_for(phi: f64, theta: f64) -> f64 {
    let (mut lo, mut hi) = (-0.999_999, 0.999_999);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if allpass_phase(mid, theta) > phi {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// A stable `Δ(z)` with `Δ(f₀) = target` and `|Δ(f_k)| ≤ b_k` on every line of `bound`
/// (module documentation: resonator × all-pass × sign, the resonator narrowed until the bound
/// holds), with its largest `|Δ|/b` over the lines; `None` when no resonator narrow enough
/// keeps it inside.
fn perturbation_at(bound: &Bound, f0: f64, target: C) -> Result<Option<(StateSpace, f64)>> {
    let ts = bound.ts;
    let b = bound.values();
    let theta = TAU * f0 * ts;
    let time = SampleTime::discrete(ts)?;
    let mut delta_r = 0.2f64.min(theta.min(PI - theta));
    for _ in 0..40 {
        let r = 1.0 - delta_r;
        delta_r *= 0.5;
        let n = resonator(theta, r, ts)?;
        let n0 = n.freqresp(&[f0])?.response()[0][(0, 0)];
        let mut phi = (target / n0).arg();
        let sign = if phi <= 0.0 {
            1.0
        } else {
            phi -= PI;
            -1.0
        };
        let a = allpass_for(phi, theta);
        let ap = TransferFunction::new(vec![-a, 1.0], vec![1.0, -a], time)?.to_ss()?;
        let g = sign * target.norm() / n0.norm();
        let gain = StateSpace::gain(nalgebra::DMatrix::from_element(1, 1, g), time)?;
        let delta = sd_model::series(&sd_model::series(&n, &ap)?, &gain)?;
        let resp = delta.freqresp(&bound.freq_hz)?;
        let ratio = resp
            .response()
            .iter()
            .zip(&b)
            .map(|(d, bk)| d[(0, 0)].norm() / bk.max(f64::MIN_POSITIVE))
            .fold(0.0, f64::max);
        if ratio <= 1.0 + 1e-9 {
            return Ok(Some((delta, ratio)));
        }
    }
    Ok(None)
}

/// The plant `P̂ + Δ` or `P̂(1 + Δ)` by the bound's form.
fn perturbed(plant: &StateSpace, delta: &StateSpace, form: Form, ts: f64) -> Result<StateSpace> {
    Ok(match form {
        Form::Additive => sd_model::parallel(plant, delta)?,
        Form::Multiplicative => {
            let one = StateSpace::gain(
                nalgebra::DMatrix::from_element(1, 1, 1.0),
                SampleTime::discrete(ts)?,
            )?;
            sd_model::series(&sd_model::parallel(&one, delta)?, plant)?
        }
    })
}

/// The index of line `f0` of `bound`.
fn line_of(bound: &Bound, f0: f64) -> Result<usize> {
    bound
        .freq_hz
        .iter()
        .position(|f| *f == f0)
        .ok_or_else(|| UncertaintyError::Input(format!("{f0} Hz is not a line of the bound")))
}

/// A perturbation inside `bound` that destabilises the loop, built at line `f0` (module
/// documentation): `Δ(f₀) = −(1 + ε)/M(f₀)`, `ε` up to 1 % within the bound there; `None` when
/// no resonator narrow enough keeps it inside the bound.
///
/// # Errors
/// `f0` not a line of the bound; numerical failures of the models.
pub fn destabilising(
    plant: &StateSpace,
    controller: &StateSpace,
    bound: &Bound,
    cl: &ClosedLoop,
    f0: f64,
) -> Result<Option<Destabilising>> {
    let b = bound.values();
    let k0 = line_of(bound, f0)?;
    let c = -1.0 / m_at(cl, bound.form, f0)?;
    let eps = (0.5 * (b[k0] / c.norm() - 1.0)).clamp(0.0, 0.01);
    let Some((delta, ratio)) = perturbation_at(bound, f0, c * (1.0 + eps))? else {
        return Ok(None);
    };
    let plant = perturbed(plant, &delta, bound.form, bound.ts)?;
    let (radius, _) = ClosedLoop::new(&plant, controller)?.stability()?;
    Ok(Some(Destabilising {
        freq_hz: f0,
        magnitude: (1.0 + eps) * c.norm(),
        bound_at: b[k0],
        max_ratio_to_bound: ratio,
        closed_loop_radius: radius,
        perturbation: delta,
        plant,
    }))
}

/// The worst-phase plant at the full bound at line `f0`: `Δ(f₀) = −b₀·M̄(f₀)/|M(f₀)|`, which
/// takes `1 + Δ·M` there to `1 − b₀|M|`, the closest to 0 the bound allows. Against a
/// controller with a margin above 1 on the lines this plant must be stable: a check of the
/// margin where random perturbations rarely go. Returns the perturbed plant and its largest
/// `|Δ|/b` over the lines; `None` as [`destabilising`].
///
/// # Errors
/// As [`destabilising`].
pub fn worst_case_plant(
    plant: &StateSpace,
    controller: &StateSpace,
    bound: &Bound,
    f0: f64,
) -> Result<Option<(StateSpace, f64)>> {
    check(plant, controller, bound)?;
    let cl = ClosedLoop::new(plant, controller)?;
    let k0 = line_of(bound, f0)?;
    let m0 = m_at(&cl, bound.form, f0)?;
    let b0 = bound.values()[k0];
    let target = -b0 * m0.conj() / m0.norm().max(f64::MIN_POSITIVE);
    perturbation_at(bound, f0, target)?
        .map(|(d, r)| perturbed(plant, &d, bound.form, bound.ts).map(|p| (p, r)))
        .transpose()
}
