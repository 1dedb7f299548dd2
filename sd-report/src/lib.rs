//! `sd-report`: what people read. SVG figures with plotters ([`plot`], on plain slices of
//! frequencies and values: no toolkit types) and, with the default feature `diagnosis`, the
//! diagnosis report (`diagnosis`: `report.md`, `diagnosis.json` and its figures). The only library crate that writes files; the
//! numerics live elsewhere.

#[cfg(feature = "diagnosis")]
pub mod diagnosis;
pub mod mimo;
pub mod plot;
#[cfg(feature = "diagnosis")]
pub mod prediction;
pub mod stabilization;

/// Errors of the report.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// Drawing a figure failed (the message names the figure).
    #[error("figure: {0}")]
    Plot(String),
    /// The diagnosis could not be serialised.
    #[error("diagnosis JSON: {0}")]
    Json(String),
    /// Writing a file failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, ReportError>;

pub(crate) fn plot_err<E: std::fmt::Display>(e: E) -> ReportError {
    ReportError::Plot(e.to_string())
}

/// The crate README's example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;

/// Writes `text` to `path` through a temporary file in the same folder and a rename, so a
/// reader never sees half a file; an error names `path`, never the temporary file. The one
/// atomic writer of the workspace (`sdctl` writes its outputs through it too).
///
/// # Errors
/// The file cannot be written or renamed into place.
pub fn write_atomic(path: &std::path::Path, text: &str) -> Result<()> {
    write_atomic_parts(path, &[text.as_bytes()])
}

/// [`write_atomic`] of the concatenation of `parts`, written one after the other (a large
/// output formatted in pieces is not copied into one buffer first).
///
/// # Errors
/// As [`write_atomic`].
pub fn write_atomic_parts(path: &std::path::Path, parts: &[&[u8]]) -> Result<()> {
    use std::io::Write;
    let io = |source| ReportError::Io {
        path: path.display().to_string(),
        source,
    };
    let name = path.file_name().ok_or_else(|| {
        io(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a file name",
        ))
    })?;
    let name = name.to_string_lossy();
    let tmp = path.with_file_name(format!(".{name}.tmp{}", std::process::id()));
    let written = std::fs::File::create(&tmp).and_then(|mut f| {
        for p in parts {
            f.write_all(p)?;
        }
        Ok(())
    });
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(e));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(e)
    })
}
