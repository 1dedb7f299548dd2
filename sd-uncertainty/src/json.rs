//! The uncertainty JSON format: a bound on its lines, with its overbounding weight.
//!
//! ```json
//! {"type": "uncertainty", "form": "additive", "confidence": 0.95, "ts": 0.0002,
//!  "freq_hz": [...], "nominal_re": [...], "nominal_im": [...],
//!  "bound": [...], "residual": [...], "sigma": [...],
//!  "weight": {"model": {model JSON}, "scale": 1.4, "median_ratio": 1.8, "max_ratio": 150.0}}
//! ```
//!
//! `bound` is in the form's units (plant units for `additive`, relative for `multiplicative`)
//! and is what a reader uses; `residual` and `sigma` (plant units) say where it came from;
//! `weight` is optional; [`from_json_str`] reads the bound, [`weight_from_json_str`] the
//! weight's model (robust analysis uses it between the lines).
//!
//! **Carried by a model or FRD.** The same object under the key `"uncertainty"` of a model JSON
//! (any form) or an FRD JSON: the model with its error bound in one file ([`embed`]). Both
//! readers accept either file.

use crate::bound::{sigma_factor, Bound, Form};
use crate::error::{Result, UncertaintyError};
use crate::weight::Weight;
use num_complex::Complex64 as C;

const KEYS: &[&str] = &[
    "type",
    "form",
    "confidence",
    "ts",
    "freq_hz",
    "nominal_re",
    "nominal_im",
    "bound",
    "residual",
    "sigma",
    "weight",
];

fn bad(m: impl std::fmt::Display) -> UncertaintyError {
    UncertaintyError::Input(format!("cannot read uncertainty JSON: {m}"))
}

/// The JSON text of a bound and, optionally, its weight.
///
/// # Errors
/// The weight's model cannot be written (never for a valid model).
pub fn to_json_string(b: &Bound, w: Option<&Weight>) -> Result<String> {
    let mut v = serde_json::json!({
        "type": "uncertainty",
        "form": b.form,
        "confidence": b.confidence,
        "ts": b.ts,
        "freq_hz": b.freq_hz,
        "nominal_re": b.nominal.iter().map(|c| c.re).collect::<Vec<_>>(),
        "nominal_im": b.nominal.iter().map(|c| c.im).collect::<Vec<_>>(),
        "bound": b.values(),
        "residual": b.residual,
        "sigma": b.sigma,
    });
    if let (Some(w), Some(obj)) = (w, v.as_object_mut()) {
        let model: serde_json::Value =
            serde_json::from_str(&sd_model::model_to_json_string(&w.model)?).map_err(bad)?;
        obj.insert(
            "weight".into(),
            serde_json::json!({
                "model": model,
                "scale": w.scale,
                "median_ratio": w.median_ratio,
                "max_ratio": w.max_ratio,
            }),
        );
    }
    serde_json::to_string(&v).map_err(bad)
}

/// A bound from its JSON text (module documentation).
///
/// # Errors
/// Syntax, an unknown key (with the closest allowed one), a missing or mistyped key, arrays of
/// different lengths, a negative or non-finite bound, a confidence outside (0, 1).
pub fn from_json_str(text: &str) -> Result<Bound> {
    let v: serde_json::Value = serde_json::from_str(text).map_err(bad)?;
    from_value(carrier(&v)?)
}

/// The uncertainty object of a JSON value: the value itself (`"type": "uncertainty"`), or the
/// `uncertainty` a model or FRD JSON carries.
fn carrier(v: &serde_json::Value) -> Result<&serde_json::Value> {
    let own = v.get("type").and_then(|t| t.as_str()) == Some("uncertainty");
    match (own, v.get("uncertainty")) {
        (true, _) => Ok(v),
        (false, Some(u)) => Ok(u),
        (false, None) => Err(bad(
            "neither an uncertainty JSON (`\"type\": \"uncertainty\"`) nor a model or FRD \
             JSON carrying one (`\"uncertainty\": {…}`; `sdctl uncertainty … --embed` writes one)",
        )),
    }
}

/// Whether a model or FRD JSON text carries an uncertainty (`"uncertainty"` key).
pub fn carries(text: &str) -> bool {
    serde_json::from_str::<serde_json::Value>(text)
        .ok()
        .is_some_and(|v| v.get("uncertainty").is_some())
}

/// A model or FRD JSON text with the bound (and its weight) carried under `"uncertainty"`.
///
/// # Errors
/// The text is not a JSON object; the weight's model cannot be written.
pub fn embed(text: &str, b: &Bound, w: Option<&Weight>) -> Result<String> {
    let mut v: serde_json::Value = serde_json::from_str(text).map_err(bad)?;
    let u: serde_json::Value = serde_json::from_str(&to_json_string(b, w)?).map_err(bad)?;
    v.as_object_mut()
        .ok_or_else(|| bad("a bound is carried by a model or FRD JSON object"))?
        .insert("uncertainty".into(), u);
    serde_json::to_string(&v).map_err(bad)
}

fn from_value(v: &serde_json::Value) -> Result<Bound> {
    let obj = v
        .as_object()
        .ok_or_else(|| bad("the file must hold one JSON object"))?;
    sd_model::keys::check_keys(obj.keys().map(String::as_str), KEYS, &[], "the file")
        .map_err(bad)?;
    if obj.get("type").and_then(|t| t.as_str()) != Some("uncertainty") {
        return Err(bad("`type` must be \"uncertainty\""));
    }
    let form = match obj.get("form").and_then(|f| f.as_str()) {
        Some("additive") => Form::Additive,
        Some("multiplicative") => Form::Multiplicative,
        other => {
            return Err(bad(format!(
                "`form` must be \"additive\" or \"multiplicative\", got {other:?}"
            )))
        }
    };
    let num = |k: &str| -> Result<f64> {
        obj.get(k)
            .and_then(|x| x.as_f64())
            .ok_or_else(|| bad(format!("`{k}` must be a number")))
    };
    let arr = |k: &str| -> Result<Vec<f64>> {
        obj.get(k)
            .and_then(|x| x.as_array())
            .ok_or_else(|| bad(format!("`{k}` must be an array of numbers")))?
            .iter()
            .map(|x| {
                x.as_f64()
                    .ok_or_else(|| bad(format!("`{k}` holds a non-number")))
            })
            .collect()
    };
    let confidence = num("confidence")?;
    let kappa = sigma_factor(confidence)?;
    let ts = num("ts")?;
    if !(ts.is_finite() && ts > 0.0) {
        return Err(bad(format!(
            "`ts` must be a sampling period > 0 s, got {ts}"
        )));
    }
    let freq_hz = arr("freq_hz")?;
    let (re, im, values) = (arr("nominal_re")?, arr("nominal_im")?, arr("bound")?);
    let n = freq_hz.len();
    let opt = |k: &str| -> Result<Vec<f64>> {
        if obj.contains_key(k) {
            arr(k)
        } else {
            Ok(vec![f64::NAN; n])
        }
    };
    let (residual, sigma) = (opt("residual")?, opt("sigma")?);
    if [
        re.len(),
        im.len(),
        values.len(),
        residual.len(),
        sigma.len(),
    ]
    .iter()
    .any(|l| *l != n)
    {
        return Err(bad(
            "`freq_hz`, `nominal_re`, `nominal_im`, `bound`, `residual` and \
             `sigma` must have the same length",
        ));
    }
    if n == 0 || freq_hz.windows(2).any(|w| w[1] <= w[0]) {
        return Err(bad("`freq_hz` must be non-empty and increasing"));
    }
    if values.iter().any(|b| !(b.is_finite() && *b >= 0.0)) {
        return Err(bad("`bound` must hold finite, non-negative values"));
    }
    let nominal: Vec<C> = re.iter().zip(&im).map(|(r, i)| C::new(*r, *i)).collect();
    let additive = match form {
        Form::Additive => values,
        Form::Multiplicative => values
            .iter()
            .zip(&nominal)
            .map(|(b, p)| b * p.norm())
            .collect(),
    };
    Ok(Bound {
        form,
        confidence,
        sigma_factor: kappa,
        ts,
        freq_hz,
        nominal,
        residual,
        sigma,
        additive,
    })
}

/// The overbounding weight's model `W(z)` of an uncertainty JSON text, `None` when the file
/// has none. The weight must be SISO and discrete at the bound's `ts`.
///
/// # Errors
/// What [`from_json_str`] refuses; a `weight` without a valid `model`.
pub fn weight_from_json_str(text: &str) -> Result<Option<sd_model::StateSpace>> {
    let b = from_json_str(text)?;
    let v: serde_json::Value = serde_json::from_str(text).map_err(bad)?;
    let Some(w) = carrier(&v)?.get("weight") else {
        return Ok(None);
    };
    let m = w
        .get("model")
        .ok_or_else(|| bad("`weight` must hold a `model`"))?;
    let model = sd_model::model_from_json_str(&m.to_string())
        .map_err(|e| bad(format!("`weight.model`: {e}")))?;
    let at_ts = matches!(model.time(), sd_model::SampleTime::Discrete { ts }
        if (ts - b.ts).abs() <= 1e-9 * b.ts);
    if model.nu() != 1 || model.ny() != 1 || !at_ts {
        return Err(bad(format!(
            "`weight.model` must be SISO and discrete at the bound's ts = {} s",
            b.ts
        )));
    }
    Ok(Some(model))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn sample(form: Form) -> Bound {
        Bound {
            form,
            confidence: 0.95,
            sigma_factor: sigma_factor(0.95).unwrap(),
            ts: 1e-3,
            freq_hz: vec![1.0, 2.0, 3.0],
            nominal: vec![C::new(1.0, 0.5), C::new(-2.0, 0.0), C::new(0.0, 3.0)],
            residual: vec![0.1, 0.2, 0.3],
            sigma: vec![0.01, 0.02, 0.03],
            additive: vec![0.2, 0.3, 0.4],
        }
    }

    #[test]
    fn round_trip_and_strict_keys() {
        for form in [Form::Additive, Form::Multiplicative] {
            let b = sample(form);
            let back = from_json_str(&to_json_string(&b, None).unwrap()).unwrap();
            assert_eq!(back.form, form);
            assert_eq!(back.freq_hz, b.freq_hz);
            assert_eq!(back.nominal, b.nominal);
            for (x, y) in back.additive.iter().zip(&b.additive) {
                assert!((x - y).abs() <= 1e-15 * y);
            }
        }
        let text = to_json_string(&sample(Form::Additive), None).unwrap();
        let typo = text.replace("\"confidence\"", "\"confidance\"");
        let e = from_json_str(&typo).unwrap_err().to_string();
        assert!(e.contains("did you mean `confidence`"), "{e}");
        let short = text.replace("\"bound\":[0.2,", "\"bound\":[");
        assert!(from_json_str(&short)
            .unwrap_err()
            .to_string()
            .contains("same length"));
        let neg = text.replace("\"bound\":[0.2,", "\"bound\":[-0.2,");
        assert!(from_json_str(&neg).is_err());
        assert!(from_json_str("{").is_err());
        assert!(from_json_str(&text.replace("0.95", "1.5")).is_err());
    }

    #[test]
    fn a_model_carries_its_bound() {
        let b = sample(Form::Additive);
        let model = r#"{"type":"tf","ts":0.001,"num":[1.0],"den":[1.0,-0.5]}"#;
        assert!(!carries(model));
        let with = embed(model, &b, None).unwrap();
        assert!(carries(&with));
        // the model reader accepts it, the bound reads back
        let m = sd_model::model_from_json_str(&with).unwrap();
        assert_eq!(m.n(), 1);
        let back = from_json_str(&with).unwrap();
        assert_eq!(back.freq_hz, b.freq_hz);
        assert!(weight_from_json_str(&with).unwrap().is_none());
        // a model without one is refused with what to do
        let e = from_json_str(model).unwrap_err().to_string();
        assert!(e.contains("--embed"), "{e}");
        // not an object
        assert!(embed("[1, 2]", &b, None).is_err());
    }
}
