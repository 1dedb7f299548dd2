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

pub mod designs;
pub mod gen;

/// A PID-like controller (integrator, lead around the bandwidth, first-order roll-off) for a
/// mass `m` with crossover near `bw_hz`, discretised by Tustin at `ts`:
/// `K(s) = k (s/ω_z + 1)(s + ω_i) / (s (s/ω_p + 1))`, ω_z = ω_c/3, ω_p = 3ω_c, ω_i = ω_c/5,
/// `k = m ω_c²/3` (|m s² K| ≈ 1 at ω_c).
pub fn pid(bw_hz: f64, mass: f64, ts: f64) -> sd_model::StateSpace {
    use sd_model::{c2d, Discretization, SampleTime, TransferFunction};
    let wc = 2.0 * std::f64::consts::PI * bw_hz;
    let (wz, wp, wi) = (wc / 3.0, wc * 3.0, wc / 5.0);
    let k = mass * wc * wc / 3.0;
    let tf = TransferFunction::new(
        vec![k / wz, k * (1.0 + wi / wz), k * wi],
        vec![1.0 / wp, 1.0, 0.0],
        SampleTime::Continuous,
    )
    .unwrap();
    c2d(
        &tf.to_ss().unwrap(),
        ts,
        Discretization::Tustin { prewarp_hz: None },
    )
    .unwrap()
}
pub mod diagcases;
