//! Stage 1: the data — the model experiment, the validation experiments with their FRFs,
//! levels and rate factors.

use crate::data::{carry_within, estimate, level, parts, rate_factor, Estimate, Part};
use crate::lemma6::Pair;
use crate::stats::Statistic;
use crate::{DiagnoseError, Result};
use sd_ident::{Experiment, Role};
use sd_model::{SampleTime, StateSpace};

/// Excitation levels within this relative distance count as the same level.
pub(super) const LEVEL_TOL: f64 = 0.2;

/// A validation experiment with its estimates and the model's simulation at its rate.
pub(super) struct Val<'a> {
    pub(super) exp: &'a Experiment,
    pub(super) factor: usize,
    pub(super) whole: Estimate,
    /// Training and held-out parts, when both give variances.
    pub(super) parts: Option<(Estimate, Estimate)>,
    /// Level relative to the model experiment's.
    pub(super) level: f64,
    /// Compared as if at the model experiment's level: within [`LEVEL_TOL`] of it, or (a
    /// slower experiment) inside the span of fast-rate levels that agree with each other
    /// ([`Data::widen_levels`]).
    pub(super) comparable: std::cell::Cell<bool>,
    /// The model's simulation at this rate (Lemma 6).
    pub(super) model: StateSpace,
}

impl Val<'_> {
    /// At the model experiment's level (within [`LEVEL_TOL`]).
    pub(super) fn same_level(&self) -> bool {
        (self.level - 1.0).abs() <= LEVEL_TOL
    }
    /// Compared with the model experiment as at its level.
    pub(super) fn comparable(&self) -> bool {
        self.comparable.get()
    }
    /// Rate-tied effects show on it: a comparable level, slower rate.
    pub(super) fn rate_tied(&self) -> bool {
        self.comparable() && self.factor > 1
    }
}

/// Stage 1: the data and their FRFs.
pub(super) struct Data<'a> {
    pub(super) model_exp: &'a Experiment,
    pub(super) fast: Estimate,
    pub(super) h: f64,
    pub(super) vals: Vec<Val<'a>>,
}

pub(super) fn has_var(e: &Estimate) -> bool {
    e.frd.variance().is_some()
}

impl<'a> Data<'a> {
    pub(super) fn read(
        experiments: &'a [Experiment],
        progress: &mut dyn FnMut(&str),
    ) -> Result<Self> {
        if experiments.len() < 2 {
            return Err(DiagnoseError::Setup(
                "a diagnosis needs a model experiment and at least one validation experiment"
                    .into(),
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
        // every rate first: a wrong one is said before any work
        for e in experiments.iter().filter(|e| !std::ptr::eq(*e, model_exp)) {
            rate_factor(model_exp, e)?;
        }
        progress(&format!("FRF of `{}`", model_exp.spec.name));
        let fast = estimate(model_exp, Part::Whole)?;
        if !has_var(&fast) {
            return Err(DiagnoseError::Setup(format!(
                "`{}` gives no FRF variance: a periodic experiment needs at least two steady \
                 periods",
                model_exp.spec.name
            )));
        }
        let lm = level(model_exp);
        let vals = experiments
            .iter()
            .filter(|e| !std::ptr::eq(*e, model_exp))
            .map(|e| {
                progress(&format!("FRF of `{}`", e.spec.name));
                Ok((e, rate_factor(model_exp, e)?, estimate(e, Part::Whole)?))
            })
            .collect::<Result<Vec<_>>>()?;
        // a full multisine's distortion from a sibling of the same channel, band and level
        let mut set: Vec<(&Experiment, Estimate)> = std::iter::once((model_exp, fast))
            .chain(vals.into_iter().map(|(e, _, w)| (e, w)))
            .collect();
        carry_within(&mut set)?;
        let mut set = set.into_iter();
        let (_, fast) = set
            .next()
            .ok_or_else(|| DiagnoseError::Setup("no model experiment".into()))?;
        let vals: Vec<(&Experiment, usize, Estimate)> = set
            .map(|(e, w)| Ok((e, rate_factor(model_exp, e)?, w)))
            .collect::<Result<_>>()?;
        let data = Data {
            model_exp,
            fast,
            h: 1.0 / model_exp.spec.sample_rate_hz,
            vals: Vec::new(),
        };
        let mut out = Vec::with_capacity(vals.len());
        for (e, factor, whole) in vals {
            if !has_var(&whole) {
                return Err(DiagnoseError::Setup(format!(
                    "`{}` gives no FRF variance: it needs at least two steady periods",
                    e.spec.name
                )));
            }
            let parts = parts(e, &whole);
            out.push(Val {
                exp: e,
                factor,
                whole,
                parts,
                level: level(e) / lm.max(f64::MIN_POSITIVE),
                comparable: std::cell::Cell::new(false),
                model: StateSpace::new(
                    nalgebra::DMatrix::zeros(0, 0),
                    nalgebra::DMatrix::zeros(0, 1),
                    nalgebra::DMatrix::zeros(1, 0),
                    nalgebra::DMatrix::zeros(1, 1),
                    SampleTime::Continuous,
                )?,
            });
        }
        for v in &out {
            v.comparable.set(v.same_level());
        }
        Ok(Data { vals: out, ..data })
    }

    /// When every fast-rate experiment at another level agrees with the model experiment
    /// (its level test passes), the plant is linear over their span: a slower experiment at a
    /// level inside it (widened by [`LEVEL_TOL`]) is compared as if at the model experiment's
    /// level, so that a rate-tied effect on it is tested rather than taken for amplitude.
    pub(super) fn widen_levels(&self, tests: &[(usize, Statistic)]) {
        if tests.is_empty() || tests.iter().any(|(_, s)| !s.passes()) {
            return;
        }
        let (lo, hi) = tests
            .iter()
            .map(|(i, _)| self.vals[*i].level)
            .fold((1.0f64, 1.0f64), |(lo, hi), l| (lo.min(l), hi.max(l)));
        for v in self.vals.iter().filter(|v| v.factor > 1) {
            let inside = v.level >= lo * (1.0 - LEVEL_TOL) && v.level <= hi * (1.0 + LEVEL_TOL);
            v.comparable.set(v.comparable.get() || inside);
        }
    }

    pub(super) fn pair(&self, factor: usize) -> Pair<'_> {
        Pair {
            fast: &self.fast.frd,
            factor,
            h: self.h,
            dof: self.fast.dof,
        }
    }
}
