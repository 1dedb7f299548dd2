//! Issue #40 item 1: Riccati equations with complex data (`sd_hinf::care_complex`,
//! `dare_complex`), never solved for the real parts alone. References: the mathematics — the
//! complex equation's residual (conjugate transposes) and a stable closed loop characterise the
//! Hermitian stabilizing solution; a scalar case in closed form; a unitary change of
//! coordinates of a real problem (`X = UᴴX₀U`) — and, where scipy solves a case, scipy's X
//! (`test_data/complex_riccati.json`, `tools/gen_complex_riccati.py`).
//! `cargo test --release -p sd-tests --test riccati_complex -- --nocapture` prints each case.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_hinf::{care_complex, dare_complex, CMatrix, ComplexRiccatiData};
use sd_tests::{mat, read_json};

fn cmat(v: &serde_json::Value) -> CMatrix {
    let (re, im) = (mat(&v["re"]), mat(&v["im"]));
    CMatrix::from_fn(re.nrows(), re.ncols(), |i, j| {
        C::new(re[(i, j)], im[(i, j)])
    })
}

fn crel(x: &CMatrix, y: &CMatrix) -> f64 {
    (x - y).norm() / y.norm().max(f64::MIN_POSITIVE)
}

fn stable(continuous: bool, cl: &CMatrix) -> bool {
    // the real representation's spectrum is that of cl with its conjugates
    let real = sd_hinf::riccati::complex::realify(cl).complex_eigenvalues();
    if continuous {
        real.iter().all(|l| l.re < 0.0)
    } else {
        real.iter().all(|l| l.norm() < 1.0)
    }
}

#[test]
fn complex_riccati_solves_the_complex_equation() {
    let data = read_json("complex_riccati.json");
    let (mut scipy_solved, mut worst) = (0, 0.0f64);
    for c in data["cases"].as_array().unwrap() {
        let name = c["name"].as_str().unwrap();
        let (a, b, q, r, s) = (
            cmat(&c["A"]),
            cmat(&c["B"]),
            cmat(&c["Q"]),
            cmat(&c["R"]),
            cmat(&c["S"]),
        );
        let e = cmat(&c["E"]);
        let descriptor = c["descriptor"].as_bool().unwrap();
        let d = ComplexRiccatiData {
            a: &a,
            b: &b,
            q: &q,
            r: &r,
            s: Some(&s),
            e: descriptor.then_some(&e),
        };
        let continuous = c["kind"] == "care";
        let sol = if continuous {
            care_complex(&d)
        } else {
            dare_complex(&d)
        }
        .unwrap_or_else(|err| panic!("{name}: {err}"));
        let ei = e.clone().try_inverse().unwrap();
        assert!(
            stable(continuous, &(&ei * (&a - &b * &sol.gain))),
            "{name}: closed loop not stable"
        );
        assert!(
            crel(&sol.x, &sol.x.adjoint()) == 0.0,
            "{name}: X not Hermitian"
        );
        let n = a.nrows();
        let floor = 100.0 * (2 * n) as f64 * f64::EPSILON;
        let scipy_res = c["scipy_residual"].as_f64();
        assert!(
            sol.residual <= scipy_res.unwrap_or(0.0).max(floor),
            "{name}: residual {:e} (scipy {scipy_res:?})",
            sol.residual
        );
        worst = worst.max(sol.residual);
        let agree = c.get("X_scipy").map(|x| crel(&sol.x, &cmat(x)));
        if let Some(dx) = agree {
            scipy_solved += 1;
            assert!(
                dx <= 1e-9 * sol.condition.max(1.0),
                "{name}: X differs from scipy's by {dx:e}"
            );
        }
        let im = sol.x.map(|v| v.im).norm() / sol.x.norm();
        println!(
            "{name:>12}: residual {:.2e} (scipy {}), ‖Im X‖/‖X‖ {im:.2}, |X − X_scipy|/|X| {}",
            sol.residual,
            scipy_res.map_or("refused".into(), |v| format!("{v:.2e}")),
            agree.map_or("-".into(), |v| format!("{v:.1e}")),
        );
    }
    println!("worst residual {worst:.2e}; scipy solved {scipy_solved} of the cases");
}

/// `ȧ x + x a − |b|²x²/r + q = 0` for scalars: `x = r(Re a + √((Re a)² + q|b|²/r))/|b|²`,
/// real although `a` and `b` are complex; the DARE's scalar form
/// `|a|²x − x − |a|²|b|²x²/(r + |b|²x) + q = 0` by the positive root of
/// `|b|²x² + (r(1 − |a|²) − q|b|²)x − qr = 0`.
#[test]
fn scalar_complex_riccati_in_closed_form() {
    let (a, b, q, r) = (C::new(0.3, 2.0), C::new(-0.5, 1.5), 2.0, 0.7);
    let one = |v: C| CMatrix::from_element(1, 1, v);
    let (am, bm, qm, rm) = (one(a), one(b), one(C::new(q, 0.0)), one(C::new(r, 0.0)));
    let d = ComplexRiccatiData {
        a: &am,
        b: &bm,
        q: &qm,
        r: &rm,
        s: None,
        e: None,
    };
    let b2 = b.norm_sqr();
    let xc = r * (a.re + (a.re * a.re + q * b2 / r).sqrt()) / b2;
    let sol = care_complex(&d).unwrap();
    assert!(
        (sol.x[(0, 0)] - C::new(xc, 0.0)).norm() <= 1e-14 * xc,
        "{:?} vs {xc}",
        sol.x
    );
    let bb = r * (1.0 - a.norm_sqr()) - q * b2;
    let xd = (-bb + (bb * bb + 4.0 * b2 * q * r).sqrt()) / (2.0 * b2);
    let sol = dare_complex(&d).unwrap();
    assert!(
        (sol.x[(0, 0)] - C::new(xd, 0.0)).norm() <= 1e-13 * xd,
        "{:?} vs {xd}",
        sol.x
    );
}

/// A real problem in complex unitary coordinates: `A = UᴴA₀U`, `B = UᴴB₀`, `Q = UᴴQ₀U` has
/// `X = UᴴX₀U`, a genuinely complex Hermitian matrix.
#[test]
fn unitary_coordinates_of_a_real_problem() {
    let n = 5;
    let a0 = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 11) as f64 / 5.0 - 1.0);
    let b0 = DMatrix::from_fn(n, 2, |i, j| ((i + 2 * j) % 3) as f64 - 0.5);
    let q0 = DMatrix::identity(n, n);
    let r0 = DMatrix::from_row_slice(2, 2, &[2.0, 0.3, 0.3, 1.0]);
    let z = CMatrix::from_fn(n, n, |i, j| {
        C::new(
            ((i * 5 + j) % 7) as f64 - 3.0,
            ((i + 3 * j) % 5) as f64 - 2.0,
        )
    });
    let u = z.qr().q();
    let c = |m: &DMatrix<f64>| m.map(|v| C::new(v, 0.0));
    let (a, b, q, r) = (
        u.adjoint() * c(&a0) * &u,
        u.adjoint() * c(&b0),
        u.adjoint() * c(&q0) * &u,
        c(&r0),
    );
    let d = ComplexRiccatiData {
        a: &a,
        b: &b,
        q: &q,
        r: &r,
        s: None,
        e: None,
    };
    for continuous in [true, false] {
        let (x0, x) = if continuous {
            (
                sd_hinf::care(&a0, &b0, &q0, &r0, None).unwrap().x,
                care_complex(&d).unwrap().x,
            )
        } else {
            let a0 = &a0 * 0.5;
            let a = &a * C::new(0.5, 0.0);
            let d = ComplexRiccatiData { a: &a, ..d };
            (
                sd_hinf::dare(&a0, &b0, &q0, &r0, None).unwrap().x,
                dare_complex(&d).unwrap().x,
            )
        };
        let want = u.adjoint() * c(&x0) * &u;
        let err = crel(&x, &want);
        assert!(
            want.map(|v| v.im).norm() > 0.1 * want.norm(),
            "X is nearly real: no test"
        );
        assert!(err < 1e-12, "continuous {continuous}: {err:e}");
        println!("continuous {continuous}: |X − UᴴX₀U|/|X| = {err:.1e}");
    }
}

#[test]
fn complex_riccati_bad_input_is_named() {
    let one = |v: C| CMatrix::from_element(1, 1, v);
    let q = CMatrix::from_row_slice(
        2,
        2,
        &[
            C::new(1.0, 0.0),
            C::new(0.0, 1.0),
            C::new(0.0, 1.0),
            C::new(1.0, 0.0),
        ],
    );
    let a = CMatrix::identity(2, 2);
    let b = CMatrix::from_element(2, 1, C::new(1.0, 0.0));
    let r = one(C::new(1.0, 0.0));
    let d = ComplexRiccatiData {
        a: &a,
        b: &b,
        q: &q,
        r: &r,
        s: None,
        e: None,
    };
    let msg = care_complex(&d).unwrap_err().to_string();
    assert!(msg.contains("Q must be Hermitian"), "{msg}");
    let bad = one(C::new(1.0, 0.0));
    let d = ComplexRiccatiData { q: &bad, ..d };
    let msg = dare_complex(&d).unwrap_err().to_string();
    assert!(msg.contains("Q") && msg.contains("2x2"), "{msg}");
}
