//! The diagnosis of experiments with several inputs and outputs: one model with poles shared
//! by every channel, rate-tied causes with one parameter per actuator (hold delay), per
//! sensor (averaging window) and per slower set (its sample clock), as the physics says.
//!
//! **Data.** The experiments are grouped by sample rate; the set holding the model experiments
//! (role `model`; else the fastest) is the model set, every slower set must run at an integer
//! fraction `1/F` of its rate. Each set gives the `ny × nu` FRF with per-entry variances
//! ([`sd_ident::frf_of_experiments`]: periodic experiments, open loop or through the
//! references). The variances have `4(M − 1)` real degrees of freedom for `M` steady periods,
//! as in the single-channel diagnosis.
//!
//! **Model.** [`sd_ident::fit_common_poles`] on the model set's FRF, the rigid-body poles
//! counted on the diagonal entries' low-frequency slope; the order (rigid body plus pairs) is
//! the given one or scanned upwards two at a time while the cost falls by more than three
//! times what an added pair removes from noise alone (`ny + nu + 2` for a pole pair with
//! rank-one residues), up to `max_order`.
//!
//! **Hypotheses.** Every entry `(i, j)` is the fitted model's entry on the continuous modal
//! basis of its poles ([`crate::modal`]), its residues refitted to the fast entry under each
//! trial non-ideality. Actuator `j`'s hold delay `α_j` acts on column `j` only, sensor `i`'s
//! averaging window `β_i` on row `i`: entry `(i, j)` is predicted at every slower rate with
//! `(α_j, β_i)`. Each actuator's `α_j` is fitted to the pooled statistic of its column's
//! entries (a 0.1 grid over [0, 2], golden section in the best cell), each sensor's `β_i` to
//! its row's (0.1 over [0, 1]), alternately, twice. Its standard error comes from the
//! curvature of the score sum (the negative log-likelihood of the exponential scores) at the
//! optimum. A channel's parameter is named when the plain model fails on that channel's
//! entries, the parameter lowers the penalised criterion (score sum plus `½ ln K'` per
//! parameter) and lies more than three standard errors from 0. A slower set's clock error
//! `e` (true period `T(1 + e)`: its lines sit at `f/(1 + e)` on the model's axis) acts on
//! every entry of that set only; it is fitted on a 0.1 % grid over ±3 %, then a 0.01 % grid
//! over ±0.1 % around the best, and named by the same rule on that set's entries.
//!
//! **Gain.** With two or more slower sets, each is held out in turn: the parameters are fitted
//! on the others and the held-out set is predicted; the gain is the plain model's pooled
//! statistic over the held-out sets over the extension's. With one slower set the ratio is
//! measured on the data the parameters were fitted on and labelled as such. A named clock is
//! fitted on its set's earlier steady periods and the set judged on its later ones.

use crate::data::Estimate;
use crate::hypotheses::{penalised, Modal, RateTied, Target};
use crate::modal::ModalBasis;
use crate::stats::{statistic, Line, Statistic};
use crate::{DiagnoseError, Result, Verdict};
use sd_ident::{fit_common_poles, Experiment, FitOptions, MimoFitOptions, Role, Weighting};
use sd_model::{Frd, StateSpace};
use serde::Serialize;

/// Options of [`diagnose_mimo`].
#[derive(Debug, Clone)]
pub struct MimoDiagnoseOptions {
    /// False-alarm probability of the verdicts.
    pub alpha: f64,
    /// The model order (rigid body and pairs); `None`: scanned (module documentation).
    pub order: Option<usize>,
    /// Highest order the scan tries.
    pub max_order: usize,
}

impl Default for MimoDiagnoseOptions {
    fn default() -> Self {
        MimoDiagnoseOptions {
            alpha: 0.01,
            order: None,
            max_order: 40,
        }
    }
}

/// Which kind of channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ChannelKind {
    /// An actuator (a plant input): its hold delay.
    Actuator,
    /// A sensor (a plant output): its averaging window.
    Sensor,
    /// The sample clock of a slower set (`channel` indexes `validation`): its experiments'
    /// true period is nominal·(1 + e). One clock drives every channel of an experiment.
    Clock,
}

/// One channel's rate-tied parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChannelFinding {
    /// Actuator or sensor.
    pub kind: ChannelKind,
    /// The channel (0-based).
    pub channel: usize,
    /// Hold delay (actuator) or averaging window (sensor), as a fraction of each
    /// experiment's own sample period; a clock's relative error e.
    pub fraction: f64,
    /// Its standard error.
    pub fraction_std: f64,
    /// Named as a cause (module documentation).
    pub named: bool,
    /// Pooled statistic of the channel's entries at the slower rates without the parameter.
    pub before: Statistic,
    /// With it.
    pub after: Statistic,
}

/// One entry's agreement at the slower rates.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EntryCheck {
    /// Output (sensor, 0-based).
    pub output: usize,
    /// Input (actuator, 0-based).
    pub input: usize,
    /// The model's simulation (Lemma 6, no non-ideality) against the slower sets.
    pub plain: Statistic,
    /// The extension's (every named channel parameter).
    pub extended: Statistic,
}

/// The gain of the extension.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MimoGain {
    /// The plain model's pooled statistic over the sets it is measured on, over the
    /// extension's.
    pub ratio: f64,
    /// The experiments it is measured on.
    pub measured_on: Vec<String>,
    /// Whether those were held out of the parameters' fit.
    pub held_out: bool,
}

/// One entry at the slowest rate: the measured FRF, the model's simulation and the extended
/// model's (the report's figures).
#[derive(Debug, Clone, PartialEq)]
pub struct EntryCurves {
    /// Output (0-based).
    pub output: usize,
    /// Input (0-based).
    pub input: usize,
    /// The slowest set's rate factor.
    pub factor: usize,
    /// Frequencies (Hz).
    pub freq_hz: Vec<f64>,
    /// Measured.
    pub measured: Vec<num_complex::Complex64>,
    /// The model's simulation (Lemma 6).
    pub model: Vec<num_complex::Complex64>,
    /// The extended model's.
    pub extended: Vec<num_complex::Complex64>,
}

/// The diagnosis of a MIMO experiment set.
#[derive(Debug, Clone, Serialize)]
pub struct MimoDiagnosis {
    /// Consistent when every entry agrees at every slower rate.
    pub verdict: Verdict,
    /// Outputs and inputs.
    pub shape: (usize, usize),
    /// The model's order and its states.
    pub order: usize,
    /// States of the modal realisation.
    pub states: usize,
    /// The common-pole fit's cost and lines (a consistent fit: about one per entry and line).
    pub fit_cost: f64,
    /// Entry lines of the model set.
    pub fit_lines: usize,
    /// The fitted model at the model set's rate (not serialised; model JSON elsewhere).
    #[serde(skip)]
    pub model: StateSpace,
    /// Per actuator and sensor.
    pub channels: Vec<ChannelFinding>,
    /// Per entry.
    pub entries: Vec<EntryCheck>,
    /// The extension's gain (`None` when nothing is named).
    pub gain: Option<MimoGain>,
    /// The model set's and the slower sets' experiments.
    pub model_experiments: Vec<String>,
    /// The slower sets: their experiments and rate factor.
    pub validation: Vec<(Vec<String>, usize)>,
    /// Every entry at the slowest rate (figures; not serialised).
    #[serde(skip)]
    pub curves: Vec<EntryCurves>,
}

impl MimoDiagnosis {
    /// The `diagnosis.json` form: the serde fields and `"kind": "mimo"`.
    pub fn to_json(&self) -> serde_json::Value {
        let mut v = serde_json::to_value(self)
            .unwrap_or_else(|e| serde_json::json!({"error": e.to_string()}));
        if let Some(o) = v.as_object_mut() {
            o.insert("kind".into(), "mimo".into());
        }
        v
    }
}

/// One rate's FRF, split into per-entry estimates.
struct RateSet {
    names: Vec<String>,
    factor: usize,
    /// Position among the slower sets (0 for the model set).
    index: usize,
    /// `[output][input]`.
    entries: Vec<Vec<Estimate>>,
}

/// The entry `(i, j)` of a MIMO FRD as a single-channel estimate.
fn entry(frd: &Frd, i: usize, j: usize, dof: f64) -> Result<Estimate> {
    Ok(Estimate {
        frd: frd.entry(i, j)?,
        dof,
        inflation: 1.0,
        correlation: Vec::new(),
        spectra: None,
        distortion: None,
        local_distortion: Vec::new(),
        bla: None,
        expected_var: None,
    })
}

/// A slower set of experiments with its rate factor.
type SlowSet<'a> = (Vec<&'a Experiment>, usize);

/// The experiments grouped by rate: the model set first (module documentation).
fn rate_sets(experiments: &[Experiment]) -> Result<(Vec<&Experiment>, Vec<SlowSet<'_>>)> {
    let rate_of = |e: &Experiment| e.spec.sample_rate_hz;
    let fast = experiments
        .iter()
        .find(|e| e.spec.role == Role::Model)
        .map(rate_of)
        .or_else(|| experiments.iter().map(rate_of).reduce(f64::max))
        .ok_or_else(|| DiagnoseError::Setup("no experiment".into()))?;
    let mut groups: Vec<(f64, Vec<&Experiment>)> = Vec::new();
    for e in experiments {
        match groups
            .iter_mut()
            .find(|g| (g.0 / rate_of(e) - 1.0).abs() < 1e-9)
        {
            Some(g) => g.1.push(e),
            None => groups.push((rate_of(e), vec![e])),
        }
    }
    let mut model = Vec::new();
    let mut slow = Vec::new();
    for (rate, set) in groups {
        let f = fast / rate;
        let factor = f.round() as usize;
        if factor == 1 && (f - 1.0).abs() < 1e-9 {
            model = set;
        } else if factor >= 2 && (f / factor as f64 - 1.0).abs() < 1e-6 {
            slow.push((set, factor));
        } else {
            return Err(DiagnoseError::Setup(format!(
                "experiments at {rate} Hz: not an integer fraction of the model experiments' \
                 {fast} Hz (the rate-tied causes need T = F·h)"
            )));
        }
    }
    slow.sort_by_key(|s| s.1);
    Ok((model, slow))
}

/// The FRF of a set of experiments as per-entry estimates.
fn rate_set(set: &[&Experiment], factor: usize, index: usize) -> Result<(RateSet, Frd)> {
    let est = sd_ident::frf_of_experiments(set, &Default::default())?;
    if est.periods < 2 {
        return Err(DiagnoseError::Setup(format!(
            "`{}`: the MIMO diagnosis needs at least two steady periods per experiment (their \
             spread gives the variances)",
            set.first().map_or("", |e| e.spec.name.as_str())
        )));
    }
    let dof = 4.0 * (est.periods as f64 - 1.0);
    let (ny, nu) = est.frd.shape();
    let entries = (0..ny)
        .map(|i| (0..nu).map(|j| entry(&est.frd, i, j, dof)).collect())
        .collect::<Result<Vec<Vec<_>>>>()?;
    Ok((
        RateSet {
            names: set.iter().map(|e| e.spec.name.clone()).collect(),
            factor,
            index,
            entries,
        },
        est.frd,
    ))
}

/// The common-pole fit of the model set (module documentation).
fn fit_model(frd: &Frd, opt: &MimoDiagnoseOptions) -> Result<(sd_ident::MimoFitResult, usize)> {
    let (ny, nu) = frd.shape();
    let rigid = (0..ny.min(nu))
        .map(|d| {
            entry(frd, d, d, f64::INFINITY)
                .map(|e| crate::model::rigid_body_count(&e.frd))
                .unwrap_or(0)
        })
        .max()
        .unwrap_or(0);
    let fit = |order: usize| {
        fit_common_poles(
            frd,
            &MimoFitOptions {
                fit: FitOptions {
                    order,
                    rigid_body: rigid,
                    feedthrough: false,
                    weighting: Weighting::Variance,
                    ..Default::default()
                },
                ..Default::default()
            },
        )
    };
    if let Some(order) = opt.order {
        return Ok((fit(order)?, order));
    }
    // upwards two at a time while the cost falls by more than three times what a pair with
    // rank-one residues removes from noise alone (one step of look-ahead over a plateau)
    let noise_drop = (ny + nu + 2) as f64;
    let mut best = fit(rigid + 2)?;
    let mut order = rigid + 2;
    // the look-ahead fit is computed only when the next order alone does not pay
    let pays = |best: &sd_ident::MimoFitResult, r: &sd_ident::MimoFitResult, pairs: f64| {
        best.cost - r.cost > 3.0 * pairs * noise_drop
    };
    while order + 2 <= opt.max_order {
        let step = match fit(order + 2) {
            Ok(next) if pays(&best, &next, 1.0) => Some((next, 2)),
            _ if order + 4 <= opt.max_order => fit(order + 4)
                .ok()
                .filter(|after| pays(&best, after, 2.0))
                .map(|after| (after, 4)),
            _ => None,
        };
        let Some((r, k)) = step else {
            break;
        };
        best = r;
        order += k;
    }
    Ok((best, order))
}

/// Every entry's continuous modal model with the fast data it is fitted to.
fn entry_models<'a>(
    model: &StateSpace,
    fast: &'a RateSet,
    h: f64,
    alpha: f64,
) -> Result<Vec<Vec<Modal<'a>>>> {
    fast.entries
        .iter()
        .enumerate()
        .map(|(i, row)| {
            row.iter()
                .enumerate()
                .map(|(j, est)| {
                    let m = model.select(&[j], &[i])?;
                    Ok(Modal {
                        basis: ModalBasis::from_model_entry(&m)?,
                        fast: est,
                        h,
                        alpha,
                    })
                })
                .collect()
        })
        .collect()
}

/// Per-channel parameters: `delay[j]` per actuator, `window[i]` per sensor, `clock[s]` per
/// slower set.
#[derive(Clone, Debug)]
struct Params {
    delay: Vec<f64>,
    window: Vec<f64>,
    clock: Vec<f64>,
}

/// The plant's shape and the number of slower sets.
type Shape = ((usize, usize), usize);

impl Params {
    /// Every parameter 0 on an `(ny, nu)` plant with `slow` slower sets.
    fn zero(((ny, nu), slow): Shape) -> Self {
        Params {
            delay: vec![0.0; nu],
            window: vec![0.0; ny],
            clock: vec![0.0; slow],
        }
    }

    /// Channel `(kind, c)`'s parameter.
    fn get(&self, kind: ChannelKind, c: usize) -> f64 {
        match kind {
            ChannelKind::Actuator => self.delay[c],
            ChannelKind::Sensor => self.window[c],
            ChannelKind::Clock => self.clock[c],
        }
    }

    fn of(&self, i: usize, j: usize) -> RateTied {
        RateTied {
            hold_delay: self.delay[j],
            averaging: self.window[i],
            clock_error: Vec::new(),
        }
    }
}

/// The lines of entries `cells` of the slower sets `sets` under `p`.
fn lines_of(
    models: &[Vec<Modal<'_>>],
    sets: &[&RateSet],
    cells: &[(usize, usize)],
    p: &Params,
) -> Result<Vec<Vec<Line>>> {
    let mut out = Vec::new();
    for &(i, j) in cells {
        let rt = p.of(i, j);
        for s in sets {
            let t = Target {
                factor: s.factor,
                est: &s.entries[i][j],
            };
            let clock = p.clock.get(s.index).copied().unwrap_or(0.0);
            out.push(models[i][j].lines_for(&rt, clock, &t, false)?);
        }
    }
    Ok(out)
}

/// The pooled statistic of entries `cells` over the slower sets.
fn pooled(
    models: &[Vec<Modal<'_>>],
    sets: &[&RateSet],
    cells: &[(usize, usize)],
    p: &Params,
    alpha: f64,
) -> Result<Statistic> {
    let lines = lines_of(models, sets, cells, p)?;
    Ok(statistic(lines.iter().map(|l| (l.as_slice(), 1.0)), alpha))
}

/// The entries of a channel (a clock: every entry).
fn cells(kind: ChannelKind, c: usize, (ny, nu): (usize, usize)) -> Vec<(usize, usize)> {
    match kind {
        ChannelKind::Actuator => (0..ny).map(|i| (i, c)).collect(),
        ChannelKind::Sensor => (0..nu).map(|j| (c, j)).collect(),
        ChannelKind::Clock => every_entry((ny, nu)),
    }
}

/// Every entry, row by row.
fn every_entry((ny, nu): (usize, usize)) -> Vec<(usize, usize)> {
    (0..ny).flat_map(|i| (0..nu).map(move |j| (i, j))).collect()
}

/// The slower sets a channel's parameter acts on: a clock its own set only.
fn sets_of<'a>(kind: ChannelKind, c: usize, sets: &[&'a RateSet]) -> Vec<&'a RateSet> {
    sets.iter()
        .copied()
        .filter(|s| kind != ChannelKind::Clock || s.index == c)
        .collect()
}

/// The parameters with channel `(kind, c)` set to `v`.
fn with(p: &Params, kind: ChannelKind, c: usize, v: f64) -> Params {
    let mut q = p.clone();
    match kind {
        ChannelKind::Actuator => q.delay[c] = v,
        ChannelKind::Sensor => q.window[c] = v,
        ChannelKind::Clock => q.clock[c] = v,
    }
    q
}

/// The clock of set `c` fitted to its entries' score sum: a 0.1 % grid over ±3 % (the score
/// oscillates in e as the lines slide past the modes), then a 0.01 % grid over ±0.1 % around
/// the best, golden section in the best cell of each.
fn fit_clock(score: &mut dyn FnMut(f64) -> f64) -> (f64, f64) {
    let (e, _) = crate::hypotheses::min1d(score, -0.03, 0.03, 60);
    crate::hypotheses::min1d(score, e - 1e-3, e + 1e-3, 20)
}

/// One channel's parameter fitted to its entries' pooled score sum, with its standard error
/// from the score sum's curvature (module documentation).
fn fit_channel(
    models: &[Vec<Modal<'_>>],
    sets: &[&RateSet],
    (kind, c, shape): (ChannelKind, usize, (usize, usize)),
    p: &Params,
    alpha: f64,
) -> (f64, f64) {
    let cl = cells(kind, c, shape);
    let own = sets_of(kind, c, sets);
    if kind == ChannelKind::Clock {
        return match own.first() {
            Some(set) => fit_clock_of(models, set, &cl, p, alpha),
            None => (0.0, f64::INFINITY),
        };
    }
    let mut score = |v: f64| {
        pooled(models, &own, &cl, &with(p, kind, c, v), alpha)
            .map_or(f64::INFINITY, |s| s.value * s.effective_lines)
    };
    let (lo, hi, d, (v, s0)) = match kind {
        ChannelKind::Actuator => {
            let hi = sd_multirate::MAX_HOLD_DELAY.min(2.0);
            let m = crate::hypotheses::min1d(&mut score, 0.0, hi, 20);
            (0.0, hi, 0.01 * hi, m)
        }
        _ => (
            0.0,
            1.0,
            0.01,
            crate::hypotheses::min1d(&mut score, 0.0, 1.0, 10),
        ),
    };
    // curvature by central differences (one-sided at a bound)
    let (a, b) = ((v - d).max(lo), (v + d).min(hi));
    let (sa, sb) = (score(a), score(b));
    let curv = if b - v > 0.0 && v - a > 0.0 {
        (sa - 2.0 * s0 + sb) / ((b - v) * (v - a))
    } else {
        let (x, sx) = if b > v { (b, sb) } else { (a, sa) };
        2.0 * (sx - s0).max(0.0) / (x - v).powi(2)
    };
    (v, std_of(curv))
}

/// A standard error from the score sum's curvature.
fn std_of(curv: f64) -> f64 {
    if curv > 0.0 {
        curv.recip().sqrt()
    } else {
        f64::INFINITY
    }
}

/// The clock of set `s` fitted over its entries `cl` with the other parameters at `p`; the
/// residues do not depend on the clock and are fitted once per entry.
fn fit_clock_of(
    models: &[Vec<Modal<'_>>],
    s: &RateSet,
    cl: &[(usize, usize)],
    p: &Params,
    alpha: f64,
) -> (f64, f64) {
    let res: Vec<_> = cl
        .iter()
        .map(|&(i, j)| models[i][j].residues(p.of(i, j).nonideal()).ok())
        .collect();
    let mut score = |e: f64| -> f64 {
        let mut lines = Vec::with_capacity(cl.len());
        for (&(i, j), r) in cl.iter().zip(&res) {
            let t = Target {
                factor: s.factor,
                est: &s.entries[i][j],
            };
            match r
                .as_ref()
                .map(|r| models[i][j].lines(r, p.of(i, j).nonideal(), e, &t))
            {
                Some(Ok(l)) => lines.push(l),
                _ => return f64::INFINITY,
            }
        }
        let st = statistic(lines.iter().map(|l| (l.as_slice(), 1.0)), alpha);
        st.value * st.effective_lines
    };
    let (v, s0) = fit_clock(&mut score);
    let d = 1e-5;
    let curv = (score(v - d) - 2.0 * s0 + score(v + d)) / (d * d);
    (v, std_of(curv))
}

/// The channels' parameters fitted alternately (two rounds) on the slower sets `sets`, each
/// with its standard error; only the channels in `which`, the others at 0.
fn fit_params(
    models: &[Vec<Modal<'_>>],
    sets: &[&RateSet],
    (shape, slow): Shape,
    which: &[(ChannelKind, usize)],
    alpha: f64,
) -> (Params, Vec<f64>) {
    let mut p = Params::zero((shape, slow));
    let mut std = vec![f64::INFINITY; which.len()];
    for _ in 0..2 {
        for (k, &(kind, c)) in which.iter().enumerate() {
            let (v, s) = fit_channel(models, sets, (kind, c, shape), &p, alpha);
            p = with(&p, kind, c, v);
            std[k] = s;
        }
    }
    (p, std)
}

/// Every channel: actuators, sensors, then the slower sets' clocks.
fn every_channel(((ny, nu), slow): Shape) -> Vec<(ChannelKind, usize)> {
    (0..nu)
        .map(|j| (ChannelKind::Actuator, j))
        .chain((0..ny).map(|i| (ChannelKind::Sensor, i)))
        .chain((0..slow).map(|s| (ChannelKind::Clock, s)))
        .collect()
}

/// Each channel's finding at the parameters `p` fitted on `sets` (module documentation).
fn findings(
    models: &[Vec<Modal<'_>>],
    sets: &[&RateSet],
    shape: Shape,
    (p, std): (&Params, &[f64]),
    alpha: f64,
) -> Result<Vec<ChannelFinding>> {
    every_channel(shape)
        .into_iter()
        .zip(std)
        .map(|((kind, c), s)| {
            let cl = cells(kind, c, shape.0);
            let own = sets_of(kind, c, sets);
            let before = pooled(models, &own, &cl, &with(p, kind, c, 0.0), alpha)?;
            let after = pooled(models, &own, &cl, p, alpha)?;
            let v = p.get(kind, c);
            let named = !before.passes()
                && penalised(&after, 1) < penalised(&before, 0)
                && v.abs() > 3.0 * s;
            Ok(ChannelFinding {
                kind,
                channel: c,
                fraction: v,
                fraction_std: *s,
                named,
                before,
                after,
            })
        })
        .collect()
}

/// The extension's gain: each slower set held out in turn (parameters of the named channels
/// refitted on the others), or in-sample with one set. A named clock belongs to its own set:
/// it is fitted on the set's earlier periods and the set is judged on its later ones
/// (`halves`; in-sample when the set has fewer than four steady periods). Only the sets a
/// named parameter acts on are judged (a clock's own set; every set for a hold delay or an
/// averaging window).
fn gain(
    models: &[Vec<Modal<'_>>],
    sets: &[&RateSet],
    shape: Shape,
    (named, p): (&[(ChannelKind, usize)], &Params),
    halves: &[Option<(RateSet, RateSet)>],
    alpha: f64,
) -> Result<MimoGain> {
    let all = every_entry(shape.0);
    let zero = Params::zero(shape);
    let (mut before, mut after, mut names) = (Vec::new(), Vec::new(), Vec::new());
    let timing_named = named.iter().any(|(k, _)| *k != ChannelKind::Clock);
    let mut held_out = sets.len() >= 2 || !timing_named;
    for (k, &set) in sets.iter().enumerate() {
        let own_clock = (ChannelKind::Clock, set.index);
        if !timing_named && !named.contains(&own_clock) {
            // nothing named acts on this set
            continue;
        }
        let mut fitted = if sets.len() >= 2 {
            let rest: Vec<&RateSet> = (0..sets.len())
                .filter(|&q| q != k)
                .map(|q| sets[q])
                .collect();
            let others: Vec<(ChannelKind, usize)> =
                named.iter().copied().filter(|c| *c != own_clock).collect();
            fit_params(models, &rest, shape, &others, alpha).0
        } else {
            p.clone()
        };
        let judged = match halves.get(set.index).and_then(Option::as_ref) {
            Some((early, late)) if named.contains(&own_clock) => {
                let (e, _) = fit_channel(
                    models,
                    &[early],
                    (ChannelKind::Clock, set.index, shape.0),
                    &fitted,
                    alpha,
                );
                fitted.clock[set.index] = e;
                names.extend(set.names.iter().map(|n| format!("{n} (later periods)")));
                late
            }
            _ => {
                if named.contains(&own_clock) {
                    held_out = false;
                    fitted.clock[set.index] = p.clock[set.index];
                }
                names.extend(set.names.iter().cloned());
                set
            }
        };
        let one = [judged];
        before.extend(lines_of(models, &one, &all, &zero)?);
        after.extend(lines_of(models, &one, &all, &fitted)?);
    }
    let stat = |l: &[Vec<Line>]| statistic(l.iter().map(|x| (x.as_slice(), 1.0)), alpha);
    Ok(MimoGain {
        ratio: stat(&before).value / stat(&after).value.max(f64::MIN_POSITIVE),
        measured_on: names,
        held_out,
    })
}

/// A set's earlier and later steady periods as two sets (`None` when an experiment is not
/// periodic or has fewer than four steady periods: each half needs two for its variances).
fn half_sets(set: &[&Experiment], factor: usize, index: usize) -> Option<(RateSet, RateSet)> {
    let cut = |e: &Experiment, later: bool| -> Option<Experiment> {
        let period = e.spec.period_samples?.max(1);
        let total = e.u.len() / period;
        let skip = e.spec.skip_periods;
        let steady = total.checked_sub(skip).filter(|s| *s >= 4)?;
        let (lo, hi) = if later {
            (skip + steady / 2, total)
        } else {
            (skip, skip + steady / 2)
        };
        let c = |x: &Vec<f64>| x.get(lo * period..hi * period).map(<[f64]>::to_vec);
        let many = |v: &[Vec<f64>]| v.iter().map(c).collect::<Option<Vec<_>>>();
        let mut x = e.clone();
        x.spec.skip_periods = 0;
        x.u = c(&e.u)?;
        x.y = c(&e.y)?;
        x.r = match &e.r {
            Some(r) => Some(c(r)?),
            None => None,
        };
        x.extra.u = many(&e.extra.u)?;
        x.extra.y = many(&e.extra.y)?;
        x.extra.r = many(&e.extra.r)?;
        Some(x)
    };
    let part = |later: bool| -> Option<RateSet> {
        let exps = set
            .iter()
            .map(|e| cut(e, later))
            .collect::<Option<Vec<_>>>()?;
        let refs: Vec<&Experiment> = exps.iter().collect();
        rate_set(&refs, factor, index).ok().map(|x| x.0)
    };
    Some((part(false)?, part(true)?))
}

/// Every entry's measured FRF at the slowest set and the predictions without and with the
/// extension `ext`.
fn curves(
    models: &[Vec<Modal<'_>>],
    slowest: &RateSet,
    ext: &Params,
    zero: &Params,
) -> Result<Vec<EntryCurves>> {
    let mut out = Vec::new();
    for (i, row) in slowest.entries.iter().enumerate() {
        for (j, est) in row.iter().enumerate() {
            let t = [Target {
                factor: slowest.factor,
                est,
            }];
            let pred = |p: &Params| -> Result<Vec<num_complex::Complex64>> {
                let mut rt = p.of(i, j);
                rt.clock_error = vec![p.clock.get(slowest.index).copied().unwrap_or(0.0)];
                Ok(models[i][j]
                    .predictions(&rt, &t)?
                    .into_iter()
                    .next()
                    .unwrap_or_default())
            };
            out.push(EntryCurves {
                output: i,
                input: j,
                factor: slowest.factor,
                freq_hz: est.frd.freq_hz().to_vec(),
                measured: est.frd.response().iter().map(|m| m[(0, 0)]).collect(),
                model: pred(zero)?,
                extended: pred(ext)?,
            });
        }
    }
    Ok(out)
}

/// Diagnoses a set of MIMO experiments (module documentation); `progress` receives one line
/// per stage.
///
/// # Errors
/// Experiments of different shapes, no slower set, rates that are not integer fractions, too
/// few periods, the FRF estimators' and the fit's errors.
pub fn diagnose_mimo(
    experiments: &[Experiment],
    opt: &MimoDiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<MimoDiagnosis> {
    crate::stats::check_alpha(opt.alpha)?;
    let shape = experiments
        .first()
        .map(|e| (e.spec.outputs().len(), e.spec.inputs().len()))
        .ok_or_else(|| DiagnoseError::Setup("no experiment".into()))?;
    if let Some(e) = experiments
        .iter()
        .find(|e| (e.spec.outputs().len(), e.spec.inputs().len()) != shape)
    {
        return Err(DiagnoseError::Setup(format!(
            "experiment `{}` has {} outputs and {} inputs, the first {} and {}: one plant, \
             one set of columns",
            e.spec.name,
            e.spec.outputs().len(),
            e.spec.inputs().len(),
            shape.0,
            shape.1
        )));
    }
    let (model_set, slow_sets) = rate_sets(experiments)?;
    if model_set.is_empty() || slow_sets.is_empty() {
        return Err(DiagnoseError::Setup(
            "the MIMO diagnosis needs a model set and experiments at a slower rate (an integer \
             fraction of the model set's)"
                .into(),
        ));
    }
    progress("MIMO FRFs of every rate");
    let (fast, fast_frd) = rate_set(&model_set, 1, 0)?;
    let slow: Vec<RateSet> = slow_sets
        .iter()
        .enumerate()
        .map(|(k, (s, f))| rate_set(s, *f, k).map(|x| x.0))
        .collect::<Result<_>>()?;
    let sh: Shape = (shape, slow.len());
    progress("common-pole fit of the model set");
    let (fit, order) = fit_model(&fast_frd, opt)?;
    let h = fast_frd.time().ts().unwrap_or(1.0);
    let models = entry_models(&fit.model, &fast, h, opt.alpha)?;
    let sets: Vec<&RateSet> = slow.iter().collect();
    progress("per-channel hold delays and averaging windows, per-set clocks");
    let channels_all = every_channel(sh);
    let (p, std) = fit_params(&models, &sets, sh, &channels_all, opt.alpha);
    let channels = findings(&models, &sets, sh, (&p, &std), opt.alpha)?;
    let named: Vec<(ChannelKind, usize)> = channels
        .iter()
        .filter(|c| c.named)
        .map(|c| (c.kind, c.channel))
        .collect();
    // the extension: the named channels' parameters, the others at 0
    let zero = Params::zero(sh);
    let ext = named.iter().fold(zero.clone(), |e, &(kind, c)| {
        with(&e, kind, c, p.get(kind, c))
    });
    let mut entries = Vec::new();
    for i in 0..shape.0 {
        for j in 0..shape.1 {
            entries.push(EntryCheck {
                output: i,
                input: j,
                plain: pooled(&models, &sets, &[(i, j)], &zero, opt.alpha)?,
                extended: pooled(&models, &sets, &[(i, j)], &ext, opt.alpha)?,
            });
        }
    }
    let all = every_entry(shape);
    let verdict = if pooled(&models, &sets, &all, &zero, opt.alpha)?.passes() {
        Verdict::Consistent
    } else {
        Verdict::Discrepancy
    };
    let gain = if named.is_empty() {
        None
    } else {
        progress("gain on held-out rates");
        let halves: Vec<Option<(RateSet, RateSet)>> = slow_sets
            .iter()
            .enumerate()
            .map(|(k, (s, f))| {
                named
                    .contains(&(ChannelKind::Clock, k))
                    .then(|| half_sets(s, *f, k))
                    .flatten()
            })
            .collect();
        Some(gain(
            &models,
            &sets,
            sh,
            (&named, &ext),
            &halves,
            opt.alpha,
        )?)
    };
    let curves = match sets.last() {
        Some(slowest) => curves(&models, slowest, &ext, &zero)?,
        None => Vec::new(),
    };
    Ok(MimoDiagnosis {
        curves,
        verdict,
        shape,
        order,
        states: fit.model.n(),
        fit_cost: fit.cost,
        fit_lines: fast_frd.len() * shape.0 * shape.1,
        model: fit.model,
        channels,
        entries,
        gain,
        model_experiments: fast.names,
        validation: slow.iter().map(|s| (s.names.clone(), s.factor)).collect(),
    })
}
