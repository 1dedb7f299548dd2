//! The diagnosis itself (crate documentation).

use crate::lemma6::{compare, pooled, stat, threshold, Line, Pair};
use crate::modal::{ModalBasis, Residues};
use crate::timedomain::AveragedPeriod;
use crate::{
    Band, Curves, DiagnoseError, DiagnoseOptions, Diagnosis, Evidence, ExperimentReport, Hyp,
    Result, TimeDomain,
};
use num_complex::Complex64 as C;
use sd_ident::{
    frf_periodic, DistortionReport, Experiment, FitOptions, PeriodicOptions, Role, Weighting,
};
use sd_model::{Frd, SampleTime, StateSpace};
use sd_multirate::{downsample, hold_weight, NonIdeal};
use serde_json::json;
use std::f64::consts::PI;

/// Which part of an experiment's steady data.
#[derive(Clone, Copy, PartialEq)]
enum Part {
    Whole,
    First,
    Second,
}

/// The FRF of (part of) an experiment, with the distortion report of a periodic one.
fn estimate(e: &Experiment, part: Part) -> Result<(Frd, Option<DistortionReport>)> {
    let Some(period) = e.spec.period_samples else {
        // non-periodic data: the local polynomial method (transients handled); the halves for
        // the held-out gain are the two halves of the record
        let n = e.u.len();
        let (lo, hi) = match part {
            Part::Whole => (0, n),
            Part::First => (0, n / 2),
            Part::Second => (n / 2, n),
        };
        let opt = sd_ident::LpmOptions::default();
        let fs = e.spec.sample_rate_hz;
        let frd = match &e.r {
            Some(r) => sd_ident::lpm_closed_loop(fs, &r[lo..hi], &e.u[lo..hi], &e.y[lo..hi], &opt)?,
            None => {
                let x = nalgebra::DMatrix::from_column_slice(hi - lo, 1, &e.u[lo..hi]);
                let z = nalgebra::DMatrix::from_column_slice(hi - lo, 1, &e.y[lo..hi]);
                sd_ident::lpm(fs, &x, &z, &opt)?.frd
            }
        };
        return Ok((frd, None));
    };
    let skip = e.spec.skip_periods;
    let total = e.u.len() / period;
    let steady = total.saturating_sub(skip);
    let (lo, hi) = match part {
        Part::Whole => (skip, total),
        Part::First => (skip, skip + steady / 2),
        Part::Second => (skip + steady / 2, total),
    };
    let cut = |x: &[f64]| x[lo * period..hi * period].to_vec();
    let r = e.r.as_ref().map(|r| cut(r));
    let est = frf_periodic(
        e.spec.sample_rate_hz,
        r.as_deref(),
        &cut(&e.u),
        &cut(&e.y),
        &PeriodicOptions::new(period, 0),
    )?;
    Ok((est.frd, est.distortion))
}

/// Evidence of nonlinear distortion: the mean power at the non-excited odd and even lines of
/// the band over the noise level there (≈ 1 ± 1/√L for a linear system).
fn distortion_evidence(name: &str, d: &DistortionReport) -> Vec<Evidence> {
    [
        ("odd", d.odd_ratio, d.odd_lines),
        ("even", d.even_ratio, d.even_lines),
    ]
    .into_iter()
    .filter(|x| x.2 > 0)
    .map(|(kind, ratio, lines)| {
        Evidence::check(
            format!(
                "power at the {lines} non-excited {kind} lines of `{name}` over the noise \
                 (nonlinear distortion)"
            ),
            ratio,
            threshold(lines),
        )
    })
    .collect()
}

/// Rms of the excitation (reference, or input without one) over the steady periods.
fn level(e: &Experiment) -> f64 {
    let x = e.r.as_ref().unwrap_or(&e.u);
    let start = e.spec.skip_periods * e.spec.period_samples.unwrap_or(0);
    let s = &x[start.min(x.len())..];
    (s.iter().map(|v| v * v).sum::<f64>() / s.len().max(1) as f64).sqrt()
}

/// Rigid-body poles suggested by the low-frequency slope of |G| (−2: two, −1: one), over the
/// lowest octave pair of lines measured well (|G| above 3σ: a stiff loop leaves the lowest
/// lines in the noise).
fn rigid_body_count(frd: &Frd) -> usize {
    let f = frd.freq_hz();
    let good = |i: usize| {
        let g = frd.response()[i][(0, 0)].norm();
        let v = frd.variance().map(|v| v[i][(0, 0)]).unwrap_or(0.0);
        f[i] > 0.0 && g > 0.0 && g * g > 9.0 * v
    };
    let Some(f0) = (0..f.len()).find(|&i| good(i)).map(|i| f[i]) else {
        return 0;
    };
    let pts: Vec<(f64, f64)> = (0..f.len())
        .filter(|&i| f[i] <= 4.0 * f0 && good(i))
        .map(|i| (f[i].ln(), frd.response()[i][(0, 0)].norm().ln()))
        .collect();
    if pts.len() < 3 {
        return 0;
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let slope = sxy / sxx.max(f64::MIN_POSITIVE);
    if slope < -1.5 {
        2
    } else if slope < -0.5 {
        1
    } else {
        0
    }
}

/// The model at the fast period: given (checked, ZOH-discretised if continuous) or fitted.
fn model_for(
    fast: &Frd,
    h: f64,
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<(StateSpace, String)> {
    if let Some(m) = &opt.model {
        if m.nu() != 1 || m.ny() != 1 {
            return Err(DiagnoseError::Setup(format!(
                "the given model has {} inputs and {} outputs; the diagnosis needs a SISO model",
                m.nu(),
                m.ny()
            )));
        }
        let m = match m.time() {
            SampleTime::Continuous => sd_model::c2d(m, h, sd_model::Discretization::Zoh)?,
            SampleTime::Discrete { ts } if (ts - h).abs() <= 1e-9 * h => m.clone(),
            SampleTime::Discrete { ts } => {
                return Err(DiagnoseError::Setup(format!(
                    "the given model samples at {ts} s but the model experiment at {h} s: give \
                     it at the model experiment's rate, or as a continuous model"
                )))
            }
        };
        return Ok((m, "given".into()));
    }
    let rigid = rigid_body_count(fast);
    let base = FitOptions {
        rigid_body: rigid,
        feedthrough: true,
        weighting: Weighting::Variance,
        lm_iterations: 0,
        ..Default::default()
    };
    let mut best: Option<(f64, usize, StateSpace, f64)> = None;
    for order in rigid + 1..=opt.max_order.max(rigid + 1) {
        if let Some(b) = &best {
            // FPE has not improved for 4 orders: stop
            if order > b.1 + 4 {
                break;
            }
        }
        progress(&format!("fitting order {order}"));
        let opt_n = FitOptions {
            order,
            ..base.clone()
        };
        let Ok(r) = sd_ident::fit(fast, &opt_n) else {
            continue;
        };
        let fpe = sd_ident::final_prediction_error(r.cost, &opt_n, fast.len());
        if !fpe.is_finite() {
            continue;
        }
        if best.as_ref().map(|b| fpe < b.0).unwrap_or(true) {
            best = Some((fpe, order, r.model, r.cost));
        }
    }
    // the scan uses SK only; the chosen order is refined by Levenberg–Marquardt
    if let Some(b) = &mut best {
        progress(&format!("refining order {}", b.1));
        if let Ok(r) = sd_ident::fit(
            fast,
            &FitOptions {
                order: b.1,
                lm_iterations: FitOptions::default().lm_iterations,
                ..base.clone()
            },
        ) {
            if r.cost <= b.3 {
                b.2 = r.model;
            }
        }
    }
    match best {
        Some((_, order, m, _)) => Ok((
            m,
            format!(
                "fitted to the model experiment (order {order} by FPE, {rigid} rigid-body poles)"
            ),
        )),
        None => Err(DiagnoseError::Setup(
            "no model order could be fitted to the model experiment's FRF".into(),
        )),
    }
}

/// Excitation levels within this relative distance count as the same level.
const LEVEL_TOL: f64 = 0.2;

/// A validation experiment with its estimates.
struct Val<'a> {
    exp: &'a Experiment,
    distortion: Option<DistortionReport>,
    factor: usize,
    whole: Frd,
    halves: Option<(Frd, Frd)>,
    /// Level relative to the model experiment's.
    level: f64,
    /// The model's simulation at this rate (Lemma 6).
    model: StateSpace,
}

impl Val<'_> {
    fn rate_tied(&self) -> bool {
        (self.level - 1.0).abs() <= LEVEL_TOL
    }
}

fn with_var(f: &Frd) -> bool {
    f.variance().is_some()
}

/// Lines of `val` against the model-free prediction.
fn free_lines(pair: &Pair<'_>, val: &Frd) -> Vec<Line> {
    compare(val, |_, f| pair.predict(f))
}

/// Lines of `val` against a model's simulation, judged with the model-free prediction's
/// variance where it exists.
fn model_lines(pair: &Pair<'_>, model: &StateSpace, val: &Frd) -> Result<Vec<Line>> {
    let resp = model.freqresp(val.freq_hz())?;
    Ok(compare(val, |i, f| {
        let vp = pair.predict(f).map(|p| p.1).unwrap_or(0.0);
        Some((resp.response()[i][(0, 0)], vp))
    }))
}

/// The rate-tied hypotheses on the continuous modal model.
struct Modal<'a> {
    basis: ModalBasis,
    fast: &'a Frd,
    h: f64,
}

fn ni(kind: Hyp) -> NonIdeal {
    match kind {
        Hyp::Delay(a) => NonIdeal::hold_delay(a),
        Hyp::Average(b) => NonIdeal::averaging(b),
        _ => NonIdeal::ideal(),
    }
}

impl Modal<'_> {
    fn residues(&self, hyp: Hyp) -> Result<Residues> {
        let phi = self.basis.responses(self.h, ni(hyp), self.fast.freq_hz())?;
        Residues::fit(self.fast, &phi)
    }

    /// Lines of `val` (slower by `factor`) against the extension's prediction.
    fn lines(&self, res: &Residues, hyp: Hyp, factor: usize, val: &Frd) -> Result<Vec<Line>> {
        let phi = self
            .basis
            .responses(self.h * factor as f64, ni(hyp), val.freq_hz())?;
        Ok(compare(val, |i, _| Some(res.predict(&phi[i]))))
    }

    /// Pooled statistic of the extension over the validation FRFs.
    fn cost(&self, hyp: Hyp, vals: &[(usize, &Frd)]) -> Result<f64> {
        let res = self.residues(hyp)?;
        let sets = vals
            .iter()
            .map(|(f, v)| self.lines(&res, hyp, *f, v))
            .collect::<Result<Vec<_>>>()?;
        Ok(pooled(sets.iter().map(Vec::as_slice)).0)
    }

    /// The parameter of `make` in [0, 1] minimizing the cost (grid of 26, then golden section
    /// in the best cell).
    fn fit(&self, make: fn(f64) -> Hyp, vals: &[(usize, &Frd)]) -> Result<(f64, f64)> {
        let cost = |p: f64| self.cost(make(p), vals).unwrap_or(f64::INFINITY);
        let (mut best, mut bc) = (0.0, f64::INFINITY);
        for i in 0..=25 {
            let p = i as f64 / 25.0;
            let c = cost(p);
            if c < bc {
                bc = c;
                best = p;
            }
        }
        if !bc.is_finite() {
            return Err(DiagnoseError::Setup(
                "no parameter of the extension gives a finite statistic".into(),
            ));
        }
        let (p, c) = sd_model::linalg::golden_min(
            cost,
            (best - 0.04f64).max(0.0),
            (best + 0.04f64).min(1.0),
            24,
        );
        Ok(if c < bc { (p, c) } else { (best, bc) })
    }
}

/// Bands where the lines miss beyond 3σ (gaps up to 2 lines merged) that carry at least 1 % of
/// the statistic, largest share first.
fn bands(lines: &[Line], fold_source: impl Fn(f64) -> f64) -> Vec<Band> {
    let total: f64 = lines.iter().map(Line::chi2).sum();
    let mut out: Vec<Band> = Vec::new();
    let mut cur: Option<(usize, usize)> = None;
    let close = |out: &mut Vec<Band>, lo: usize, hi: usize| {
        let seg = &lines[lo..=hi];
        let s: f64 = seg.iter().map(Line::chi2).sum();
        let w = seg
            .iter()
            .max_by(|a, b| a.chi2().total_cmp(&b.chi2()))
            .copied()
            .unwrap_or(seg[0]);
        out.push(Band {
            f_lo: seg[0].f,
            f_hi: seg[seg.len() - 1].f,
            worst_hz: w.f,
            worst_db: 20.0 * (w.meas.norm() / w.pred.norm().max(f64::MIN_POSITIVE)).log10(),
            from_fast_hz: w.f,
            share: s / total.max(f64::MIN_POSITIVE),
        });
    };
    for (i, l) in lines.iter().enumerate() {
        if l.chi2() > 9.0 {
            cur = match cur {
                Some((lo, hi)) if i - hi <= 3 => Some((lo, i)),
                Some((lo, hi)) => {
                    close(&mut out, lo, hi);
                    Some((i, i))
                }
                None => Some((i, i)),
            };
        }
    }
    if let Some((lo, hi)) = cur {
        close(&mut out, lo, hi);
    }
    out.retain(|b| b.share >= 0.01);
    out.sort_by(|a, b| b.share.total_cmp(&a.share));
    out.truncate(5);
    for b in &mut out {
        b.from_fast_hz = fold_source(b.worst_hz);
    }
    out
}

/// Where the response at slow frequency f comes from (a fast-band frequency): the fold at which
/// the model misses the measured fast FRF the most, weighted by the hold (when that miss exceeds
/// 3σ of the fast line: the model is wrong there); otherwise the fold whose model response
/// dominates.
fn dominant_fold(model: &StateSpace, pair: &Pair<'_>, f: f64) -> f64 {
    let (h, factor) = (pair.h, pair.factor);
    if factor <= 1 {
        return f;
    }
    let t = h * factor as f64;
    let fs = 1.0 / h;
    let Ok(ev) = sd_model::FreqRespEvaluator::new(model) else {
        return f;
    };
    let terms: Vec<(f64, f64, Option<f64>)> = (0..factor)
        .map(|k| {
            let fk = f - k as f64 / t;
            let fk = (fk - fs * (fk / fs).round()).abs();
            let w = hold_weight(2.0 * PI * fk * h, factor).norm();
            let g = ev.eval_hz(fk)[(0, 0)];
            let miss = pair
                .fast_at(fk)
                .filter(|(_, v)| *v > 0.0)
                .map(|(p, v)| ((g - p).norm() / v.sqrt(), w * (g - p).norm()))
                .filter(|(z, _)| *z > 3.0)
                .map(|x| x.1);
            (fk, w * g.norm(), miss)
        })
        .collect();
    let best_miss = terms
        .iter()
        .filter_map(|t| t.2.map(|m| (t.0, m)))
        .max_by(|a, b| a.1.total_cmp(&b.1));
    match best_miss {
        Some((fk, _)) => fk,
        None => terms
            .iter()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|x| x.0)
            .unwrap_or(f),
    }
}

fn responses(model: &StateSpace, f: &[f64]) -> Result<Vec<C>> {
    Ok(model
        .freqresp(f)?
        .response()
        .iter()
        .map(|r| r[(0, 0)])
        .collect())
}

/// A model given by its response at a list of frequencies.
type ResponseFn<'a> = dyn Fn(&[f64]) -> Result<Vec<C>> + 'a;

fn time_domain(
    e: &Experiment,
    model: &StateSpace,
    extended: Option<&ResponseFn<'_>>,
    ext_model: Option<&StateSpace>,
    found: &[Band],
) -> Result<Option<TimeDomain>> {
    let Some(per) = AveragedPeriod::of(e) else {
        if e.spec.period_samples.is_some() {
            return Ok(None);
        }
        // a non-periodic record: simulated from the least-squares initial state
        let rms = |x: &mut dyn Iterator<Item = f64>| {
            let (s, n) = x.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
            (s / n.max(1) as f64).sqrt()
        };
        let sim = crate::timedomain::simulate_record(model, &e.u, &e.y)?;
        let ext = match ext_model {
            Some(m) => Some(crate::timedomain::simulate_record(m, &e.u, &e.y)?),
            None => None,
        };
        let mean = e.y.iter().sum::<f64>() / e.y.len().max(1) as f64;
        return Ok(Some(TimeDomain {
            rate_hz: e.spec.sample_rate_hz,
            output_rms: rms(&mut e.y.iter().map(|v| v - mean)),
            noise_rms: f64::NAN,
            error_rms_model: rms(&mut e.y.iter().zip(&sim).map(|(a, b)| a - b)),
            error_rms_extended: ext
                .as_ref()
                .map(|x| rms(&mut e.y.iter().zip(x).map(|(a, b)| a - b))),
            in_bands: None,
            measured: e.y.clone(),
            model: sim,
            extended: ext,
        }));
    };
    let bins = per.bins_hz();
    let resp = responses(model, &bins)?;
    let sim = per.simulate(&resp)?;
    let ext_resp = match extended {
        Some(f) => Some(f(&bins)?),
        None => None,
    };
    let ext = match &ext_resp {
        Some(r) => Some(per.simulate(r)?),
        None => None,
    };
    let in_band = |f: f64| found.iter().any(|b| f >= b.f_lo && f <= b.f_hi);
    let in_bands = (!found.is_empty()).then(|| {
        let (em, noise) = per.band_rms(&resp, &in_band);
        let ee = ext_resp.as_ref().map(|r| per.band_rms(r, &in_band).0);
        (noise, em, ee)
    });
    Ok(Some(TimeDomain {
        rate_hz: per.rate_hz,
        output_rms: per.output_rms(),
        noise_rms: per.noise_rms(&resp),
        error_rms_model: per.error_rms(&sim),
        error_rms_extended: ext.as_ref().map(|s| per.error_rms(s)),
        in_bands,
        measured: per.y.clone(),
        model: sim,
        extended: ext,
    }))
}

/// [`diagnose_with_progress`] without progress messages.
///
/// # Errors
/// As [`diagnose_with_progress`].
pub fn diagnose(experiments: &[Experiment], opt: &DiagnoseOptions) -> Result<Diagnosis> {
    diagnose_with_progress(experiments, opt, &mut |_| {})
}

/// Diagnoses the model experiment's model against the validation experiments (crate
/// documentation), reporting each step to `progress`.
///
/// # Errors
/// Fewer than two experiments, rates that are not integer fractions of the model experiment's,
/// experiments without enough periods for variances, a given model that is not SISO or not at
/// the model experiment's rate, a model that cannot be fitted.
pub fn diagnose_with_progress(
    experiments: &[Experiment],
    opt: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<Diagnosis> {
    if experiments.len() < 2 {
        return Err(DiagnoseError::Setup(
            "a diagnosis needs a model experiment and at least one validation experiment".into(),
        ));
    }
    let model_exp = experiments
        .iter()
        .find(|e| e.spec.role == Role::Model)
        .or_else(|| {
            experiments
                .iter()
                .max_by(|a, b| a.spec.sample_rate_hz.total_cmp(&b.spec.sample_rate_hz))
        })
        .ok_or_else(|| DiagnoseError::Setup("no model experiment".into()))?;
    progress(&format!("FRF of `{}`", model_exp.spec.name));
    let (fast, fast_distortion) = estimate(model_exp, Part::Whole)?;
    if !with_var(&fast) {
        return Err(DiagnoseError::Setup(format!(
            "`{}` gives no FRF variance: a periodic experiment needs at least two steady periods",
            model_exp.spec.name
        )));
    }
    let h = 1.0 / model_exp.spec.sample_rate_hz;
    let (model, model_source) = model_for(&fast, h, opt, progress)?;
    let fast_model_lines = compare(&fast, {
        let r = responses(&model, fast.freq_hz())?;
        move |i, _| Some((r[i], 0.0))
    });
    let (fast_chi2, fast_k) = stat(&fast_model_lines);
    let mut evidence = vec![Evidence::check(
        format!(
            "model ({model_source}) against its own data `{}`",
            model_exp.spec.name
        ),
        fast_chi2,
        threshold(fast_k),
    )];
    let lm = level(model_exp);
    // validation experiments
    let mut vals = Vec::new();
    for e in experiments.iter().filter(|e| !std::ptr::eq(*e, model_exp)) {
        let ratio = model_exp.spec.sample_rate_hz / e.spec.sample_rate_hz;
        let factor = ratio.round() as usize;
        if factor < 1 || (ratio - ratio.round()).abs() > 1e-9 * ratio {
            return Err(DiagnoseError::Setup(format!(
                "`{}` runs at {} Hz, not an integer fraction of the model experiment's {} Hz",
                e.spec.name, e.spec.sample_rate_hz, model_exp.spec.sample_rate_hz
            )));
        }
        progress(&format!("FRF of `{}`", e.spec.name));
        let (whole, distortion) = estimate(e, Part::Whole)?;
        if !with_var(&whole) {
            return Err(DiagnoseError::Setup(format!(
                "`{}` gives no FRF variance: it needs at least two steady periods",
                e.spec.name
            )));
        }
        let halves = match (estimate(e, Part::First), estimate(e, Part::Second)) {
            (Ok((a, _)), Ok((b, _))) if with_var(&a) && with_var(&b) => Some((a, b)),
            _ => None,
        };
        vals.push(Val {
            exp: e,
            distortion,
            factor,
            whole,
            halves,
            level: level(e) / lm.max(f64::MIN_POSITIVE),
            model: if factor == 1 {
                model.clone()
            } else {
                downsample(&model, factor)?
            },
        });
    }
    // nonlinear distortion at non-excited lines (random-odd or sparse multisines)
    if let Some(d) = &fast_distortion {
        evidence.extend(distortion_evidence(&model_exp.spec.name, d));
    }
    for v in &vals {
        if let Some(d) = &v.distortion {
            evidence.extend(distortion_evidence(&v.exp.spec.name, d));
        }
    }
    let pair = |factor| Pair {
        fast: &fast,
        factor,
        h,
    };
    // the model-free and the model's comparisons, per validation experiment
    let mut compared: Vec<(Vec<Line>, Vec<Line>)> = Vec::with_capacity(vals.len());
    let mut reports = Vec::new();
    let mut nonlinear: Vec<(String, f64, f64, f64)> = Vec::new();
    let mut held = Vec::new();
    for v in &vals {
        let p = pair(v.factor);
        let fl = free_lines(&p, &v.whole);
        let ml = model_lines(&p, &v.model, &v.whole)?;
        let (s0, k) = stat(&fl);
        if k == 0 {
            return Err(DiagnoseError::Setup(format!(
                "no line of `{}` has all its fold frequencies on the model experiment's grid: the \
                 model experiment's f₀ must divide {} Hz",
                v.exp.spec.name, v.exp.spec.sample_rate_hz
            )));
        }
        let thr = threshold(k);
        evidence.push(Evidence::check(
            format!(
                "Lemma 6 prediction of `{}` from `{}` (model-free)",
                v.exp.spec.name, model_exp.spec.name
            ),
            s0,
            thr,
        ));
        let (sm, km) = stat(&ml);
        evidence.push(Evidence::check(
            format!("the model's simulation of `{}`", v.exp.spec.name),
            sm,
            threshold(km),
        ));
        if v.factor == 1 {
            // same rate: nothing rate-tied can differ; a different excitation level that
            // changes the FRF is a nonlinearity
            evidence.push(Evidence::check(
                format!(
                    "`{}` at {:.3}× the model experiment's excitation level (|ratio − 1| \
                     within 20 %: the same level)",
                    v.exp.spec.name, v.level
                ),
                (v.level - 1.0).abs(),
                LEVEL_TOL,
            ));
            if s0 > thr && !v.rate_tied() {
                // extension: a best linear approximation per level, judged on held-out periods
                let (mut b, mut a) = (s0, s0);
                if let Some((v1, v2)) = &v.halves {
                    b = stat(&free_lines(&p, v2)).0;
                    a = stat(&free_lines(&pair_of(v1, h), v2)).0;
                    held.push(format!("{} (second half)", v.exp.spec.name));
                }
                nonlinear.push((v.exp.spec.name.clone(), v.level, b, a));
            }
        }
        compared.push((fl, ml));
    }
    let tied_sets = || {
        vals.iter()
            .zip(&compared)
            .filter(|(v, _)| v.rate_tied())
            .map(|(_, c)| c)
    };
    let (s_free, k_free) = pooled(tied_sets().map(|c| c.0.as_slice()));
    let (s_model, k_model) = pooled(tied_sets().map(|c| c.1.as_slice()));
    let modal = Modal {
        basis: ModalBasis::from_model(&model)?,
        fast: &fast,
        h,
    };
    let mut ranking: Vec<(String, f64, usize)> = vec![("none".into(), s_model, 0)];
    let mut parameters = json!({});
    let (verdict, cause, extension, gain_before, gain_after);
    if !nonlinear.is_empty() {
        let n = nonlinear.len() as f64;
        let (b, a) = nonlinear
            .iter()
            .fold((0.0, 0.0), |acc, x| (acc.0 + x.2 / n, acc.1 + x.3 / n));
        let levels: serde_json::Map<String, serde_json::Value> = nonlinear
            .iter()
            .map(|x| (x.0.clone(), json!(x.1)))
            .collect();
        ranking.insert(0, ("nonlinearity".into(), a, 1));
        parameters = json!({"relative_levels": levels});
        verdict = "discrepancy";
        cause = "nonlinearity".to_string();
        extension = Hyp::PerLevel;
        gain_before = b;
        gain_after = a;
    } else if k_free == 0 && vals.iter().all(|v| v.factor == 1) {
        // only same-rate experiments at other excitation levels, and they agree: linear
        verdict = "consistent";
        cause = "none".into();
        extension = Hyp::None;
        gain_before = pooled(compared.iter().map(|c| c.1.as_slice())).0;
        gain_after = gain_before;
    } else if k_free == 0 {
        return Err(DiagnoseError::Setup(
            "no validation experiment at the model experiment's excitation level (±20 %): \
             nothing to compare rate-tied effects on"
                .into(),
        ));
    } else if s_free <= threshold(k_free) {
        // the data agree with each other through Lemma 6: the model decides
        if s_model <= threshold(k_model) {
            verdict = "consistent";
            cause = "none".into();
            extension = Hyp::None;
            gain_before = s_model;
            gain_after = s_model;
        } else {
            verdict = "discrepancy";
            cause = "fast_model_error".into();
            extension = Hyp::FastFrf;
            ranking.insert(0, ("fast_model_error".into(), s_free, 0));
            // the model's misfit on its own data, largest normalized residuals
            let mut worst: Vec<&Line> = fast_model_lines.iter().collect();
            worst.sort_by(|a, b| b.chi2().total_cmp(&a.chi2()));
            let fold: Vec<f64> = worst.iter().take(5).map(|l| l.f).collect();
            parameters = json!({"model_misfit_on_fast_data": fast_chi2, "worst_fast_hz": fold});
            let (mut b, mut a, mut n) = (0.0, 0.0, 0.0);
            for v in vals.iter().filter(|v| v.rate_tied()) {
                if let Some((_, v2)) = &v.halves {
                    let p = pair(v.factor);
                    b += stat(&model_lines(&p, &v.model, v2)?).0;
                    a += stat(&free_lines(&p, v2)).0;
                    n += 1.0;
                    held.push(format!("{} (second half)", v.exp.spec.name));
                }
            }
            let n = f64::max(n, 1.0);
            gain_before = b / n;
            gain_after = a / n;
        }
    } else if !vals.iter().any(|v| v.rate_tied() && v.factor > 1) {
        // only same-rate experiments at the same level, and they disagree: the plant changed
        // between the experiments or is not time-invariant; nothing rate-tied to test
        verdict = "discrepancy";
        cause = "unexplained".into();
        extension = Hyp::None;
        evidence.push(Evidence::check(
            "same rate and excitation level, yet different FRFs: not repeatable",
            s_free,
            threshold(k_free),
        ));
        gain_before = s_model;
        gain_after = s_model;
    } else {
        // rate-tied hypotheses on the continuous modal model
        let tied: Vec<&Val<'_>> = vals
            .iter()
            .filter(|v| v.rate_tied() && v.factor > 1)
            .collect();
        let whole: Vec<(usize, &Frd)> = tied.iter().map(|v| (v.factor, &v.whole)).collect();
        progress("rate-tied hypotheses: plain modal model");
        let c0 = modal.cost(Hyp::None, &whole)?;
        progress("rate-tied hypotheses: hold delay");
        let (alpha, ca) = modal.fit(Hyp::Delay, &whole)?;
        progress("rate-tied hypotheses: averaging sampler");
        let (beta, cb) = modal.fit(Hyp::Average, &whole)?;
        ranking = vec![
            ("none".into(), c0, 0),
            ("hold_delay".into(), ca, 1),
            ("averaging_sampler".into(), cb, 1),
        ];
        ranking.sort_by(|a, b| a.1.total_cmp(&b.1));
        evidence.push(Evidence::check(
            "best extension brings the statistic under the threshold",
            ranking[0].1,
            threshold(k_free),
        ));
        // named when the extension explains at least 90 % of the excess over the noise level
        // and the other extension is significantly worse: its statistic exceeds the best by
        // more than 5 standard deviations of a mean over K lines (1/√K per unit statistic)
        let named = {
            let best = &ranking[0];
            let other = if best.0 == "hold_delay" { cb } else { ca };
            let sd = best.1.max(1.0) / (k_model.max(1) as f64).sqrt();
            best.0 != "none" && c0 - best.1 >= 0.9 * (c0 - 1.0) && other - best.1 >= 5.0 * sd
        };
        verdict = "discrepancy";
        if named && ranking[0].0 == "hold_delay" {
            cause = "hold_delay".into();
            extension = Hyp::Delay(alpha);
            let delays: serde_json::Map<String, serde_json::Value> = experiments
                .iter()
                .map(|e| (e.spec.name.clone(), json!(alpha / e.spec.sample_rate_hz)))
                .collect();
            parameters = json!({"delay_frac": alpha, "delay_s": delays});
        } else if named {
            cause = "averaging_sampler".into();
            extension = Hyp::Average(beta);
            parameters = json!({"window_frac": beta});
        } else {
            cause = "unexplained".into();
            extension = Hyp::None;
        }
        // held-out gain: the parameter from the first halves, both statistics on the second
        let firsts: Vec<(usize, &Frd)> = tied
            .iter()
            .filter_map(|v| v.halves.as_ref().map(|h| (v.factor, &h.0)))
            .collect();
        let seconds: Vec<(usize, &Frd, &Val<'_>)> = tied
            .iter()
            .filter_map(|v| v.halves.as_ref().map(|h| (v.factor, &h.1, *v)))
            .collect();
        let before_sets = seconds
            .iter()
            .map(|(f, v2, v)| model_lines(&pair(*f), &v.model, v2))
            .collect::<Result<Vec<_>>>()?;
        gain_before = pooled(before_sets.iter().map(Vec::as_slice)).0;
        gain_after = match extension {
            Hyp::Delay(_) | Hyp::Average(_) if !firsts.is_empty() => {
                progress("held-out gain");
                let make: fn(f64) -> Hyp = if matches!(extension, Hyp::Delay(_)) {
                    Hyp::Delay
                } else {
                    Hyp::Average
                };
                // the extended model from the first halves, judged on the second halves with
                // the same yardstick as the model (measured plus fast-FRF-propagated variance)
                let (p1, _) = modal.fit(make, &firsts)?;
                let res1 = modal.residues(make(p1))?;
                let sets = seconds
                    .iter()
                    .map(|(f, v2, _)| {
                        let m = modal.basis.model(&res1.r, h * *f as f64, ni(make(p1)))?;
                        model_lines(&pair(*f), &m, v2)
                    })
                    .collect::<Result<Vec<_>>>()?;
                pooled(sets.iter().map(Vec::as_slice)).0
            }
            _ => gain_before,
        };
        held.extend(
            seconds
                .iter()
                .map(|s| format!("{} (second half)", s.2.exp.spec.name)),
        );
    }
    // per-experiment reports: curves, bands, time domain
    progress("reports");
    let ext_res = match extension {
        Hyp::Delay(_) | Hyp::Average(_) => Some(modal.residues(extension)?),
        _ => None,
    };
    if let Some(r) = &ext_res {
        evidence.push(Evidence::check(
            format!(
                "the extended continuous modal model against `{}`",
                model_exp.spec.name
            ),
            r.chi2,
            threshold(fast_k),
        ));
    }
    let ext_model = |ts: f64| -> Result<Option<StateSpace>> {
        match &ext_res {
            Some(r) => Ok(Some(modal.basis.model(&r.r, ts, ni(extension))?)),
            None => Ok(None),
        }
    };
    let ex_report = |e: &Experiment,
                     frd: &Frd,
                     factor: usize,
                     lines: Vec<Line>,
                     model_at: &StateSpace,
                     free: Option<(f64, usize)>,
                     distortion: Option<DistortionReport>|
     -> Result<ExperimentReport> {
        let ts = h * factor as f64;
        let em = ext_model(ts)?;
        let p = pair(factor);
        let freq: Vec<f64> = lines.iter().map(|l| l.f).collect();
        let extended: Option<Vec<C>> = match (&em, extension) {
            (Some(m), _) => Some(responses(m, &freq)?),
            (None, Hyp::FastFrf) => Some(
                lines
                    .iter()
                    .map(|l| p.predict(l.f).map(|x| x.0).unwrap_or(l.pred))
                    .collect(),
            ),
            _ => None,
        };
        // the extension judged with the model's yardstick: measured variance plus the fast
        // FRF's, propagated through Lemma 6
        let extended_stat = match (&em, extension) {
            (Some(m), _) => Some(stat(&model_lines(&p, m, frd)?).0),
            (None, Hyp::FastFrf) if factor > 1 => Some(stat(&free_lines(&p, frd)).0),
            _ => None,
        };
        let found = bands(&lines, |f| dominant_fold(&model, &p, f));
        // in the time domain the fast FRF replaces the model only inside the bands where the
        // model misses: elsewhere its noisy (and, in closed loop at the lowest lines, biased)
        // lines would add error where the model is right
        let ext_fn = |bins: &[f64]| -> Result<Vec<C>> {
            match (&em, extension) {
                (Some(m), _) => responses(m, bins),
                _ => {
                    let base = responses(model_at, bins)?;
                    Ok(bins
                        .iter()
                        .zip(base)
                        .map(|(&f, b)| {
                            if found.iter().any(|x| f >= x.f_lo && f <= x.f_hi) {
                                p.predict(f).map(|x| x.0).unwrap_or(b)
                            } else {
                                b
                            }
                        })
                        .collect())
                }
            }
        };
        let td = time_domain(
            e,
            model_at,
            if extended.is_some() {
                Some(&ext_fn)
            } else {
                None
            },
            em.as_ref(),
            &found,
        )?;
        Ok(ExperimentReport {
            name: e.spec.name.clone(),
            role: if factor == 1 && std::ptr::eq(e, model_exp) {
                "model".into()
            } else {
                "validation".into()
            },
            rate_hz: e.spec.sample_rate_hz,
            factor,
            model_free: free,
            model_stat: stat(&lines),
            extended_stat,
            bands: found,
            curves: Curves {
                freq_hz: freq,
                measured: lines.iter().map(|l| l.meas).collect(),
                noise_var: lines.iter().map(|l| l.var).collect(),
                model: lines.iter().map(|l| l.pred).collect(),
                extended,
            },
            time_domain: td,
            distortion,
        })
    };
    reports.push(ex_report(
        model_exp,
        &fast,
        1,
        fast_model_lines,
        &model,
        None,
        fast_distortion,
    )?);
    for (v, (fl, ml)) in vals.iter().zip(compared) {
        reports.push(ex_report(
            v.exp,
            &v.whole,
            v.factor,
            ml,
            &v.model,
            Some(stat(&fl)),
            v.distortion.clone(),
        )?);
    }
    Ok(Diagnosis {
        verdict: verdict.into(),
        cause,
        parameters,
        evidence,
        ranking,
        gain_before,
        gain_after,
        held_out: held,
        extension,
        model,
        model_source,
        experiments: reports,
    })
}

fn pair_of(f: &Frd, h: f64) -> Pair<'_> {
    Pair {
        fast: f,
        factor: 1,
        h,
    }
}
