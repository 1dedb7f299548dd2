//! Shared helpers of the cross-crate integration and property tests (package `sd-tests`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use std::path::PathBuf;

/// Path of a file in the repository's `test_data/` folder.
pub fn test_data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("test_data")
        .join(name)
}

/// Reads a JSON file of `test_data/`.
pub fn read_json(name: &str) -> serde_json::Value {
    let p = test_data(name);
    let text =
        std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("cannot read {}: {e}", p.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("bad JSON in {}: {e}", p.display()))
}

/// A row-major JSON array of rows as a matrix.
pub fn mat(v: &serde_json::Value) -> DMatrix<f64> {
    let rows: Vec<Vec<f64>> = serde_json::from_value(v.clone()).expect("matrix as array of rows");
    let nr = rows.len();
    let nc = rows.first().map(|r| r.len()).unwrap_or(0);
    DMatrix::from_fn(nr, nc, |i, j| rows[i][j])
}

/// ‖X − Y‖_F / ‖Y‖_F (absolute when Y = 0).
pub fn rel_err(x: &DMatrix<f64>, y: &DMatrix<f64>) -> f64 {
    let d = (x - y).norm();
    let s = y.norm();
    if s == 0.0 {
        d
    } else {
        d / s
    }
}

/// The seed range `a..b` in the environment variable `var`, `default` when it is unset; a
/// value that is not `a..b` with whole numbers stops the test, naming it.
pub fn env_seeds(var: &str, default: std::ops::Range<u64>) -> std::ops::Range<u64> {
    let Ok(spec) = std::env::var(var) else {
        return default;
    };
    let parsed = spec
        .split_once("..")
        .and_then(|(a, b)| Some(a.trim().parse().ok()?..b.trim().parse().ok()?));
    parsed.unwrap_or_else(|| panic!("{var}={spec:?} is not a seed range `a..b`"))
}

/// The whole number in the environment variable `var`, `default` when it is unset; a value
/// that is no whole number stops the test, naming it.
pub fn env_number(var: &str, default: u64) -> u64 {
    let Ok(spec) = std::env::var(var) else {
        return default;
    };
    spec.trim()
        .parse()
        .unwrap_or_else(|_| panic!("{var}={spec:?} is not a whole number"))
}

pub mod designs;
pub mod gen;

/// The library's PID-like controller ([`sd_hinf::weights::pid`] with its default shape:
/// integrator at ω_c/5, lead from ω_c/3 to 3ω_c, `|K/(m ω_c²)| = 1` at the crossover) for a
/// mass `mass` with crossover at `bw_hz`, discretised (prewarped Tustin) at `ts`.
pub fn pid(bw_hz: f64, mass: f64, ts: f64) -> sd_model::StateSpace {
    sd_hinf::weights::pid(bw_hz, mass, Some(ts), &Default::default())
        .expect("a valid PID-like weight")
}
pub mod diagcases;
pub mod modal_truth;
pub mod stage;
