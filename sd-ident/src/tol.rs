//! Tolerances and defaults of this crate, in one place.

/// A line counts as excited when its reference (or input) amplitude exceeds this fraction of
/// the largest one.
pub const EXCITED_FRACTION: f64 = 1e-3;
/// Vector-fitting (Sanathanan–Koerner) iterations by default.
pub const SK_ITERATIONS: usize = 12;
/// Levenberg–Marquardt iterations by default.
pub const LM_ITERATIONS: usize = 40;
/// LM stops when the relative cost decrease of an accepted step is below this.
pub const LM_STOP: f64 = 1e-9;
/// Relative pole damping of the starting poles of the fit.
pub const START_DAMPING: f64 = 0.01;
/// A pole this close to the unit circle (|p| > 1 − ε) after reflection is pulled inside to
/// 1 − STABILITY_MARGIN (free poles only; fixed rigid-body poles stay at z = 1).
pub const STABILITY_MARGIN: f64 = 1e-9;
