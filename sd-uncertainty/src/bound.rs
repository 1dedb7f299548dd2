//! The pointwise bound on a model's error from a measured FRF, and its coverage of another
//! measurement.
//!
//! **Math.** At a measured line `f_k` with estimate `G_k`, variance `σ_k² = E|G_k − P(f_k)|²`
//! and model `P̂`, the true plant `P` satisfies
//! `|P(f_k) − P̂(f_k)| ≤ |G_k − P̂(f_k)| + |P(f_k) − G_k| ≤ r_k + κσ_k`
//! with probability at least `c` per line when `G_k − P(f_k)` is circular complex Gaussian:
//! then `|G_k − P|²/σ_k²` is Exp(1) and `P(|G − P| ≤ κσ) = 1 − e^{−κ²}`, so
//! `κ = √(−ln(1 − c))` (1.731 at c = 95 %). The additive bound is `a_k = r_k + κσ_k`; the
//! multiplicative (input = output for SISO) bound is `a_k/|P̂(f_k)|`. The bound is conservative
//! by construction: the residual `r_k` itself contains noise of size `σ_k`.

use crate::error::{Result, UncertaintyError};
use num_complex::Complex64 as C;
use sd_model::{Frd, StateSpace};

/// The form of an uncertainty bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Form {
    /// `P = P̂ + Δ`, `|Δ(f)| ≤ b(f)` (plant units).
    Additive,
    /// `P = P̂(1 + Δ)`, `|Δ(f)| ≤ b(f)` (relative; input and output coincide for SISO).
    Multiplicative,
}

/// A pointwise bound on a model's error at the lines of a measurement.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Bound {
    /// Additive or multiplicative.
    pub form: Form,
    /// Probability per line that the bound holds (e.g. 0.95).
    pub confidence: f64,
    /// `κ = √(−ln(1 − confidence))`.
    pub sigma_factor: f64,
    /// Sample time of the data and model (s).
    pub ts: f64,
    /// The lines (Hz).
    pub freq_hz: Vec<f64>,
    /// The model's response `P̂(f_k)` (serialised as `[re, im]`).
    #[serde(serialize_with = "complex_pairs")]
    pub nominal: Vec<C>,
    /// `r_k = |G_k − P̂(f_k)|` (plant units).
    pub residual: Vec<f64>,
    /// `σ_k` (plant units).
    pub sigma: Vec<f64>,
    /// `a_k = r_k + κσ_k`, the additive bound (plant units), whatever the form.
    pub additive: Vec<f64>,
}

fn complex_pairs<S: serde::Serializer>(v: &[C], s: S) -> std::result::Result<S::Ok, S::Error> {
    use serde::ser::SerializeSeq;
    let mut seq = s.serialize_seq(Some(v.len()))?;
    for c in v {
        seq.serialize_element(&[c.re, c.im])?;
    }
    seq.end()
}

impl Bound {
    /// The bound in its form's units: `a_k` (additive) or `a_k/|P̂(f_k)|` (multiplicative).
    pub fn values(&self) -> Vec<f64> {
        match self.form {
            Form::Additive => self.additive.clone(),
            Form::Multiplicative => self
                .additive
                .iter()
                .zip(&self.nominal)
                .map(|(a, p)| a / p.norm().max(f64::MIN_POSITIVE))
                .collect(),
        }
    }

    /// The same bound in another form.
    pub fn with_form(&self, form: Form) -> Bound {
        Bound {
            form,
            ..self.clone()
        }
    }
}

/// `κ` for a per-line confidence `c`: `√(−ln(1 − c))`.
///
/// # Errors
/// `c` outside (0, 1).
pub fn sigma_factor(confidence: f64) -> Result<f64> {
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(UncertaintyError::Input(format!(
            "confidence {confidence} must be a probability in (0, 1), e.g. 0.95"
        )));
    }
    Ok((-(1.0 - confidence).ln()).sqrt())
}

/// The per-line confidence that makes a bound hold on all `lines` lines at once with
/// probability at least `simultaneous` (Bonferroni: `1 − (1 − c)/K`, valid whatever the
/// correlation between lines, e.g. the local polynomial method's; for independent lines the
/// bound then holds everywhere with probability between `c` and `c + (1 − c)²/2`). At
/// K = 1000 lines and c = 99.9 % the per-line confidence is 1 − 10⁻⁶ and
/// `κ = √(ln 10⁶)` = 3.72 (1.73 at 95 % per line).
///
/// # Errors
/// `simultaneous` outside (0, 1); no lines.
pub fn per_line_confidence(simultaneous: f64, lines: usize) -> Result<f64> {
    sigma_factor(simultaneous)?;
    if lines == 0 {
        return Err(UncertaintyError::Input(
            "a simultaneous confidence needs at least one line".into(),
        ));
    }
    Ok(1.0 - (1.0 - simultaneous) / lines as f64)
}

/// SISO check shared by the constructors.
pub(crate) fn siso(what: &str, shape: (usize, usize)) -> Result<()> {
    if shape != (1, 1) {
        return Err(UncertaintyError::Input(format!(
            "{what} is {}x{}; uncertainty bounds are SISO (take one entry)",
            shape.0, shape.1
        )));
    }
    Ok(())
}

/// The bound on `model`'s error from the measured `frd` (module documentation).
///
/// # Errors
/// Not SISO; the FRD has no variance, or another sample time than the model (a continuous
/// model is evaluated at `s = j2πf` against a discrete FRD only if the caller discretises it
/// first: refused); a confidence outside (0, 1).
pub fn from_data(model: &StateSpace, frd: &Frd, form: Form, confidence: f64) -> Result<Bound> {
    siso("the model", (model.ny(), model.nu()))?;
    siso("the FRD", frd.shape())?;
    let ts = match (model.ts(), frd.time().ts()) {
        (Some(a), Some(b)) if (a - b).abs() <= 1e-9 * a => a,
        (a, b) => {
            let said =
                |t: Option<f64>| t.map_or("continuous time".to_string(), |t| format!("{t} s"));
            return Err(UncertaintyError::Input(format!(
                "the model's sample time ({}) and the FRD's ({}) differ: bound a model at the \
                 rate its data were measured at",
                said(a),
                said(b)
            )));
        }
    };
    let var = frd.variance().ok_or_else(|| {
        UncertaintyError::Input(
            "the FRD has no variance (`var`): a bound needs the measurement's noise level; \
             estimate the FRF from two or more periods"
                .into(),
        )
    })?;
    let kappa = sigma_factor(confidence)?;
    let nominal: Vec<C> = model
        .freqresp(frd.freq_hz())?
        .response()
        .iter()
        .map(|m| m[(0, 0)])
        .collect();
    let residual: Vec<f64> = frd
        .response()
        .iter()
        .zip(&nominal)
        .map(|(g, p)| (g[(0, 0)] - p).norm())
        .collect();
    let sigma: Vec<f64> = var.iter().map(|v| v[(0, 0)].max(0.0).sqrt()).collect();
    let additive = residual
        .iter()
        .zip(&sigma)
        .map(|(r, s)| r + kappa * s)
        .collect();
    Ok(Bound {
        form,
        confidence,
        sigma_factor: kappa,
        ts,
        freq_hz: frd.freq_hz().to_vec(),
        nominal,
        residual,
        sigma,
        additive,
    })
}

/// How many lines of a measurement a bound covers.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Coverage {
    /// Lines compared (those of the measurement that the bound has).
    pub lines: usize,
    /// Lines where `|G − P̂| ≤ a + κσ_G` (the bound widened by the measurement's own noise at
    /// the bound's confidence).
    pub covered: usize,
    /// `covered / lines`.
    pub fraction: f64,
}

/// The coverage of a measured FRF by a bound (at the bound's lines; `measured` lines the bound
/// does not have are skipped). A measurement without variance is compared with the bound
/// alone.
///
/// # Errors
/// Not SISO; a sampled FRD at another rate than the bound's; no line in common.
pub fn coverage(bound: &Bound, measured: &Frd) -> Result<Coverage> {
    siso("the FRD", measured.shape())?;
    // a bound holds at its own rate: a sampled measurement at another rate is another plant
    // (its lines fold differently), and a share of "covered" lines would mean nothing
    if let Some(t) = measured.time().ts() {
        if (t - bound.ts).abs() > 1e-9 * bound.ts {
            return Err(UncertaintyError::Input(format!(
                "the FRD is sampled at {:.6} Hz and the bound at {:.6} Hz: a bound holds at its \
                 own rate; bring the bound to the FRD's rate (`sdctl downsample --uncertainty`) \
                 or compare with an FRD measured at the bound's rate",
                1.0 / t,
                1.0 / bound.ts
            )));
        }
    }
    let tol = 1e-9 * bound.freq_hz.last().copied().unwrap_or(1.0).max(1.0);
    let (mut lines, mut covered) = (0, 0);
    for (i, f) in measured.freq_hz().iter().enumerate() {
        let Some(j) = sd_model::line_index(&bound.freq_hz, *f, tol) else {
            continue;
        };
        let g = measured.response()[i][(0, 0)];
        let s = measured
            .variance()
            .map(|v| v[i][(0, 0)].max(0.0).sqrt())
            .unwrap_or(0.0);
        lines += 1;
        if (g - bound.nominal[j]).norm() <= bound.additive[j] + bound.sigma_factor * s {
            covered += 1;
        }
    }
    if lines == 0 {
        return Err(UncertaintyError::Input(
            "the measurement and the bound have no line in common".into(),
        ));
    }
    Ok(Coverage {
        lines,
        covered,
        fraction: covered as f64 / lines as f64,
    })
}
