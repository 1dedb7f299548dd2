//! `sd-diagnose`: what a model gets wrong on measured data, why, and how much an extension gains.
//!
//! **Inputs.** One model experiment (its rate `1/h`) and validation experiments at the same
//! rate or an integer fraction `1/T = 1/(F h)`, each estimated as an FRF with variances
//! (periodic: averaged periods, with the noise and distortion levels at non-excited lines where
//! the excitation leaves some; non-periodic: local polynomial method).
//!
//! **The model** is fitted to the model experiment's FRF ([`sd_ident::fit()`], the order chosen by
//! two-fold cross-validation between its earlier and later periods (FPE without them), rigid-body poles from the low-frequency slope) or given. Its simulation of a
//! slower experiment is Lemma 6 ([`sd_multirate::downsample()`]); in the frequency domain it is
//! compared line by line, in the time domain the measured input period goes through it
//! ([`timedomain`]).
//!
//! **Model-free check (Lemma 6 on measured FRFs).** The folding identity
//! `P_T(f) = Σ_{k<F} P_h(f_k) H_F(f_k)/F`, `f_k = f − k/T`, holds exactly for any LTI plant,
//! filters and delays common to both rates included. With a fold-aware excitation grid every
//! `f_k` is a measured line, so the slow FRF is predicted without a model, with variance
//! `Σ_k |H_F/F|² var P_h(f_k)`.
//!
//! **Statistic** ([`stats`]): per line `x = |P_meas − P_pred|²/(σ̂²_meas + σ̂²_pred)`, turned into
//! the exponential score `(ν/2) ln(1 + 2x/ν)` with ν the degrees of freedom of the estimated
//! variances (periods, LPM window), averaged over the lines: 1 at the noise level for any
//! number of periods. The threshold is the `1 − α` quantile of that mean (Gamma, with the LPM's
//! line correlation), α the false-alarm probability ([`DiagnoseOptions::alpha`], default 1 %,
//! shared by the tests of one verdict). The model's prediction variance is the residue
//! covariance of its modal form refitted to the fast data (zero for a given model).
//!
//! **Verdict and cause.**
//! - both predictions consistent: `consistent`, cause `none`;
//! - the model-free prediction consistent, the model's not: the model is wrong at the folding
//!   frequencies, cause `fast_model_error`; the extension is the fast FRF itself through Lemma 6;
//! - a same-rate experiment at another excitation level (> 20 % apart) whose FRF differs
//!   significantly: cause `nonlinearity`; the extension is the amplitude-dependent modal model
//!   (module `amplitude`: frequency and damping trends of the modes that move, in each mode's band
//!   amplitude, and a friction-damped rigid body's corner), judged on whole levels left out in
//!   turn. Non-periodic records of changing amplitude are first cut into pieces of constant
//!   amplitude ([`pieces`]);
//! - levels that disagree while no experiment involved shows nonlinear distortion at its
//!   non-excited lines (a calibrated per-line score, [`sd_ident::DistortionReport`]), or a
//!   same-level repeat that disagrees without distortion: cause `drift` (the plant changed
//!   with time); a same-level disagreement *with* distortion and nothing rate-tied to test
//!   (model-free, or in the model's simulation only when counting both realisations'
//!   stochastic distortion explains it): `nonlinearity` at one level (named, not modelled);
//! - the model-free prediction inconsistent: the rate-tied hypotheses ([`hypotheses`]),
//!   parametric extensions of a continuous modal model built from the model's poles
//!   ([`modal`]): `hold_delay` α (the hold switches α of each experiment's own period late,
//!   up to [`sd_multirate::MAX_HOLD_DELAY`] periods), `averaging_sampler` β (the sensor
//!   averages over β of each period), `clock_error` e (a validation experiment's true period
//!   is nominal·(1 + e), one e per experiment), and the pairs delay + averaging, delay + clock,
//!   averaging + clock. Each is discretised exactly at each experiment's (true) period
//!   ([`sd_multirate::c2d_nonideal`]); the modal residues are refitted to the fast FRF per
//!   trial. Parameters and the family are chosen on the *training* part of the data only
//!   (earlier periods, or the first part of a record) by a penalised criterion (the sum of
//!   scores plus ½ ln K per parameter); the chosen extension is named only when its statistic
//!   on the *held-out* part (later periods of every slower experiment together, then the
//!   earlier ones in turn; whole left-out experiments when they cannot be split) passes the
//!   naming threshold, and a pair only when its second parameter pays
//!   for itself there too; otherwise `unexplained`, with the best partial explanation reported
//!   as such. Reported parameters are refined on all data (`docs/diagnosis.md`).
//!
//! **Gain** is measured on the held-out part: the plain modal model (the same poles, residues
//! refitted to the fast data) before, the extension with the training parameters after; the
//! same yardstick for both. Where no part can be held out the gain is `null` with the reason.

mod amplitude;
mod data;
mod findings;
pub mod hypotheses;
mod lemma6;
pub mod mimo;
pub mod modal;
mod model;
pub mod next_experiment;
pub mod pieces;
pub mod prediction;
pub mod predictor;
pub mod stats;
pub mod timedomain;
pub mod tracks;

mod diagnose;

pub use diagnose::{diagnose, diagnose_with_progress};
pub use hypotheses::RateTied;
pub use lemma6::predict;
pub use mimo::{
    diagnose_mimo, ChannelFinding, ChannelKind, EntryCheck, EntryCurves, MimoDiagnoseOptions,
    MimoDiagnosis, MimoGain,
};
pub use next_experiment::{Injection, NextExperiment};
pub use pieces::{Piece, RecordUse};
pub use prediction::{
    predict_experiments, InBand, ModeAmplitude, PredictedExperiment, Prediction, Unpredictable,
};
pub use predictor::{AmplitudePredictor, ModelUncertainty, Predictor, SavedExtension};
pub use sd_ident::{BandLevel, Distortion, Role, Unmeasurable};
pub use stats::Statistic;
pub use timedomain::AveragedPeriod;
pub use tracks::{ModeTrack, TrackPoint, Tracked};

use num_complex::Complex64 as C;
use sd_model::StateSpace;
use serde::Serialize;
use serde_json::json;
use std::collections::BTreeMap;

/// Errors of the diagnosis.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DiagnoseError {
    /// FRF estimation, model fit or data reading.
    #[error(transparent)]
    Ident(#[from] sd_ident::IdentError),
    /// Model operations.
    #[error(transparent)]
    Model(#[from] sd_model::ModelError),
    /// Multirate operations.
    #[error(transparent)]
    Multirate(#[from] sd_multirate::MultirateError),
    /// Experiments or a model that cannot be diagnosed together (message says why).
    #[error("{0}")]
    Setup(String),
    /// A numerical step failed on valid data (message says which).
    #[error("{0}")]
    Numerical(String),
}

impl DiagnoseError {
    /// A numerical failure on valid data; everything else is input to fix.
    pub fn is_numerical(&self) -> bool {
        match self {
            DiagnoseError::Ident(e) => e.is_numerical(),
            DiagnoseError::Model(e) => e.is_numerical(),
            DiagnoseError::Multirate(e) => e.is_numerical(),
            DiagnoseError::Numerical(_) => true,
            DiagnoseError::Setup(_) => false,
        }
    }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, DiagnoseError>;

/// Settings of a diagnosis.
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// A given model of the plant (SISO; discrete at the model experiment's period, or
    /// continuous and then ZOH-discretised there). `None`: fitted to the model experiment.
    pub model: Option<StateSpace>,
    /// Highest order tried when fitting (the error on held-out periods picks one; default 60).
    pub max_order: usize,
    /// False-alarm probability of a verdict (default 0.01).
    pub alpha: f64,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            model: None,
            max_order: 60,
            alpha: 0.01,
        }
    }
}

/// The verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The model and the data agree within the noise (at the false-alarm probability).
    Consistent,
    /// They do not.
    Discrepancy,
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Verdict::Consistent => "consistent",
            Verdict::Discrepancy => "discrepancy",
        })
    }
}

/// A named cause with its parameters.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "name", rename_all = "snake_case")]
pub enum Cause {
    /// Nothing to explain.
    None,
    /// The hold switches `delay_frac` of each sample period late.
    HoldDelay {
        /// Fraction of the period (may exceed 1).
        delay_frac: f64,
        /// Its standard error (null where the data do not bound it).
        delay_frac_std: Option<f64>,
        /// The delay in seconds per experiment.
        delay_s: BTreeMap<String, f64>,
        /// With an averaging window named too: `delay_frac + window_frac/2`, the lag both act
        /// like to first order, which the data determine even where the split between the two
        /// is not (compare its standard error with theirs).
        #[serde(skip_serializing_if = "Option::is_none")]
        combined_lag_frac: Option<f64>,
        /// Its standard error.
        #[serde(skip_serializing_if = "Option::is_none")]
        combined_lag_frac_std: Option<f64>,
    },
    /// The sensor averages over `window_frac` of each sample period.
    AveragingSampler {
        /// Fraction of the period.
        window_frac: f64,
        /// Its standard error (null where the data do not bound it).
        window_frac_std: Option<f64>,
    },
    /// A validation experiment's true period is nominal·(1 + e).
    ClockError {
        /// e per experiment.
        clock_error: BTreeMap<String, f64>,
        /// Standard error of e per experiment (those the data bound).
        clock_error_std: BTreeMap<String, f64>,
    },
    /// Experiments at other excitation levels disagree.
    Nonlinearity {
        /// Level of each disagreeing experiment relative to the model experiment's.
        relative_levels: BTreeMap<String, f64>,
        /// Whether the dominant moving mode's frequency rises or falls with amplitude.
        kind: FreqTrend,
        /// Whether its damping rises or falls with amplitude.
        damping_trend: DampingTrend,
        /// Whether the real poles' corners (a friction-damped rigid body) rise or fall with
        /// amplitude.
        corner_trend: CornerTrend,
        /// The modes that move with amplitude, with every level's points and the trends.
        modes: Vec<MovingMode>,
        /// Every physical mode followed over the levels by local fits ([`tracks`]), reported
        /// beside the amplitude model (`kind` and `damping_trend` are the amplitude model's).
        tracks: Vec<tracks::ModeTrack>,
        /// What rules out drift over time as the reason the levels differ.
        drift_check: DriftCheck,
    },
    /// The plant changed between experiments (with time, not with amplitude or rate).
    Drift {
        /// The experiments that disagree with the model experiment.
        experiments: Vec<String>,
        /// What tells drift from nonlinearity here.
        sign: DriftSign,
    },
    /// The model is wrong where the data agree with each other.
    FastModelError {
        /// The model's statistic on its own data.
        model_misfit_on_fast_data: f64,
        /// Its worst fast lines (Hz).
        worst_fast_hz: Vec<f64>,
    },
    /// No catalogued cause explains the discrepancy.
    Unexplained,
}

impl Cause {
    /// The name in `diagnosis.json`.
    pub fn name(&self) -> &'static str {
        match self {
            Cause::None => "none",
            Cause::HoldDelay { .. } => "hold_delay",
            Cause::AveragingSampler { .. } => "averaging_sampler",
            Cause::ClockError { .. } => "clock_error",
            Cause::Nonlinearity { .. } => "nonlinearity",
            Cause::Drift { .. } => "drift",
            Cause::FastModelError { .. } => "fast_model_error",
            Cause::Unexplained => "unexplained",
        }
    }

    /// Its parameters as a JSON object (empty for none/unexplained).
    pub fn parameters(&self) -> serde_json::Map<String, serde_json::Value> {
        match serde_json::to_value(self) {
            Ok(serde_json::Value::Object(mut m)) => {
                m.remove("name");
                m
            }
            _ => serde_json::Map::new(),
        }
    }
}

/// What an evidence row tests; the report explains a failed row from its kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EvidenceKind {
    /// The model against the experiment it was fitted on (or judged at).
    OwnData,
    /// Exact downsampling (Lemma 6) of the measured fast FRF against a slower experiment: no
    /// model involved.
    ModelFree,
    /// The model's simulation of one validation experiment.
    ModelSimulation,
    /// The model's simulation of all validation experiments, pooled.
    AllValidation,
    /// Nonlinear distortion at the non-excited lines of one experiment.
    Distortion,
    /// The model's simulation of a same-level experiment with the nonlinear distortion's
    /// variance (seen at the non-excited lines) added to the noise's.
    DistortionVariance,
    /// Whether an experiment at the model's rate ran at the model experiment's level.
    SameLevel,
    /// Two experiments at one rate and level that disagree.
    NotRepeatable,
    /// A repeat of the model experiment that disagrees without distortion (a change in time).
    Drift,
}

/// One test of the evidence list.
#[derive(Debug, Clone, Serialize)]
pub struct Evidence {
    /// What the test is, for the report's explanation of a failed row.
    pub kind: EvidenceKind,
    /// What was tested.
    pub test: String,
    /// Its statistic.
    pub statistic: f64,
    /// The threshold it is compared with.
    pub threshold: f64,
    /// Whether the test passed (statistic ≤ threshold).
    pub passed: bool,
}

impl Evidence {
    /// A test that passes when `statistic ≤ threshold`.
    pub(crate) fn check(
        kind: EvidenceKind,
        test: impl Into<String>,
        statistic: f64,
        threshold: f64,
    ) -> Self {
        Evidence {
            kind,
            test: test.into(),
            statistic,
            threshold,
            passed: statistic <= threshold,
        }
    }

    /// A calibrated statistic as evidence.
    pub(crate) fn of(kind: EvidenceKind, test: impl Into<String>, s: &Statistic) -> Self {
        Self::check(kind, test, s.value, s.threshold)
    }
}

/// One ranked hypothesis.
#[derive(Debug, Clone, Serialize)]
pub struct Ranked {
    /// Cause name(s), joined by `+`.
    pub cause: String,
    /// Statistic on the training data.
    pub cost: f64,
    /// Penalised criterion on the training data (smaller is better).
    pub criterion: f64,
    /// Statistic on the held-out data, with the training parameters.
    pub held_out: Option<f64>,
    /// Number of parameters.
    pub n_params: usize,
}

/// The gain of the extension on held-out data.
#[derive(Debug, Clone, Serialize)]
pub struct Gain {
    /// What is compared.
    pub metric: &'static str,
    /// Statistic before the extension.
    pub before: Option<f64>,
    /// After.
    pub after: Option<f64>,
    /// before / after.
    pub ratio: Option<f64>,
    /// The held-out data, named.
    pub held_out: Vec<String>,
    /// Why there is no gain, when there is none.
    pub why: Option<String>,
}

impl Gain {
    pub(crate) const METRIC: &'static str =
        "mean calibrated score per line (1 = noise level), plain modal model before, extension after";
    /// The amplitude model's metric: only the lines it changes.
    pub(crate) const METRIC_BANDS: &'static str =
        "mean calibrated score per line (1 = noise level) in the moving modes' bands (their \
         linear and predicted frequencies ± max(5ζ, 2 %)), linear model before, amplitude \
         model after";

    /// This gain measured with another metric.
    pub(crate) fn with_metric(mut self, metric: &'static str) -> Self {
        self.metric = metric;
        self
    }

    pub(crate) fn measured(before: f64, after: f64, held_out: Vec<String>) -> Self {
        let ok = before.is_finite() && after.is_finite() && after > 0.0;
        Gain {
            metric: Self::METRIC,
            before: ok.then_some(before),
            after: ok.then_some(after),
            ratio: ok.then(|| before / after),
            held_out,
            why: (!ok).then(|| "the held-out statistic is not finite".to_string()),
        }
    }

    pub(crate) fn none(why: impl Into<String>) -> Self {
        Gain {
            metric: Self::METRIC,
            before: None,
            after: None,
            ratio: None,
            held_out: Vec::new(),
            why: Some(why.into()),
        }
    }
}

/// The evidence that names drift rather than nonlinearity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DriftSign {
    /// A repeat at the model experiment's level and rate disagrees, and neither of the two
    /// shows nonlinear distortion at its non-excited lines (where they have none, the repeat
    /// alone decides).
    RepeatWithoutDistortion,
    /// Experiments at other levels disagree, yet every experiment involved has non-excited
    /// lines and none shows nonlinear distortion there: an FRF that changes with amplitude
    /// brings distortion with it; one that changes without it changed with time.
    LevelsWithoutDistortion,
}

/// The kind of a pole that moves with amplitude.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PoleKind {
    /// A complex pair: a mode with a natural frequency and a damping.
    Pair,
    /// A real pole `−a`: a corner at `a/2π` Hz (a rigid body damped by friction, `a = c/m`).
    Real,
}

/// How the real poles' corners move with amplitude.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CornerTrend {
    /// The corner rises with amplitude.
    Rising,
    /// It falls: the equivalent damping of Coulomb friction, `c_eq ≈ 4F_c/(πωA)` (sine) or
    /// `F_c·√(2/π)/σ_v` (random), shrinks as the motion grows, so the rigid body's corner
    /// `c_eq/m` falls as `1/amplitude`.
    Falling,
    /// No change beyond its uncertainty.
    None,
}

/// What tells a nonlinearity from a plant that drifted between experiments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DriftCheck {
    /// Nonlinear distortion shows at the non-excited lines of a periodic experiment.
    DistortionSeen,
    /// A repeat at the model experiment's level agrees with it.
    RepeatAgrees,
    /// Neither: no non-excited lines free of excitation (non-periodic records, full
    /// multisines) and no repeat. A drift over the campaign would look the same; repeat the
    /// model experiment's level at the end, or use odd multisines with detection lines.
    Unchecked,
}

/// How a mode's frequency changes with amplitude.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FreqTrend {
    /// It rises (a stiffening spring, e.g. cubic stiffness κ > 0).
    Hardening,
    /// It falls.
    Softening,
    /// No change beyond its uncertainty.
    None,
}

/// How a mode's damping changes with amplitude.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DampingTrend {
    /// It rises with amplitude.
    Increasing,
    /// It falls with amplitude (e.g. Coulomb friction, whose equivalent damping is ∝ 1/A).
    Decreasing,
    /// No change beyond its uncertainty.
    None,
}

/// A trend `p(ρ) = at_reference + slope·(ρ^exponent − 1)` in the relative amplitude ρ (1 at
/// the model experiment).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Trend {
    /// 2, 1 or −1.
    pub exponent: i32,
    /// The value at the model experiment's amplitude.
    pub at_reference: f64,
    /// Its standard error.
    pub at_reference_std: f64,
    /// The coefficient of `ρ^exponent − 1`.
    pub slope: f64,
    /// Its standard error.
    pub slope_std: f64,
    /// Covariance of `at_reference` and `slope`.
    pub covariance: f64,
}

/// One level's modal frequency and damping of a moving mode.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModePoint {
    /// The experiment.
    pub experiment: String,
    /// Rms of the measured output in the mode's band (output units).
    pub amplitude: f64,
    /// Relative to the model experiment's.
    pub relative_amplitude: f64,
    /// Natural frequency (Hz).
    pub freq_hz: f64,
    /// Its standard error (Hz).
    pub freq_hz_std: f64,
    /// Damping ratio.
    pub damping: f64,
    /// Its standard error.
    pub damping_std: f64,
    /// Natural frequency (Hz) and damping that the amplitude model fitted without this level
    /// predicted for it (left-out levels only).
    pub held_out_prediction: Option<(f64, f64)>,
    /// Which fit the frequency and damping come from.
    pub fit: PointFit,
}

/// Where a moving mode's frequency and damping at one level come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PointFit {
    /// The local fit in the mode's band of a tracked physical mode ([`tracks`]): the trend
    /// and the amplitude model's pole use it.
    Local,
    /// The level's modal fit with the candidates' poles free: no tracked mode is this pole
    /// (a friction corner, or a pair no local fit follows), or the track has no local fit at
    /// this level (its band's SNR gate or its fit dropped it).
    Level,
}

/// A mode whose frequency or damping moves with amplitude.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MovingMode {
    /// A lightly damped pair (a mode) or a real pole (a corner: `linear_freq_hz` is `a/2π`
    /// of the pole `−a`, the damping 1).
    pub pole: PoleKind,
    /// The linear model's natural frequency (Hz).
    pub linear_freq_hz: f64,
    /// The linear model's damping ratio.
    pub linear_damping: f64,
    /// The frequencies differ beyond their errors.
    pub frequency_moves: bool,
    /// The dampings differ beyond their errors.
    pub damping_moves: bool,
    /// Natural frequency (Hz) against relative amplitude.
    pub frequency: Trend,
    /// Damping ratio against relative amplitude.
    pub damping: Trend,
    /// Every level's fit.
    pub points: Vec<ModePoint>,
}

/// The extension of the model that the diagnosis settled on.
#[derive(Clone, Debug, PartialEq)]
pub enum Extension {
    /// No extension.
    None,
    /// Rate-tied non-idealities on the continuous modal model.
    RateTied(RateTied),
    /// The fast FRF itself replaces the model at the folding frequencies.
    FastFrf,
    /// One best linear approximation per excitation level (no in-band mode to move).
    PerLevel,
    /// The amplitude-dependent modal model: these modes move with amplitude.
    Amplitude(Vec<MovingMode>),
}

/// A band of lines where a prediction misses the data beyond the noise.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Band {
    /// Lowest frequency (Hz).
    #[serde(rename = "f_lo_hz")]
    pub f_lo: f64,
    /// Highest frequency (Hz).
    #[serde(rename = "f_hi_hz")]
    pub f_hi: f64,
    /// The line with the largest normalized residual (Hz).
    pub worst_hz: f64,
    /// `20 log10 |P_meas/P_pred|` there (dB).
    pub worst_db: f64,
    /// Phase of `P_meas/P_pred` there (degrees).
    pub worst_deg: f64,
    /// Where the model's response that folds onto `worst_hz` mostly comes from (Hz, fast band).
    pub from_fast_hz: f64,
    /// Share of the whole statistic that this band carries.
    pub share: f64,
}

/// Measured and predicted FRFs of one experiment, on its lines.
#[derive(Debug, Clone, Default)]
pub struct Curves {
    /// Frequencies (Hz).
    pub freq_hz: Vec<f64>,
    /// Measured FRF.
    pub measured: Vec<C>,
    /// The noise variance the residual is judged against (measured plus prediction).
    pub noise_var: Vec<f64>,
    /// The model's simulation (Lemma 6 at a slower rate).
    pub model: Vec<C>,
    /// The extended model's simulation, when there is an extension.
    pub extended: Option<Vec<C>>,
}

/// Rms values of a time-domain comparison inside the discrepancy bands.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct InBands {
    /// Noise.
    pub noise_rms: f64,
    /// Measured − model.
    pub error_rms_model: f64,
    /// Measured − extended model.
    pub error_rms_extended: Option<f64>,
}

/// The time-domain comparison of one experiment: one averaged steady period of a periodic
/// experiment, or a whole non-periodic record simulated from the least-squares initial state.
#[derive(Debug, Clone, Serialize)]
pub struct TimeDomain {
    /// Sample rate (Hz).
    #[serde(skip)]
    pub rate_hz: f64,
    /// Measured averaged output period.
    #[serde(skip)]
    pub measured: Vec<f64>,
    /// The model's periodic response to the measured input.
    #[serde(skip)]
    pub model: Vec<f64>,
    /// The extended model's, when there is an extension.
    #[serde(skip)]
    pub extended: Option<Vec<f64>>,
    /// Rms of the output around its mean.
    pub output_rms: f64,
    /// Rms noise of the comparison (spread of the per-period residual of the model; `None` for
    /// a non-periodic record, where it is not known).
    pub noise_rms: Option<f64>,
    /// Rms of measured − model.
    pub error_rms_model: f64,
    /// Rms of measured − extended model.
    pub error_rms_extended: Option<f64>,
    /// The same, counting only the bands where the model misses in the frequency domain.
    pub in_bands: Option<InBands>,
}

/// What the diagnosis found on one experiment.
#[derive(Debug, Clone, Serialize)]
pub struct ExperimentReport {
    /// Experiment name.
    pub name: String,
    /// Its role.
    pub role: sd_ident::Role,
    /// Sample rate (Hz).
    pub rate_hz: f64,
    /// Model rate / this rate.
    pub factor: usize,
    /// Excitation level relative to the model experiment's.
    pub relative_level: f64,
    /// Model-free Lemma 6 statistic (validation experiments).
    #[serde(rename = "model_free_statistic")]
    pub model_free: Option<Statistic>,
    /// The model's statistic.
    #[serde(rename = "model_statistic")]
    pub model_stat: Statistic,
    /// The extended model's statistic, when there is an extension.
    #[serde(rename = "extended_statistic")]
    pub extended_stat: Option<Statistic>,
    /// Where the model misses beyond 3σ (bands carrying ≥ 1 % of the statistic, largest share
    /// first, at most 5).
    pub bands: Vec<Band>,
    /// The FRFs.
    #[serde(skip)]
    pub curves: Curves,
    /// The time-domain comparison.
    pub time_domain: Option<TimeDomain>,
    /// Noise and distortion levels at the non-excited lines of a periodic experiment.
    #[serde(serialize_with = "distortion_json")]
    pub distortion: Option<sd_ident::DistortionReport>,
    /// Its best linear approximation: noise and distortion per band, and how the distortion
    /// was measured or why it was not (`None` for MIMO entries).
    pub bla: Option<BlaReport>,
    /// When this whole experiment was held out of the extension's fit: the statistics
    /// before and after on it (in the metric of `gain`).
    pub held_out: Option<HeldOut>,
    /// The extended model at this experiment's rate (discrete, with the named non-idealities,
    /// clock error and amplitude), where the extension is a model; written by the report as
    /// `extended_model_<name>.json`.
    #[serde(skip)]
    pub extended_model: Option<StateSpace>,
}

/// One held-out experiment's statistics before and after the extension.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HeldOut {
    /// The linear (plain) model's statistic.
    pub before: f64,
    /// The extension's, fitted without this experiment.
    pub after: f64,
    /// before / after.
    pub ratio: f64,
    /// The experiment's own fit in the extension's model class on the same lines (its moving
    /// poles and residues fitted to it): the floor a prediction can approach. `after` near it
    /// means the prediction does as well as a fit to the held-out data itself; `before /
    /// floor` is the largest ratio the model class allows.
    pub floor: f64,
    /// Lines compared.
    pub lines: usize,
    /// The experiment's amplitude lay beyond those the extension was fitted on.
    pub extrapolated: bool,
}

fn distortion_json<S: serde::Serializer>(
    d: &Option<sd_ident::DistortionReport>,
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    d.as_ref()
        .map(|d| {
            json!({"odd_lines": d.odd_lines, "even_lines": d.even_lines,
                "odd_ratio": d.odd_ratio, "even_ratio": d.even_ratio, "noise_level": d.noise_level,
                "noise_dof": d.noise_dof, "odd_score": d.odd_score, "even_score": d.even_score})
        })
        .serialize(s)
}

/// What the model's misfit on its own experiment is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OwnFit {
    /// At the noise level.
    Noise,
    /// Above it, and the non-excited lines show nonlinear distortion.
    Distortion,
    /// Above the total variance (noise + the distortion the data measured, or the LPM
    /// residual that holds both): the model does not fit (order, structure).
    FitError,
    /// Above the noise, and the excitation leaves the distortion unmeasurable (e.g. every line
    /// excited with one realisation; the reason is the model experiment's
    /// [`ExperimentReport::bla`]): distortion cannot be told from a fit error.
    NotSeparable,
}

/// The best linear approximation of an experiment: how its stochastic nonlinear distortion
/// was measured (or why not) and its noise and distortion per band.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlaReport {
    /// How the distortion was measured.
    pub distortion: sd_ident::Distortion,
    /// Noise and distortion per band, relative to `|Ĝ|`.
    pub bands: Vec<sd_ident::BandLevel>,
}

/// The model that was judged.
#[derive(Debug, Clone, Serialize)]
pub struct ModelInfo {
    /// "given" or how it was fitted.
    pub source: String,
    /// States.
    pub order: usize,
    /// Sample period (s).
    pub ts: Option<f64>,
    /// Its statistic on its own (model) experiment.
    pub own_data: Option<Statistic>,
    /// What that misfit is.
    pub own_fit: Option<OwnFit>,
    /// How a fitted model's order was chosen (`None` for a given model).
    pub fitted: Option<OrderChoice>,
}

/// How the order of the diagnosis's own fit is judged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OrderRule {
    /// Fitted on the earlier periods (or first half of the record), judged on the later ones.
    HeldOutPeriods,
    /// Fitted on the even-indexed lines, judged on the odd-indexed ones (and the other way):
    /// the rule when the periods cannot show a fit error, because what no linear model
    /// describes (stochastic nonlinear distortion) repeats from period to period.
    HeldOutLines,
    /// Akaike's final prediction error on the whole estimate (no held-out part).
    Fpe,
}

/// The order choice of the diagnosis's own fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct OrderChoice {
    /// How the orders were judged.
    pub rule: OrderRule,
    /// The chosen order (states, rigid body included).
    pub order: usize,
    /// The highest order the scan could reach (`DiagnoseOptions::max_order`).
    pub max_order: usize,
    /// Rigid-body poles (from the low-frequency slope).
    pub rigid_body: usize,
}

/// The outcome.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Consistent or not.
    pub verdict: Verdict,
    /// The cause name, or the names joined by `+` (alphabetical) when several are named.
    pub cause: String,
    /// The named causes with their parameters.
    pub causes: Vec<Cause>,
    /// All named causes' parameters in one object.
    pub parameters: serde_json::Value,
    /// The best partial explanation when the cause is `unexplained`.
    pub partial: Option<Ranked>,
    /// The false-alarm probability of the verdict.
    pub alpha: f64,
    /// The tests performed.
    pub evidence: Vec<Evidence>,
    /// Hypotheses ranked by their penalised criterion on the training data.
    pub ranking: Vec<Ranked>,
    /// Held-out gain.
    pub gain: Gain,
    /// The extension.
    #[serde(skip)]
    pub extension: Extension,
    /// The model used (discrete, at the model experiment's period).
    #[serde(skip)]
    pub model: StateSpace,
    /// Summary of the model.
    #[serde(rename = "model")]
    pub model_info: ModelInfo,
    /// Per experiment (the model experiment first).
    pub experiments: Vec<ExperimentReport>,
    /// Non-periodic records of changing amplitude cut into pieces, each diagnosed as an
    /// experiment of its own level ([`pieces`]); empty when none was cut.
    pub pieces: Vec<Piece>,
    /// How each non-periodic record with windows without excitation (burst random, pauses)
    /// or cut into pieces was used ([`pieces`]); empty when there is none.
    pub records: Vec<RecordUse>,
    /// The rate-tied extension as a continuous model with its non-idealities (written by the
    /// report as `extended_model.json`; `sdctl c2d` with `--hold-delay` and `--averaging`
    /// discretises it at any rate).
    #[serde(skip)]
    pub extended_model: Option<ExtendedModel>,
    /// The model and the extension as `sdctl predict` takes them to new experiments (written
    /// by the report as `predictor.json`).
    #[serde(skip)]
    pub predictor: Predictor,
    /// Where two explanations fit the data alike (`unexplained` with `partial`): the cheapest
    /// experiment that would separate them with probability ≥ [`next_experiment::NEXT_POWER`]
    /// (`null` otherwise, or when none in the searched set does; [`next_experiment`]).
    pub next_experiment: Option<NextExperiment>,
    /// Where two explanations fit alike but no experiment is proposed: why
    /// ([`next_experiment::NoProposal`]; `null` otherwise).
    pub no_next_experiment: Option<next_experiment::NoProposal>,
}

impl Diagnosis {
    /// `diagnosis.json` (the keys of [`Diagnosis`], documented in the crate README).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_else(|e| json!({"error": e.to_string()}))
    }

    /// Held-out statistic before / after (`None` when it could not be measured).
    pub fn gain_ratio(&self) -> Option<f64> {
        self.gain.ratio
    }

    /// "given" or how the model was fitted.
    pub fn model_source(&self) -> &str {
        &self.model_info.source
    }

    /// How much lower the penalised criterion (training data) of the best-ranked rate-tied
    /// extension is than the plain model's (`none`): the likelihood-ratio evidence for a
    /// rate-tied cause, parameters paid for. `None` without a rate-tied search.
    pub fn advantage_over_none(&self) -> Option<f64> {
        let none = self.ranking.iter().find(|r| r.cause == "none")?;
        let best = self
            .ranking
            .iter()
            .filter(|r| r.cause != "none")
            .map(|r| r.criterion)
            .min_by(f64::total_cmp)?;
        Some(none.criterion - best)
    }
}

/// A continuous model with the rate-tied non-idealities that act when it is discretised.
#[derive(Debug, Clone)]
pub struct ExtendedModel {
    /// The continuous modal model (one input, one output; SI units of the data).
    pub continuous: StateSpace,
    /// Hold delay as a fraction of the sample period (`sdctl c2d --hold-delay`).
    pub hold_delay: f64,
    /// Averaging window as a fraction of the sample period (`sdctl c2d --averaging`).
    pub averaging: f64,
}

/// The cause string of several named causes: names sorted and joined by `+`.
pub(crate) fn joined(causes: &[Cause]) -> String {
    let mut names: Vec<&str> = causes.iter().map(Cause::name).collect();
    names.sort_unstable();
    names.join("+")
}

/// All causes' parameters merged into one object.
pub(crate) fn merged_parameters(causes: &[Cause]) -> serde_json::Value {
    let mut m = serde_json::Map::new();
    for c in causes {
        m.extend(c.parameters());
    }
    serde_json::Value::Object(m)
}

/// The crate README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;
