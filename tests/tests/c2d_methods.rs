//! FOH and Tustin (with prewarping) against scipy / python-control references.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use num_complex::Complex64 as C;
use sd_model::{c2d, Discretization, SampleTime, StateSpace};
use sd_tests::{mat, read_json, rel_err};

#[test]
fn foh_and_tustin_match_scipy() {
    let data = read_json("c2d_methods.json");
    for c in data["cases"].as_array().unwrap() {
        let name = c["name"].as_str().unwrap();
        let h = c["h"].as_f64().unwrap();
        let sys = StateSpace::new(
            mat(&c["A"]),
            mat(&c["B"]),
            mat(&c["C"]),
            mat(&c["D"]),
            SampleTime::Continuous,
        )
        .unwrap();
        let method = match (c["method"].as_str().unwrap(), c["prewarp_hz"].as_f64()) {
            ("foh", _) => Discretization::Foh,
            (_, pw) => Discretization::Tustin { prewarp_hz: pw },
        };
        let d = c2d(&sys, h, method).unwrap();
        let mut worst: f64 = 0.0;
        for (k, f) in c["freq_hz"].as_array().unwrap().iter().enumerate() {
            let z = C::from_polar(1.0, 2.0 * std::f64::consts::PI * f.as_f64().unwrap() * h);
            let g = d.eval_direct(z).unwrap();
            let (re, im) = (mat(&c["response"][k]["re"]), mat(&c["response"][k]["im"]));
            for i in 0..g.nrows() {
                for j in 0..g.ncols() {
                    let r = C::new(re[(i, j)], im[(i, j)]);
                    worst = worst.max((g[(i, j)] - r).norm() / r.norm().max(1e-300));
                }
            }
        }
        assert!(worst <= 1e-10, "{name}: response rel err {worst:e}");
        if c["prewarp_hz"].is_null() {
            assert!(rel_err(d.a(), &mat(&c["Ad"])) <= 1e-12, "{name} A");
            assert!(rel_err(d.d(), &mat(&c["Dd"])) <= 1e-12, "{name} D");
        }
    }
}

#[test]
fn tustin_prewarp_is_exact_at_the_prewarp_frequency() {
    // notch-like resonance at 347 Hz, 1 kHz: |G_d(347 Hz)| must equal |G_c(j2π347)|
    let w = 2.0 * std::f64::consts::PI * 347.0;
    let sys = StateSpace::new(
        nalgebra::DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -0.2 * w]),
        nalgebra::DMatrix::from_row_slice(2, 1, &[0.0, w * w]),
        nalgebra::DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
        nalgebra::DMatrix::zeros(1, 1),
        SampleTime::Continuous,
    )
    .unwrap();
    let d = c2d(
        &sys,
        1e-3,
        Discretization::Tustin {
            prewarp_hz: Some(347.0),
        },
    )
    .unwrap();
    let gd = d.eval_direct(C::from_polar(1.0, w * 1e-3)).unwrap()[(0, 0)];
    let gc = sys.eval_direct(C::new(0.0, w)).unwrap()[(0, 0)];
    assert!((gd - gc).norm() <= 1e-12 * gc.norm());
    let plain = c2d(&sys, 1e-3, Discretization::Tustin { prewarp_hz: None }).unwrap();
    let gp = plain.eval_direct(C::from_polar(1.0, w * 1e-3)).unwrap()[(0, 0)];
    assert!(
        (gp - gc).norm() > 0.1 * gc.norm(),
        "without prewarping the peak moves"
    );
    assert!(c2d(
        &sys,
        1e-3,
        Discretization::Tustin {
            prewarp_hz: Some(600.0)
        }
    )
    .is_err());
}
