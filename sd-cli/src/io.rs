//! File input and atomic output for sdctl.

use sd_model::{ModelError, StateSpace};
use std::io::Read;
use std::path::Path;

/// A failure with its exit code (2: the input's fault, 1: numerical).
#[derive(Debug)]
pub struct CliError {
    pub code: u8,
    pub message: String,
}

impl CliError {
    pub fn input(msg: impl Into<String>) -> Self {
        CliError {
            code: 2,
            message: msg.into(),
        }
    }
    /// A numerical failure (exit 1).
    pub fn numerical(msg: impl Into<String>) -> Self {
        CliError {
            code: 1,
            message: msg.into(),
        }
    }
}

/// A library error with its exit code: numerical failures on valid input (each error type's
/// `is_numerical`) exit 1, everything else is the input's fault (2).
fn classify(context: &str, e: &dyn std::fmt::Display, numerical: bool) -> CliError {
    CliError {
        code: if numerical { 1 } else { 2 },
        message: format!("{context}: {e}"),
    }
}

/// Maps an `sd-model` error.
pub fn from_model(context: &str, e: ModelError) -> CliError {
    classify(context, &e, e.is_numerical())
}

/// Maps an `sd-multirate` error.
pub fn from_multirate(context: &str, e: sd_multirate::MultirateError) -> CliError {
    classify(context, &e, e.is_numerical())
}

/// Maps an `sd-hinf` error ("no stabilizing solution", a property of the problem given, is
/// the input's).
pub fn from_hinf(context: &str, e: sd_hinf::HinfError) -> CliError {
    classify(context, &e, e.is_numerical())
}

/// Maps an `sd-ident` error.
pub fn from_ident(context: &str, e: sd_ident::IdentError) -> CliError {
    classify(context, &e, e.is_numerical())
}

/// Maps an `sd-analysis` error.
pub fn from_analysis(context: &str, e: sd_analysis::AnalysisError) -> CliError {
    classify(context, &e, e.is_numerical())
}

/// Maps an `sd-testbed` error.
pub fn from_testbed(context: &str, e: sd_testbed::TestbedError) -> CliError {
    classify(context, &e, e.is_numerical())
}

/// Maps an `sd-diagnose` error.
pub fn from_diagnose(context: &str, e: sd_diagnose::DiagnoseError) -> CliError {
    classify(context, &e, e.is_numerical())
}

/// Reads a file (or stdin for "-") to a string.
pub fn read_text(path: &str) -> Result<String, CliError> {
    let mut s = String::new();
    if path == "-" {
        std::io::stdin()
            .read_to_string(&mut s)
            .map_err(|e| CliError::input(format!("cannot read stdin: {e}")))?;
    } else {
        s = std::fs::read_to_string(path)
            .map_err(|e| CliError::input(format!("cannot read {path}: {e}")))?;
    }
    Ok(s)
}

/// The experiments of a manifest (docs/formats.md) with their CSV files (relative to the
/// manifest), those `keep` accepts by name; the one manifest loader of the CLI.
pub fn load_experiments(
    manifest: &str,
    keep: impl Fn(&str) -> bool,
) -> Result<Vec<sd_ident::Experiment>, CliError> {
    sd_ident::load_experiments(Path::new(manifest), keep).map_err(|e| from_ident(manifest, e))
}

/// Reads a model file.
pub fn read_model(path: &str) -> Result<StateSpace, CliError> {
    let text = read_text(path)?;
    sd_model::model_from_json_str(&text).map_err(|e| from_model(path, e))
}

/// Writes `text` to `out` atomically, or to stdout when `out` is None.
pub fn emit(text: &str, out: Option<&str>) -> Result<(), CliError> {
    emit_parts(&[text.as_bytes()], out)
}

/// [`emit`] of the concatenation of `parts` (a large output formatted in pieces is written
/// piece by piece, not copied into one string), with the closing newline.
pub fn emit_parts(parts: &[&[u8]], out: Option<&str>) -> Result<(), CliError> {
    let mut all: Vec<&[u8]> = parts.to_vec();
    all.push(b"\n");
    match out {
        None => {
            use std::io::Write;
            let mut so = std::io::stdout().lock();
            match all.iter().try_for_each(|p| so.write_all(p)) {
                // the reader has gone (`sdctl … | head`): nothing more to say
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
                r => r.map_err(|e| CliError {
                    code: 1,
                    message: format!("cannot write stdout: {e}"),
                }),
            }
        }
        Some(path) => sd_report::write_atomic_parts(Path::new(path), &all)
            .map_err(|e| CliError::input(e.to_string())),
    }
}

/// Writes a folder of outputs so that nothing is half-written: `fill` writes every file into a
/// staging folder; a new `out` is that folder renamed into place in one step, and into an
/// existing `out` (whose other files are not touched) the finished files are renamed one by
/// one, so an interrupted run leaves the previous file or the new one, never a partial one. On
/// an error the staging folder is removed. Callers run [`check_out_dir`] before their work, so
/// that an `out` that cannot be a folder is refused at once, not after it.
pub fn write_folder<T>(
    out: &str,
    fill: impl FnOnce(&std::path::Path) -> Result<T, CliError>,
) -> Result<T, CliError> {
    let dir = std::path::Path::new(out);
    let io = |what: &std::path::Path, e: std::io::Error| {
        CliError::input(format!("cannot write {}: {e}", what.display()))
    };
    let exists = dir.is_dir();
    let pid = std::process::id();
    let staging = if exists {
        dir.join(format!(".sdctl.partial{pid}"))
    } else {
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "out".into());
        let parent = dir.parent().unwrap_or_else(|| std::path::Path::new(""));
        if !parent.as_os_str().is_empty() {
            std::fs::create_dir_all(parent).map_err(|e| io(parent, e))?;
        }
        parent.join(format!(".{name}.partial{pid}"))
    };
    let _ = std::fs::remove_dir_all(&staging);
    std::fs::create_dir_all(&staging).map_err(|e| io(&staging, e))?;
    let done = fill(&staging).and_then(|v| {
        if exists {
            let entries = std::fs::read_dir(&staging).map_err(|e| io(&staging, e))?;
            for entry in entries {
                let from = entry.map_err(|e| io(&staging, e))?.path();
                let to = dir.join(from.file_name().unwrap_or_default());
                std::fs::rename(&from, &to).map_err(|e| io(&to, e))?;
            }
            std::fs::remove_dir(&staging).map_err(|e| io(&staging, e))?;
        } else {
            std::fs::rename(&staging, dir).map_err(|e| io(dir, e))?;
        }
        Ok(v)
    });
    if done.is_err() {
        let _ = std::fs::remove_dir_all(&staging);
    }
    done
}

/// Refuses an output folder that cannot be created before any work is done: the path or its
/// nearest existing ancestor is a file.
pub fn check_out_dir(out: &str) -> Result<(), CliError> {
    let mut p = std::path::Path::new(out);
    loop {
        if p.exists() {
            if p.is_dir() {
                return Ok(());
            }
            return Err(CliError::input(format!(
                "cannot write {out}: {} is a file, not a folder; choose another --out",
                p.display()
            )));
        }
        match p.parent() {
            Some(q) if !q.as_os_str().is_empty() => p = q,
            _ => return Ok(()),
        }
    }
}

/// Warnings as JSON: each one's serialised fields plus its one-line `message`.
pub fn warnings_json<W: serde::Serialize + std::fmt::Display>(ws: &[W]) -> serde_json::Value {
    ws.iter()
        .map(|w| {
            let mut v = serde_json::to_value(w).unwrap_or(serde_json::Value::Null);
            if let Some(m) = v.as_object_mut() {
                m.insert("message".into(), w.to_string().into());
            }
            v
        })
        .collect::<Vec<_>>()
        .into()
}

/// Writes an SVG through a temporary file renamed into place (atomic).
pub fn atomic_svg(
    path: &str,
    draw: impl FnOnce(&str) -> Result<(), sd_report::ReportError>,
) -> Result<(), CliError> {
    let target = std::path::Path::new(path);
    let partial = target.with_extension(format!("partial{}.svg", std::process::id()));
    let tmp = partial.to_string_lossy().into_owned();
    draw(&tmp).map_err(|e| {
        let _ = std::fs::remove_file(&partial);
        CliError::input(format!("cannot write {path}: {e}"))
    })?;
    std::fs::rename(&partial, target).map_err(|e| {
        let _ = std::fs::remove_file(&partial);
        CliError::input(format!("cannot write {path}: {e}"))
    })
}

/// An FRD as CSV, one row per entry and line: `output,input,freq_hz,magnitude_db,phase_deg,
/// sigma,snr_db` — the phase unwrapped along each entry's lines
/// ([`sd_report::plot::unwrap_deg`]), `sigma` the standard deviation `√var` of the complex
/// estimate and `snr_db` = `20·log10(|G|/σ)` (both empty without a variance); outputs and
/// inputs 1-based.
pub fn frd_csv(frd: &sd_model::Frd) -> String {
    let (ny, nu) = frd.shape();
    let mut text = String::from("output,input,freq_hz,magnitude_db,phase_deg,sigma,snr_db\n");
    for o in 0..ny {
        for i in 0..nu {
            let g: Vec<num_complex::Complex64> = frd.response().iter().map(|m| m[(o, i)]).collect();
            let ph = sd_report::plot::unwrap_deg(
                &g.iter().map(|v| v.arg().to_degrees()).collect::<Vec<_>>(),
            );
            for (k, f) in frd.freq_hz().iter().enumerate() {
                let (sigma, snr) = match frd.variance() {
                    Some(v) => {
                        let s = v[k][(o, i)].sqrt();
                        (
                            format!("{s:e}"),
                            format!("{}", 20.0 * (g[k].norm() / s).log10()),
                        )
                    }
                    None => (String::new(), String::new()),
                };
                text += &format!(
                    "{},{},{f},{},{},{sigma},{snr}\n",
                    o + 1,
                    i + 1,
                    20.0 * g[k].norm().log10(),
                    ph[k]
                );
            }
        }
    }
    text
}
