//! Tolerances and limits of this crate, in one place.

/// A fraction times F must be within this of an integer to count as a whole number of fast
/// samples (hold delay and averaging window of a fast discrete model).
pub const WHOLE_SAMPLES_TOL: f64 = 1e-9;

/// Relative tolerance for `T = F·h` between a slow and a fast model's sample times.
pub const RATE_MATCH_TOL: f64 = 1e-9;

/// Largest rate factor accepted (lifted models have F·nu inputs and F·ny outputs).
pub const MAX_FACTOR: usize = 10_000;
