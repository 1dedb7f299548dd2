//! A diagnosis travels to new data: its plain model and its extension ([`Predictor`]) predict
//! experiments they have never seen, each at its own rate and amplitude.
//!
//! Per experiment (non-periodic records of changing amplitude cut into pieces first, as the
//! diagnosis does, [`crate::pieces`]): its FRF with its total variance (noise, and the
//! stochastic nonlinear distortion where the excitation measures it) as the diagnosis
//! estimates it; the rate factor `F = f_model/f` (a whole number, else the experiment cannot
//! be predicted); the plain model's simulation `P_F` by Lemma 6 (`[A B; 0 I]^F`); the
//! extension's:
//!
//! - **rate-tied**: the continuous modal model discretised at the experiment's own period
//!   `F·h` with the hold delay and averaging window ([`sd_multirate::c2d_nonideal`]);
//! - **amplitude-dependent**: the amplitude of every moving mode measured on the experiment's
//!   output as in the diagnosis (the rms in the band of the pole the trend predicts at that
//!   amplitude, told apart by the force), the poles moved along their trends, the model at
//!   the model rate with the common residues, then Lemma 6 to `F`. A mode whose band reaches
//!   above the experiment's Nyquist frequency cannot be measured there; an amplitude more
//!   than [`FAR`] times beyond the range the trends were fitted on is not predicted
//!   (`extrapolated` marks one beyond the range but within that factor).
//!
//! Each prediction is judged by the calibrated statistic of the diagnosis ([`crate::stats`]:
//! the mean score of `|G_meas − G_pred|²/σ²` over the experiment's lines, 1 at the noise
//! level, `σ²` the measured total variance plus the model's prediction variance). The
//! prediction variance comes from the covariance the diagnosis saved with each fitted model
//! ([`crate::ModelUncertainty`]: residues and poles of the plain model and of a rate-tied
//! extension, `gᴴΣg` at the experiment's own period; the amplitude model's common residues at
//! the moved poles); a given model, and the non-idealities' and trends' own uncertainty,
//! count as known. Without it a new experiment at a higher signal-to-noise ratio than the
//! model experiment reads the model's own estimation error as a discrepancy. `ratio` = plain
//! / extended (> 1: the extension predicts better).

use crate::data::{estimate, Estimate, Part};
use crate::findings::responses;
use crate::lemma6::model_lines;
use crate::pieces::{Piece, RecordUse};
use crate::predictor::{Predictor, SavedExtension};
use crate::stats::{in_bands, statistic, Line};
use crate::{Curves, Result};
use rayon::prelude::*;
use sd_ident::Experiment;
use sd_model::StateSpace;
use sd_multirate::{c2d_nonideal, downsample, NonIdeal};
use serde::Serialize;

/// How far beyond the fitted range of relative amplitudes (as a factor on either side) an
/// amplitude-dependent extension still predicts.
pub const FAR: f64 = 2.0;

/// Why an experiment cannot be predicted.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "code", rename_all = "snake_case")]
pub enum Unpredictable {
    /// Its FRF could not be estimated.
    NoFrf {
        /// What the estimator said.
        error: String,
    },
    /// Its rate is no whole fraction of the model's.
    Rate {
        /// The experiment's rate (Hz).
        rate_hz: f64,
        /// The model's rate (Hz).
        model_rate_hz: f64,
    },
    /// The diagnosis found no extension that predicts other data.
    NoExtension {
        /// The diagnosis's extension (`none`, `fast_frf`, `per_level`).
        kind: String,
        /// Its named cause.
        cause: String,
    },
    /// A moving mode's band reaches above the experiment's Nyquist frequency: its amplitude
    /// cannot be measured there.
    AboveNyquist {
        /// The mode's linear frequency (Hz).
        mode_hz: f64,
        /// The top of the band its amplitude is measured in (Hz).
        band_top_hz: f64,
        /// The experiment's Nyquist frequency (Hz).
        nyquist_hz: f64,
    },
    /// A moving mode's amplitude is far beyond those the trends were fitted on.
    Amplitude {
        /// The mode's linear frequency (Hz).
        mode_hz: f64,
        /// Its amplitude relative to the model experiment's (0 when nothing was measured).
        relative: f64,
        /// The fitted range of relative amplitudes.
        fitted: (f64, f64),
    },
}

impl std::fmt::Display for Unpredictable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Unpredictable::NoFrf { error } => write!(f, "no FRF: {error}"),
            Unpredictable::Rate {
                rate_hz,
                model_rate_hz,
            } => write!(
                f,
                "its rate {rate_hz} Hz is no whole fraction of the model's {model_rate_hz} Hz \
                 (Lemma 6 moves a model to whole fractions of its rate only)"
            ),
            Unpredictable::NoExtension { kind, cause } => write!(
                f,
                "the diagnosis (cause `{cause}`) found no extension that predicts other data \
                 (extension `{kind}`)"
            ),
            Unpredictable::AboveNyquist {
                mode_hz,
                band_top_hz,
                nyquist_hz,
            } => write!(
                f,
                "the moving mode at {mode_hz:.1} Hz is measured in a band up to \
                 {band_top_hz:.1} Hz, above this experiment's Nyquist frequency \
                 {nyquist_hz:.1} Hz: its amplitude cannot be measured here"
            ),
            Unpredictable::Amplitude {
                mode_hz,
                relative,
                fitted,
            } => write!(
                f,
                "the moving mode at {mode_hz:.1} Hz moves at ×{relative:.3} the model \
                 experiment's amplitude, more than {FAR}× beyond the fitted ×{:.3}…×{:.3}: \
                 add a diagnosis level near this amplitude",
                fitted.0, fitted.1
            ),
        }
    }
}

/// One moving mode's amplitude in an experiment.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ModeAmplitude {
    /// The mode's linear frequency (Hz).
    pub mode_hz: f64,
    /// Its amplitude relative to the model experiment's.
    pub relative: f64,
    /// The pole the trends give there: frequency (Hz) and damping.
    pub freq_hz: f64,
    /// Damping ratio there.
    pub damping: f64,
}

/// The statistics counted only on the lines in the moving modes' bands (from the linear to
/// the predicted frequency, widened by `max(5ζ, 2 %)`; a friction corner: every line below ten
/// times it): where an amplitude-dependent extension acts, the metric of the diagnosis's
/// held-out gain.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InBand {
    /// Lines in the bands.
    pub lines: usize,
    /// The plain model's statistic there.
    pub plain: f64,
    /// The extended model's.
    pub extended: f64,
    /// `plain / extended`.
    pub ratio: f64,
    /// The threshold at `alpha` on these lines.
    pub threshold: f64,
}

/// One experiment predicted.
#[derive(Debug, Clone, Serialize)]
pub struct PredictedExperiment {
    /// Experiment (or piece) name.
    pub name: String,
    /// Its rate (Hz).
    pub rate_hz: f64,
    /// Model rate / its rate (`None` when that is no whole number).
    pub factor: Option<usize>,
    /// Lines compared.
    pub lines: usize,
    /// The plain model's calibrated statistic (1 = noise level).
    pub plain: Option<f64>,
    /// The extended model's.
    pub extended: Option<f64>,
    /// `plain / extended`.
    pub ratio: Option<f64>,
    /// The statistic's threshold at `alpha` on these lines (a consistent prediction stays
    /// below it with probability `1 − alpha`).
    pub threshold: Option<f64>,
    /// The same in the moving modes' bands (amplitude-dependent extension).
    pub in_band: Option<InBand>,
    /// The moving modes' amplitudes (amplitude-dependent extension).
    pub amplitudes: Vec<ModeAmplitude>,
    /// An amplitude lies beyond the fitted range (within [`FAR`]).
    pub extrapolated: bool,
    /// Why it cannot be predicted (`None`: predicted).
    pub reason: Option<Unpredictable>,
    /// The same as text.
    pub why: Option<String>,
    /// Measured, plain and extended FRFs on its lines.
    #[serde(skip)]
    pub curves: Curves,
}

/// The predictions of a set of new experiments.
#[derive(Debug, Clone, Serialize)]
pub struct Prediction {
    /// The extension's kind (`rate_tied`, `amplitude`, `none`, `fast_frf`, `per_level`).
    pub extension: String,
    /// The model's rate (Hz).
    pub model_rate_hz: f64,
    /// False-alarm probability of the thresholds.
    pub alpha: f64,
    /// Per experiment, in the manifest's order (pieces in time order).
    pub experiments: Vec<PredictedExperiment>,
    /// Pieces cut from non-periodic records of changing amplitude.
    pub pieces: Vec<Piece>,
    /// How records with windows without excitation were used.
    pub records: Vec<RecordUse>,
}

impl Prediction {
    /// Experiments the extension predicted.
    pub fn predicted(&self) -> usize {
        self.experiments
            .iter()
            .filter(|x| x.reason.is_none())
            .count()
    }

    /// When no experiment was predicted: one line with every experiment's reason (what
    /// `sdctl predict` and `sd.predict` refuse with).
    pub fn nothing_predicted(&self) -> Option<String> {
        if self.predicted() > 0 {
            return None;
        }
        let why: Vec<String> = self
            .experiments
            .iter()
            .map(|x| format!("`{}`: {}", x.name, x.why.as_deref().unwrap_or("?")))
            .collect();
        Some(format!(
            "no experiment can be predicted: {}",
            why.join("; ")
        ))
    }
}

/// Predicts `experiments` with the predictor's plain model and extension (module
/// documentation); `alpha` sets the thresholds.
///
/// # Errors
/// `alpha` outside (0, 0.5], no experiment, a model that cannot be evaluated. An experiment
/// that cannot be predicted is no error: its `reason` says why.
pub fn predict_experiments(
    p: &Predictor,
    experiments: &[Experiment],
    alpha: f64,
) -> Result<Prediction> {
    crate::stats::check_alpha(alpha)?;
    if experiments.is_empty() {
        return Err(crate::DiagnoseError::Setup(
            "no experiment to predict: the manifest lists none".into(),
        ));
    }
    let h = p.model.ts().ok_or_else(|| {
        crate::DiagnoseError::Setup("the predictor's model is not discrete".into())
    })?;
    let cut = crate::pieces::cut_records(experiments);
    let (list, pieces, records) = match &cut {
        Some(c) => (
            c.experiments.as_slice(),
            c.pieces.clone(),
            c.records.clone(),
        ),
        None => (experiments, Vec::new(), Vec::new()),
    };
    let out = list
        .par_iter()
        .map(|e| one(p, h, e, alpha))
        .collect::<Result<Vec<_>>>()?;
    Ok(Prediction {
        extension: p.extension.kind().into(),
        model_rate_hz: 1.0 / h,
        alpha,
        experiments: out,
        pieces,
        records,
    })
}

/// The whole-number rate factor of an experiment against the model period `h`.
fn factor_of(h: f64, rate_hz: f64) -> Option<usize> {
    let f = 1.0 / (h * rate_hz);
    let k = f.round();
    (k >= 1.0 && (f - k).abs() <= 1e-9 * f).then_some(k as usize)
}

/// Lines of `est` against a model's simulation with its prediction variance `var` (module
/// documentation; `None`: the model taken as known).
fn lines_of(
    m: &StateSpace,
    est: &Estimate,
    (var, params): (Option<&[f64]>, usize),
) -> Result<Vec<Line>> {
    let r = responses(m, est.frd.freq_hz())?;
    Ok(model_lines(est, &r, var, params))
}

/// The extension's model for one experiment at factor `k` (or why there is none), and the
/// moving modes' amplitudes.
struct Extended {
    model: std::result::Result<StateSpace, Unpredictable>,
    /// Its prediction variance at the experiment's lines (`None`: no covariance saved).
    variance: Option<Vec<f64>>,
    amplitudes: Vec<ModeAmplitude>,
    /// The moving modes' bands (empty for a rate-tied extension).
    bands: Vec<(f64, f64)>,
    extrapolated: bool,
}

impl Extended {
    fn without(why: Unpredictable) -> Self {
        Extended {
            model: Err(why),
            variance: None,
            amplitudes: Vec::new(),
            bands: Vec::new(),
            extrapolated: false,
        }
    }
}

fn extended_model(
    p: &Predictor,
    h: f64,
    (e, k): (&Experiment, usize),
    freq_hz: &[f64],
) -> Result<Extended> {
    match &p.extension {
        SavedExtension::RateTied {
            continuous,
            hold_delay,
            averaging,
            uncertainty,
        } => {
            let ni = NonIdeal {
                hold_delay: *hold_delay,
                averaging: *averaging,
            };
            let ts = h * k as f64;
            Ok(Extended {
                model: Ok(c2d_nonideal(continuous, ts, ni)?),
                variance: match uncertainty {
                    Some(u) => Some(u.variances(ts, ni, freq_hz)?),
                    None => None,
                },
                amplitudes: Vec::new(),
                bands: Vec::new(),
                extrapolated: false,
            })
        }
        SavedExtension::Amplitude(a) => amplitude_model(&a.0, (e, k, h), freq_hz),
        other => Ok(Extended::without(Unpredictable::NoExtension {
            kind: other.kind().into(),
            cause: match other {
                SavedExtension::None { cause } => cause.clone(),
                _ => other.kind().into(),
            },
        })),
    }
}

/// The amplitude-dependent model at an experiment's measured mode amplitudes (module docs).
fn amplitude_model(
    m: &crate::amplitude::AmplitudeModel,
    (e, k, h): (&Experiment, usize, f64),
    freq_hz: &[f64],
) -> Result<Extended> {
    let nyquist = 0.5 * e.spec.sample_rate_hz;
    let moving = m.moving();
    if let Some(&(_, f, top)) = moving.iter().find(|x| x.2 >= nyquist) {
        let why = Unpredictable::AboveNyquist {
            mode_hz: f,
            band_top_hz: top,
            nyquist_hz: nyquist,
        };
        return Ok(Extended::without(why));
    }
    let amp = m.amplitudes_of(e);
    let poles = m.predicted_with(&amp);
    let mut list = Vec::new();
    let mut extrapolated = false;
    for &(c, f, _) in &moving {
        let rel = amp[c] / m.reference[c].max(f64::MIN_POSITIVE);
        let (lo, hi) = m.range[c];
        let rel = if rel.is_finite() { rel } else { 0.0 };
        if !(rel > 0.0 && rel >= lo / FAR && rel <= hi * FAR) {
            let why = Unpredictable::Amplitude {
                mode_hz: f,
                relative: rel,
                fitted: (lo, hi),
            };
            return Ok(Extended::without(why));
        }
        extrapolated |= rel < lo * 0.999 || rel > hi * 1.001;
        list.push(ModeAmplitude {
            mode_hz: f,
            relative: rel,
            freq_hz: poles[c].0,
            damping: poles[c].1,
        });
    }
    let at_h = m.model_with(&amp)?;
    let model = if k == 1 { at_h } else { downsample(&at_h, k)? };
    Ok(Extended {
        model: Ok(model),
        variance: Some(m.variances_with(&amp, h * k as f64, freq_hz)?),
        amplitudes: list,
        bands: m.moving_bands_with(&amp),
        extrapolated,
    })
}

/// One experiment's prediction.
fn one(p: &Predictor, h: f64, e: &Experiment, alpha: f64) -> Result<PredictedExperiment> {
    let rate = e.spec.sample_rate_hz;
    let mut x = PredictedExperiment {
        name: e.spec.name.clone(),
        rate_hz: rate,
        factor: factor_of(h, rate),
        lines: 0,
        plain: None,
        extended: None,
        ratio: None,
        threshold: None,
        in_band: None,
        amplitudes: Vec::new(),
        extrapolated: false,
        reason: None,
        why: None,
        curves: Curves::default(),
    };
    let fail = |mut x: PredictedExperiment, why: Unpredictable| {
        x.why = Some(why.to_string());
        x.reason = Some(why);
        Ok(x)
    };
    let Some(k) = x.factor else {
        let why = Unpredictable::Rate {
            rate_hz: rate,
            model_rate_hz: 1.0 / h,
        };
        return fail(x, why);
    };
    let est = match estimate(e, Part::Whole) {
        Ok(est) => est,
        Err(err) => {
            let why = Unpredictable::NoFrf {
                error: err.to_string(),
            };
            return fail(x, why);
        }
    };
    let plain_model = if k == 1 {
        p.model.clone()
    } else {
        downsample(&p.model, k)?
    };
    let f = est.frd.freq_hz();
    let plain_var = match &p.uncertainty {
        Some(u) => Some(u.variances(h * k as f64, NonIdeal::ideal(), f)?),
        None => None,
    };
    let params =
        |u: Option<&crate::predictor::ModelUncertainty>| u.map_or(0, |u| u.residues.n_params());
    let plain = lines_of(
        &plain_model,
        &est,
        (plain_var.as_deref(), params(p.uncertainty.as_ref())),
    )?;
    let s_plain = statistic([(plain.as_slice(), est.inflation)], alpha);
    x.lines = plain.len();
    x.plain = Some(s_plain.value);
    x.threshold = Some(s_plain.threshold);
    x.curves = Curves {
        freq_hz: plain.iter().map(|l| l.f).collect(),
        measured: plain.iter().map(|l| l.meas).collect(),
        noise_var: plain.iter().map(|l| l.var).collect(),
        model: plain.iter().map(|l| l.pred).collect(),
        extended: None,
    };
    let ext = extended_model(p, h, (e, k), f)?;
    x.amplitudes = ext.amplitudes;
    let model = match ext.model {
        Ok(m) => m,
        Err(why) => return fail(x, why),
    };
    let ext_params = match &p.extension {
        SavedExtension::RateTied { uncertainty, .. } => params(uncertainty.as_ref()),
        SavedExtension::Amplitude(a) => a.0.residues.as_ref().map_or(0, |r| r.n_params()),
        _ => 0,
    };
    let lines = lines_of(&model, &est, (ext.variance.as_deref(), ext_params))?;
    let s_ext = statistic([(lines.as_slice(), est.inflation)], alpha);
    x.extended = Some(s_ext.value);
    x.ratio = Some(s_plain.value / s_ext.value.max(f64::MIN_POSITIVE));
    x.extrapolated = ext.extrapolated;
    if !ext.bands.is_empty() {
        let a = in_bands(plain.clone(), &ext.bands);
        let b = in_bands(lines.clone(), &ext.bands);
        if !a.is_empty() {
            let sa = statistic([(a.as_slice(), est.inflation)], alpha);
            let sb = statistic([(b.as_slice(), est.inflation)], alpha);
            x.in_band = Some(InBand {
                lines: a.len(),
                plain: sa.value,
                extended: sb.value,
                ratio: sa.value / sb.value.max(f64::MIN_POSITIVE),
                threshold: sa.threshold,
            });
        }
    }
    x.curves.extended = Some(lines.iter().map(|l| l.pred).collect());
    Ok(x)
}
