//! Stage 1, the data: FRF estimates of whole experiments and of their training (earlier) and
//! held-out (later) parts, with the degrees of freedom of their variances and the correlation
//! of neighbouring lines ([`crate::stats`]).

use crate::stats::{lpm_inflation, satterthwaite};
use crate::{DiagnoseError, Result};
use sd_ident::{frf_periodic, DistortionReport, Experiment, LpmOptions, PeriodicOptions};
use sd_model::Frd;

/// Which part of an experiment's steady data.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) enum Part {
    Whole,
    /// The earlier steady periods (or the first half of a record).
    Training,
    /// The later ones (or the second half).
    HeldOut,
}

/// An FRF estimate with what the statistic needs to know about it.
#[derive(Debug, Clone)]
pub(crate) struct Estimate {
    pub(crate) frd: Frd,
    /// Real degrees of freedom of each line's variance estimate.
    pub(crate) dof: f64,
    /// Correlation inflation of neighbouring lines (1: independent).
    pub(crate) inflation: f64,
    /// Correlation `ρ(d)` of the errors of lines `d` apart (empty: independent; an LPM
    /// estimate of a whole record: [`sd_ident::lpm_excitation_correlation`]).
    pub(crate) correlation: Vec<f64>,
    /// The DFT lines of a whole open-loop non-periodic record with their noise variance (the
    /// tracks' local fits use them in place of the LPM estimate).
    pub(crate) spectra: Option<std::sync::Arc<sd_ident::LineSpectra>>,
    pub(crate) distortion: Option<DistortionReport>,
    /// Per excited line of a periodic odd or full multisine: its frequency (Hz), the local
    /// stochastic distortion variance, and the part of it not in the FRF's variance (below the
    /// significance gate of [`with_distortion`]); ascending in frequency, empty without
    /// detection lines or roughness.
    pub(crate) local_distortion: Vec<(f64, f64, f64)>,
    /// The best linear approximation at the estimate's lines: how its distortion was measured
    /// and its noise and distortion per band (`None` for a part of an experiment).
    pub(crate) bla: Option<sd_ident::Bla>,
    /// Per line of `frd`, the expected size of its variance estimate, where the estimate's
    /// noise level and design factor are known apart (an LPM estimate:
    /// [`sd_ident::LpmEstimate::expected_var`], [`sd_ident::ClosedLoopLpm::expected_var`]);
    /// `None` otherwise. What a comparison's degrees of freedom are computed from
    /// (`lemma6::compare`).
    pub(crate) expected_var: Option<Vec<f64>>,
}

/// Most lines a fit sees ([`Estimate::thinned`]).
pub(crate) const MAX_FIT_LINES: usize = 8192;

impl Estimate {
    /// Every `s`-th line, `s = ⌈lines / MAX_FIT_LINES⌉`: what the order scan and the level
    /// fits are fitted to (statistics use every line). A long non-periodic record gives an LPM
    /// line every `fs/N` Hz (0.07 Hz for 14 s), far finer than any mode's bandwidth, and
    /// neighbouring LPM lines share their local windows (their information overlaps): keeping
    /// at least 8192 lines loses little precision and makes a fit's cost independent of the
    /// record length. The thinned lines are about `s` bins apart, so their correlation
    /// inflation is divided by `s` (at least 1).
    pub(crate) fn thinned(&self) -> Result<Estimate> {
        let s = self.frd.len().div_ceil(MAX_FIT_LINES).max(1);
        if s == 1 {
            return Ok(self.clone());
        }
        Ok(Estimate {
            inflation: (self.inflation / s as f64).max(1.0),
            ..self.select(|i| i % s == 0)?
        })
    }

    /// The lines `keep` accepts (by index), with their expected variances.
    pub(crate) fn select(&self, keep: impl Fn(usize) -> bool) -> Result<Estimate> {
        Ok(Estimate {
            frd: self.frd.select(&keep)?,
            expected_var: self.expected_var.as_ref().map(|e| {
                e.iter()
                    .enumerate()
                    .filter(|(i, _)| keep(*i))
                    .map(|(_, v)| *v)
                    .collect()
            }),
            ..self.clone()
        })
    }
}

/// How a held-out part is labelled.
pub(crate) fn held_out_label(e: &Experiment) -> String {
    if e.spec.period_samples.is_some() {
        format!("{} (later periods)", e.spec.name)
    } else {
        format!("{} (later part of the record)", e.spec.name)
    }
}

/// How the earlier part is labelled when it is held out in turn.
pub(crate) fn earlier_label(e: &Experiment) -> String {
    if e.spec.period_samples.is_some() {
        format!("{} (earlier periods)", e.spec.name)
    } else {
        format!("{} (earlier part of the record)", e.spec.name)
    }
}

/// The FRF of (part of) an experiment.
pub(crate) fn estimate(e: &Experiment, part: Part) -> Result<Estimate> {
    let Some(period) = e.spec.period_samples else {
        return estimate_lpm(e, part);
    };
    let skip = e.spec.skip_periods;
    let total = e.u.len() / period.max(1);
    let steady = total.saturating_sub(skip);
    let (lo, hi) = match part {
        Part::Whole => (skip, total),
        Part::Training => (skip, skip + steady / 2),
        Part::HeldOut => (skip + steady / 2, total),
    };
    if hi <= lo {
        return Err(DiagnoseError::Setup(format!(
            "`{}` has {steady} steady periods: nothing left for this part",
            e.spec.name
        )));
    }
    let cut = |x: &[f64]| x[lo * period..hi * period].to_vec();
    let r = e.r.as_ref().map(|r| cut(r));
    let est = frf_periodic(
        e.spec.sample_rate_hz,
        r.as_deref(),
        &cut(&e.u),
        &cut(&e.y),
        &PeriodicOptions::new(period, 0),
    )?;
    let m = hi - lo;
    let noise_dof = if m >= 2 {
        4.0 * (m as f64 - 1.0)
    } else {
        f64::INFINITY
    };
    let (frd, dof, local_distortion) = with_distortion(&est, noise_dof)?;
    // lines whose input is hardly measured (in closed loop: where the loop cancels the
    // excitation) have a biased ratio and no valid variance: left out
    let frd = sd_ident::trusted(&frd, &est.input_snr)?;
    let keep = est.trusted_lines();
    let bla = match part {
        Part::Whole => sd_ident::Bla::from_periodic(&est)
            .and_then(|b| b.select(|i| keep[i]))
            .ok(),
        _ => None,
    };
    Ok(Estimate {
        frd,
        dof,
        inflation: 1.0,
        correlation: Vec::new(),
        spectra: None,
        distortion: est.distortion,
        local_distortion,
        bla,
        expected_var: None,
    })
}

/// The FRF with its total variance, its degrees of freedom and the local distortion per line.
type WithDistortion = (Frd, f64, Vec<(f64, f64, f64)>);

/// The FRF with its total variance ([`sd_ident::Bla`]: the stochastic nonlinear distortion
/// of odd multisines' detection lines added to the noise where their level is significant): a
/// model, or another experiment with its own phase realisation, can only be expected to agree
/// within both. Degrees of freedom: the noise's `noise_dof` (2(M − 1) complex noise bins
/// between two harmonics; infinite with one period, whose white-noise level comes from the
/// many non-excited bins) and the distortion level's `2·NL_NEIGHBOURS`, combined per line by
/// Satterthwaite and averaged over the lines. Also the local distortion per excited line
/// `(f, level, the part of it the total leaves out)`: the part left out (its level at or below
/// the gate) is what a comparison adds when distortion is known to be present (the
/// experiment's detection lines together show it) but weak at the line. An estimate without
/// variance is returned as it is.
fn with_distortion(est: &sd_ident::FrfEstimate, noise_dof: f64) -> Result<WithDistortion> {
    let Ok(bla) = sd_ident::Bla::from_periodic(est) else {
        return Ok((est.frd.clone(), noise_dof, Vec::new()));
    };
    let nl_dof = match bla.distortion {
        sd_ident::Distortion::DetectionLines { .. } => 2.0 * sd_ident::NL_NEIGHBOURS as f64,
        sd_ident::Distortion::Roughness { .. } => sd_ident::ROUGHNESS_DOF as f64,
        _ => return Ok((bla.frd, noise_dof, Vec::new())),
    };
    let dof_sum: f64 = bla
        .noise_var
        .iter()
        .zip(&bla.distortion_var)
        .map(|(&vn, &d)| satterthwaite(&[(vn, noise_dof), (d, nl_dof)]))
        .sum();
    let dof = dof_sum / bla.noise_var.len().max(1) as f64;
    let local = bla
        .frd
        .freq_hz()
        .iter()
        .zip(bla.distortion_level.iter().zip(&bla.distortion_var))
        .map(|(&f, (&level, &counted))| (f, level, if counted > 0.0 { 0.0 } else { level }))
        .collect();
    Ok((bla.frd, dof, local))
}

impl Estimate {
    /// The local distortion variance at frequency `f` and its part below the gate (zeros
    /// where there is none).
    pub(crate) fn local_distortion_at(&self, f: f64) -> (f64, f64) {
        let v = &self.local_distortion;
        let i = v.partition_point(|x| x.0 < f * (1.0 - 1e-9));
        v.get(i)
            .filter(|x| (x.0 - f).abs() <= 1e-9 * f.abs().max(1.0))
            .map_or((0.0, 0.0), |x| (x.1, x.2))
    }
}

/// A full multisine's distortion carried from `source` (named `name`), an experiment of the
/// same rate, period, columns and excitation rms ([`sd_ident::same_level`]) whose measure
/// may replace `est`'s ([`sd_ident::Distortion::replaced_by`], [`sd_ident::Bla::carried_from`]):
/// the FRF's variance becomes noise + the carried distortion, its degrees of freedom combined
/// per line by Satterthwaite as in [`with_distortion`] (from `est.dof`, which for a replaced
/// roughness already counts that roughness: conservative). Unchanged otherwise, or when they
/// differ in rate, period, columns or level.
pub(crate) fn carry_distortion(
    (est, exp): (&mut Estimate, &Experiment),
    (source, src_exp): (&Estimate, &Experiment),
) -> Result<()> {
    let (a, b) = (&exp.spec, &src_exp.spec);
    let alike = a.period_samples.is_some()
        && a.period_samples == b.period_samples
        && a.sample_rate_hz == b.sample_rate_hz
        && a.inputs() == b.inputs()
        && a.outputs() == b.outputs()
        && a.references() == b.references()
        && sd_ident::same_level(level(exp), level(src_exp));
    let (Some(own), Some(src)) = (&est.bla, &source.bla) else {
        return Ok(());
    };
    if !alike {
        return Ok(());
    }
    let carried = own.carried_from(src, &b.name)?;
    if !matches!(carried.distortion, sd_ident::Distortion::Carried { .. }) {
        return Ok(());
    }
    let nl_dof = 2.0 * sd_ident::NL_NEIGHBOURS as f64;
    let dof_sum: f64 = carried
        .noise_var
        .iter()
        .zip(&carried.distortion_var)
        .map(|(&vn, &d)| satterthwaite(&[(vn, est.dof), (d, nl_dof)]))
        .sum();
    est.dof = dof_sum / carried.noise_var.len().max(1) as f64;
    est.frd = carried.frd.clone();
    est.bla = Some(carried);
    Ok(())
}

/// Every full multisine of `set` with the distortion of its nearest-level sibling carried
/// ([`carry_distortion`]; the sources are taken before any is carried).
pub(crate) fn carry_within(set: &mut [(&Experiment, Estimate)]) -> Result<()> {
    let sources: Vec<(usize, Estimate)> = set
        .iter()
        .enumerate()
        .filter(|(_, (_, e))| e.bla.as_ref().is_some_and(|b| b.distortion.lends()))
        .map(|(i, (_, e))| (i, e.clone()))
        .collect();
    for t in 0..set.len() {
        let lt = level(set[t].0);
        let best = sources.iter().filter(|(i, _)| *i != t).min_by(|a, b| {
            let gap = |i: usize| (level(set[i].0) - lt).abs();
            gap(a.0).total_cmp(&gap(b.0))
        });
        if let Some((i, src)) = best {
            let src_exp = set[*i].0;
            let (exp, est) = &mut set[t];
            carry_distortion((est, exp), (src, src_exp))?;
        }
    }
    Ok(())
}

/// The training and held-out parts of an experiment (`None` when a part has no lines or no
/// variance). A periodic experiment is split only from four steady periods on: a single
/// period has no spread of its own, and a drifting sensor's leakage, which telescopes in the
/// mean over many periods, does not within one.
pub(crate) fn parts(e: &Experiment, _whole: &Estimate) -> Option<(Estimate, Estimate)> {
    if let Some(p) = e.spec.period_samples {
        let steady = (e.u.len() / p.max(1)).saturating_sub(e.spec.skip_periods);
        if steady < 4 {
            return None;
        }
    }
    let one = |part: Part| -> Option<Estimate> {
        let est = estimate(e, part).ok()?;
        (est.frd.variance().is_some() && !est.frd.is_empty()).then_some(est)
    };
    Some((one(Part::Training)?, one(Part::HeldOut)?))
}

/// Non-periodic data: the local polynomial method (transients handled); the parts are the two
/// halves of the record.
fn estimate_lpm(e: &Experiment, part: Part) -> Result<Estimate> {
    let n = e.u.len();
    let (lo, hi) = match part {
        Part::Whole => (0, n),
        Part::Training => (0, n / 2),
        Part::HeldOut => (n / 2, n),
    };
    let opt = LpmOptions::default();
    let fs = e.spec.sample_rate_hz;
    let excitation = e.r.as_deref().unwrap_or(&e.u);
    let (frd, spectra, expected_var) = match &e.r {
        Some(r) => {
            let cl =
                sd_ident::lpm_closed_loop_full(fs, &r[lo..hi], &e.u[lo..hi], &e.y[lo..hi], &opt)?;
            let keep = |i: usize| cl.input_snr[i] >= sd_ident::MIN_INPUT_SNR;
            let expected = (0..cl.expected_var.len())
                .filter(|&i| keep(i))
                .map(|i| cl.expected_var[i])
                .collect();
            (
                sd_ident::trusted(&cl.frd, &cl.input_snr)?,
                None,
                Some(expected),
            )
        }
        None => {
            let x = nalgebra::DMatrix::from_column_slice(hi - lo, 1, &e.u[lo..hi]);
            let z = nalgebra::DMatrix::from_column_slice(hi - lo, 1, &e.y[lo..hi]);
            let est = sd_ident::lpm(fs, &x, &z, &opt)?;
            let spectra = match part {
                Part::Whole => Some(std::sync::Arc::new(sd_ident::LineSpectra::new(
                    fs,
                    &e.u[lo..hi],
                    &e.y[lo..hi],
                    &est,
                )?)),
                _ => None,
            };
            let expected = est.expected_var();
            (est.frd, spectra, expected)
        }
    };
    // one excitation (the reference, or the input): q = 2(R + 1) local parameters
    let q = 2 * (opt.degree + 1);
    let half = opt.half_width.unwrap_or((q + 2).div_ceil(2));
    let resid = (2 * half + 1).saturating_sub(q).max(1);
    Ok(Estimate {
        dof: 2.0 * resid as f64,
        inflation: lpm_inflation(half, opt.degree),
        // the tracks' local fits use the whole record's
        correlation: match part {
            Part::Whole => sd_ident::lpm_excitation_correlation(&excitation[lo..hi], &opt)
                .unwrap_or_else(|_| sd_ident::lpm_polynomial_correlation(half, opt.degree)),
            _ => Vec::new(),
        },
        spectra,
        distortion: None,
        local_distortion: Vec::new(),
        bla: match part {
            Part::Whole => sd_ident::Bla::from_lpm(&frd).ok(),
            _ => None,
        },
        frd,
        expected_var,
    })
}

/// Rms of the excitation (reference, or input without one) over the steady periods.
pub(crate) fn level(e: &Experiment) -> f64 {
    sd_ident::excitation_rms(e)
}

/// The integer factor model rate / experiment rate, or an error that says what is wrong.
pub(crate) fn rate_factor(model: &Experiment, e: &Experiment) -> Result<usize> {
    let ratio = model.spec.sample_rate_hz / e.spec.sample_rate_hz;
    let factor = ratio.round();
    if factor < 1.0 || (ratio - factor).abs() > 1e-9 * ratio {
        return Err(DiagnoseError::Setup(format!(
            "`{}` runs at {} Hz: the model experiment's {} Hz is {ratio:.6} times that, not a \
             whole multiple; record it at {} Hz divided by a whole number, or give it the role \
             \"model\" if it is the fastest",
            e.spec.name,
            e.spec.sample_rate_hz,
            model.spec.sample_rate_hz,
            model.spec.sample_rate_hz
        )));
    }
    Ok(factor as usize)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A non-periodic record of `x_{k+1} = 0.9 x_k + u_k` under white noise, with the input as
    /// reference (`closed`) or without one.
    fn record(closed: bool) -> Experiment {
        let mut rng = sd_ident::rng::SplitMix::new(3);
        let (mut u, mut y, mut x) = (Vec::new(), Vec::new(), 0.0);
        for _ in 0..4096 {
            let uk = rng.normal();
            y.push(x + 0.01 * rng.normal());
            u.push(uk);
            x = 0.9 * x + uk;
        }
        Experiment {
            spec: sd_ident::ExperimentSpec {
                name: "r".into(),
                file: "r.csv".into(),
                sample_rate_hz: 100.0,
                period_samples: None,
                skip_periods: 0,
                reference: closed.then(|| "r".into()),
                input: "u".into(),
                output: "y".into(),
                role: sd_ident::Role::Validation,
                extra: Default::default(),
            },
            r: closed.then(|| u.clone()),
            u,
            y,
            extra: Default::default(),
        }
    }

    /// The whole open-loop record keeps its DFT lines for the tracks' local fits (one per LPM
    /// line, the same frequencies) and the LPM lines' correlation; a part of it, and a
    /// closed-loop record (whose input carries the loop's noise), keep no lines.
    #[test]
    fn an_open_loop_record_keeps_its_lines() {
        let open = estimate(&record(false), Part::Whole).unwrap();
        let spec = open.spectra.as_ref().unwrap();
        assert_eq!(spec.freq_hz.as_slice(), open.frd.freq_hz());
        assert!(spec.noise_var.iter().all(|v| *v > 0.0));
        assert_eq!(open.correlation.len(), 9);
        assert!(estimate(&record(false), Part::Training)
            .unwrap()
            .spectra
            .is_none());
        let closed = estimate(&record(true), Part::Whole).unwrap();
        assert!(closed.spectra.is_none());
        assert_eq!(closed.correlation.len(), 9);
    }
}
