//! Measured experiments: the TOML manifest and the CSV data of docs/formats.md.
//!
//! The manifest lists `[[experiment]]` tables (`name`, `file`, `sample_rate_hz`, optional
//! `period_samples`, `skip_periods`, `reference`, `role`, and the `input` and `output` column
//! names). CSV files are read robustly: quoted headers, extra columns, trailing commas and empty
//! cells in unused columns are fine; only the named columns are parsed, and a bad cell there is
//! an error naming the file, line and column. Nothing depends on the signals' units or scale.
//!
//! The library never opens files: [`parse_manifest`] takes the manifest text and
//! [`Experiment::from_reader`] a reader of the CSV; the CLI and xtask do the I/O.

use crate::error::{IdentError, Result};
use std::io::Read;

/// Role of an experiment in a diagnosis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// The model is fitted here.
    Model,
    /// The model's prediction is checked here (default).
    Validation,
}

impl Role {
    /// The manifest's spelling: `"model"` or `"validation"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Model => "model",
            Role::Validation => "validation",
        }
    }
}

/// One `[[experiment]]` of a manifest.
#[derive(Debug, Clone, PartialEq)]
pub struct ExperimentSpec {
    /// Unique name.
    pub name: String,
    /// CSV file, relative to the manifest.
    pub file: String,
    /// Sample rate (Hz).
    pub sample_rate_hz: f64,
    /// Samples per period of a periodic excitation.
    pub period_samples: Option<usize>,
    /// Leading periods to drop (transient).
    pub skip_periods: usize,
    /// Column of the external excitation, if any.
    pub reference: Option<String>,
    /// Column of the plant input.
    pub input: String,
    /// Column of the measured output.
    pub output: String,
    /// Model or validation.
    pub role: Role,
    /// Further columns where the manifest lists several (`output = ["acc1", "acc2"]`):
    /// `input`, `output` and `reference` hold the first of each list, these the rest.
    pub extra: ExtraColumns,
}

/// The columns after the first of a manifest's lists (empty for a SISO experiment).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ExtraColumns {
    /// Inputs after `input`.
    pub inputs: Vec<String>,
    /// Outputs after `output`.
    pub outputs: Vec<String>,
    /// References after `reference` (one reference per input).
    pub references: Vec<String>,
}

impl ExperimentSpec {
    /// Every input column, `input` first.
    pub fn inputs(&self) -> Vec<&str> {
        std::iter::once(self.input.as_str())
            .chain(self.extra.inputs.iter().map(String::as_str))
            .collect()
    }

    /// Every output column, `output` first.
    pub fn outputs(&self) -> Vec<&str> {
        std::iter::once(self.output.as_str())
            .chain(self.extra.outputs.iter().map(String::as_str))
            .collect()
    }

    /// Every reference column (none in open loop).
    pub fn references(&self) -> Vec<&str> {
        self.reference
            .iter()
            .map(String::as_str)
            .chain(self.extra.references.iter().map(String::as_str))
            .collect()
    }

    /// Several inputs or outputs.
    pub fn is_mimo(&self) -> bool {
        !(self.extra.inputs.is_empty() && self.extra.outputs.is_empty())
    }
}

/// An experiment with its signals.
#[derive(Debug, Clone)]
pub struct Experiment {
    /// What the manifest says.
    pub spec: ExperimentSpec,
    /// Reference signal, if the manifest names one.
    pub r: Option<Vec<f64>>,
    /// Plant input.
    pub u: Vec<f64>,
    /// Measured output.
    pub y: Vec<f64>,
    /// The signals of [`ExperimentSpec::extra`]'s columns, in its order.
    pub extra: ExtraSignals,
}

/// The signals after the first of each list (empty for a SISO experiment).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ExtraSignals {
    /// Inputs after `u`.
    pub u: Vec<Vec<f64>>,
    /// Outputs after `y`.
    pub y: Vec<Vec<f64>>,
    /// References after `r`.
    pub r: Vec<Vec<f64>>,
}

impl Experiment {
    /// Every input signal, `u` first.
    pub fn inputs(&self) -> Vec<&[f64]> {
        std::iter::once(self.u.as_slice())
            .chain(self.extra.u.iter().map(Vec::as_slice))
            .collect()
    }

    /// Every output signal, `y` first.
    pub fn outputs(&self) -> Vec<&[f64]> {
        std::iter::once(self.y.as_slice())
            .chain(self.extra.y.iter().map(Vec::as_slice))
            .collect()
    }

    /// Every reference signal (none in open loop).
    pub fn references(&self) -> Vec<&[f64]> {
        self.r
            .iter()
            .map(Vec::as_slice)
            .chain(self.extra.r.iter().map(Vec::as_slice))
            .collect()
    }
}

/// The experiments of the manifest file `manifest` whose names pass `keep`, with their data
/// files read relative to the manifest's folder.
///
/// # Errors
/// [`IdentError::Format`] naming the file that cannot be read, the manifest's and the data
/// files' format errors.
pub fn load_experiments(
    manifest: &std::path::Path,
    keep: impl Fn(&str) -> bool,
) -> Result<Vec<Experiment>> {
    let unreadable = |path: &std::path::Path, e: std::io::Error| IdentError::Format {
        file: path.display().to_string(),
        detail: format!("cannot read: {e}"),
    };
    let text = std::fs::read_to_string(manifest).map_err(|e| unreadable(manifest, e))?;
    let specs = parse_manifest(&text)?;
    let base = manifest
        .parent()
        .map(|p| p.to_path_buf())
        .unwrap_or_default();
    let mut exps = Vec::new();
    for spec in specs.into_iter().filter(|s| keep(&s.name)) {
        let path = base.join(&spec.file);
        let file = std::fs::File::open(&path).map_err(|e| unreadable(&path, e))?;
        exps.push(Experiment::from_reader(
            spec,
            std::io::BufReader::new(file),
        )?);
    }
    Ok(exps)
}

/// The experiment named `name` of the manifest file `manifest` ([`load_experiments`]).
///
/// # Errors
/// As [`load_experiments`]; [`IdentError::InvalidArgument`] when no experiment has that name.
pub fn load_experiment(manifest: &std::path::Path, name: &str) -> Result<Experiment> {
    load_experiments(manifest, |n| n == name)?
        .pop()
        .ok_or_else(|| IdentError::InvalidArgument(format!("no experiment named `{name}`")))
}

fn fmt_err(detail: String) -> IdentError {
    IdentError::Format {
        file: "manifest".into(),
        detail,
    }
}

/// The keys of one `[[experiment]]` table.
pub const EXPERIMENT_KEYS: &[&str] = &[
    "name",
    "file",
    "sample_rate_hz",
    "period_samples",
    "skip_periods",
    "reference",
    "input",
    "output",
    "role",
];

/// Names other tools (and the testbed config) use for manifest keys.
const EXPERIMENT_ALIASES: &[(&str, &str)] = &[
    ("fs", "sample_rate_hz"),
    ("rate_hz", "sample_rate_hz"),
    ("period", "period_samples"),
];

/// Parses a manifest (docs/formats.md).
///
/// # Errors
/// TOML syntax (with line and column), an unknown key (with the closest allowed one), a
/// missing or mistyped field, duplicate names, a non-positive rate or period.
pub fn parse_manifest(text: &str) -> Result<Vec<ExperimentSpec>> {
    let doc: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| fmt_err(e.to_string().replace('\n', " ")))?;
    sd_model::keys::check_keys(
        doc.keys().map(String::as_str),
        &["experiment"],
        &[("experiments", "experiment")],
        "the manifest's top level",
    )
    .map_err(fmt_err)?;
    let list = doc
        .get("experiment")
        .and_then(|v| v.as_array())
        .ok_or_else(|| fmt_err("no [[experiment]] tables".into()))?;
    let mut out: Vec<ExperimentSpec> = Vec::with_capacity(list.len());
    for (i, item) in list.iter().enumerate() {
        let t = item
            .as_table()
            .ok_or_else(|| fmt_err(format!("experiment {} is not a table", i + 1)))?;
        let spec = parse_experiment(i, t)?;
        if out.iter().any(|e| e.name == spec.name) {
            return Err(fmt_err(format!(
                "experiment name `{}` is used twice",
                spec.name
            )));
        }
        out.push(spec);
    }
    Ok(out)
}

/// The `i`-th (0-based) `[[experiment]]` table.
fn parse_experiment(i: usize, t: &toml::Table) -> Result<ExperimentSpec> {
    let name = t.get("name").and_then(|v| v.as_str()).unwrap_or("?");
    sd_model::keys::check_keys(
        t.keys().map(String::as_str),
        EXPERIMENT_KEYS,
        EXPERIMENT_ALIASES,
        &format!("experiment {} (`{name}`)", i + 1),
    )
    .map_err(fmt_err)?;
    let ctx = |field: &str, what: &str| {
        fmt_err(format!("experiment {} ({name}): `{field}` {what}", i + 1))
    };
    let s = |field: &str| -> Result<String> {
        t.get(field)
            .and_then(|v| v.as_str())
            .map(str::to_string)
            .ok_or_else(|| ctx(field, "is missing or not a string"))
    };
    let opt_s = |field: &str| -> Result<Option<String>> {
        match t.get(field) {
            None => Ok(None),
            Some(v) => v
                .as_str()
                .map(|x| Some(x.to_string()))
                .ok_or_else(|| ctx(field, "must be a string")),
        }
    };
    let opt_u = |field: &str| -> Result<Option<usize>> {
        match t.get(field) {
            None => Ok(None),
            Some(v) => match v.as_integer() {
                Some(x) if x >= 0 => Ok(Some(x as usize)),
                _ => Err(ctx(field, "must be a non-negative integer")),
            },
        }
    };
    let rate = match t.get("sample_rate_hz") {
        Some(v) => v
            .as_float()
            .or_else(|| v.as_integer().map(|x| x as f64))
            .ok_or_else(|| ctx("sample_rate_hz", "must be a number"))?,
        None => return Err(ctx("sample_rate_hz", "is missing")),
    };
    if !(rate.is_finite() && rate > 0.0) {
        return Err(ctx("sample_rate_hz", "must be > 0"));
    }
    let period = opt_u("period_samples")?;
    if period == Some(0) {
        return Err(ctx("period_samples", "must be > 0"));
    }
    let role = match opt_s("role")?.as_deref() {
        None | Some("validation") => Role::Validation,
        Some("model") => Role::Model,
        Some(_) => return Err(ctx("role", "must be \"model\" or \"validation\"")),
    };
    let (inputs, outputs, references) = channel_columns(t, &ctx)?;
    Ok(ExperimentSpec {
        name: s("name")?,
        file: s("file")?,
        sample_rate_hz: rate,
        period_samples: period,
        skip_periods: opt_u("skip_periods")?.unwrap_or(0),
        reference: references.first().cloned(),
        input: inputs[0].clone(),
        output: outputs[0].clone(),
        role,
        extra: ExtraColumns {
            inputs: inputs[1..].to_vec(),
            outputs: outputs[1..].to_vec(),
            references: references.iter().skip(1).cloned().collect(),
        },
    })
}

/// The input, output and reference columns of an experiment table (a name or a non-empty
/// list each; inputs and outputs required): one reference per input when any, no column
/// named twice. `ctx(field, what)` makes the error.
fn channel_columns(
    t: &toml::Table,
    ctx: &dyn Fn(&str, &str) -> IdentError,
) -> Result<(Vec<String>, Vec<String>, Vec<String>)> {
    let columns = |field: &str, required: bool| -> Result<Vec<String>> {
        match t.get(field) {
            None if required => Err(ctx(field, "is missing")),
            None => Ok(Vec::new()),
            Some(toml::Value::String(x)) => Ok(vec![x.clone()]),
            Some(toml::Value::Array(a)) if !a.is_empty() => a
                .iter()
                .map(|v| v.as_str().map(str::to_string))
                .collect::<Option<Vec<String>>>()
                .ok_or_else(|| ctx(field, "must be a column name or a list of them")),
            Some(_) => Err(ctx(
                field,
                "must be a column name or a non-empty list of them",
            )),
        }
    };
    let (inputs, outputs, references) = (
        columns("input", true)?,
        columns("output", true)?,
        columns("reference", false)?,
    );
    if !references.is_empty() && references.len() != inputs.len() {
        return Err(ctx(
            "reference",
            &format!(
                "lists {} column(s) for {} input(s): give one reference per input (lists \
                 of different lengths)",
                references.len(),
                inputs.len()
            ),
        ));
    }
    let all: Vec<&String> = inputs.iter().chain(&outputs).chain(&references).collect();
    if let Some(dup) = all
        .iter()
        .enumerate()
        .find_map(|(i, c)| all[..i].contains(c).then_some(c))
    {
        return Err(ctx(
            "input/output/reference",
            &format!("name the column `{dup}` twice: each signal needs its own column"),
        ));
    }
    Ok((inputs, outputs, references))
}

/// Reads the named columns of a CSV with a header row (module documentation).
///
/// # Errors
/// A missing column (the message lists the header), a bad or empty cell in a named column
/// (file, line, column), no data rows.
pub fn read_columns<R: Read>(reader: R, file: &str, names: &[&str]) -> Result<Vec<Vec<f64>>> {
    Ok(read_table(reader, file, names, false)?.0)
}

/// Header names taken as a time column in seconds (case ignored) when no channel uses them.
pub const TIME_COLUMNS: [&str; 4] = ["t", "time", "time_s", "t_s"];

/// The named columns, and a time column's name and values when one was asked for and found.
type Table = (Vec<Vec<f64>>, Option<(String, Vec<f64>)>);

/// [`read_columns`], and with `time` also the first column named as in [`TIME_COLUMNS`] that
/// is not among `names` (its name and values; `None` without one).
fn read_table<R: Read>(reader: R, file: &str, names: &[&str], time: bool) -> Result<Table> {
    let ferr = |detail: String| IdentError::Format {
        file: file.to_string(),
        detail,
    };
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(reader);
    let header = rdr
        .headers()
        .map_err(|e| ferr(format!("cannot read the header row: {e}")))?
        .clone();
    // a quote after a space is not CSV quoting: strip such quotes from the names too
    let cols: Vec<&str> = header
        .iter()
        .map(|h| h.trim().trim_matches('"').trim())
        .collect();
    let time_col = time
        .then(|| {
            cols.iter().position(|c| {
                TIME_COLUMNS.iter().any(|t| c.eq_ignore_ascii_case(t)) && !names.contains(c)
            })
        })
        .flatten();
    let time_name = time_col.map(|i| cols[i].to_string());
    let all: Vec<&str> = names.iter().copied().chain(time_name.as_deref()).collect();
    let names = &all[..];
    let mut idx = Vec::with_capacity(names.len());
    for name in names {
        match cols.iter().position(|c| c == name) {
            Some(i) => idx.push(i),
            None => {
                return Err(ferr(format!(
                    "no column `{name}` in the header ({})",
                    cols.join(", ")
                )))
            }
        }
    }
    let mut out: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    let mut rec = csv::ByteRecord::new();
    let mut line = 1usize;
    loop {
        match rdr.read_byte_record(&mut rec) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => return Err(ferr(format!("line {}: {e}", line + 1))),
        }
        line = rec
            .position()
            .map(|p| p.line() as usize)
            .unwrap_or(line + 1);
        if rec.iter().all(|f| f.iter().all(u8::is_ascii_whitespace)) {
            continue; // blank line
        }
        for (k, &i) in idx.iter().enumerate() {
            let cell = rec.get(i).unwrap_or(b"");
            let text = std::str::from_utf8(cell).map(str::trim).unwrap_or("");
            let v: f64 = text.parse().map_err(|_| {
                ferr(format!(
                    "line {line}, column {} (`{}`): {}",
                    i + 1,
                    names[k],
                    if text.is_empty() {
                        "empty cell".to_string()
                    } else {
                        format!("`{text}` is not a number")
                    }
                ))
            })?;
            if !v.is_finite() {
                return Err(ferr(format!(
                    "line {line}, column {} (`{}`): {text} is not finite",
                    i + 1,
                    names[k]
                )));
            }
            out[k].push(v);
        }
    }
    if out.first().map(|c| c.is_empty()).unwrap_or(true) {
        return Err(ferr("no data rows".into()));
    }
    let t = match time_name {
        Some(name) => out.pop().map(|v| (name, v)),
        None => None,
    };
    Ok((out, t))
}

/// The rate a time column (seconds) implies, `(n − 1)/(t_last − t_first)`, against the
/// manifest's: more than 1 % apart (a rate in kHz given as Hz, a wrong column) is an error
/// naming both; a time column that does not increase is one too; a sample counter (steps of
/// exactly 1) is not checked.
fn check_time_column(spec: &ExperimentSpec, name: &str, t: &[f64]) -> Result<()> {
    let ferr = |detail: String| IdentError::Format {
        file: spec.file.clone(),
        detail,
    };
    if t.len() < 2 {
        return Ok(());
    }
    if let Some(k) = t.windows(2).position(|w| w[1] <= w[0]) {
        return Err(ferr(format!(
            "the time column `{name}` does not increase at data row {} ({} then {}): sort the \
             rows or name the column otherwise if it is no time",
            k + 2,
            t[k],
            t[k + 1]
        )));
    }
    // a sample counter (steps of exactly 1) says nothing of the rate
    if t.windows(2).all(|w| w[1] - w[0] == 1.0) {
        return Ok(());
    }
    let span = t[t.len() - 1] - t[0];
    let implied = (t.len() - 1) as f64 / span;
    let given = spec.sample_rate_hz;
    if (implied / given - 1.0).abs() > 0.01 {
        return Err(ferr(format!(
            "the time column `{name}` implies {implied:.6} Hz but sample_rate_hz = {given} \
             (kHz given as Hz?): correct sample_rate_hz in the manifest, or rename the column \
             if it is not the time in seconds"
        )));
    }
    Ok(())
}

impl Experiment {
    /// Reads an experiment's columns from its CSV.
    ///
    /// # Errors
    /// As [`read_columns`]; a period longer than the record.
    pub fn from_reader<R: Read>(spec: ExperimentSpec, reader: R) -> Result<Self> {
        let (ins, outs, refs) = (spec.inputs(), spec.outputs(), spec.references());
        let names: Vec<&str> = ins.iter().chain(&outs).chain(&refs).copied().collect();
        let (cols, time) = read_table(reader, &spec.file, &names, true)?;
        if let Some((name, t)) = &time {
            check_time_column(&spec, name, t)?;
        }
        let mut cols = cols.into_iter();
        let mut take = |n: usize| -> Vec<Vec<f64>> { cols.by_ref().take(n).collect() };
        let (mut u, mut y, mut r) = (take(ins.len()), take(outs.len()), take(refs.len()));
        let first = |v: &mut Vec<Vec<f64>>| (!v.is_empty()).then(|| v.remove(0));
        let (u0, y0, r0) = (first(&mut u), first(&mut y), first(&mut r));
        let u0 = u0.unwrap_or_default();
        check_periods(&spec, u0.len())?;
        Ok(Experiment {
            spec,
            r: r0,
            u: u0,
            y: y0.unwrap_or_default(),
            extra: ExtraSignals { u, y, r },
        })
    }

    /// An experiment from recorded arrays (no files): `period` samples per period (None:
    /// non-periodic), `skip_periods` transient periods, `r` the reference (None: open loop),
    /// the role [`Role::Validation`].
    ///
    /// # Errors
    /// [`IdentError::Data`] for arrays of different lengths, non-finite samples, a zero period
    /// or fewer samples than `period · (skip_periods + 1)`; [`IdentError::InvalidArgument`] for
    /// a sample rate that is not positive.
    pub fn from_arrays(
        name: &str,
        sample_rate_hz: f64,
        period: Option<usize>,
        skip_periods: usize,
        r: Option<Vec<f64>>,
        u: Vec<f64>,
        y: Vec<f64>,
    ) -> Result<Self> {
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(IdentError::InvalidArgument(format!(
                "sample rate {sample_rate_hz} Hz must be positive"
            )));
        }
        if u.len() != y.len() || r.as_ref().is_some_and(|r| r.len() != u.len()) {
            return Err(IdentError::Data(format!(
                "{name}: r, u and y must have the same length (u {}, y {}{})",
                u.len(),
                y.len(),
                r.as_ref()
                    .map_or(String::new(), |r| format!(", r {}", r.len()))
            )));
        }
        if u.iter()
            .chain(&y)
            .chain(r.iter().flatten())
            .any(|v| !v.is_finite())
        {
            return Err(IdentError::Data(format!(
                "{name}: a sample is NaN or infinite"
            )));
        }
        if period == Some(0) {
            return Err(IdentError::Data(format!("{name}: a period of 0 samples")));
        }
        let spec = ExperimentSpec {
            name: name.into(),
            file: name.into(),
            sample_rate_hz,
            period_samples: period,
            skip_periods,
            reference: r.as_ref().map(|_| "r".into()),
            input: "u".into(),
            output: "y".into(),
            role: Role::Validation,
            extra: ExtraColumns::default(),
        };
        check_periods(&spec, u.len())?;
        Ok(Experiment {
            spec,
            r,
            u,
            y,
            extra: ExtraSignals::default(),
        })
    }
}

/// A periodic record must hold its transient periods and one steady period.
fn check_periods(spec: &ExperimentSpec, rows: usize) -> Result<()> {
    if let Some(p) = spec.period_samples {
        let needed = p * (spec.skip_periods + 1);
        if rows < needed {
            return Err(IdentError::Data(format!(
                "{}: {rows} rows, but period_samples = {p} and skip_periods = {} need at least \
                 {needed}",
                spec.file, spec.skip_periods
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    const MANIFEST: &str = r#"
[[experiment]]
name = "fast"
file = "fast.csv"
sample_rate_hz = 5000.0
period_samples = 4
skip_periods = 1
reference = "r"
input = "u"
output = "y"
role = "model"

[[experiment]]
name = "slow"
file = "slow.csv"
sample_rate_hz = 1000
input = "u"
output = "y"
"#;

    #[test]
    fn manifest_and_messy_csv() {
        let specs = parse_manifest(MANIFEST).unwrap();
        assert_eq!(specs.len(), 2);
        assert_eq!(specs[0].role, Role::Model);
        assert_eq!(specs[1].role, Role::Validation);
        assert_eq!(specs[1].sample_rate_hz, 1000.0);
        // quoted header, extra column, trailing comma, empty cell in an unused column
        let csv = "\"t\", \"u\",\"y\" ,r,extra,\n0,1,2,3,,\n1,1.5,2.5,3.5,x,\n\n2,1e-3,-2,0,,\n3,1,1,1,,\n4,1,1,1,,\n5,1,1,1,,\n6,1,1,1,,\n7,1,1,1,,\n";
        let e = Experiment::from_reader(specs[0].clone(), csv.as_bytes()).unwrap();
        assert_eq!(e.u.len(), 8);
        assert_eq!(e.u[2], 1e-3);
        assert_eq!(e.r.as_ref().unwrap()[1], 3.5);
    }

    #[test]
    fn a_time_column_checks_the_sample_rate() {
        let spec = |rate: f64| {
            let mut s = parse_manifest(MANIFEST).unwrap().remove(1);
            s.sample_rate_hz = rate;
            s
        };
        // 5 kHz rows: 0.0002 s apart (the testbed's `{:e}` format)
        let csv: String = std::iter::once("t,u,y\n".to_string())
            .chain((0..50).map(|i| format!("{:e},{},{}\n", i as f64 * 2e-4, i, 2 * i)))
            .collect();
        assert!(Experiment::from_reader(spec(5000.0), csv.as_bytes()).is_ok());
        let e = Experiment::from_reader(spec(5.0), csv.as_bytes())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("implies 5000.000000 Hz") && e.contains("sample_rate_hz = 5"),
            "{e}"
        );
        // a column named `time` that goes backwards
        let back = "time,u,y\n0.0,1,2\n0.001,1,2\n0.0005,1,2\n";
        let e = Experiment::from_reader(spec(1000.0), back.as_bytes())
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not increase at data row 3"), "{e}");
        // without a time column nothing is checked
        let plain = "u,y\n1,2\n3,4\n";
        assert!(Experiment::from_reader(spec(5.0), plain.as_bytes()).is_ok());
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let specs = parse_manifest(MANIFEST).unwrap();
        let csv = "u,y,r\n1,2,3\n1,,3\n";
        let e = Experiment::from_reader(specs[0].clone(), csv.as_bytes())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("fast.csv")
                && e.contains("line 3")
                && e.contains("column 2")
                && e.contains("empty"),
            "{e}"
        );
        let csv = "u,y,r\n1,2,abc\n";
        let e = Experiment::from_reader(specs[0].clone(), csv.as_bytes())
            .unwrap_err()
            .to_string();
        assert!(e.contains("`abc`"), "{e}");
        let e = read_columns("a,b\n1,2\n".as_bytes(), "f.csv", &["c"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("no column `c`"), "{e}");
        assert!(parse_manifest("[[experiment]]\nname = 1\n").is_err());
        assert!(parse_manifest(&MANIFEST.replace("1000", "-1")).is_err());
        assert!(parse_manifest(&MANIFEST.replace("\"slow\"", "\"fast\""))
            .unwrap_err()
            .to_string()
            .contains("twice"));
        assert!(parse_manifest("[[experiment\n")
            .unwrap_err()
            .to_string()
            .contains("line"));
    }
}
