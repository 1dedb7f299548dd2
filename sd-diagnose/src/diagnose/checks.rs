//! Stage 3: the consistency checks of every validation experiment and the distortion tests
//! of the non-excited lines.

use super::judged::*;
use super::read::*;
use crate::data::Estimate;
use crate::lemma6::{compare, Pair};
use crate::stats::{statistic, Line};
use crate::{DiagnoseError, Evidence, EvidenceKind, Result};
use sd_ident::DistortionReport;

/// Stage 3: the consistency checks of every validation experiment.
pub(super) struct Checks {
    pub(super) free: Vec<Vec<Line>>,
    pub(super) model: Vec<Vec<Line>>,
    pub(super) fast_model: Vec<Line>,
    /// False-alarm probability per test (α over the number of verdict tests).
    pub(super) alpha_test: f64,
    pub(super) evidence: Vec<Evidence>,
}

pub(super) fn free_lines(p: &Pair<'_>, est: &Estimate) -> Vec<Line> {
    compare(est, |_, f| p.predict(f))
}

pub(super) fn checks(data: &Data<'_>, j: &Judged<'_>, alpha: f64) -> Result<Checks> {
    let mut free = Vec::new();
    let mut model = Vec::new();
    for v in &data.vals {
        let fl = free_lines(&data.pair(v.factor), &v.whole);
        if fl.is_empty() {
            return Err(DiagnoseError::Setup(format!(
                "no line of `{}` has all its fold frequencies on the model experiment's grid: \
                 the model experiment's line spacing must divide this experiment's ({} Hz \
                 sampling); for non-periodic records make the fast record's duration a whole \
                 multiple of this one's",
                v.exp.spec.name, v.exp.spec.sample_rate_hz
            )));
        }
        free.push(fl);
        model.push(j.lines(&v.model, v.factor, &v.whole)?);
    }
    // the verdict's tests: the pooled model-free test of the same-level experiments, the
    // pooled model test, one level test per same-rate experiment at another level
    let level_tests = data
        .vals
        .iter()
        .filter(|v| v.factor == 1 && !v.same_level())
        .count();
    let alpha_test = alpha / (2 + level_tests) as f64;
    let fast_model = j.lines(&j.model, 1, &data.fast)?;
    let mut evidence = vec![Evidence::of(
        EvidenceKind::OwnData,
        format!(
            "model ({}) against its own data `{}`",
            j.info.source, data.model_exp.spec.name
        ),
        &statistic([(fast_model.as_slice(), data.fast.inflation)], alpha_test),
    )];
    if let Some(d) = &data.fast.distortion {
        evidence.extend(distortion_evidence(
            &data.model_exp.spec.name,
            d,
            alpha_test,
        ));
    }
    for (i, v) in data.vals.iter().enumerate() {
        let c = v.whole.inflation.max(data.fast.inflation);
        evidence.push(Evidence::of(
            EvidenceKind::ModelFree,
            format!(
                "Lemma 6 prediction of `{}` from `{}` (model-free)",
                v.exp.spec.name, data.model_exp.spec.name
            ),
            &statistic([(free[i].as_slice(), c)], alpha_test),
        ));
        evidence.push(Evidence::of(
            EvidenceKind::ModelSimulation,
            format!("the model's simulation of `{}`", v.exp.spec.name),
            &statistic([(model[i].as_slice(), c)], alpha_test),
        ));
        if let Some(d) = &v.whole.distortion {
            evidence.extend(distortion_evidence(&v.exp.spec.name, d, alpha_test));
        }
        if v.factor == 1 {
            evidence.push(Evidence::check(
                EvidenceKind::SameLevel,
                format!(
                    "`{}` at {:.3}× the model experiment's excitation level (|ratio − 1| within \
                     20 %: the same level)",
                    v.exp.spec.name, v.level
                ),
                (v.level - 1.0).abs(),
                LEVEL_TOL,
            ));
        }
    }
    Ok(Checks {
        free,
        model,
        fast_model,
        alpha_test,
        evidence,
    })
}

/// Evidence of nonlinear distortion at the non-excited odd and even lines of the band: each
/// line's power over its own noise estimate, combined by Fisher's method (the mean `−ln p`,
/// [`sd_ident::DistortionReport::odd_score`]), which is `Gamma(L, 1)/L` without distortion
/// whatever the noise spectrum: its threshold is that law's `1 − α` quantile.
pub(super) fn distortion_evidence(name: &str, d: &DistortionReport, alpha: f64) -> Vec<Evidence> {
    [
        ("odd", d.odd_score, d.odd_lines),
        ("even", d.even_score, d.even_lines),
    ]
    .into_iter()
    .filter(|x| x.2 > 0)
    .map(|(kind, score, lines)| {
        Evidence::check(
            EvidenceKind::Distortion,
            format!(
                "power at the {lines} non-excited {kind} lines of `{name}` over each line's \
                 noise (nonlinear distortion; Fisher's score, 1 without)"
            ),
            score,
            crate::stats::threshold(lines as f64, alpha),
        )
    })
    .collect()
}
