//! JSON (de)serialisation of models and FRDs in the formats of docs/formats.md.
//!
//! Model: `{"type": "ss", "ts": 0.0002 | null, "a": [[..]], "b": [[..]], "c": [[..]], "d": [[..]],
//! "name"?, "inputs"?, "outputs"?}` with row-major arrays of rows; `d` fixes ny and nu. A SISO
//! transfer function `{"type": "tf", "ts": .., "num": [..], "den": [..]}` is read too (realised
//! in observable canonical form). FRD: `{"type": "frd", "ts": .., "freq_hz": [..],
//! "re": [f][o][i], "im": [f][o][i], "var"?: [f][o][i]}`.

use crate::error::{ModelError, Result};
use crate::frd::Frd;
use crate::ss::StateSpace;
use crate::tf::TransferFunction;
use crate::time::SampleTime;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};

#[derive(Serialize, Deserialize)]
struct SsJson {
    #[serde(rename = "type", default = "ss_kind")]
    kind: String,
    ts: Option<f64>,
    a: Vec<Vec<f64>>,
    b: Vec<Vec<f64>>,
    c: Vec<Vec<f64>>,
    d: Vec<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    inputs: Option<Vec<String>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    outputs: Option<Vec<String>>,
}

/// A model file without `"type"` is a state-space model.
fn ss_kind() -> String {
    "ss".into()
}

#[derive(Deserialize)]
struct TfJson {
    ts: Option<f64>,
    name: Option<String>,
    num: Vec<f64>,
    den: Vec<f64>,
}

#[derive(Deserialize)]
struct FrdJson {
    #[serde(rename = "type")]
    kind: String,
    ts: Option<f64>,
    freq_hz: Vec<f64>,
    re: Vec<Vec<Vec<f64>>>,
    im: Vec<Vec<Vec<f64>>>,
    var: Option<Vec<Vec<Vec<f64>>>>,
}

fn parse_err(what: &str, e: impl std::fmt::Display) -> ModelError {
    ModelError::Parse {
        what: what.into(),
        detail: e.to_string(),
    }
}

fn rows_to_matrix(
    rows: &[Vec<f64>],
    nrows: usize,
    ncols: usize,
    what: &str,
) -> Result<DMatrix<f64>> {
    // A matrix with zero columns may be written as [] or as nrows empty rows.
    if ncols == 0 && rows.is_empty() {
        return Ok(DMatrix::zeros(nrows, 0));
    }
    if rows.len() != nrows {
        return Err(ModelError::dim(
            format!("\"{what}\" (rows)"),
            nrows,
            rows.len(),
        ));
    }
    for (i, r) in rows.iter().enumerate() {
        if r.len() != ncols {
            return Err(ModelError::dim(
                format!("\"{what}\" row {i} (ragged or wrong width)"),
                ncols,
                r.len(),
            ));
        }
    }
    Ok(DMatrix::from_fn(nrows, ncols, |i, j| rows[i][j]))
}

fn matrix_to_rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| m.row(i).iter().cloned().collect())
        .collect()
}

/// `uncertainty` (in every form) is the model's error bound, read by `sd-uncertainty`
/// (ignored here).
const SS_KEYS: &[&str] = &[
    "type",
    "ts",
    "a",
    "b",
    "c",
    "d",
    "name",
    "inputs",
    "outputs",
    "uncertainty",
];
const TF_KEYS: &[&str] = &["type", "ts", "num", "den", "name", "uncertainty"];
/// `warnings` is what `sdctl frf` found in the data, `eval_path` how `sdctl freqresp`
/// evaluated a model, `covariance` the full covariance of a MIMO estimate (`sdctl frf
/// --covariance`), `var_noise`, `var_distortion` and `distortion` the parts of `var` and how
/// the distortion was measured (`sdctl frf`; all informational, ignored on reading).
const FRD_KEYS: &[&str] = &[
    "type",
    "ts",
    "freq_hz",
    "re",
    "im",
    "var",
    "warnings",
    "covariance",
    "var_noise",
    "var_distortion",
    "distortion",
    "eval_path",
    "uncertainty",
];
/// Names other tools use for the sampling period.
const TS_ALIASES: &[(&str, &str)] = &[("dt", "ts"), ("Ts", "ts"), ("sample_time", "ts")];

/// A JSON syntax error, with NaN and infinities named (JSON has no literal for them).
fn syntax_err(what: &str, text: &str, e: serde_json::Error) -> ModelError {
    let line: Vec<char> = text
        .lines()
        .nth(e.line().saturating_sub(1))
        .unwrap_or("")
        .chars()
        .collect();
    // the token may start one column earlier, at its sign
    let mut col = e.column().saturating_sub(1).min(line.len());
    if col > 0 && matches!(line[col - 1], '-' | '+') {
        col -= 1;
    }
    let at: String = line[col..].iter().take(9).collect();
    let at = at.trim_start_matches(['-', '+']).to_ascii_lowercase();
    if at.starts_with("nan") || at.starts_with("inf") {
        return parse_err(
            what,
            format!(
                "line {} column {}: NaN and infinite values are not allowed; every number must \
                 be finite",
                e.line(),
                col + 1
            ),
        );
    }
    parse_err(what, e)
}

/// The top-level object of a model or FRD file with its keys checked against `allowed`, and
/// `ts` present (a number of seconds, or `null` for continuous time; `0` is explained).
fn checked_object<'a>(
    v: &'a serde_json::Value,
    what: &str,
    allowed: &[&str],
) -> Result<&'a serde_json::Map<String, serde_json::Value>> {
    let obj = v
        .as_object()
        .ok_or_else(|| parse_err(what, "the file must hold one JSON object"))?;
    crate::keys::check_keys(
        obj.keys().map(String::as_str),
        allowed,
        TS_ALIASES,
        "the file",
    )
    .map_err(|m| parse_err(what, m))?;
    match obj.get("ts") {
        None => Err(parse_err(
            what,
            "the key `ts` is missing: give the sampling period in seconds, or `\"ts\": null` \
             for a continuous-time model",
        )),
        Some(t) if t.as_f64() == Some(0.0) => Err(parse_err(
            what,
            "`\"ts\": 0` is not a sampling period: write `\"ts\": null` for continuous time \
             (python-control's dt = 0) or the sampling period in seconds",
        )),
        Some(_) => Ok(obj),
    }
}

/// The first entry of the numeric arrays under `keys` that is not a number, named with its
/// position — a complex entry (`{"re", "im"}`, `"1+2j"`, `[re, im]`) said to be one: a model
/// has real coefficients, and an imaginary part is never dropped.
fn non_real_entry(
    obj: &serde_json::Map<String, serde_json::Value>,
    keys: &[&str],
) -> Option<String> {
    fn walk(v: &serde_json::Value, path: &mut Vec<usize>, depth: usize) -> Option<String> {
        match v {
            serde_json::Value::Number(_) => None,
            serde_json::Value::Array(items) if depth > 0 => {
                items.iter().enumerate().find_map(|(i, item)| {
                    path.push(i);
                    let found = walk(item, path, depth - 1);
                    path.pop();
                    found
                })
            }
            other => {
                let complex = match other {
                    serde_json::Value::Object(m) => m.contains_key("re") || m.contains_key("im"),
                    serde_json::Value::String(t) => t.contains('j') || t.contains('i'),
                    serde_json::Value::Array(p) => p.len() == 2 && p.iter().all(|x| x.is_number()),
                    _ => false,
                };
                let at: Vec<String> = path.iter().map(|i| format!("[{i}]")).collect();
                Some(format!(
                    "{} is {other}{}",
                    at.join(""),
                    if complex {
                        ", a complex number: a model's coefficients must be real (refused, not \
                         made real by dropping the imaginary part)"
                    } else {
                        ", not a number"
                    }
                ))
            }
        }
    }
    keys.iter().find_map(|k| {
        let v = obj.get(*k)?;
        let depth = if matches!(*k, "num" | "den") { 1 } else { 2 };
        walk(v, &mut Vec::new(), depth).map(|m| format!("`{k}`{m}"))
    })
}

/// Reads a model (state space, or SISO transfer function) from JSON text.
///
/// # Errors
/// Syntax (NaN and infinities named), an unknown key (with the closest allowed one), a missing
/// `ts` or `ts = 0`, wrong shapes, an invalid model.
pub fn model_from_json_str(text: &str) -> Result<StateSpace> {
    let v: serde_json::Value =
        serde_json::from_str(text).map_err(|e| syntax_err("model JSON", text, e))?;
    let kind = match v.get("type") {
        None => "ss",
        Some(t) => t
            .as_str()
            .ok_or_else(|| parse_err("model JSON", "\"type\" must be \"ss\" or \"tf\""))?,
    };
    match kind {
        "ss" => {
            let obj = checked_object(&v, "state-space model JSON", SS_KEYS)?;
            if let Some(m) = non_real_entry(obj, &["a", "b", "c", "d"]) {
                return Err(parse_err("state-space model JSON", m));
            }
            let s: SsJson =
                serde_json::from_value(v).map_err(|e| parse_err("state-space model JSON", e))?;
            // D fixes the shape; an empty D (`[]`: no outputs, or `[[], …]`: no inputs) leaves
            // the count it cannot show to B's width and C's rows
            let n = s.a.len();
            let ny = if s.d.is_empty() { s.c.len() } else { s.d.len() };
            let nu = match s.d.first() {
                Some(r) if !r.is_empty() => r.len(),
                _ => s.b.first().map_or(0, |r| r.len()),
            };
            let time = SampleTime::from_option(s.ts)?;
            let a = rows_to_matrix(&s.a, n, n, "a")?;
            let b = rows_to_matrix(&s.b, n, nu, "b")?;
            let c = rows_to_matrix(&s.c, ny, n, "c")?;
            let d = rows_to_matrix(&s.d, ny, nu, "d")?;
            let mut sys = StateSpace::new(a, b, c, d, time)?;
            if let Some(name) = s.name {
                sys = sys.with_name(name);
            }
            sys.with_signal_names(s.inputs, s.outputs)
        }
        "tf" => {
            let obj = checked_object(&v, "transfer-function JSON", TF_KEYS)?;
            if let Some(m) = non_real_entry(obj, &["num", "den"]) {
                return Err(parse_err("transfer-function JSON", m));
            }
            let t: TfJson =
                serde_json::from_value(v).map_err(|e| parse_err("transfer-function JSON", e))?;
            let sys =
                TransferFunction::new(t.num, t.den, SampleTime::from_option(t.ts)?)?.to_ss()?;
            Ok(match t.name {
                Some(n) => sys.with_name(n),
                None => sys,
            })
        }
        other => Err(parse_err(
            "model JSON",
            format!("unknown \"type\": \"{other}\" (expected \"ss\" or \"tf\")"),
        )),
    }
}

/// Reads a model from a reader.
pub fn read_model<R: Read>(mut r: R) -> Result<StateSpace> {
    let mut s = String::new();
    r.read_to_string(&mut s)
        .map_err(|e| parse_err("model JSON", e))?;
    model_from_json_str(&s)
}

/// Serialises a model to a JSON string.
pub fn model_to_json_string(sys: &StateSpace) -> Result<String> {
    let s = SsJson {
        kind: "ss".into(),
        ts: sys.ts(),
        a: matrix_to_rows(sys.a()),
        b: matrix_to_rows(sys.b()),
        c: matrix_to_rows(sys.c()),
        d: matrix_to_rows(sys.d()),
        name: sys.name().map(String::from),
        inputs: sys.input_names().map(|v| v.to_vec()),
        outputs: sys.output_names().map(|v| v.to_vec()),
    };
    serde_json::to_string(&s).map_err(|e| parse_err("model", e))
}

/// Writes a model as JSON.
pub fn write_model<W: Write>(sys: &StateSpace, mut w: W) -> Result<()> {
    let s = model_to_json_string(sys)?;
    w.write_all(s.as_bytes())
        .map_err(|e| parse_err("model output", e))
}

/// Reads an FRD from JSON text.
///
/// # Errors
/// As [`model_from_json_str`], for the FRD keys.
pub fn frd_from_json_str(text: &str) -> Result<Frd> {
    let v: serde_json::Value =
        serde_json::from_str(text).map_err(|e| syntax_err("FRD JSON", text, e))?;
    checked_object(&v, "FRD JSON", FRD_KEYS)?;
    let f: FrdJson = serde_json::from_value(v).map_err(|e| parse_err("FRD JSON", e))?;
    if f.kind != "frd" {
        return Err(parse_err(
            "FRD JSON",
            format!("\"type\" is \"{}\", expected \"frd\"", f.kind),
        ));
    }
    let nf = f.freq_hz.len();
    if f.re.len() != nf || f.im.len() != nf {
        return Err(ModelError::dim(
            "FRD \"re\"/\"im\" (one matrix per frequency)",
            nf,
            format!("{}/{}", f.re.len(), f.im.len()),
        ));
    }
    let ny = f.re.first().map(|m| m.len()).unwrap_or(1);
    let nu =
        f.re.first()
            .and_then(|m| m.first())
            .map(|r| r.len())
            .unwrap_or(1);
    let mut resp = Vec::with_capacity(nf);
    for k in 0..nf {
        let re = rows_to_matrix(&f.re[k], ny, nu, &format!("re[{k}]"))?;
        let im = rows_to_matrix(&f.im[k], ny, nu, &format!("im[{k}]"))?;
        resp.push(DMatrix::from_fn(ny, nu, |i, j| {
            C::new(re[(i, j)], im[(i, j)])
        }));
    }
    let var = match &f.var {
        None => None,
        Some(v) => {
            if v.len() != nf {
                return Err(ModelError::dim(
                    "FRD \"var\" (one matrix per frequency)",
                    nf,
                    v.len(),
                ));
            }
            Some(
                v.iter()
                    .enumerate()
                    .map(|(k, m)| rows_to_matrix(m, ny, nu, &format!("var[{k}]")))
                    .collect::<Result<Vec<_>>>()?,
            )
        }
    };
    Frd::new(f.freq_hz, resp, var, SampleTime::from_option(f.ts)?)
}

/// Streams `[f][o][i]` arrays of a per-frequency matrix list without building nested vectors.
struct Cube<'a, T, F: Fn(&T) -> f64> {
    mats: &'a [DMatrix<T>],
    f: F,
}

struct Rows<'a, T, F: Fn(&T) -> f64> {
    m: &'a DMatrix<T>,
    f: &'a F,
}

struct Row<'a, T, F: Fn(&T) -> f64> {
    m: &'a DMatrix<T>,
    i: usize,
    f: &'a F,
}

impl<T: nalgebra::Scalar, F: Fn(&T) -> f64> Serialize for Cube<'_, T, F> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_seq(self.mats.iter().map(|m| Rows { m, f: &self.f }))
    }
}

impl<T: nalgebra::Scalar, F: Fn(&T) -> f64> Serialize for Rows<'_, T, F> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_seq((0..self.m.nrows()).map(|i| Row {
            m: self.m,
            i,
            f: self.f,
        }))
    }
}

impl<T: nalgebra::Scalar, F: Fn(&T) -> f64> Serialize for Row<'_, T, F> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_seq((0..self.m.ncols()).map(|j| (self.f)(&self.m[(self.i, j)])))
    }
}

#[derive(Serialize)]
#[serde(bound = "")]
struct FrdOut<'a, FR: Fn(&C) -> f64, FI: Fn(&C) -> f64, FV: Fn(&f64) -> f64> {
    #[serde(rename = "type")]
    kind: &'static str,
    ts: Option<f64>,
    freq_hz: &'a [f64],
    re: Cube<'a, C, FR>,
    im: Cube<'a, C, FI>,
    #[serde(skip_serializing_if = "Option::is_none")]
    var: Option<Cube<'a, f64, FV>>,
}

/// Serialises an FRD to a JSON string (streamed: no intermediate nested vectors).
pub fn frd_to_json_string(frd: &Frd) -> Result<String> {
    let out = FrdOut {
        kind: "frd",
        ts: frd.time().ts(),
        freq_hz: frd.freq_hz(),
        re: Cube {
            mats: frd.response(),
            f: |v: &C| v.re,
        },
        im: Cube {
            mats: frd.response(),
            f: |v: &C| v.im,
        },
        var: frd.variance().map(|v| Cube {
            mats: v,
            f: |x: &f64| *x,
        }),
    };
    // sized up front (about 25 bytes per number): a 200 000-point FRD is megabytes, and a
    // growing buffer would copy and fault it in several times
    let entries = frd.shape().0 * frd.shape().1;
    let numbers = frd.len() * (1 + entries * if frd.variance().is_some() { 3 } else { 2 });
    let mut buf = Vec::with_capacity(64 + 25 * numbers);
    serde_json::to_writer(&mut buf, &out).map_err(|e| parse_err("FRD", e))?;
    String::from_utf8(buf).map_err(|e| parse_err("FRD", e))
}

/// The FRD JSON of a flat response — point `k`'s `ny·nu` entries at `k·ny·nu`, column-major
/// ([`crate::FreqRespEvaluator::eval_many_flat`]) — as byte chunks to be written in order, the
/// numbers formatted in parallel: the same text as [`frd_to_json_string`] of that FRD (no
/// variance), with `extra` (e.g. `,"eval_path":"hessenberg"`, empty for none) before the closing
/// brace. For large FRDs (`sdctl freqresp`): no per-point matrices, no single growing buffer.
///
/// # Errors
/// A response whose length is not `freq_hz.len()·ny·nu`, or that is not finite (as
/// [`Frd::new`] refuses it).
pub fn frd_json_chunks(
    freq_hz: &[f64],
    (ny, nu): (usize, usize),
    resp: &[C],
    ts: Option<f64>,
    extra: &str,
) -> Result<Vec<Vec<u8>>> {
    use rayon::prelude::*;
    let m = ny * nu;
    if resp.len() != freq_hz.len() * m {
        return Err(crate::error::ModelError::dim(
            "flat FRD response (ny·nu per frequency)",
            freq_hz.len() * m,
            resp.len(),
        ));
    }
    if let Some(k) = resp
        .iter()
        .position(|v| !(v.re.is_finite() && v.im.is_finite()))
    {
        return Err(crate::frd::non_finite_response(freq_hz[k / m]));
    }
    const POINTS: usize = 8192;
    let num = |buf: &mut Vec<u8>, x: f64| {
        // serde_json's own number text (null for a non-finite value); writing into a Vec
        // cannot fail
        let _ = serde_json::to_writer(&mut *buf, &x);
    };
    // one chunk of points: ",v,v,…" (the leading comma dropped on the first chunk)
    let numbers = |part: &(dyn Fn(usize, &mut Vec<u8>) + Sync)| -> Vec<Vec<u8>> {
        (0..freq_hz.len().div_ceil(POINTS))
            .into_par_iter()
            .map(|c| {
                let (lo, hi) = (c * POINTS, ((c + 1) * POINTS).min(freq_hz.len()));
                let mut buf = Vec::with_capacity((hi - lo) * (4 + 25 * m.max(1)));
                for k in lo..hi {
                    if k > 0 {
                        buf.push(b',');
                    }
                    part(k, &mut buf);
                }
                buf
            })
            .collect()
    };
    let cube = |im: bool| {
        numbers(&|k, buf: &mut Vec<u8>| {
            buf.push(b'[');
            for i in 0..ny {
                if i > 0 {
                    buf.push(b',');
                }
                buf.push(b'[');
                for j in 0..nu {
                    if j > 0 {
                        buf.push(b',');
                    }
                    let v = resp[k * m + j * ny + i];
                    num(buf, if im { v.im } else { v.re });
                }
                buf.push(b']');
            }
            buf.push(b']');
        })
    };
    let mut head = br#"{"type":"frd","ts":"#.to_vec();
    match ts {
        Some(t) => num(&mut head, t),
        None => head.extend_from_slice(b"null"),
    }
    head.extend_from_slice(br#","freq_hz":["#);
    let mut out = vec![head];
    out.extend(numbers(&|k, buf: &mut Vec<u8>| num(buf, freq_hz[k])));
    out.push(br#"],"re":["#.to_vec());
    out.extend(cube(false));
    out.push(br#"],"im":["#.to_vec());
    out.extend(cube(true));
    out.push(format!("]{extra}}}").into_bytes());
    Ok(out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn empty_matrices_are_refused_or_shaped_never_filled() {
        // B and C empty beside a one-state A and a 1×1 D: refused, not filled with zeros
        let e = model_from_json_str(
            r#"{"type": "ss", "a": [[1.0]], "b": [], "c": [], "d": [[1.0]], "ts": null}"#,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("\"b\" (rows)"), "{e}");
        // a model without outputs (C 0×n, D 0×m) is legal: its inputs come from B
        let s = model_from_json_str(
            r#"{"type": "ss", "a": [[-1.0]], "b": [[1.0, 2.0]], "c": [], "d": [], "ts": null}"#,
        )
        .unwrap();
        assert_eq!((s.n(), s.nu(), s.ny()), (1, 2, 0));
        let back = model_from_json_str(&model_to_json_string(&s).unwrap()).unwrap();
        assert_eq!((back.nu(), back.ny()), (2, 0));
        // without inputs: D written as one empty row per output
        let s = model_from_json_str(
            r#"{"type": "ss", "a": [[-1.0]], "b": [[]], "c": [[3.0]], "d": [[]], "ts": null}"#,
        )
        .unwrap();
        assert_eq!((s.nu(), s.ny()), (0, 1));
    }

    #[test]
    fn complex_entries_are_refused_by_name() {
        for (entry, at) in [
            (r#"{"re": 1.0, "im": 0.5}"#, "`a`[0][1]"),
            (r#""1+0.5j""#, "`a`[0][1]"),
            ("[1.0, 0.5]", "`a`[0][1]"),
        ] {
            let txt = format!(
                r#"{{"ts": null, "a": [[0.0, {entry}], [1.0, 0.0]], "b": [[1], [0]], "c": [[1, 0]], "d": [[0]]}}"#
            );
            let e = model_from_json_str(&txt).unwrap_err().to_string();
            assert!(e.contains(at) && e.contains("a complex number"), "{e}");
        }
        let e =
            model_from_json_str(r#"{"type":"tf","ts":null,"num":[1],"den":[1,{"re":1,"im":2}]}"#)
                .unwrap_err()
                .to_string();
        assert!(e.contains("`den`[1]") && e.contains("complex"), "{e}");
        let e = model_from_json_str(r#"{"ts":null,"a":[[null]],"b":[[1]],"c":[[1]],"d":[[0]]}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`a`[0][0] is null, not a number"), "{e}");
    }

    #[test]
    fn roundtrip_and_static_gain() {
        let txt = r#"{"type":"ss","ts":0.001,"a":[[0.5]],"b":[[1.0]],"c":[[2.0]],"d":[[0.0]],"name":"x"}"#;
        let m = model_from_json_str(txt).unwrap();
        let back = model_from_json_str(&model_to_json_string(&m).unwrap()).unwrap();
        assert_eq!(m, back);
        let g = model_from_json_str(
            r#"{"type":"ss","ts":null,"a":[],"b":[],"c":[[],[]],"d":[[1,2],[3,4]]}"#,
        )
        .unwrap();
        assert_eq!((g.n(), g.ny(), g.nu()), (0, 2, 2));
        let tf = model_from_json_str(r#"{"type":"tf","ts":null,"num":[1],"den":[1,2,1]}"#).unwrap();
        assert_eq!(tf.n(), 2);
    }

    /// The chunked writer gives the streamed writer's text, byte for byte, on a 2×3 FRD of
    /// 20 000 points (three chunks), and on an empty one; a wrong length and a non-finite
    /// response are refused.
    #[test]
    fn chunked_frd_json_equals_the_streamed_one() {
        let n = 20_000;
        let f: Vec<f64> = (0..n).map(|k| 0.1 + k as f64 * 0.37).collect();
        let resp: Vec<DMatrix<C>> = (0..n)
            .map(|k| {
                DMatrix::from_fn(2, 3, |i, j| {
                    C::new(
                        (k * (i + 1)) as f64 / 7.0,
                        -((j + 2) as f64).powi(k as i32 % 40),
                    )
                })
            })
            .collect();
        let frd = Frd::new(
            f.clone(),
            resp.clone(),
            None,
            SampleTime::discrete(2e-4).unwrap(),
        )
        .unwrap();
        let flat: Vec<C> = resp.iter().flat_map(|m| m.as_slice().to_vec()).collect();
        let chunks = frd_json_chunks(&f, (2, 3), &flat, Some(2e-4), ",\"x\":1").unwrap();
        let text: Vec<u8> = chunks.concat();
        let mut want = frd_to_json_string(&frd).unwrap();
        want.pop();
        want.push_str(",\"x\":1}");
        assert_eq!(String::from_utf8(text).unwrap(), want);
        let empty = frd_json_chunks(&[], (1, 1), &[], None, "")
            .unwrap()
            .concat();
        let e = Frd::new(vec![], vec![], None, SampleTime::Continuous).unwrap();
        assert_eq!(
            String::from_utf8(empty).unwrap(),
            frd_to_json_string(&e).unwrap()
        );
        assert!(frd_json_chunks(&f, (2, 2), &flat, None, "").is_err());
        // a non-finite response is refused as Frd::new refuses it, naming its frequency
        let mut bad = flat.clone();
        bad[6 * 5 + 2] = C::new(f64::INFINITY, 0.0);
        let e = frd_json_chunks(&f, (2, 3), &bad, None, "")
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("at {} Hz", f[5])), "{e}");
    }

    #[test]
    fn frd_roundtrip_with_variance() {
        let r = vec![DMatrix::from_row_slice(1, 2, &[C::new(1.0, -2.0), C::new(0.5, 0.25)]); 3];
        let v = Some(vec![DMatrix::from_row_slice(1, 2, &[0.1, 0.2]); 3]);
        let f = Frd::new(
            vec![1.0, 2.0, 3.0],
            r,
            v,
            SampleTime::discrete(0.001).unwrap(),
        )
        .unwrap();
        let txt = frd_to_json_string(&f).unwrap();
        assert!(txt.contains("\"re\":[[[1.0,0.5]],"), "{txt}");
        assert_eq!(frd_from_json_str(&txt).unwrap(), f);
    }
}
