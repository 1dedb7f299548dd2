//! `sd-diagnose`: what a model gets wrong on measured data, why, and how much an extension gains.
//!
//! **Inputs.** One model experiment (its rate `1/h`) and validation experiments at the same
//! rate or an integer fraction `1/T = 1/(F h)`, each estimated as an FRF with variances
//! (periodic: averaged periods, with the noise and distortion levels at non-excited lines where
//! the excitation leaves some; non-periodic: local polynomial method).
//!
//! **The model** is fitted to the model experiment's FRF ([`sd_ident::fit`], orders chosen by
//! Akaike's FPE, rigid-body poles from the low-frequency slope) or given. Its simulation of a
//! slower experiment is Lemma 6 ([`sd_multirate::downsample`]); in the frequency domain it is
//! compared line by line, in the time domain the measured input period goes through it
//! ([`timedomain`]).
//!
//! **Model-free check (Lemma 6 on measured FRFs).** The folding identity
//! `P_T(f) = Σ_{k<F} P_h(f_k) H_F(f_k)/F`, `f_k = f − k/T`, holds exactly for any LTI plant,
//! filters and delays common to both rates included. With a fold-aware excitation grid every
//! `f_k` is a measured line, so the slow FRF is predicted without a model, with variance
//! `Σ_k |H_F/F|² var P_h(f_k)`.
//!
//! **Statistic.** `V/K = (1/K) Σ_lines |P_meas − P_pred|²/(var_meas + var_pred)`, ≈ 1 ± 1/√K for
//! a consistent pair; above `1 + 5/√K` it is a discrepancy. The model's prediction is judged with
//! the model-free prediction's variance (a model that fits the fast data to their noise level
//! predicts the slow data to the propagated noise level).
//!
//! **Verdict and cause.**
//! - both predictions consistent: `consistent`, cause `none`;
//! - the model-free prediction consistent, the model's not: the model is wrong at the folding
//!   frequencies, cause `fast_model_error`; the extension is the fast FRF itself through Lemma 6;
//! - a same-rate experiment at another excitation level (> 20 % apart) whose FRF differs
//!   significantly: cause `nonlinearity`; the extension is one best linear approximation per
//!   level, judged on held-out periods of that level;
//! - the model-free prediction inconsistent: the rate-tied hypotheses, each a one-parameter
//!   extension of a continuous modal model built from the fitted model's poles ([`modal`]):
//!   `hold_delay` α (the hold switches α of each experiment's own period late) and
//!   `averaging_sampler` β (the sensor averages over β of each period), each discretised
//!   exactly at each experiment's period ([`sd_multirate::c2d_nonideal`]). For a trial
//!   parameter the modal residues are fitted to the fast FRF, then the slow FRFs are predicted;
//!   the parameter minimizing the slow statistic is found by a grid and golden section. A cause
//!   is named only when its extension removes at least 90 % of the plain modal model's excess
//!   over the noise level (`c₀ − c ≥ 0.9 (c₀ − 1)`) and the other extension is worse by more
//!   than five standard deviations of the statistic (`5 max(c, 1)/√K`); otherwise
//!   `unexplained`.
//!
//! **Gain** is measured on held-out data: each validation experiment's steady periods (or its
//! record) are split in two halves; the extension's parameter is fitted with the first and the
//! model's and the extension's statistics are compared on the second.

mod lemma6;
mod lstsq;
pub mod modal;
pub mod timedomain;

mod diagnose;

pub use diagnose::{diagnose, diagnose_with_progress};
pub use lemma6::predict;
pub use timedomain::AveragedPeriod;

use num_complex::Complex64 as C;
use sd_model::StateSpace;
use serde_json::json;

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
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, DiagnoseError>;

/// Settings of a diagnosis.
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// A given model of the plant (SISO; discrete at the model experiment's period, or
    /// continuous and then ZOH-discretised there). `None`: fitted to the model experiment.
    pub model: Option<StateSpace>,
    /// Highest order tried when fitting (FPE picks one).
    pub max_order: usize,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            model: None,
            max_order: 20,
        }
    }
}

/// The extension of the model that the diagnosis settled on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Hyp {
    /// No extension.
    None,
    /// The hold switches this fraction of each period late.
    Delay(f64),
    /// The sensor averages over this fraction of each period.
    Average(f64),
    /// The fast FRF itself replaces the model at the folding frequencies.
    FastFrf,
    /// One best linear approximation per excitation level.
    PerLevel,
}

/// One test of the evidence list.
#[derive(Debug, Clone)]
pub struct Evidence {
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
    pub(crate) fn check(test: impl Into<String>, statistic: f64, threshold: f64) -> Self {
        Evidence {
            test: test.into(),
            statistic,
            threshold,
            passed: statistic <= threshold,
        }
    }
}

/// A band of lines where a prediction misses the data beyond the noise.
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    /// Lowest frequency (Hz).
    pub f_lo: f64,
    /// Highest frequency (Hz).
    pub f_hi: f64,
    /// The line with the largest normalized residual (Hz).
    pub worst_hz: f64,
    /// `20 log10 |P_meas/P_pred|` there (dB).
    pub worst_db: f64,
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

/// The time-domain comparison of one experiment: one averaged steady period of a periodic
/// experiment, or a whole non-periodic record simulated from the least-squares initial state.
#[derive(Debug, Clone)]
pub struct TimeDomain {
    /// Sample rate (Hz).
    pub rate_hz: f64,
    /// Measured averaged output period.
    pub measured: Vec<f64>,
    /// The model's periodic response to the measured input.
    pub model: Vec<f64>,
    /// The extended model's, when there is an extension.
    pub extended: Option<Vec<f64>>,
    /// Rms of the output around its mean.
    pub output_rms: f64,
    /// Rms noise of the comparison (spread of the per-period residual of the model; NaN for a
    /// non-periodic record, where it is not known).
    pub noise_rms: f64,
    /// Rms of measured − model.
    pub error_rms_model: f64,
    /// Rms of measured − extended model.
    pub error_rms_extended: Option<f64>,
    /// The same three, counting only the bands where the model misses in the frequency domain
    /// (`None` without bands): noise, model, extended.
    pub in_bands: Option<(f64, f64, Option<f64>)>,
}

/// What the diagnosis found on one experiment.
#[derive(Debug, Clone)]
pub struct ExperimentReport {
    /// Experiment name.
    pub name: String,
    /// "model" or "validation".
    pub role: String,
    /// Sample rate (Hz).
    pub rate_hz: f64,
    /// Model rate / this rate.
    pub factor: usize,
    /// Model-free Lemma 6 statistic and its line count (validation experiments).
    pub model_free: Option<(f64, usize)>,
    /// The model's statistic and its line count.
    pub model_stat: (f64, usize),
    /// The extended model's statistic, when there is an extension.
    pub extended_stat: Option<f64>,
    /// Where the model misses beyond 3σ (bands carrying ≥ 1 % of the statistic, largest share
    /// first, at most 5).
    pub bands: Vec<Band>,
    /// The FRFs.
    pub curves: Curves,
    /// The time-domain comparison.
    pub time_domain: Option<TimeDomain>,
    /// Noise and distortion levels at the non-excited lines of a periodic experiment.
    pub distortion: Option<sd_ident::DistortionReport>,
}

/// The outcome.
#[derive(Debug, Clone)]
pub struct Diagnosis {
    /// "consistent" or "discrepancy".
    pub verdict: String,
    /// "none", "hold_delay", "averaging_sampler", "nonlinearity", "fast_model_error" or
    /// "unexplained".
    pub cause: String,
    /// Fitted parameters (JSON object, DESIGN §4).
    pub parameters: serde_json::Value,
    /// The tests performed.
    pub evidence: Vec<Evidence>,
    /// Hypotheses ranked by cost `(cause, cost per line, parameters)`.
    pub ranking: Vec<(String, f64, usize)>,
    /// Held-out statistic before the extension.
    pub gain_before: f64,
    /// After.
    pub gain_after: f64,
    /// Experiments whose data were held out for the gain.
    pub held_out: Vec<String>,
    /// The extension.
    pub extension: Hyp,
    /// The model used (discrete, at the model experiment's period).
    pub model: StateSpace,
    /// "fitted (order n, FPE)" or "given".
    pub model_source: String,
    /// Per experiment (the model experiment first).
    pub experiments: Vec<ExperimentReport>,
}

impl Diagnosis {
    /// `diagnosis.json` (DESIGN §4, with the per-experiment findings added).
    pub fn to_json(&self) -> serde_json::Value {
        json!({
            "verdict": self.verdict,
            "cause": self.cause,
            "parameters": self.parameters,
            "evidence": self.evidence.iter().map(|e| json!({"test": e.test, "statistic": e.statistic, "threshold": e.threshold, "passed": e.passed})).collect::<Vec<_>>(),
            "ranking": self.ranking.iter().map(|r| json!({"cause": r.0, "cost": r.1, "n_params": r.2})).collect::<Vec<_>>(),
            "gain": {"metric": "mean |P_meas − P_pred|²/var per line (1 = noise level)", "before": self.gain_before,
                     "after": self.gain_after, "ratio": self.gain_ratio(), "held_out": self.held_out},
            "model": {"source": self.model_source, "order": self.model.n(), "ts": self.model.ts()},
            "experiments": self.experiments.iter().map(|x| json!({
                "name": x.name, "role": x.role, "rate_hz": x.rate_hz, "factor": x.factor,
                "model_free_statistic": x.model_free.map(|m| m.0),
                "model_statistic": x.model_stat.0, "lines": x.model_stat.1,
                "extended_statistic": x.extended_stat,
                "bands": x.bands.iter().map(|b| json!({"f_lo_hz": b.f_lo, "f_hi_hz": b.f_hi, "worst_hz": b.worst_hz,
                    "worst_db": b.worst_db, "from_fast_hz": b.from_fast_hz, "share": b.share})).collect::<Vec<_>>(),
                "time_domain": x.time_domain.as_ref().map(|t| json!({"output_rms": t.output_rms, "noise_rms": t.noise_rms,
                    "error_rms_model": t.error_rms_model, "error_rms_extended": t.error_rms_extended,
                    "in_bands": t.in_bands.map(|b| json!({"noise_rms": b.0, "error_rms_model": b.1, "error_rms_extended": b.2}))})),
                "distortion": x.distortion.as_ref().map(|d| json!({"odd_lines": d.odd_lines, "even_lines": d.even_lines,
                    "odd_ratio": d.odd_ratio, "even_ratio": d.even_ratio, "noise_level": d.noise_level})),
            })).collect::<Vec<_>>(),
        })
    }

    /// Held-out statistic before / after.
    pub fn gain_ratio(&self) -> f64 {
        self.gain_before / self.gain_after.max(f64::MIN_POSITIVE)
    }
}
