//! every CAREX/DAREX case of `test_data/riccati_exact.json` against its
//! analytic solution. Pass: relative error within scipy's (recorded per case in the file) or
//! 1e-13, whichever is larger — or, where ill-conditioning makes that impossible, within
//! 10·κ·ε with κ our condition estimate (the estimate "says so"). CAREX 2.6 at ε = 1e6 must
//! beat scipy's 8.6e-4.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_hinf::{care, dare};
use sd_tests::{mat, read_json, rel_err};

#[test]
fn riccati_exact_cases() {
    let cases = read_json("riccati_exact.json");
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    for c in cases.as_array().unwrap() {
        let name = format!("{} ({})", c["name"].as_str().unwrap(), c["param"]);
        let (a, b, q, r) = (mat(&c["A"]), mat(&c["B"]), mat(&c["Q"]), mat(&c["R"]));
        let x_ref = if c.get("X_for_listed_data").is_some() {
            mat(&c["X_for_listed_data"])
        } else {
            mat(&c["X_exact"])
        };
        let sol = match c["kind"].as_str().unwrap() {
            "CARE" => care(&a, &b, &q, &r, None),
            _ => dare(&a, &b, &q, &r, None),
        };
        let sol = match sol {
            Ok(s) => s,
            Err(e) => {
                failures.push(format!("{name}: error {e}"));
                continue;
            }
        };
        let err = rel_err(&sol.x, &x_ref);
        let scipy = c["scipy_rel_err"].as_f64().unwrap();
        let explained = err <= 10.0 * sol.condition * f64::EPSILON;
        let ok = err <= scipy.max(1e-13) || explained;
        rows.push(format!(
            "{name:<22} err {err:9.2e}  scipy {scipy:9.2e}  κ {:9.2e}  residual {:9.2e}  doubling {:2} newton {}{}",
            sol.condition,
            sol.residual,
            sol.doubling_steps,
            sol.refinement_steps,
            if ok { "" } else { "  FAIL" }
        ));
        if !ok {
            failures.push(format!(
                "{name}: relative error {err:e} (scipy {scipy:e}, κε {:e})",
                sol.condition * f64::EPSILON
            ));
        }
        if c["name"] == "CAREX 2.6" && c["param"].as_f64() == Some(1e6) {
            assert!(
                err < 8.6e-4,
                "CAREX 2.6 at 1e6: {err:e} does not beat scipy's 8.6e-4"
            );
        }
    }
    println!("{}", rows.join("\n"));
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
