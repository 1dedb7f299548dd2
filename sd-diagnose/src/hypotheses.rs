//! Stage 4, the rate-tied hypotheses: parametric extensions of the continuous modal model
//! ([`crate::modal`]) that predict experiments at other rates.
//!
//! A hypothesis is a [`Family`] (which parameters are free) and its parameters [`RateTied`]:
//! hold delay α (fraction of each experiment's own period, up to
//! [`sd_multirate::MAX_HOLD_DELAY`]), averaging window β (fraction), and a clock error `e_j`
//! per validation experiment (its true period is `T_j(1 + e_j)`; the model experiment's clock
//! is the reference). For trial (α, β) the modal residues are refitted to the fast FRF with the
//! fast experiment discretised the same way; a slow experiment's lines are predicted by the
//! basis discretised at its true period and evaluated at `f/(1 + e_j)` (the measured line f
//! is at the true frequency `f/(1 + e_j)`: the controller counts samples, not seconds).
//!
//! **Search.** Single causes: α on a 0.05 grid over [0, 2], β on a 0.04 grid over [0, 1],
//! each e_j on a 0.001 grid over [−3 %, 3 %] (per experiment: e_j only moves its own lines),
//! each refined by golden section in the best cell. Delay + averaging: a 0.2 × 0.2 grid, then
//! coordinate refinement in shrinking windows along σ = α + β/2 (the delay both act like) and β. A cause with clock errors: the clock errors
//! over ±3 % at the other cause's single estimate, then alternately that cause over its whole
//! range and the clock errors within ±0.4 %. The criterion is the statistic's score sum on the
//! effective scale (`K'/K` of it for correlated LPM lines) plus `½ ln K'` per parameter (BIC in
//! the score's units: the score sum is the negative log-likelihood of exponential scores). The residue covariance used while searching has the
//! poles fixed; the held-out yardstick adds the poles' uncertainty (`Modal::stat_full`).

use crate::data::Estimate;
use crate::lemma6::{compare, Pred};
use crate::modal::{ModalBasis, Residues};
use crate::stats::{statistic, Line, Statistic};
use crate::Result;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::linalg::golden_min;
use sd_multirate::NonIdeal;
use serde::Serialize;

/// Parameters of a rate-tied extension.
#[derive(Clone, Debug, PartialEq, Default, Serialize)]
pub struct RateTied {
    /// Hold delay α (fraction of each experiment's own period).
    pub hold_delay: f64,
    /// Averaging window β (fraction of the period).
    pub averaging: f64,
    /// Clock error per validation experiment (in the order of the targets; empty: none).
    pub clock_error: Vec<f64>,
}

impl RateTied {
    /// The non-idealities at every rate.
    pub fn nonideal(&self) -> NonIdeal {
        NonIdeal {
            hold_delay: self.hold_delay,
            averaging: self.averaging,
        }
    }

    /// Clock error of target `j` (0 without one).
    pub fn clock(&self, j: usize) -> f64 {
        self.clock_error.get(j).copied().unwrap_or(0.0)
    }
}

/// Standard errors of a rate-tied extension's parameters ([`Modal::std_errors`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct StdErrors {
    pub(crate) hold_delay: Option<f64>,
    pub(crate) averaging: Option<f64>,
    pub(crate) clock_error: Vec<Option<f64>>,
    /// With a delay and a window: the standard error of `α + β/2`, the lag both act like to
    /// first order (determined even where the split between them is not).
    pub(crate) combined_lag: Option<f64>,
}

/// A free coordinate of an extension.
#[derive(Clone, Copy, Debug)]
enum Coord {
    Delay,
    Average,
    Clock(usize),
}

/// `p` moved by `shift[k]` steps along each coordinate `coords[k]` (coordinate, step).
fn shifted(p: &RateTied, coords: &[(Coord, f64)], shift: &[f64]) -> RateTied {
    let mut q = p.clone();
    for ((c, h), s) in coords.iter().zip(shift) {
        match c {
            Coord::Delay => q.hold_delay += s * h,
            Coord::Average => q.averaging += s * h,
            Coord::Clock(j) => q.clock_error[*j] += s * h,
        }
    }
    q
}

/// The free coordinates of family `fam` at `p` with their difference steps: 0.01 for α, 0.02
/// for β, 2·10⁻⁴ per clock error.
fn coords_of(fam: Family, p: &RateTied) -> Vec<(Coord, f64)> {
    let mut coords: Vec<(Coord, f64)> = Vec::new();
    if fam.delay() {
        coords.push((Coord::Delay, 0.01));
    }
    if fam.average() {
        coords.push((Coord::Average, 0.02));
    }
    if fam.clock() {
        coords.extend((0..p.clock_error.len()).map(|j| (Coord::Clock(j), 2e-4)));
    }
    coords
}

/// Which parameters are free.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Family {
    /// The plain modal model.
    None,
    /// Hold delay.
    Delay,
    /// Averaging sampler.
    Average,
    /// Clock error per experiment.
    Clock,
    /// Hold delay and averaging sampler.
    DelayAverage,
    /// Hold delay and clock error.
    DelayClock,
    /// Averaging sampler and clock error.
    AverageClock,
}

impl Family {
    /// All families, simplest first.
    pub const ALL: [Family; 7] = [
        Family::None,
        Family::Delay,
        Family::Average,
        Family::Clock,
        Family::DelayAverage,
        Family::DelayClock,
        Family::AverageClock,
    ];

    /// Has a hold delay.
    pub fn delay(self) -> bool {
        matches!(
            self,
            Family::Delay | Family::DelayAverage | Family::DelayClock
        )
    }
    /// Has an averaging window.
    pub fn average(self) -> bool {
        matches!(
            self,
            Family::Average | Family::DelayAverage | Family::AverageClock
        )
    }
    /// Has clock errors.
    pub fn clock(self) -> bool {
        matches!(
            self,
            Family::Clock | Family::DelayClock | Family::AverageClock
        )
    }

    /// The cause names, alphabetical, joined by `+` (`none` for the plain model).
    pub fn name(self) -> String {
        let mut v = Vec::new();
        if self.average() {
            v.push("averaging_sampler");
        }
        if self.clock() {
            v.push("clock_error");
        }
        if self.delay() {
            v.push("hold_delay");
        }
        if v.is_empty() {
            "none".into()
        } else {
            v.join("+")
        }
    }

    /// Free parameters with `n` validation experiments.
    pub fn n_params(self, n: usize) -> usize {
        usize::from(self.delay()) + usize::from(self.average()) + if self.clock() { n } else { 0 }
    }

    /// The families with one cause fewer (empty for single causes).
    pub fn nested(self) -> Vec<Family> {
        match self {
            Family::DelayAverage => vec![Family::Delay, Family::Average],
            Family::DelayClock => vec![Family::Delay, Family::Clock],
            Family::AverageClock => vec![Family::Average, Family::Clock],
            _ => Vec::new(),
        }
    }
}

/// The penalised criterion of a statistic with `p` parameters: the score sum on the effective
/// scale (K'/K of it: correlated lines carry less information) plus `½ ln K'` per parameter.
pub(crate) fn penalised(s: &Statistic, p: usize) -> f64 {
    let k = s.effective_lines.max(1.0);
    s.value * k + 0.5 * p as f64 * k.ln()
}

/// A slower experiment to predict (the FRF of a part or the whole).
pub(crate) struct Target<'a> {
    pub(crate) factor: usize,
    pub(crate) est: &'a Estimate,
}

/// A fitted hypothesis.
#[derive(Clone, Debug)]
pub(crate) struct Fitted {
    pub(crate) family: Family,
    pub(crate) params: RateTied,
    pub(crate) stat: Statistic,
    pub(crate) criterion: f64,
}

/// The continuous modal model with the fast data it is fitted to.
pub(crate) struct Modal<'a> {
    pub(crate) basis: ModalBasis,
    pub(crate) fast: &'a Estimate,
    pub(crate) h: f64,
    pub(crate) alpha: f64,
}

/// Minimizes `f` on a grid of `n` cells over [lo, hi], then by golden section in the best cell.
pub(crate) fn min1d(f: &mut dyn FnMut(f64) -> f64, lo: f64, hi: f64, n: usize) -> (f64, f64) {
    let n = n.max(1);
    let step = (hi - lo) / n as f64;
    let (mut best, mut bc) = (lo, f64::INFINITY);
    for i in 0..=n {
        let p = lo + step * i as f64;
        let c = f(p);
        if c < bc {
            bc = c;
            best = p;
        }
    }
    if !bc.is_finite() || step <= 0.0 {
        return (best, bc);
    }
    let (p, c) = golden_min(&mut *f, (best - step).max(lo), (best + step).min(hi), 14);
    if c < bc {
        (p, c)
    } else {
        (best, bc)
    }
}

impl Modal<'_> {
    /// Residues fitted to the fast FRF under the non-idealities.
    pub(crate) fn residues(&self, ni: NonIdeal) -> Result<Residues> {
        let phi = self.basis.responses(self.h, ni, self.fast.frd.freq_hz())?;
        Ok(Residues::fit(&self.fast.frd, &phi)?
            .for_estimated_weights(self.fast.dof, self.fast.inflation))
    }

    /// Residues with the covariance of residues and poles together (the yardstick of the
    /// verdict and the gain).
    pub(crate) fn residues_full(&self, ni: NonIdeal) -> Result<Residues> {
        let f = self.fast.frd.freq_hz();
        let phi = self.basis.responses(self.h, ni, f)?;
        let res = Residues::fit(&self.fast.frd, &phi)?;
        let dphi = self.basis.pole_sensitivities(&res.r, self.h, ni, f)?;
        Ok(res
            .with_poles(&self.fast.frd, &phi, &dphi)?
            .for_estimated_weights(self.fast.dof, self.fast.inflation))
    }

    /// Lines of a target against the extension's prediction (with the residues' variance; with
    /// the poles' too when `res` carries it).
    pub(crate) fn lines(
        &self,
        res: &Residues,
        ni: NonIdeal,
        clock: f64,
        t: &Target<'_>,
    ) -> Result<Vec<Line>> {
        self.lines_with(res, ni, clock, t, false)
    }

    /// A target's true period and the frequencies of its lines on the model's time axis under
    /// a clock error: the slow clock runs `1 + e` slow, so line `f` of the record is `f/(1 + e)`.
    fn grid(&self, clock: f64, t: &Target<'_>) -> (f64, Vec<f64>) {
        let ts = self.h * t.factor as f64 * (1.0 + clock);
        let f = t
            .est
            .frd
            .freq_hz()
            .iter()
            .map(|f| f / (1.0 + clock))
            .collect();
        (ts, f)
    }

    /// The extension's prediction at every line of every target, residues refitted under its
    /// non-idealities (the profile the fit itself follows).
    pub(crate) fn predictions(&self, p: &RateTied, targets: &[Target<'_>]) -> Result<Vec<Vec<C>>> {
        let res = self.residues(p.nonideal())?;
        targets
            .iter()
            .enumerate()
            .map(|(j, t)| {
                let (ts, f) = self.grid(p.clock(j), t);
                let phi = self.basis.responses(ts, p.nonideal(), &f)?;
                Ok(phi.iter().map(|row| res.predict(row).0).collect())
            })
            .collect()
    }

    /// The covariance the model's own estimation error adds to fitted parameters θ (delta
    /// method). The residues and poles `q` were fitted to the fast experiment with covariance
    /// `Σ_q` ([`Residues::with_poles`]). At the optimum the normal equations
    /// `Re Σ_i w_i J_iᴴ e_i = 0` (`J_i = ∂P̂_i/∂θ` by central differences with the coordinates'
    /// steps, `e_i` the line's residual, `w_i = 1/(c·var_i)`) move with `q` by `δθ = M⁻¹N δq`,
    /// `M = Re Σ w_i J_iᴴJ_i`, `N = Re Σ w_i J_iᴴ g_i`, `g_i = ∂P̂_i/∂q = [φ_i, ∂φ_i/∂poles]`; so
    /// `cov θ` gains `A Σ_q Aᵀ` with `A = M⁻¹N`. The data's own term (the Hessian's inverse)
    /// counts the model's error per line, as if independent; shared by all lines through `q`, it
    /// does not average out, and a hold delay trades against the modes' phases. `None` when the
    /// joint covariance or `M⁻¹` is not available.
    fn model_covariance(
        &self,
        coords: &[(Coord, f64)],
        centre: &RateTied,
        targets: &[Target<'_>],
    ) -> Result<Option<DMatrix<f64>>> {
        let ni = centre.nonideal();
        let res = self.residues_full(ni)?;
        let Some(sq) = res.joint_covariance() else {
            return Ok(None);
        };
        let along = |k: usize, s: f64| {
            let mut unit = vec![0.0; coords.len()];
            unit[k] = s;
            shifted(centre, coords, &unit)
        };
        let mut slopes = Vec::with_capacity(coords.len());
        for (k, (_, h)) in coords.iter().enumerate() {
            let plus = self.predictions(&along(k, 1.0), targets)?;
            let minus = self.predictions(&along(k, -1.0), targets)?;
            slopes.push((plus, minus, *h));
        }
        let (nt, nq) = (coords.len(), sq.nrows());
        let mut m = DMatrix::<f64>::zeros(nt, nt);
        let mut n = DMatrix::<f64>::zeros(nt, nq);
        for (j, t) in targets.iter().enumerate() {
            let (ts, f) = self.grid(centre.clock(j), t);
            let phi = self.basis.responses(ts, ni, &f)?;
            let dphi = self.basis.pole_sensitivities(&res.r, ts, ni, &f)?;
            let Some(var) = t.est.frd.variance() else {
                continue;
            };
            for i in 0..f.len() {
                let v = (var[i][(0, 0)] + res.predict(&phi[i]).1) * t.est.inflation.max(1.0);
                if !(v.is_finite() && v > 0.0) {
                    continue;
                }
                let jac: Vec<C> = slopes
                    .iter()
                    .map(|(p, mi, h)| (p[j][i] - mi[j][i]) / (2.0 * h))
                    .collect();
                let g: Vec<&C> = phi[i].iter().chain(&dphi[i]).collect();
                for a in 0..nt {
                    for b in 0..nt {
                        m[(a, b)] += (jac[a].conj() * jac[b]).re / v;
                    }
                    for (c, gc) in g.iter().enumerate().take(nq) {
                        n[(a, c)] += (jac[a].conj() * **gc).re / v;
                    }
                }
            }
        }
        let Some(mi) = m.try_inverse() else {
            return Ok(None);
        };
        let a = mi * n;
        let cov = &a * sq * a.transpose();
        Ok(cov.iter().all(|x| x.is_finite()).then_some(cov))
    }

    fn lines_with(
        &self,
        res: &Residues,
        ni: NonIdeal,
        clock: f64,
        t: &Target<'_>,
        full: bool,
    ) -> Result<Vec<Line>> {
        let (ts, f) = self.grid(clock, t);
        let phi = self.basis.responses(ts, ni, &f)?;
        let dphi = if full {
            Some(self.basis.pole_sensitivities(&res.r, ts, ni, &f)?)
        } else {
            None
        };
        Ok(compare(t.est, |i, _| {
            let (value, var) = match &dphi {
                Some(d) => res.predict_full(&phi[i], &d[i]),
                None => res.predict(&phi[i]),
            };
            Some(Pred {
                value,
                var,
                dof: f64::INFINITY,
                // judged as independent lines: naming stays strict (the shared-parameter
                // correction is the verdict's, for the model's simulation)
                params: 0,
            })
        }))
    }

    /// The pooled statistic of an extension over the targets.
    pub(crate) fn stat(&self, p: &RateTied, targets: &[Target<'_>]) -> Result<Statistic> {
        let res = self.residues(p.nonideal())?;
        self.stat_with(&res, p, targets)
    }

    /// The pooled statistic with the poles' uncertainty in the prediction variance (the
    /// verdict's and the gain's yardstick).
    pub(crate) fn stat_full(&self, p: &RateTied, targets: &[Target<'_>]) -> Result<Statistic> {
        let res = self.residues_full(p.nonideal())?;
        self.pooled(&res, p, targets, true)
    }

    fn stat_with(&self, res: &Residues, p: &RateTied, targets: &[Target<'_>]) -> Result<Statistic> {
        self.pooled(res, p, targets, false)
    }

    fn pooled(
        &self,
        res: &Residues,
        p: &RateTied,
        targets: &[Target<'_>],
        full: bool,
    ) -> Result<Statistic> {
        let sets = targets
            .iter()
            .enumerate()
            .map(|(j, t)| self.lines_with(res, p.nonideal(), p.clock(j), t, full))
            .collect::<Result<Vec<_>>>()?;
        Ok(statistic(
            sets.iter()
                .zip(targets)
                .map(|(s, t)| (s.as_slice(), t.est.inflation)),
            self.alpha,
        ))
    }

    /// Lines of one target under an extension with its own clock error; with `full` the
    /// prediction variance includes the poles' (the naming yardstick).
    pub(crate) fn lines_for(
        &self,
        p: &RateTied,
        clock: f64,
        t: &Target<'_>,
        full: bool,
    ) -> Result<Vec<Line>> {
        let res = if full {
            self.residues_full(p.nonideal())?
        } else {
            self.residues(p.nonideal())?
        };
        self.lines_with(&res, p.nonideal(), clock, t, full)
    }

    /// The clock error of one target under an extension's (α, β), over ±3 %.
    pub(crate) fn clock_of(&self, p: &RateTied, t: &Target<'_>) -> Result<f64> {
        let res = self.residues(p.nonideal())?;
        Ok(self.fit_clock(&res, p.nonideal(), t, 0.0, 0.03))
    }

    /// Clock error of one target for given residues, searched over `[c − w, c + w]`.
    fn fit_clock(&self, res: &Residues, ni: NonIdeal, t: &Target<'_>, c: f64, w: f64) -> f64 {
        let mut cost = |e: f64| {
            self.lines(res, ni, e, t)
                .map(|l| statistic([(l.as_slice(), 1.0)], self.alpha).value)
                .unwrap_or(f64::INFINITY)
        };
        // grid step 0.1 % over the wide search, w/10 in the narrow refinements: the cost
        // oscillates in e (a clock error slides the lines past the modes), and a grid cell
        // wider than one oscillation can hold the wrong basin
        let step = 0.001f64.min(w / 10.0);
        let cells = (2.0 * w / step).round() as usize;
        // a minimum on the window's edge lies beyond it: the window follows it (the cost is
        // smooth at this scale), at most ten times and within the wide search's ±3 %
        let mut centre = c;
        let mut e = min1d(&mut cost, centre - w, centre + w, cells).0;
        for _ in 0..10 {
            let edge = (e - (centre - w)).abs() < 0.5 * step || (centre + w - e).abs() < 0.5 * step;
            if !edge || (e.abs() + w) > 0.03 + 1e-12 {
                break;
            }
            centre = e;
            e = min1d(&mut cost, centre - w, centre + w, cells).0;
        }
        e
    }

    /// Statistic of (α, β) with fixed clock errors.
    fn eval_fixed(&self, a: f64, b: f64, clocks: &[f64], targets: &[Target<'_>]) -> f64 {
        let p = RateTied {
            hold_delay: a,
            averaging: b,
            clock_error: clocks.to_vec(),
        };
        self.stat(&p, targets)
            .map(|s| s.value)
            .unwrap_or(f64::INFINITY)
    }

    /// Clock errors for (α, β), each searched over `[c − w, c + w]` around `center`.
    fn fit_clocks(
        &self,
        ni: NonIdeal,
        center: &[f64],
        w: f64,
        targets: &[Target<'_>],
    ) -> Result<Vec<f64>> {
        let res = self.residues(ni)?;
        Ok(targets
            .iter()
            .enumerate()
            .map(|(j, t)| {
                let c = center.get(j).copied().unwrap_or(0.0);
                self.fit_clock(&res, ni, t, c, w)
            })
            .collect())
    }

    /// Fits one family. `start` holds the single-cause estimates (the pairs start there).
    /// Single causes: grids over the whole range, then golden section. Delay + averaging: a
    /// 0.2 × 0.2 grid and the two single causes' estimates, from the best of them coordinate
    /// refinement in shrinking windows along σ = α + β/2 (the delay both act like) and β, kept
    /// only where it improves on that start. A cause with clock errors: clock errors over ±3 %
    /// at the other cause's single estimate, then alternately the other parameter over its
    /// whole range and the clock errors within ±0.4 %.
    fn fit(&self, fam: Family, targets: &[Target<'_>], start: &RateTied) -> Result<RateTied> {
        let ideal = NonIdeal::ideal();
        let (mut a, mut b, mut clocks) = (0.0, 0.0, Vec::new());
        match fam {
            Family::None => {}
            Family::Delay => {
                a = min1d(&mut |x| self.eval_fixed(x, 0.0, &[], targets), 0.0, 2.0, 40).0
            }
            Family::Average => {
                b = min1d(&mut |x| self.eval_fixed(0.0, x, &[], targets), 0.0, 1.0, 25).0
            }
            Family::Clock => clocks = self.fit_clocks(ideal, &[], 0.03, targets)?,
            Family::DelayAverage => {
                // the grid and the nested single causes' estimates (the pair contains both:
                // its fit must never end worse than either, as a grid cell far from a small
                // delay with a small window can)
                let grid =
                    (0..=8).flat_map(|i| (0..=5).map(move |j| (0.2 * i as f64, 0.2 * j as f64)));
                let singles = [(start.hold_delay, 0.0), (0.0, start.averaging)];
                let mut best = (f64::INFINITY, 0.0, 0.0);
                for (x, y) in grid.chain(singles) {
                    let c = self.eval_fixed(x, y, &[], targets);
                    if c < best.0 {
                        best = (c, x, y);
                    }
                }
                // refined in (σ, β) with σ = α + β/2, the delay both act like to first order:
                // the valley of the cost runs along constant σ, so the coordinates decouple
                let (mut sg, mut bb) = (best.1 + 0.5 * best.2, best.2);
                let ev = |sg: f64, y: f64| {
                    let x = sg - 0.5 * y;
                    if x < 0.0 {
                        f64::INFINITY
                    } else {
                        self.eval_fixed(x, y, &[], targets)
                    }
                };
                for w in [0.2, 0.1, 0.05, 0.02] {
                    sg = min1d(&mut |x| ev(x, bb), (sg - w).max(0.0), sg + w, 4).0;
                    bb = min1d(
                        &mut |y| ev(sg, y),
                        (bb - 2.0 * w).max(0.0),
                        (bb + 2.0 * w).min(1.0),
                        4,
                    )
                    .0;
                }
                let refined = ((sg - 0.5 * bb).max(0.0), bb);
                (a, b) = if ev(sg, bb) <= best.0 {
                    refined
                } else {
                    (best.1, best.2)
                };
            }
            Family::DelayClock | Family::AverageClock => {
                let delay = fam == Family::DelayClock;
                let ni = |x: f64| NonIdeal {
                    hold_delay: if delay { x } else { 0.0 },
                    averaging: if delay { 0.0 } else { x },
                };
                let (hi, cells) = if delay { (2.0, 40) } else { (1.0, 25) };
                let mut x = if delay {
                    start.hold_delay
                } else {
                    start.averaging
                };
                clocks = self.fit_clocks(ni(x), &start.clock_error, 0.03, targets)?;
                for round in 0..3 {
                    let mut cost = |v: f64| {
                        let n = ni(v);
                        self.eval_fixed(n.hold_delay, n.averaging, &clocks, targets)
                    };
                    x = if round == 0 {
                        min1d(&mut cost, 0.0, hi, cells).0
                    } else {
                        min1d(&mut cost, (x - 0.1).max(0.0), (x + 0.1).min(hi), 4).0
                    };
                    clocks = self.fit_clocks(ni(x), &clocks, 0.004, targets)?;
                }
                let n = ni(x);
                (a, b) = (n.hold_delay, n.averaging);
            }
        }
        Ok(RateTied {
            hold_delay: a,
            averaging: b,
            clock_error: clocks,
        })
    }

    /// The family's parameters refined on `targets` around `start` (±0.05 for α and β, ±0.2 %
    /// for the clock errors; two coordinate rounds): the final refit on all data.
    pub(crate) fn refine(
        &self,
        fam: Family,
        targets: &[Target<'_>],
        start: &RateTied,
    ) -> Result<RateTied> {
        let mut p = start.clone();
        for _ in 0..2 {
            if fam.delay() {
                let (b, c) = (p.averaging, p.clock_error.clone());
                let a0 = p.hold_delay;
                p.hold_delay = min1d(
                    &mut |x| self.eval_fixed(x, b, &c, targets),
                    (a0 - 0.05).max(0.0),
                    (a0 + 0.05).min(2.0),
                    4,
                )
                .0;
            }
            if fam.average() {
                let (a, c) = (p.hold_delay, p.clock_error.clone());
                let b0 = p.averaging;
                p.averaging = min1d(
                    &mut |y| self.eval_fixed(a, y, &c, targets),
                    (b0 - 0.05).max(0.0),
                    (b0 + 0.05).min(1.0),
                    4,
                )
                .0;
            }
            if fam.clock() {
                p.clock_error = self.fit_clocks(p.nonideal(), &p.clock_error, 0.002, targets)?;
            }
            if fam.n_params(targets.len()) <= 1 {
                break;
            }
        }
        Ok(p)
    }

    /// Standard errors of a fitted extension's parameters. The effective score sum
    /// `C(θ) = K'·s̄(θ)` is a negative log-likelihood up to a constant (each score is `−ln` of
    /// the F(2, ν) tail, → `|e|²/σ²`, the Gaussian's, for large ν), so `cov θ ≈ H⁻¹` with `H`
    /// its Hessian, here by central differences (steps: 0.01 for α, 0.02 for β, 2·10⁻⁴ for
    /// clock errors; a stencil that would cross a bound moves inside it). When the extension
    /// leaves misfit (`s̄ > 1`) the errors widen by `√s̄`, the residual-variance factor of least
    /// squares. The model's own estimation error is added by the delta method
    /// ([`Modal::model_covariance`]). `None` where the curvature is not positive (a flat
    /// direction).
    pub(crate) fn std_errors(
        &self,
        fam: Family,
        targets: &[Target<'_>],
        p: &RateTied,
    ) -> Result<StdErrors> {
        let coords = coords_of(fam, p);
        let mut out = StdErrors {
            hold_delay: None,
            averaging: None,
            clock_error: vec![None; p.clock_error.len()],
            combined_lag: None,
        };
        if coords.is_empty() {
            return Ok(out);
        }
        let base = self.stat(p, targets)?;
        let keff = base.effective_lines.max(1.0);
        // the stencil's centre, moved inside the bounds
        let mut centre = p.clone();
        for (c, h) in &coords {
            match c {
                Coord::Delay => centre.hold_delay = centre.hold_delay.clamp(*h, 2.0 - h),
                Coord::Average => centre.averaging = centre.averaging.clamp(*h, 1.0 - h),
                Coord::Clock(_) => {}
            }
        }
        let eval = |shift: &[f64]| -> f64 {
            self.stat(&shifted(&centre, &coords, shift), targets)
                .map(|st| st.value * keff)
                .unwrap_or(f64::NAN)
        };
        let n = coords.len();
        let unit = |i: usize, v: f64| {
            let mut x = vec![0.0; n];
            x[i] = v;
            x
        };
        let f0 = eval(&vec![0.0; n]);
        let mut hess = nalgebra::DMatrix::zeros(n, n);
        for i in 0..n {
            let hi = coords[i].1;
            hess[(i, i)] = (eval(&unit(i, 1.0)) - 2.0 * f0 + eval(&unit(i, -1.0))) / (hi * hi);
            for k in 0..i {
                let hk = coords[k].1;
                let at = |a: f64, b: f64| {
                    let mut x = vec![0.0; n];
                    x[i] = a;
                    x[k] = b;
                    eval(&x)
                };
                let v = (at(1.0, 1.0) - at(1.0, -1.0) - at(-1.0, 1.0) + at(-1.0, -1.0))
                    / (4.0 * hi * hk);
                hess[(i, k)] = v;
                hess[(k, i)] = v;
            }
        }
        let Some(mut cov) = hess.clone().try_inverse() else {
            return Ok(out);
        };
        if let Some(model) = self.model_covariance(&coords, &centre, targets)? {
            cov += model;
        }
        let widen = base.value.max(1.0);
        let at = |c: fn(&Coord) -> bool| coords.iter().position(|(x, _)| c(x));
        if let (Some(d), Some(a)) = (
            at(|c| matches!(c, Coord::Delay)),
            at(|c| matches!(c, Coord::Average)),
        ) {
            let v = (cov[(d, d)] + 0.25 * cov[(a, a)] + cov[(d, a)]) * widen;
            out.combined_lag = (v.is_finite() && v > 0.0).then(|| v.sqrt());
        }
        for (i, (c, _)) in coords.iter().enumerate() {
            let v = cov[(i, i)] * widen;
            let sd = (v.is_finite() && v > 0.0 && hess[(i, i)] > 0.0).then(|| v.sqrt());
            match c {
                Coord::Delay => out.hold_delay = sd,
                Coord::Average => out.averaging = sd,
                Coord::Clock(j) => out.clock_error[*j] = sd,
            }
        }
        Ok(out)
    }

    /// The score-sum excess a hypothesis keeps, to first order, when its parameters are refitted
    /// to `targets` whose last one's truth is `truth` (value per line) with variance `var`: the
    /// earlier targets are where `p` was fitted (their gradient is zero there, their Gauss–Newton
    /// curvature `H₀ = Σ Re(J_kᴴJ_k)/v_k` resists a compromise), the last one's residuals are
    /// `r_k = truth_k − P̂_k(p)`. Minimizing `Σ_new |r_k − J_k δ|²/v_k + δᵀH₀δ` over the step δ
    /// leaves `Σ|r_k|²/v_k − bᵀ(H₀ + H₁)⁻¹b`, `b = Σ_new Re(J_kᴴ r_k)/v_k`: the excess over the
    /// new lines and the loss on the old ones together. `J` by central differences of
    /// [`Modal::predictions`] (residues refitted at each step) with [`coords_of`]'s steps; `p`
    /// holds one clock error per target when `fam` has clock errors.
    pub(crate) fn refit_excess(
        &self,
        fam: Family,
        p: &RateTied,
        targets: &[Target<'_>],
        (truth, var): (&[C], &[f64]),
    ) -> Result<f64> {
        let coords = coords_of(fam, p);
        let n = coords.len();
        let base = self.predictions(p, targets)?;
        let Some(new) = base.last() else {
            return Ok(0.0);
        };
        let r: Vec<C> = truth.iter().zip(new).map(|(t, a)| t - a).collect();
        let v_new: Vec<f64> = var.to_vec();
        let whole: f64 = r
            .iter()
            .zip(&v_new)
            .map(|(r, v)| r.norm_sqr() / v)
            .filter(|x| x.is_finite())
            .sum();
        if n == 0 {
            return Ok(whole);
        }
        let mut slopes = Vec::with_capacity(n);
        for k in 0..n {
            let mut unit = vec![0.0; n];
            unit[k] = 1.0;
            let plus = self.predictions(&shifted(p, &coords, &unit), targets)?;
            unit[k] = -1.0;
            let minus = self.predictions(&shifted(p, &coords, &unit), targets)?;
            let h = coords[k].1;
            slopes.push(
                plus.iter()
                    .zip(&minus)
                    .map(|(a, b)| a.iter().zip(b).map(|(a, b)| (a - b) / (2.0 * h)).collect())
                    .collect::<Vec<Vec<C>>>(),
            );
        }
        let mut hess = DMatrix::<f64>::zeros(n, n);
        let mut b = nalgebra::DVector::<f64>::zeros(n);
        let last = targets.len() - 1;
        for (j, t) in targets.iter().enumerate() {
            let var_j: Vec<f64> = if j == last {
                v_new.clone()
            } else {
                let Some(v) = t.est.frd.variance() else {
                    continue;
                };
                v.iter()
                    .map(|m| m[(0, 0)] * t.est.inflation.max(1.0))
                    .collect()
            };
            for (i, v) in var_j.iter().enumerate() {
                if !(v.is_finite() && *v > 0.0) {
                    continue;
                }
                for a in 0..n {
                    for c in 0..n {
                        hess[(a, c)] += (slopes[a][j][i].conj() * slopes[c][j][i]).re / v;
                    }
                    if j == last {
                        b[a] += (slopes[a][j][i].conj() * r[i]).re / v;
                    }
                }
            }
        }
        let Some(hi) = hess.try_inverse() else {
            return Ok(whole);
        };
        let gain = (b.transpose() * hi * &b)[(0, 0)];
        Ok((whole - gain.max(0.0)).max(0.0))
    }

    /// Every family fitted on `targets`, ranked by the penalised criterion.
    pub(crate) fn search(
        &self,
        targets: &[Target<'_>],
        progress: &mut dyn FnMut(&str),
    ) -> Result<Vec<Fitted>> {
        let mut out: Vec<Fitted> = Vec::new();
        let mut start = RateTied::default();
        for fam in Family::ALL {
            progress(&format!("rate-tied hypotheses: {}", fam.name()));
            let params = self.fit(fam, targets, &start)?;
            match fam {
                Family::Delay => start.hold_delay = params.hold_delay,
                Family::Average => start.averaging = params.averaging,
                Family::Clock => start.clock_error = params.clock_error.clone(),
                _ => {}
            }
            let stat = self.stat(&params, targets)?;
            let criterion = penalised(&stat, fam.n_params(targets.len()));
            out.push(Fitted {
                family: fam,
                params,
                stat,
                criterion,
            });
        }
        out.sort_by(|a, b| a.criterion.total_cmp(&b.criterion));
        Ok(out)
    }
}
