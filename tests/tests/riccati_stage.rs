//! the lightly damped 60-state stage (rigid body + 29 modes) at 1 kHz and
//! 5 kHz, Q = CᵀC, R = 1 — the problem SLICOT SB02OD (python-control's route) fails on.
//! Relative residual ≤ 1e-12 and ρ(A − BK) < 1. Timing is reported here and measured against
//! scipy in `cargo xtask bench`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use sd_hinf::dare;
use sd_model::{c2d, Discretization};

#[test]
fn stage60_dare() {
    let p = sd_model::stage::stage60().unwrap();
    for ts in [1e-3, 2e-4] {
        let pd = c2d(&p, ts, Discretization::Zoh).unwrap();
        let q = pd.c().transpose() * pd.c();
        let r = DMatrix::from_element(1, 1, 1.0);
        let t0 = std::time::Instant::now();
        let sol = dare(pd.a(), pd.b(), &q, &r, None).unwrap();
        let dt = t0.elapsed();
        println!(
            "stage60 at {} Hz: residual {:.2e}, ρ(A − BK) = {:.9}, κ {:.2e}, doubling {}, newton {}, {:.2} ms",
            1.0 / ts,
            sol.residual,
            sol.closed_loop,
            sol.condition,
            sol.doubling_steps,
            sol.refinement_steps,
            dt.as_secs_f64() * 1e3
        );
        assert!(sol.residual <= 1e-12, "residual {:e}", sol.residual);
        assert!(sol.closed_loop < 1.0);
        // the solution is symmetric positive semidefinite
        assert!((&sol.x - sol.x.transpose()).norm() == 0.0);
        assert!(
            sol.x.clone().cholesky().is_some()
                || sol.x.symmetric_eigenvalues().min() > -1e-10 * sol.x.norm()
        );
    }
}
