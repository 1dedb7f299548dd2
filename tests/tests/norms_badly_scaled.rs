//! The H2 norm of a badly scaled closed loop (`test_data/h2_badly_scaled_loop.json`: the
//! 124-state loop of the 60-state stage at 1 kHz with a mixed-sensitivity controller, ‖A‖ =
//! 4.7e4, spectral radius 0.99984) against the impulse-response sum printed by
//! `tools/gen_h2_badly_scaled.py` (0.931222114532758). Before the states were balanced, the
//! Gramian route returned 0 (C·P·Cᵀ cancelled to a negative trace); scipy's
//! `solve_discrete_lyapunov` route gives 0.7597.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_model::model_from_json_str;

const IMPULSE_SUM: f64 = 0.931222114532758;

#[test]
fn h2_norm_of_a_badly_scaled_loop() {
    let text = std::fs::read_to_string(sd_tests::test_data("h2_badly_scaled_loop.json")).unwrap();
    let cl = model_from_json_str(&text).unwrap();
    let h2 = cl.h2_norm().unwrap();
    let rel = (h2 - IMPULSE_SUM).abs() / IMPULSE_SUM;
    println!("H2 {h2:.12} vs impulse-response sum {IMPULSE_SUM:.12}: relative {rel:.1e}");
    assert!(rel <= 1e-4, "{h2}");
}
