//! Stage 6: the report context — each experiment's findings, curves and extended model.

use super::checks::*;
use super::judged::*;
use super::read::*;
use crate::data::Estimate;
use crate::findings::{bands, dominant_fold, responses, time_domain};
use crate::modal::Residues;
use crate::stats::{statistic, Line, Statistic};
use crate::{Curves, ExperimentReport, ExtendedModel, Extension, RateTied, Result};
use num_complex::Complex64 as C;
use sd_ident::{Experiment, Role};
use sd_model::{SampleTime, StateSpace};
use std::collections::BTreeMap;

/// The extended model of an experiment slower by `factor` with clock error `e`, labelled
/// with its nominal period (its responses on the nominal frequency axis).
pub(super) fn extended_model(
    j: &Judged<'_>,
    res: &Residues,
    p: &RateTied,
    factor: usize,
    e: f64,
) -> Result<StateSpace> {
    let ts = j.modal.h * factor as f64;
    let m = j.modal.basis.model(&res.r, ts * (1.0 + e), p.nonideal())?;
    Ok(StateSpace::new(
        m.a().clone(),
        m.b().clone(),
        m.c().clone(),
        m.d().clone(),
        SampleTime::discrete(ts)?,
    )?)
}

/// Stage 6: the findings of every experiment.
pub(super) fn reports(
    data: &Data<'_>,
    j: &Judged<'_>,
    ch: &Checks,
    (ext, models): (&Extension, &BTreeMap<String, StateSpace>),
    res: Option<&(Residues, &RateTied)>,
) -> Result<Vec<ExperimentReport>> {
    let tied: Vec<&str> = data
        .vals
        .iter()
        .filter(|v| v.rate_tied())
        .map(|v| v.exp.spec.name.as_str())
        .collect();
    let clock_of = |name: &str| -> f64 {
        match res {
            Some((_, p)) => tied
                .iter()
                .position(|n| *n == name)
                .map(|k| p.clock(k))
                .unwrap_or(0.0),
            None => 0.0,
        }
    };
    let mut out = Vec::with_capacity(1 + data.vals.len());
    let ctx = ReportCtx {
        alpha: ch.alpha_test,
        data,
        j,
        ext,
    };
    let em = |factor: usize, name: &str| -> Result<Option<StateSpace>> {
        if let Some(m) = models.get(name) {
            return Ok(Some(m.clone()));
        }
        res.map(|(r, p)| extended_model(j, r, p, factor, clock_of(name)))
            .transpose()
    };
    out.push(ctx.report(
        data.model_exp,
        &data.fast,
        1,
        ch.fast_model.clone(),
        &j.model,
        None,
        em(1, &data.model_exp.spec.name)?,
        1.0,
    )?);
    for (i, v) in data.vals.iter().enumerate() {
        let c = v.whole.inflation.max(data.fast.inflation);
        out.push(ctx.report(
            v.exp,
            &v.whole,
            v.factor,
            ch.model[i].clone(),
            &v.model,
            Some(statistic([(ch.free[i].as_slice(), c)], ch.alpha_test)),
            em(v.factor, &v.exp.spec.name)?,
            v.level,
        )?);
    }
    Ok(out)
}

pub(super) struct ReportCtx<'a, 'b> {
    pub(super) alpha: f64,
    pub(super) data: &'a Data<'b>,
    pub(super) j: &'a Judged<'b>,
    pub(super) ext: &'a Extension,
}

impl ReportCtx<'_, '_> {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn report(
        &self,
        e: &Experiment,
        est: &Estimate,
        factor: usize,
        lines: Vec<Line>,
        model_at: &StateSpace,
        free: Option<Statistic>,
        em: Option<StateSpace>,
        level: f64,
    ) -> Result<ExperimentReport> {
        let p = self.data.pair(factor);
        let alpha = self.alpha;
        let freq: Vec<f64> = lines.iter().map(|l| l.f).collect();
        let extended: Option<Vec<C>> = match (&em, self.ext) {
            (Some(m), _) => Some(responses(m, &freq)?),
            (None, Extension::FastFrf) => Some(
                lines
                    .iter()
                    .map(|l| p.predict(l.f).map(|x| x.value).unwrap_or(l.pred))
                    .collect(),
            ),
            _ => None,
        };
        // the extension judged with the model's yardstick
        let extended_stat = match (&em, self.ext) {
            (Some(m), _) => Some(self.j.lines(m, factor, est)?),
            (None, Extension::FastFrf) if factor > 1 => Some(free_lines(&p, est)),
            _ => None,
        }
        .map(|l| statistic([(l.as_slice(), est.inflation)], alpha));
        let found = bands(&lines, |f| dominant_fold(&self.j.model, &p, f));
        let ext_fn = |bins: &[f64]| -> Result<Vec<C>> {
            match &em {
                Some(m) => responses(m, bins),
                None => {
                    let base = responses(model_at, bins)?;
                    Ok(bins
                        .iter()
                        .zip(base)
                        .map(|(&f, b)| {
                            if found.iter().any(|x| f >= x.f_lo && f <= x.f_hi) {
                                p.predict(f).map(|x| x.value).unwrap_or(b)
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
            extended
                .as_ref()
                .map(|_| &ext_fn as &crate::findings::ResponseFn<'_>),
            em.as_ref(),
            &found,
        )?;
        Ok(ExperimentReport {
            name: e.spec.name.clone(),
            role: if std::ptr::eq(e, self.data.model_exp) {
                Role::Model
            } else {
                Role::Validation
            },
            rate_hz: e.spec.sample_rate_hz,
            factor,
            relative_level: level,
            model_free: free,
            model_stat: statistic([(lines.as_slice(), est.inflation)], alpha),
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
            distortion: est.distortion.clone(),
            bla: est.bla.as_ref().map(|b| crate::BlaReport {
                distortion: b.distortion.clone(),
                bands: b.bands(),
            }),
            held_out: None,
            extended_model: em,
        })
    }
}

/// The rate-tied extension (its residues and parameters) as a continuous model with its hold
/// delay and averaging window (`None` for any other extension).
pub(super) fn extended_continuous(
    j: &Judged<'_>,
    tied: Option<&(Residues, &RateTied)>,
) -> Result<Option<ExtendedModel>> {
    let Some((res, p)) = tied else {
        return Ok(None);
    };
    Ok(Some(ExtendedModel {
        continuous: j.modal.basis.continuous(&res.r)?,
        hold_delay: p.hold_delay,
        averaging: p.averaging,
    }))
}
