//! A physical modal model from a measured FRF: the stabilisation diagram of experimental modal
//! analysis, poles no narrower than the data resolve, the order and the rigid body chosen by
//! held-out lines, and an input delay where the data show one.
//!
//! **Stabilisation diagram** (Peeters, Van der Auweraer, Guillaume & Leuridan, "The PolyMAX
//! frequency-domain method", *Shock and Vibration* 11, 2004; Ewins, *Modal Testing*, 2nd ed.,
//! §4.4): the FRF is fitted ([`crate::fit()`]: SK iterations, then Levenberg–Marquardt on the
//! variance-weighted cost) at the orders `n = m + 2, m + 4, …, max_order` (m rigid-body poles),
//! and each pole of order n is compared with the poles of order n − 2: **stable** when one is
//! within [`FREQ_TOL`] (1 %) in natural frequency and [`DAMPING_TOL`] (5 %, relative) in
//! damping, **frequency-stable** when only the frequency matches, **new** otherwise. A
//! physical pole persists across orders; a pole that chases noise or distortion moves.
//!
//! **Resolution** (the data's own limit): the lines are `Δf` apart, so a pole pair whose
//! half-power bandwidth `2ζf_n` is below `Δf` has no line on its peak and its damping is not
//! measured. Every order is fitted twice, free and with the bandwidth floor `Δf`
//! ([`crate::FitOptions::min_bandwidth_hz`]); the free fit is kept only when the data demand it
//! (its held-out cost below the floored fit's by the factor `q` below).
//!
//! **Held-out lines and the order**: the fits see the even-indexed lines; the odd-indexed
//! ones (L lines) are held out. `H(n) = V_held(n)/L`, the held-out cost per line with the
//! FRD's variance (1 = the variance's level). With `H*` the least over every order and
//! rigid-body count, the chosen model is the lowest order with `H(n) ≤ q·H*`,
//! `q = exp(z₀.₉₅·√(2/L))` (the 95 % spread of the ratio of two `χ²_2L/2L` costs): the order
//! beyond which added poles buy nothing the held-out lines can see. When the variance misses a
//! distortion that no linear model can describe, `H*` is far above 1 and the rule still
//! stops at the order where the error stops falling. The rigid body is chosen the same way
//! over m = 0, 1, 2 unless given.
//!
//! **Input delay** (`max_delay > 0`): a rational model absorbs a delay in extra poles and
//! zeros (a Padé approximation), so the delay is chosen with the order, not after it: at
//! every order up to the one chosen without a delay (its rigid body), the delay
//! `δ ∈ [0, max_delay]` whose advanced training lines `G·e^{jωδT}` the fit follows best is
//! searched (half-sample grid, then golden section to 1/100 sample), that fit is judged on
//! the held-out lines, and the order rule runs over every (delay, rigid body, order): a
//! delay wins when it lets a lower order predict the held-out lines as well. Then the
//! fraction: `V(τ)` on `G·e^{jωτT}` (all lines, the chosen order) over `τ ∈ [0, max_delay]`
//! on a grid of 1/8 sample, refined by golden-section search to 1/100 sample around the
//! least; `τ*` replaces `δ` only when `V(τ*) < V(δ)·(1 − 5√(2/M))`, M = 2K real equations
//! (the significance rule of [`crate::input_delay`]). The delays whose `V` is within
//! `V(τ*)(1 + 5√(2/M))` are what the data cannot tell apart: their hull is
//! [`PhysicalFit::delay_interval`] (wide when the zeros absorb the delay: free residues and a
//! feedthrough give the numerator that freedom).
//! [`PhysicalFit::model_with_delay`] is the fitted model preceded by that delay (whole samples
//! exactly, the fraction by Thiran's allpass: [`sd_model::delay`]).
//!
//! The final model is fitted on all lines at the chosen order; each of its terms is a mode of
//! the table with its share of the modal response (`Σ_k|term_k|²` over the sum of all
//! terms'), the number of orders of the diagram at which it is stable, and whether it is a
//! *ripple* (a pair at the bandwidth floor inside a broader resonance's half-power band with
//! no peak of its own: [`FLOOR_RESOLUTION`]).

mod delay;
mod ripple;

use crate::fit::{fit, model_cost, FitOptions, FitResult, ModalTerm, Weighting};
use crate::{IdentError, Result};
use delay::{advance, best_delay, fraction};
use num_complex::Complex64 as C;
use rayon::prelude::*;
pub use ripple::FLOOR_RESOLUTION;
use sd_model::Frd;
use std::f64::consts::PI;

/// Relative natural-frequency tolerance of a stable pole.
pub const FREQ_TOL: f64 = 0.01;
/// Relative damping tolerance of a stable pole.
pub const DAMPING_TOL: f64 = 0.05;
/// One-sided 95 % normal quantile of the held-out order rule.
const Z95: f64 = 1.645;

/// Settings of [`physical_fit`].
#[derive(Debug, Clone, PartialEq)]
pub struct StabilizationOptions {
    /// Highest order of the diagram (states, rigid body included).
    pub max_order: usize,
    /// Rigid-body poles at z = 1; `None`: chosen from the data among 0, 1 and 2.
    pub rigid_body: Option<usize>,
    /// Fit a feedthrough.
    pub feedthrough: bool,
    /// Largest whole-sample input delay tried (0: none).
    pub max_delay: usize,
}

impl Default for StabilizationOptions {
    fn default() -> Self {
        StabilizationOptions {
            max_order: 24,
            rigid_body: None,
            feedthrough: true,
            max_delay: 0,
        }
    }
}

/// A pole's class in the diagram (ordered: new < frequency < stable).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PoleClass {
    /// Nothing alike at the order below.
    New,
    /// The frequency matches a pole of the order below, the damping does not.
    Frequency,
    /// Frequency and damping match.
    Stable,
}

/// One pole of the diagram.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DiagramPole {
    /// The order of the fit.
    pub order: usize,
    /// Natural frequency (Hz) of `ln(p)/T`.
    pub freq_hz: f64,
    /// Damping ratio.
    pub damping: f64,
    /// Class against the order below.
    pub class: PoleClass,
}

/// One order of the scan.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct OrderRow {
    /// States (rigid body included).
    pub order: usize,
    /// Rigid-body poles.
    pub rigid_body: usize,
    /// Training cost per training line.
    pub train_cost: f64,
    /// Held-out cost per held-out line (1 = the variance's level).
    pub heldout_cost: f64,
    /// Whether the bandwidth floor was lifted because the data demand a narrower pair.
    pub free: bool,
    /// The input delay (samples) the FRD was advanced by for this fit.
    pub delay_samples: f64,
}

/// What a mode of the table is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ModeKind {
    /// Poles at z = 1.
    RigidBody,
    /// A real pole.
    Real,
    /// A complex pole pair.
    Pair,
}

/// One mode of the final model.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PhysicalMode {
    /// Kind.
    pub kind: ModeKind,
    /// Natural frequency (Hz; 0 for the rigid body).
    pub freq_hz: f64,
    /// Damping ratio (1 for a real pole, 0 for the rigid body).
    pub damping: f64,
    /// Residue (z-domain partial fraction; the rigid body's `c_1`).
    pub residue: [f64; 2],
    /// Share of the modal response over the lines.
    pub share: f64,
    /// Orders of the diagram (same rigid body) with a pole within [`FREQ_TOL`] in frequency
    /// and [`DAMPING_TOL`] in damping of this one.
    pub stable_orders: usize,
    /// Orders with a pole within [`FREQ_TOL`] in frequency (any damping).
    pub frequency_orders: usize,
    /// Whether its natural frequency is inside the measured band.
    pub in_band: bool,
    /// A pair's half-power bandwidth `2ζf_n` (Hz) over the line spacing (≥ 1: resolved).
    pub resolution: Option<f64>,
    /// A pair at the bandwidth floor inside a broader resonance's half-power band with no
    /// peak of its own ([`FLOOR_RESOLUTION`]; module `ripple`): no mode an analyst would name.
    pub ripple: bool,
}

/// A physical modal model ([`physical_fit`]).
#[derive(Debug, Clone)]
pub struct PhysicalFit {
    /// The final fit (all lines) at the chosen order; it maps the input delayed by
    /// `delay_samples`.
    pub fit: FitResult,
    /// The chosen order.
    pub order: usize,
    /// The chosen rigid-body count.
    pub rigid_body: usize,
    /// Input delay in samples, a fraction allowed (0 when none was searched or found).
    pub delay_samples: f64,
    /// The delays (samples) whose cost on all lines is within the significance rule of the
    /// least: what the data determine. A wide interval means the model's zeros absorb the
    /// delay (free residues give the numerator that freedom); `(0, 0)` without a search.
    pub delay_interval: (f64, f64),
    /// Modes of the final model.
    pub modes: Vec<PhysicalMode>,
    /// The diagram of the chosen rigid-body count.
    pub diagram: Vec<DiagramPole>,
    /// Every order tried.
    pub orders: Vec<OrderRow>,
    /// The order rule's factor `q`.
    pub heldout_factor: f64,
    /// The line spacing (Hz), the resolution floor.
    pub line_spacing_hz: f64,
    /// Cost per line of the final model on all lines (1 = the variance's level).
    pub cost_per_line: f64,
    /// The delay scan (τ in samples, cost), whole samples then the fractional search; empty
    /// without one.
    pub delay_scan: Vec<(f64, f64)>,
}

/// What `modes.json` holds ([`PhysicalFit::summary`]): the choice, the modes, every order's
/// costs, the diagram and the delay search (serde; the fit's warnings as they are).
#[derive(Debug, Clone, serde::Serialize)]
pub struct PhysicalFitSummary<'a> {
    /// The chosen order.
    pub order: usize,
    /// The chosen rigid-body count.
    pub rigid_body: usize,
    /// Input delay (samples).
    pub delay_samples: f64,
    /// The delays the data cannot tell apart, [lo, hi] (samples).
    pub delay_interval: [f64; 2],
    /// Worst phase error (degrees) of the delay's realization in the model with it.
    pub delay_phase_error_deg: f64,
    /// Cost per line on all lines (1 = the variance's level).
    pub cost_per_line: f64,
    /// Line spacing (Hz).
    pub line_spacing_hz: f64,
    /// The order rule's factor `q`.
    pub heldout_factor: f64,
    /// Modes of the final model.
    pub modes: &'a [PhysicalMode],
    /// Every order tried.
    pub orders: &'a [OrderRow],
    /// The stabilisation diagram.
    pub diagram: &'a [DiagramPole],
    /// The delay search at the chosen order, [τ, cost].
    pub delay_scan: &'a [(f64, f64)],
    /// The final fit's warnings.
    pub warnings: &'a [crate::FitWarning],
}

impl PhysicalFit {
    /// The summary of the fit, with the delay realization's phase error from
    /// [`PhysicalFit::model_with_delay`].
    pub fn summary(&self, delay_phase_error_deg: f64) -> PhysicalFitSummary<'_> {
        PhysicalFitSummary {
            order: self.order,
            rigid_body: self.rigid_body,
            delay_samples: self.delay_samples,
            delay_interval: [self.delay_interval.0, self.delay_interval.1],
            delay_phase_error_deg,
            cost_per_line: self.cost_per_line,
            line_spacing_hz: self.line_spacing_hz,
            heldout_factor: self.heldout_factor,
            modes: &self.modes,
            orders: &self.orders,
            diagram: &self.diagram,
            delay_scan: &self.delay_scan,
            warnings: &self.fit.warnings,
        }
    }

    /// The fitted model preceded by its input delay ([`sd_model::input_delay`]: whole samples
    /// exactly, a fraction by Thiran's first-order allpass) and the allpass's worst phase
    /// error (degrees) against the exact delay over `freq_hz` (0 for whole samples).
    ///
    /// # Errors
    /// The model's own errors (a continuous model cannot occur here).
    pub fn model_with_delay(&self, freq_hz: &[f64]) -> Result<(sd_model::StateSpace, f64)> {
        let m = &self.fit.model;
        let ts = m.ts().unwrap_or(1.0);
        let delayed = sd_model::input_delay(m, self.delay_samples)?;
        Ok((
            delayed,
            sd_model::phase_error_deg(self.delay_samples, ts, freq_hz),
        ))
    }
}

/// A scanned order's fits: the training fit and its held-out cost.
struct Scanned {
    row: OrderRow,
    fit: FitResult,
}

/// Fits the physical modal model of a SISO discrete FRD (module documentation).
///
/// # Errors
/// A MIMO or continuous FRD, fewer than 8 lines, a `max_order` below 2 or above 120, a
/// rigid-body count above 2, the fits' errors.
pub fn physical_fit(
    frd: &Frd,
    opt: &StabilizationOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<PhysicalFit> {
    check(frd, opt)?;
    let spacing = line_spacing(frd.freq_hz());
    let train = frd.select(|i| i % 2 == 0)?;
    let held = frd.select(|i| i % 2 == 1)?;
    let q = (Z95 * (2.0 / held.len() as f64).sqrt()).exp();
    let rbs: Vec<usize> = opt.rigid_body.map_or_else(|| vec![0, 1, 2], |r| vec![r]);
    let jobs: Vec<(usize, usize)> = rbs
        .iter()
        .flat_map(|&rb| {
            orders_of(rb, opt.max_order)
                .into_iter()
                .map(move |o| (rb, o))
        })
        .collect();
    progress(&format!(
        "{} fits (orders up to {}, rigid body {:?})",
        jobs.len(),
        opt.max_order,
        rbs
    ));
    let mut scanned = scan_jobs(&train, &held, &jobs, opt, spacing, q)?;
    let mut chosen = choose(&scanned, q, opt.feedthrough)?;
    if opt.max_delay > 0 {
        // a rational model absorbs a delay in extra poles and zeros: at each order up to the
        // one chosen without it (its rigid body), the delay that fits the training lines best
        // is searched, and the order rule then runs over every (delay, rigid body, order)
        let orders = orders_of(chosen.rigid_body, chosen.order);
        progress(&format!(
            "input delays up to {} samples at the orders up to {}",
            opt.max_delay, chosen.order
        ));
        let rb = chosen.rigid_body;
        let with_delay: Vec<Option<Scanned>> = orders
            .par_iter()
            .map(|&o| {
                let fo = fit_options(o, rb, opt, spacing, false);
                let tau = best_delay(&train, &fo, opt.max_delay)?;
                let (t, h) = (advance(&train, tau)?, advance(&held, tau)?);
                scan_order(&t, &h, o, rb, tau, opt, spacing, q)
            })
            .collect::<Result<_>>()?;
        scanned.extend(with_delay.into_iter().flatten());
        chosen = choose(&scanned, q, opt.feedthrough)?;
    }
    let fopt = fit_options(chosen.order, chosen.rigid_body, opt, spacing, chosen.free);
    progress(&format!(
        "chosen order {} (rigid body {}, delay {:.3} samples); final fit on all lines",
        chosen.order, chosen.rigid_body, chosen.delay_samples
    ));
    let start = chosen.delay_samples;
    let delay = fraction(frd, &fopt, start, opt.max_delay)?;
    let shifted = advance(frd, delay.samples)?;
    let final_fit = fit(&shifted, &fopt)?;
    let diagram = diagram_of(&scanned, chosen.rigid_body, frd.time().ts().unwrap_or(1.0));
    let modes = modes_of(&final_fit, &shifted, &diagram, spacing);
    let cost_per_line = final_fit.cost / frd.len() as f64;
    Ok(PhysicalFit {
        fit: final_fit,
        order: chosen.order,
        rigid_body: chosen.rigid_body,
        delay_samples: delay.samples,
        delay_interval: delay.interval,
        modes,
        diagram,
        orders: scanned.into_iter().map(|s| s.row).collect(),
        heldout_factor: q,
        line_spacing_hz: spacing,
        cost_per_line,
        delay_scan: delay.scan,
    })
}

/// The (rigid body, order) fits of `jobs` without a delay, in parallel, kept in job order.
fn scan_jobs(
    train: &Frd,
    held: &Frd,
    jobs: &[(usize, usize)],
    opt: &StabilizationOptions,
    spacing: f64,
    q: f64,
) -> Result<Vec<Scanned>> {
    Ok(jobs
        .par_iter()
        .map(|&(rb, order)| scan_order(train, held, order, rb, 0.0, opt, spacing, q))
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .flatten()
        .collect())
}

/// The order rule (module documentation): the lowest order whose held-out cost is within `q`
/// of the least, then the fewest parameters, then no delay (a delay is chosen here only when
/// it buys a lower order; at the chosen order [`fraction`] judges it on all lines), then the
/// least held-out cost.
fn choose(scanned: &[Scanned], q: f64, feedthrough: bool) -> Result<OrderRow> {
    let best = scanned
        .iter()
        .map(|s| s.row.heldout_cost)
        .fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return Err(IdentError::Data(
            "no order could be fitted: too few lines for the orders asked".into(),
        ));
    }
    scanned
        .iter()
        .filter(|s| s.row.heldout_cost <= q * best)
        .min_by(|a, b| {
            a.row
                .order
                .cmp(&b.row.order)
                .then(parameters(&a.row, feedthrough).cmp(&parameters(&b.row, feedthrough)))
                .then((a.row.delay_samples > 0.0).cmp(&(b.row.delay_samples > 0.0)))
                .then(a.row.heldout_cost.total_cmp(&b.row.heldout_cost))
        })
        .map(|s| s.row.clone())
        .ok_or_else(|| IdentError::Numerical("order selection found no order".into()))
}

/// The settings' and the data's own checks.
fn check(frd: &Frd, opt: &StabilizationOptions) -> Result<()> {
    if frd.shape() != (1, 1) {
        return Err(IdentError::InvalidArgument(format!(
            "the stabilisation fit is SISO; the FRD is {}x{}",
            frd.shape().0,
            frd.shape().1
        )));
    }
    if frd.time().ts().is_none() {
        return Err(IdentError::InvalidArgument(
            "the stabilisation fit needs a discrete FRD (with `ts`)".into(),
        ));
    }
    if frd.len() < 8 {
        return Err(IdentError::Data(format!(
            "{} lines: the stabilisation fit needs at least 8 (half of them are held out)",
            frd.len()
        )));
    }
    if !(2..=120).contains(&opt.max_order) {
        return Err(IdentError::InvalidArgument(format!(
            "max_order {} must be in 2..=120",
            opt.max_order
        )));
    }
    if opt.rigid_body.is_some_and(|r| r > 2) {
        return Err(IdentError::InvalidArgument(
            "rigid_body must be 0, 1 or 2".into(),
        ));
    }
    Ok(())
}

/// The orders of the diagram for `rb` rigid-body poles: every order from `rb` (the rigid
/// body alone; from 1 without one) to `max` (an odd number of free poles has one real pole: a
/// viscously damped rigid body's, a current loop's).
fn orders_of(rb: usize, max: usize) -> Vec<usize> {
    (rb.max(1)..=max).collect()
}

/// The real parameters of an order: pole and residue per free pole, a residue per rigid-body
/// pole, the feedthrough.
fn parameters(row: &OrderRow, feedthrough: bool) -> usize {
    2 * (row.order - row.rigid_body) + row.rigid_body + usize::from(feedthrough)
}

/// The median spacing of the lines (Hz).
fn line_spacing(f: &[f64]) -> f64 {
    let d: Vec<f64> = f.windows(2).map(|w| w[1] - w[0]).collect();
    sd_model::median(&d)
}

/// The fit settings of one order: the bandwidth floor unless `free`.
fn fit_options(
    order: usize,
    rb: usize,
    opt: &StabilizationOptions,
    spacing: f64,
    free: bool,
) -> FitOptions {
    FitOptions {
        order,
        rigid_body: rb,
        feedthrough: opt.feedthrough,
        weighting: Weighting::Variance,
        min_bandwidth_hz: if free { 0.0 } else { spacing },
        ..FitOptions::default()
    }
}

/// One order: the floored fit, and the free one where it has a pair narrower than the
/// floor; the free one kept when its held-out cost is below the floored one's by `q`.
/// `None` when the training lines are too few for the order.
#[allow(clippy::too_many_arguments)]
fn scan_order(
    train: &Frd,
    held: &Frd,
    order: usize,
    rb: usize,
    delay: f64,
    opt: &StabilizationOptions,
    spacing: f64,
    q: f64,
) -> Result<Option<Scanned>> {
    let nparams = 2 * (order - rb) + rb + usize::from(opt.feedthrough);
    if 2 * train.len() <= nparams {
        return Ok(None);
    }
    let heldout = |f: &FitResult| -> Result<f64> {
        Ok(model_cost(held, &f.model, Weighting::Variance)? / held.len() as f64)
    };
    let floored = fit(train, &fit_options(order, rb, opt, spacing, false))?;
    let h_floor = heldout(&floored)?;
    let free = fit(train, &fit_options(order, rb, opt, spacing, true))?;
    let narrow = free.terms.iter().any(|t| match t {
        ModalTerm::Pair { pole, .. } => {
            let (f, z) = natural(*pole, train.time().ts().unwrap_or(1.0));
            2.0 * z * f < spacing
        }
        _ => false,
    });
    let h_free = heldout(&free)?;
    let (fit_kept, h, is_free) = if narrow && h_free * q < h_floor {
        (free, h_free, true)
    } else {
        (floored, h_floor, false)
    };
    Ok(Some(Scanned {
        row: OrderRow {
            order,
            rigid_body: rb,
            train_cost: fit_kept.cost / train.len() as f64,
            heldout_cost: h,
            free: is_free,
            delay_samples: delay,
        },
        fit: fit_kept,
    }))
}

/// Natural frequency (Hz) and damping of a discrete pole.
fn natural(p: C, ts: f64) -> (f64, f64) {
    if p.norm() == 0.0 {
        return (0.5 / ts, 1.0);
    }
    let s = p.ln() / ts;
    let w = s.norm();
    (w / (2.0 * PI), if w > 0.0 { -s.re / w } else { 0.0 })
}

/// The diagram of the scanned orders of `rb` rigid-body poles, each pole classed against the
/// order below.
fn diagram_of(scanned: &[Scanned], rb: usize, ts: f64) -> Vec<DiagramPole> {
    let poles_of = |s: &Scanned| -> Vec<(f64, f64)> {
        s.fit
            .terms
            .iter()
            .filter_map(|t| match t {
                ModalTerm::Pair { pole, .. } => Some(natural(*pole, ts)),
                ModalTerm::Real { pole, .. } => Some(natural(C::new(*pole, 0.0), ts)),
                ModalTerm::Rigid { .. } => None,
            })
            .collect()
    };
    let mut out = Vec::new();
    let mut below: Vec<(f64, f64)> = Vec::new();
    for s in scanned
        .iter()
        .filter(|s| s.row.rigid_body == rb && s.row.delay_samples == 0.0)
    {
        let here = poles_of(s);
        for &(f, z) in &here {
            out.push(DiagramPole {
                order: s.row.order,
                freq_hz: f,
                damping: z,
                class: classify((f, z), &below),
            });
        }
        below = here;
    }
    out
}

/// The class of pole `(f, ζ)` against the poles of the order below.
fn classify((f, z): (f64, f64), below: &[(f64, f64)]) -> PoleClass {
    let mut class = PoleClass::New;
    for &(fb, zb) in below {
        if (f - fb).abs() <= FREQ_TOL * f.max(fb) {
            if (z - zb).abs() <= DAMPING_TOL * z.max(zb) {
                return PoleClass::Stable;
            }
            class = PoleClass::Frequency;
        }
    }
    class
}

/// The modes of the final fit with their shares, stability counts and ripples.
fn modes_of(
    fit: &FitResult,
    frd: &Frd,
    diagram: &[DiagramPole],
    spacing: f64,
) -> Vec<PhysicalMode> {
    let ts = frd.time().ts().unwrap_or(1.0);
    let z: Vec<C> = frd
        .freq_hz()
        .iter()
        .map(|&f| C::from_polar(1.0, 2.0 * PI * f * ts))
        .collect();
    let energy: Vec<f64> = fit
        .terms
        .iter()
        .map(|t| z.iter().map(|&zk| t.eval(zk).norm_sqr()).sum())
        .collect();
    let total: f64 = energy.iter().sum::<f64>().max(f64::MIN_POSITIVE);
    let (flo, fhi) = (
        frd.freq_hz().first().copied().unwrap_or(0.0),
        frd.freq_hz().last().copied().unwrap_or(0.0),
    );
    let mut modes = fit
        .terms
        .iter()
        .zip(&energy)
        .map(|(t, e)| {
            let (kind, (f, d), residue) = match *t {
                ModalTerm::Rigid { residues, .. } => {
                    (ModeKind::RigidBody, (0.0, 0.0), [residues[0], residues[1]])
                }
                ModalTerm::Real { pole, residue } => (
                    ModeKind::Real,
                    natural(C::new(pole, 0.0), ts),
                    [residue, 0.0],
                ),
                ModalTerm::Pair { pole, residue } => {
                    (ModeKind::Pair, natural(pole, ts), [residue.re, residue.im])
                }
            };
            let count = |class: PoleClass| {
                if kind == ModeKind::RigidBody {
                    return 0;
                }
                diagram
                    .iter()
                    .filter(|p| classify((f, d), &[(p.freq_hz, p.damping)]) >= class)
                    .count()
            };
            let (stable_orders, frequency_orders) =
                (count(PoleClass::Stable), count(PoleClass::Frequency));
            PhysicalMode {
                kind,
                freq_hz: f,
                damping: d,
                residue,
                share: e / total,
                stable_orders,
                frequency_orders,
                in_band: f >= flo && f <= fhi,
                resolution: (kind == ModeKind::Pair).then(|| 2.0 * d * f / spacing),
                ripple: false,
            }
        })
        .collect::<Vec<_>>();
    let ripple = ripple::ripples(&modes, &fit.terms, ts);
    for (m, r) in modes.iter_mut().zip(ripple) {
        m.ripple = r;
    }
    modes
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    /// A synthetic FRD in another form than the fit's partial fractions in z: the exact ZOH
    /// response of a rigid body `T²(z + 1)/(2(z − 1)²)` plus two continuous modes
    /// `a_i ω_i²/(s² + 2ζ_iω_is + ω_i²)` (120 Hz, ζ = 0.02; 310 Hz, ζ = 0.01) at `s = j2πf`
    /// through the hold's half-sample lag `e^{−sT/2}` (at most 5 % of the 10 kHz rate, where
    /// that approximates the ZOH within the noise), 250 lines 2 Hz apart, complex Gaussian
    /// noise of 0.5 % of |G|, its variance in the FRD.
    pub(super) fn synthetic(seed: u64) -> Frd {
        let (f1, z1, f2, z2) = (120.0, 0.02, 310.0, 0.01);
        let ts = 1e-4;
        let mut s = seed;
        let mut gauss = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let a = ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let b = ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
            (-2.0 * a.ln()).sqrt() * (2.0 * PI * b).cos()
        };
        let freq: Vec<f64> = (1..=250).map(|k| 2.0 * k as f64).collect();
        let mut resp = Vec::new();
        let mut var = Vec::new();
        for &f in &freq {
            let sj = C::new(0.0, 2.0 * PI * f);
            let mode = |fh: f64, z: f64, a: f64| {
                let w = 2.0 * PI * fh;
                a * w * w / (sj * sj + 2.0 * z * w * sj + w * w)
            };
            // the exact ZOH response of the rigid body, the modes continuous (their ZOH
            // distortion at these frequencies is below the noise)
            let zz = C::from_polar(1.0, 2.0 * PI * f * ts);
            let rigid = C::new(ts * ts / 2.0, 0.0) * (zz + 1.0) / ((zz - 1.0) * (zz - 1.0));
            // the modes through the hold's half-sample lag
            let g = rigid + (mode(f1, z1, 2e-7) + mode(f2, z2, 5e-8)) * (-sj * ts / 2.0).exp();
            let sd = 0.005 * g.norm();
            let n = C::new(gauss(), gauss()) * (sd / 2f64.sqrt());
            resp.push(DMatrix::from_element(1, 1, g + n));
            var.push(DMatrix::from_element(1, 1, sd * sd));
        }
        Frd::new(
            freq,
            resp,
            Some(var),
            sd_model::SampleTime::discrete(ts).unwrap(),
        )
        .unwrap()
    }

    #[test]
    fn finds_the_rigid_body_and_both_modes() {
        for seed in [11, 12, 13] {
            let frd = synthetic(seed);
            let opt = StabilizationOptions {
                max_order: 12,
                ..Default::default()
            };
            let r = physical_fit(&frd, &opt, &mut |_| {}).unwrap();
            assert_eq!(r.rigid_body, 2, "seed {seed}: {:?}", r.orders);
            let find = |f: f64| {
                r.modes
                    .iter()
                    .find(|m| m.kind == ModeKind::Pair && (m.freq_hz - f).abs() < 0.02 * f)
                    .unwrap_or_else(|| panic!("seed {seed}: no mode at {f} Hz: {:?}", r.modes))
            };
            let (m1, m2) = (find(120.0), find(310.0));
            assert!((m1.damping - 0.02).abs() < 0.004, "{m1:?}");
            assert!((m2.damping - 0.01).abs() < 0.003, "{m2:?}");
            assert!(
                m1.frequency_orders >= 3 && m2.frequency_orders >= 3,
                "{:?}",
                r.modes
            );
            assert!(r.order <= 8, "seed {seed}: order {}", r.order);
            assert!(r.cost_per_line < 2.0, "seed {seed}: {}", r.cost_per_line);
        }
    }

    #[test]
    fn refuses_bad_settings() {
        let frd = synthetic(1);
        let bad = StabilizationOptions {
            max_order: 1,
            ..Default::default()
        };
        assert!(physical_fit(&frd, &bad, &mut |_| {}).is_err());
        let bad = StabilizationOptions {
            rigid_body: Some(3),
            ..Default::default()
        };
        assert!(physical_fit(&frd, &bad, &mut |_| {}).is_err());
    }
}
