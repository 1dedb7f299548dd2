//! What a diagnosis leaves behind for new data: the plain model and the extension it found,
//! in a form that is written (`predictor.json`, docs/formats.md) and read back exactly.
//!
//! A rate-tied extension is the continuous modal model with its hold delay and averaging
//! window (discretised at each new experiment's own period by
//! [`sd_multirate::c2d_nonideal`]); the per-experiment clock errors the diagnosis estimated
//! belong to those experiments' clocks and are not carried. An amplitude-dependent extension
//! is the modal basis (continuous poles), the moving modes' frequency and damping trends in
//! the relative amplitude, the reference amplitudes and forces that measure a new
//! experiment's amplitude (`AmplitudeModel::amplitudes_of`), the range of relative amplitudes
//! it was fitted on and the common residues. Each fitted model carries the covariance of its
//! parameters ([`ModelUncertainty`]; version 2 — version 1 files, without it, are still read
//! and predict with the models taken as known). Every number is kept at full precision (JSON
//! numbers written by `serde_json` round-trip `f64` exactly); an infinite standard error (a
//! trend the data did not determine) is written as `null`.

use crate::amplitude::AmplitudeModel;
use crate::modal::{ModalBasis, Residues};
use crate::{DiagnoseError, Extension, Result, Trend};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::StateSpace;
use serde::{Deserialize, Serialize};

/// Format tag of `predictor.json`.
pub const PREDICTOR_FORMAT: &str = "sd-predictor";
/// Version of `predictor.json` this crate writes and reads.
pub const PREDICTOR_VERSION: u32 = 2;

/// The plain model and the extension a diagnosis found, as `sdctl predict` reads them.
#[derive(Debug, Clone)]
pub struct Predictor {
    /// The model judged (discrete, at the model experiment's period).
    pub model: StateSpace,
    /// The extension.
    pub extension: SavedExtension,
    /// The model's modal form with its parameters' covariance, where the diagnosis fitted it
    /// (`None` for a given model): the prediction variance of new experiments.
    pub uncertainty: Option<ModelUncertainty>,
}

/// A fitted modal model's basis and residues with the covariance of residues and pole
/// parameters (`predictor.json`'s `uncertainty`; docs/formats.md): a prediction's variance
/// `gᴴΣg` at any rate, `g = [φ, ∂φ/∂poles]` the basis responses and their pole sensitivities.
#[derive(Debug, Clone)]
pub struct ModelUncertainty {
    pub(crate) basis: ModalBasis,
    pub(crate) residues: Residues,
}

impl ModelUncertainty {
    /// The prediction variance at `freq_hz` at period `ts` under the non-idealities `ni`.
    pub(crate) fn variances(
        &self,
        ts: f64,
        ni: sd_multirate::NonIdeal,
        freq_hz: &[f64],
    ) -> Result<Vec<f64>> {
        self.residues.variances(&self.basis, ts, ni, freq_hz)
    }
}

/// An extension as written to `predictor.json`.
#[derive(Debug, Clone)]
pub enum SavedExtension {
    /// The diagnosis found none (the cause it named, for the message).
    None {
        /// The named cause.
        cause: String,
    },
    /// Rate-tied non-idealities on the continuous modal model.
    RateTied {
        /// The continuous modal model (residues refitted under the non-idealities).
        continuous: Box<StateSpace>,
        /// Hold delay (fraction of each experiment's period).
        hold_delay: f64,
        /// Averaging window (fraction of the period).
        averaging: f64,
        /// Its modal form with the covariance of the refitted residues and the poles (the
        /// delay's and window's own uncertainty is not in it).
        uncertainty: Option<ModelUncertainty>,
    },
    /// The model experiment's measured FRF at the folding frequencies: not a model, it
    /// predicts nothing new.
    FastFrf,
    /// One linear model per level: no model of the amplitude between them.
    PerLevel,
    /// The amplitude-dependent modal model.
    Amplitude(AmplitudePredictor),
}

/// The amplitude-dependent modal model a diagnosis fitted (its parts are written to
/// `predictor.json`; docs/formats.md).
#[derive(Debug, Clone)]
pub struct AmplitudePredictor(pub(crate) Box<AmplitudeModel>);

impl SavedExtension {
    /// Its name in `predictor.json` and `prediction.json`.
    pub fn kind(&self) -> &'static str {
        match self {
            SavedExtension::None { .. } => "none",
            SavedExtension::RateTied { .. } => "rate_tied",
            SavedExtension::FastFrf => "fast_frf",
            SavedExtension::PerLevel => "per_level",
            SavedExtension::Amplitude(_) => "amplitude",
        }
    }
}

impl Predictor {
    /// The predictor of a diagnosis's outcome: its model, and its extension as found
    /// (`extended` the rate-tied one's continuous model, `amplitude` the amplitude model).
    pub(crate) fn of(
        (model, uncertainty): (&StateSpace, Option<ModelUncertainty>),
        (extension, cause): (&Extension, &str),
        (extended, tied): (Option<&crate::ExtendedModel>, Option<ModelUncertainty>),
        amplitude: Option<&AmplitudeModel>,
    ) -> Self {
        let extension = match (extension, extended, amplitude) {
            (Extension::RateTied(_), Some(x), _) => SavedExtension::RateTied {
                continuous: Box::new(x.continuous.clone()),
                hold_delay: x.hold_delay,
                averaging: x.averaging,
                uncertainty: tied,
            },
            (Extension::Amplitude(_), _, Some(m)) => {
                SavedExtension::Amplitude(AmplitudePredictor(Box::new(m.clone())))
            }
            (Extension::FastFrf, _, _) => SavedExtension::FastFrf,
            (Extension::PerLevel, _, _) => SavedExtension::PerLevel,
            _ => SavedExtension::None {
                cause: cause.to_string(),
            },
        };
        Predictor {
            model: model.clone(),
            extension,
            uncertainty,
        }
    }

    /// `predictor.json`.
    ///
    /// # Errors
    /// A model that cannot be written (non-finite entries).
    pub fn to_json_string(&self) -> Result<String> {
        let file = File {
            format: PREDICTOR_FORMAT.into(),
            version: PREDICTOR_VERSION,
            model: model_value(&self.model)?,
            uncertainty: self
                .uncertainty
                .as_ref()
                .map(saved_uncertainty)
                .transpose()?,
            extension: match &self.extension {
                SavedExtension::None { cause } => Saved::None {
                    cause: cause.clone(),
                },
                SavedExtension::RateTied {
                    continuous,
                    hold_delay,
                    averaging,
                    uncertainty,
                } => Saved::RateTied {
                    continuous: model_value(continuous)?,
                    hold_delay: *hold_delay,
                    averaging: *averaging,
                    uncertainty: uncertainty.as_ref().map(saved_uncertainty).transpose()?,
                },
                SavedExtension::FastFrf => Saved::FastFrf,
                SavedExtension::PerLevel => Saved::PerLevel,
                SavedExtension::Amplitude(m) => Saved::Amplitude(Box::new(saved_amplitude(&m.0)?)),
            },
        };
        serde_json::to_string_pretty(&file).map_err(|e| DiagnoseError::Setup(e.to_string()))
    }

    /// Reads `predictor.json`; unknown keys, another format or version, and models that do
    /// not fit together are errors that name what is wrong.
    ///
    /// # Errors
    /// [`DiagnoseError::Setup`] naming the problem.
    pub fn from_json_str(text: &str) -> Result<Self> {
        let bad = |m: String| DiagnoseError::Setup(format!("predictor.json: {m}"));
        let file: File = serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        if file.format != PREDICTOR_FORMAT || !(1..=PREDICTOR_VERSION).contains(&file.version) {
            return Err(bad(format!(
                "format `{}` version {} is not `{PREDICTOR_FORMAT}` version 1 to \
                 {PREDICTOR_VERSION}: write it again with this version's `sdctl diagnose`",
                file.format, file.version
            )));
        }
        let model = model_of(&file.model).map_err(|e| bad(format!("model: {e}")))?;
        let h = model.ts().ok_or_else(|| {
            bad(
                "the model is continuous; it must be discrete at the model experiment's rate"
                    .into(),
            )
        })?;
        if model.nu() != 1 || model.ny() != 1 {
            return Err(bad(format!(
                "the model has {} inputs and {} outputs; a diagnosis's model is SISO",
                model.nu(),
                model.ny()
            )));
        }
        let uncertainty = file
            .uncertainty
            .map(|u| uncertainty_of(u, h))
            .transpose()
            .map_err(|e| bad(format!("uncertainty: {e}")))?;
        let extension = match file.extension {
            Saved::None { cause } => SavedExtension::None { cause },
            Saved::RateTied {
                continuous,
                hold_delay,
                averaging,
                uncertainty,
            } => {
                let continuous =
                    model_of(&continuous).map_err(|e| bad(format!("extension: {e}")))?;
                if continuous.ts().is_some() || continuous.nu() != 1 || continuous.ny() != 1 {
                    return Err(bad(
                        "the rate-tied extension must be a continuous SISO model".into(),
                    ));
                }
                if !(0.0..=sd_multirate::MAX_HOLD_DELAY).contains(&hold_delay)
                    || !(0.0..=1.0).contains(&averaging)
                {
                    return Err(bad(format!(
                        "hold_delay {hold_delay} (0 to {}) or averaging {averaging} (0 to 1) \
                         out of range",
                        sd_multirate::MAX_HOLD_DELAY
                    )));
                }
                SavedExtension::RateTied {
                    continuous: Box::new(continuous),
                    hold_delay,
                    averaging,
                    uncertainty: uncertainty
                        .map(|u| uncertainty_of(u, h))
                        .transpose()
                        .map_err(|e| bad(format!("extension uncertainty: {e}")))?,
                }
            }
            Saved::FastFrf => SavedExtension::FastFrf,
            Saved::PerLevel => SavedExtension::PerLevel,
            Saved::Amplitude(a) => SavedExtension::Amplitude(AmplitudePredictor(Box::new(
                amplitude_of(*a, h).map_err(bad)?,
            ))),
        };
        Ok(Predictor {
            model,
            extension,
            uncertainty,
        })
    }
}

/// The file.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    format: String,
    version: u32,
    model: serde_json::Value,
    /// Since version 2; absent for a given model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    uncertainty: Option<SavedUncertainty>,
    extension: Saved,
}

/// [`ModelUncertainty`] in the file: the basis as [`SavedAmplitude`]'s, the residues, and the
/// covariance (rows; the residues' own, or residues then pole parameters).
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SavedUncertainty {
    rigid_body: usize,
    rigid_damping: f64,
    real_poles: Vec<f64>,
    pairs: Vec<[f64; 2]>,
    residues: Vec<f64>,
    covariance: Vec<Vec<f64>>,
}

/// The extension in the file.
#[derive(Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum Saved {
    None {
        cause: String,
    },
    RateTied {
        continuous: serde_json::Value,
        hold_delay: f64,
        averaging: f64,
        /// Since version 2.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        uncertainty: Option<SavedUncertainty>,
    },
    FastFrf,
    PerLevel,
    Amplitude(Box<SavedAmplitude>),
}

/// The amplitude model in the file (fields of [`AmplitudeModel`]; poles in rad/s as
/// `[re, im]`).
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SavedAmplitude {
    rigid_body: usize,
    rigid_damping: f64,
    real_poles: Vec<f64>,
    pairs: Vec<[f64; 2]>,
    candidates: Vec<SavedCandidate>,
    residues: Vec<f64>,
    /// The common residues' covariance (rows; since version 2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    residue_covariance: Option<Vec<Vec<f64>>>,
}

/// One candidate mode of the amplitude model.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SavedCandidate {
    pole: usize,
    frequency: SavedTrend,
    damping: SavedTrend,
    frequency_moves: bool,
    damping_moves: bool,
    reference_amplitude: f64,
    reference_force: f64,
    per_force: Vec<[f64; 2]>,
    /// `null` when no fitted level measured the mode's amplitude (a mode that then does not
    /// move).
    fitted_range: Option<[f64; 2]>,
}

/// A [`Trend`] with its undetermined (infinite) standard errors as `null`.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SavedTrend {
    exponent: i32,
    at_reference: f64,
    at_reference_std: Option<f64>,
    slope: f64,
    slope_std: Option<f64>,
    covariance: f64,
}

impl SavedTrend {
    fn of(t: &Trend) -> Self {
        let finite = |x: f64| x.is_finite().then_some(x);
        SavedTrend {
            exponent: t.exponent,
            at_reference: t.at_reference,
            at_reference_std: finite(t.at_reference_std),
            slope: t.slope,
            slope_std: finite(t.slope_std),
            covariance: t.covariance,
        }
    }

    fn trend(&self) -> std::result::Result<Trend, String> {
        if ![2, 1, -1].contains(&self.exponent) {
            return Err(format!(
                "a trend's exponent is 2, 1 or −1, not {}",
                self.exponent
            ));
        }
        Ok(Trend {
            exponent: self.exponent,
            at_reference: self.at_reference,
            at_reference_std: self.at_reference_std.unwrap_or(f64::INFINITY),
            slope: self.slope,
            slope_std: self.slope_std.unwrap_or(f64::INFINITY),
            covariance: self.covariance,
        })
    }
}

fn model_value(m: &StateSpace) -> Result<serde_json::Value> {
    let text = sd_model::model_to_json_string(m)?;
    serde_json::from_str(&text).map_err(|e| DiagnoseError::Setup(e.to_string()))
}

fn model_of(v: &serde_json::Value) -> std::result::Result<StateSpace, String> {
    sd_model::model_from_json_str(&v.to_string()).map_err(|e| e.to_string())
}

/// Every number of the saved amplitude model finite (JSON has no infinity or NaN: serde_json
/// would write `null`, which reads back as an error far from its cause).
fn check_finite(a: &SavedAmplitude) -> Result<()> {
    let mut all: Vec<(&str, f64)> = vec![("rigid_damping", a.rigid_damping)];
    all.extend(a.real_poles.iter().map(|x| ("real_poles", *x)));
    all.extend(a.pairs.iter().flatten().map(|x| ("pairs", *x)));
    all.extend(a.residues.iter().map(|x| ("residues", *x)));
    for c in &a.candidates {
        for t in [&c.frequency, &c.damping] {
            all.extend([
                ("trend at_reference", t.at_reference),
                ("trend slope", t.slope),
                ("trend covariance", t.covariance),
            ]);
        }
        all.extend([
            ("reference_amplitude", c.reference_amplitude),
            ("reference_force", c.reference_force),
        ]);
        all.extend(c.per_force.iter().flatten().map(|x| ("per_force", *x)));
        all.extend(
            c.fitted_range
                .iter()
                .flatten()
                .map(|x| ("fitted_range", *x)),
        );
    }
    match all.iter().find(|(_, x)| !x.is_finite()) {
        Some((name, x)) => Err(DiagnoseError::Numerical(format!(
            "the amplitude model's {name} is {x}: it cannot be saved"
        ))),
        None => Ok(()),
    }
}

fn saved_amplitude(m: &AmplitudeModel) -> Result<SavedAmplitude> {
    let ((rigid_body, rigid_damping), real, pairs) = m.basis.parts();
    let fitted = m
        .residues
        .as_ref()
        .ok_or_else(|| DiagnoseError::Numerical("amplitude model without residues".into()))?;
    let residues = fitted.r.clone();
    let cov = fitted.saved_covariance();
    let residue_covariance = (cov.nrows() >= residues.len() && !residues.is_empty()).then(|| {
        let n = residues.len();
        rows(&cov.view((0, 0), (n, n)).into_owned())
    });
    let candidates = m
        .cand
        .iter()
        .enumerate()
        .map(|(k, &pole)| {
            let (ft, zt, fm, zm) = &m.trends[k];
            SavedCandidate {
                pole,
                frequency: SavedTrend::of(ft),
                damping: SavedTrend::of(zt),
                frequency_moves: *fm,
                damping_moves: *zm,
                reference_amplitude: m.reference[k],
                reference_force: m.reference_force[k],
                per_force: m.per_force[k].iter().map(|&(a, b)| [a, b]).collect(),
                fitted_range: (m.range[k].0.is_finite() && m.range[k].1 > 0.0)
                    .then_some([m.range[k].0, m.range[k].1]),
            }
        })
        .collect();
    let saved = SavedAmplitude {
        rigid_body,
        rigid_damping,
        real_poles: real.to_vec(),
        pairs: pairs.iter().map(|p| [p.re, p.im]).collect(),
        candidates,
        residues,
        residue_covariance,
    };
    check_finite(&saved)?;
    Ok(saved)
}

/// A matrix as rows.
fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| m.row(i).iter().copied().collect())
        .collect()
}

/// The modal basis of a saved model, checked: a rigid body of 0 to 2 poles with a finite
/// damping ≥ 0, finite real poles, pairs given by their pole with positive imaginary part.
fn basis_of(
    (rigid_body, rigid_damping): (usize, f64),
    real_poles: &[f64],
    pairs: &[[f64; 2]],
) -> std::result::Result<ModalBasis, String> {
    if rigid_body > 2 || !(rigid_damping >= 0.0 && rigid_damping.is_finite()) {
        return Err(format!(
            "rigid_body {rigid_body} (0 to 2) or rigid_damping {rigid_damping} (finite, ≥ 0) \
             out of range"
        ));
    }
    let pairs: Vec<C> = pairs.iter().map(|p| C::new(p[0], p[1])).collect();
    if real_poles.iter().any(|p| !p.is_finite())
        || pairs
            .iter()
            .any(|p| !(p.re.is_finite() && p.im.is_finite() && p.im > 0.0))
    {
        return Err(
            "the poles must be finite, each pair given by the pole with the positive \
                    imaginary part"
                .into(),
        );
    }
    ModalBasis::build((rigid_body, rigid_damping), real_poles, &pairs).map_err(|e| e.to_string())
}

/// Basis functions and pole parameters of `basis` at the model period `h`.
fn basis_sizes(basis: &ModalBasis, h: f64) -> std::result::Result<(usize, usize), String> {
    let ideal = sd_multirate::NonIdeal::ideal();
    let nb = basis
        .responses(h, ideal, &[0.0])
        .map_err(|e| e.to_string())?
        .first()
        .map_or(0, Vec::len);
    let np = basis
        .pole_sensitivities(&vec![0.0; nb], h, ideal, &[1.0])
        .map_err(|e| e.to_string())?
        .first()
        .map_or(0, Vec::len);
    Ok((nb, np))
}

/// A saved covariance checked: `sizes` rows of as many finite entries, symmetric to 1e-9 of
/// its largest entry, a non-negative diagonal.
fn covariance_of(rows: &[Vec<f64>], sizes: &[usize]) -> std::result::Result<DMatrix<f64>, String> {
    let n = rows.len();
    if !sizes.contains(&n) || rows.iter().any(|r| r.len() != n) {
        return Err(format!(
            "the covariance is {n} rows of {:?} entries; {sizes:?} square expected",
            rows.iter()
                .map(Vec::len)
                .collect::<std::collections::BTreeSet<_>>()
        ));
    }
    let m = DMatrix::from_fn(n, n, |i, j| rows[i][j]);
    let big = m.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let symmetric = (0..n).all(|i| (0..i).all(|j| (m[(i, j)] - m[(j, i)]).abs() <= 1e-9 * big));
    if m.iter().any(|x| !x.is_finite()) || !symmetric || (0..n).any(|i| m[(i, i)] < 0.0) {
        return Err(
            "the covariance must be finite, symmetric, with a non-negative diagonal".into(),
        );
    }
    Ok(m)
}

fn saved_uncertainty(u: &ModelUncertainty) -> Result<SavedUncertainty> {
    let ((rigid_body, rigid_damping), real, pairs) = u.basis.parts();
    let cov = u.residues.saved_covariance();
    let saved = SavedUncertainty {
        rigid_body,
        rigid_damping,
        real_poles: real.to_vec(),
        pairs: pairs.iter().map(|p| [p.re, p.im]).collect(),
        residues: u.residues.r.clone(),
        covariance: rows(cov),
    };
    let all = std::iter::once(rigid_damping)
        .chain(saved.real_poles.iter().copied())
        .chain(saved.pairs.iter().flatten().copied())
        .chain(saved.residues.iter().copied())
        .chain(saved.covariance.iter().flatten().copied());
    if let Some(x) = all.into_iter().find(|x| !x.is_finite()) {
        return Err(DiagnoseError::Numerical(format!(
            "the model's uncertainty holds {x}: it cannot be saved"
        )));
    }
    Ok(saved)
}

/// One finite residue per basis function of `functions`.
fn check_residues(residues: &[f64], functions: usize) -> std::result::Result<(), String> {
    if residues.len() != functions || residues.iter().any(|r| !r.is_finite()) {
        return Err(format!(
            "{} residues for a basis of {functions} functions (all finite)",
            residues.len()
        ));
    }
    Ok(())
}

/// The saved uncertainty at the model's period `h`, checked (basis, one residue per basis
/// function, a covariance of the residues or of residues and pole parameters).
fn uncertainty_of(u: SavedUncertainty, h: f64) -> std::result::Result<ModelUncertainty, String> {
    let basis = basis_of((u.rigid_body, u.rigid_damping), &u.real_poles, &u.pairs)?;
    let (nb, np) = basis_sizes(&basis, h)?;
    check_residues(&u.residues, nb)?;
    let cov = covariance_of(&u.covariance, &[nb, nb + np])?;
    Ok(ModelUncertainty {
        basis,
        residues: Residues::with_covariance(u.residues, cov),
    })
}

/// The amplitude model of the file at the model's period `h`, checked: finite stable poles,
/// candidates that index them, one residue per basis function.
fn amplitude_of(a: SavedAmplitude, h: f64) -> std::result::Result<AmplitudeModel, String> {
    let basis = basis_of((a.rigid_body, a.rigid_damping), &a.real_poles, &a.pairs)?;
    let n_poles = basis.poles().len();
    let (n_functions, _) = basis_sizes(&basis, h)?;
    check_residues(&a.residues, n_functions)?;
    let residues = match &a.residue_covariance {
        Some(rows) => Residues::with_covariance(
            a.residues.clone(),
            covariance_of(rows, &[n_functions]).map_err(|e| format!("residue_{e}"))?,
        ),
        None => Residues::known(a.residues.clone()),
    };
    let mut m = AmplitudeModel {
        basis,
        h,
        cand: Vec::new(),
        trends: Vec::new(),
        reference: Vec::new(),
        reference_force: Vec::new(),
        per_force: Vec::new(),
        range: Vec::new(),
        residues: Some(residues),
    };
    for c in a.candidates {
        if c.pole >= n_poles {
            return Err(format!(
                "candidate pole {} of a basis with {n_poles} movable poles",
                c.pole
            ));
        }
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !positive(c.reference_amplitude)
            || !positive(c.reference_force)
            || c.per_force.iter().flatten().any(|x| !positive(*x))
        {
            return Err(
                "reference amplitudes, forces and per_force ratios must be positive".into(),
            );
        }
        if c.fitted_range
            .is_some_and(|r| !(positive(r[0]) && positive(r[1]) && r[0] <= r[1]))
        {
            return Err("a fitted_range is [lowest, highest], both positive".into());
        }
        m.cand.push(c.pole);
        m.trends.push((
            c.frequency.trend()?,
            c.damping.trend()?,
            c.frequency_moves,
            c.damping_moves,
        ));
        m.reference.push(c.reference_amplitude);
        m.reference_force.push(c.reference_force);
        m.per_force
            .push(c.per_force.iter().map(|p| (p[0], p[1])).collect());
        m.range.push(
            c.fitted_range
                .map_or((f64::INFINITY, 0.0), |r| (r[0], r[1])),
        );
    }
    Ok(m)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn trend(at: f64) -> SavedTrend {
        SavedTrend {
            exponent: 2,
            at_reference: at,
            at_reference_std: None,
            slope: 0.5,
            slope_std: Some(0.1),
            covariance: 0.0,
        }
    }

    /// A rigid body and one pair at about 95 Hz, the pair moving.
    fn saved(h: f64) -> SavedAmplitude {
        let basis = ModalBasis::build((2, 0.0), &[], &[C::new(-10.0, 600.0)]).unwrap();
        let n = basis
            .responses(h, sd_multirate::NonIdeal::ideal(), &[1.0])
            .unwrap()[0]
            .len();
        SavedAmplitude {
            rigid_body: 2,
            rigid_damping: 0.0,
            real_poles: Vec::new(),
            pairs: vec![[-10.0, 600.0]],
            candidates: vec![SavedCandidate {
                pole: 0,
                frequency: trend(95.5),
                damping: trend(0.017),
                frequency_moves: true,
                damping_moves: false,
                reference_amplitude: 1e-6,
                reference_force: 0.5,
                per_force: vec![[1.0, 1.0], [2.0, 1.9]],
                fitted_range: Some([1.0, 1.9]),
            }],
            residues: vec![1.0; n],
            residue_covariance: None,
        }
    }

    #[test]
    fn a_saved_amplitude_model_reads_back_and_its_faults_are_named() {
        let h = 1e-3;
        let m = amplitude_of(saved(h), h).unwrap();
        let again = saved_amplitude(&m).unwrap();
        assert_eq!(again.pairs, saved(h).pairs);
        assert_eq!(again.residues, saved(h).residues);
        assert_eq!(again.candidates[0].fitted_range, Some([1.0, 1.9]));
        let mut bad = saved(h);
        bad.candidates[0].pole = 3;
        assert!(amplitude_of(bad, h)
            .unwrap_err()
            .contains("candidate pole 3"));
        let mut bad = saved(h);
        bad.residues.pop();
        assert!(amplitude_of(bad, h).unwrap_err().contains("residues"));
        let mut bad = saved(h);
        bad.candidates[0].fitted_range = Some([2.0, 1.0]);
        assert!(amplitude_of(bad, h).unwrap_err().contains("fitted_range"));
        let mut bad = saved(h);
        bad.candidates[0].frequency.exponent = 3;
        assert!(amplitude_of(bad, h).unwrap_err().contains("exponent"));
        // a number JSON cannot hold is refused before it is written as null
        let mut nan = saved(h);
        nan.candidates[0].damping.slope = f64::NAN;
        let e = check_finite(&nan).unwrap_err().to_string();
        assert!(e.contains("trend slope is NaN"), "{e}");
    }
}
