//! Issue #40 item 5: generalized (descriptor) CARE and DARE with `E ≠ I`
//! (`sd_hinf::gcare`, `gdare`). Reference: the mathematics — the generalized equation's
//! residual and a stable closed loop `λ(A − BK, E)` characterise the stabilizing solution —
//! and, where scipy solves a case, scipy's X (`test_data/descriptor_riccati.json`,
//! `tools/gen_descriptor_riccati.py`). `cargo test --release -p sd-tests --test
//! riccati_descriptor -- --nocapture` prints each case.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use sd_tests::{mat, read_json, rel_err};

#[test]
fn generalized_riccati_solves_the_generalized_equation() {
    let data = read_json("descriptor_riccati.json");
    let (mut ours_solved, mut scipy_solved, mut worst) = (0, 0, 0.0f64);
    for c in data["cases"].as_array().unwrap() {
        let name = c["name"].as_str().unwrap();
        let (a, e, b) = (mat(&c["A"]), mat(&c["E"]), mat(&c["B"]));
        let (q, r, s) = (mat(&c["Q"]), mat(&c["R"]), mat(&c["S"]));
        let n = a.nrows();
        let continuous = c["kind"] == "care";
        let sol = if continuous {
            sd_hinf::gcare(&a, &e, &b, &q, &r, Some(&s))
        } else {
            sd_hinf::gdare(&a, &e, &b, &q, &r, Some(&s))
        }
        .unwrap_or_else(|err| panic!("{name}: {err}"));
        ours_solved += 1;
        // the closed loop λ(A − BK, E), computed here from the returned gain
        let ei = e.clone().try_inverse().unwrap();
        let cl = (&ei * (&a - &b * &sol.gain)).complex_eigenvalues();
        let stable = if continuous {
            cl.iter().all(|l| l.re < 0.0)
        } else {
            cl.iter().all(|l| l.norm() < 1.0)
        };
        assert!(stable, "{name}: closed loop {cl:?}");
        assert!(
            rel_err(&sol.x, &sol.x.transpose()) == 0.0,
            "{name}: X not symmetric"
        );
        let floor = 100.0 * n as f64 * f64::EPSILON;
        let scipy_res = c["scipy_residual"].as_f64();
        assert!(
            sol.residual <= scipy_res.unwrap_or(0.0).max(floor),
            "{name}: residual {:e} (scipy {scipy_res:?})",
            sol.residual
        );
        worst = worst.max(sol.residual);
        let agree = c.get("X_scipy").map(|x| rel_err(&sol.x, &mat(x)));
        if let Some(d) = agree {
            scipy_solved += 1;
            assert!(
                d <= 1e-9 * sol.condition.max(1.0),
                "{name}: X differs from scipy's by {d:e}"
            );
        }
        println!(
            "{name:>16}: κ(E) {:7.2}, residual {:.2e} (scipy {}), |X − X_scipy|/|X| {}",
            c["cond_E"].as_f64().unwrap(),
            sol.residual,
            scipy_res.map_or("refused".into(), |v| format!("{v:.2e}")),
            agree.map_or("—".into(), |d| format!("{d:.1e}"))
        );
    }
    println!(
        "solved {ours_solved} of {ours_solved}; scipy solved {scipy_solved}; worst generalized residual {worst:.2e}"
    );
}

#[test]
fn a_singular_or_ill_conditioned_e_is_refused() {
    let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -1.0, -0.5]);
    let b = DMatrix::from_row_slice(2, 1, &[0.0, 1.0]);
    let (q, r) = (DMatrix::identity(2, 2), DMatrix::identity(1, 1));
    let singular = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 0.0]);
    let e = sd_hinf::gcare(&a, &singular, &b, &q, &r, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("E is singular"), "{e}");
    let ill = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 1e-10]);
    let e = sd_hinf::gdare(&a, &ill, &b, &q, &r, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("ill-conditioned"), "{e}");
    let wrong = DMatrix::identity(3, 3);
    assert!(sd_hinf::gcare(&a, &wrong, &b, &q, &r, None).is_err());
    // E = I is the standard equation
    let std = sd_hinf::care(&a, &b, &q, &r, None).unwrap();
    let gen = sd_hinf::gcare(&a, &DMatrix::identity(2, 2), &b, &q, &r, None).unwrap();
    assert!(rel_err(&gen.x, &std.x) < 1e-14);
}
