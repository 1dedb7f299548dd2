//! `sd-report`: what people read. SVG figures with plotters ([`plot`], on plain slices of
//! frequencies and values: no toolkit types) and, with the default feature `diagnosis`, the
//! diagnosis report (`diagnosis`: `report.md`, `diagnosis.json` and its figures). The only library crate that writes files; the
//! numerics live elsewhere.

#[cfg(feature = "diagnosis")]
pub mod diagnosis;
pub mod plot;

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
