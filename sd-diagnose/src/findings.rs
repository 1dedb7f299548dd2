//! Stage 6, the findings per experiment: where the model misses (bands, their fast origin),
//! the FRF curves, the time-domain comparison.

use crate::lemma6::Pair;
use crate::stats::Line;
use crate::timedomain::AveragedPeriod;
use crate::{Band, InBands, Result, TimeDomain};
use num_complex::Complex64 as C;
use sd_ident::Experiment;
use sd_model::{rms_of, StateSpace};
use sd_multirate::hold_weight;
use std::f64::consts::PI;

/// Bands where the lines miss beyond 3σ (gaps up to 2 lines merged) that carry at least 1 % of
/// the statistic, largest share first.
pub(crate) fn bands(lines: &[Line], fold_source: impl Fn(f64) -> f64) -> Vec<Band> {
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
            worst_deg: (w.meas / w.pred).arg().to_degrees(),
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
pub(crate) fn dominant_fold(model: &StateSpace, pair: &Pair<'_>, f: f64) -> f64 {
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
            let fk = sd_model::fold(fk, fs).abs();
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

pub(crate) fn responses(model: &StateSpace, f: &[f64]) -> Result<Vec<C>> {
    Ok(model
        .freqresp(f)?
        .response()
        .iter()
        .map(|r| r[(0, 0)])
        .collect())
}

/// A model given by its response at a list of frequencies.
pub(crate) type ResponseFn<'a> = dyn Fn(&[f64]) -> Result<Vec<C>> + 'a;

pub(crate) fn time_domain(
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
        let sim = crate::timedomain::simulate_record(model, &e.u, &e.y)?;
        let ext = match ext_model {
            Some(m) => Some(crate::timedomain::simulate_record(m, &e.u, &e.y)?),
            None => None,
        };
        let mean = e.y.iter().sum::<f64>() / e.y.len().max(1) as f64;
        return Ok(Some(TimeDomain {
            rate_hz: e.spec.sample_rate_hz,
            output_rms: rms_of(e.y.iter().map(|v| v - mean)),
            noise_rms: None,
            error_rms_model: rms_of(e.y.iter().zip(&sim).map(|(a, b)| a - b)),
            error_rms_extended: ext
                .as_ref()
                .map(|x| rms_of(e.y.iter().zip(x).map(|(a, b)| a - b))),
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
        InBands {
            noise_rms: noise,
            error_rms_model: em,
            error_rms_extended: ee,
        }
    });
    Ok(Some(TimeDomain {
        rate_hz: per.rate_hz,
        output_rms: per.output_rms(),
        noise_rms: Some(per.noise_rms(&resp)),
        error_rms_model: per.error_rms(&sim),
        error_rms_extended: ext.as_ref().map(|s| per.error_rms(s)),
        in_bands,
        measured: per.y.clone(),
        model: sim,
        extended: ext,
    }))
}
