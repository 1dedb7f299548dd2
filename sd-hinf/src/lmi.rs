//! H∞ norm by the bounded-real lemma as a semidefinite program (clarabel) — an independent
//! cross-check of [`sd_model::StateSpace::hinf_norm`] and of achieved loopshaping levels.
//!
//! For a stable `G = (A, B, C, D)`, `‖G‖∞ ≤ γ` iff some `P ≻ 0` satisfies (Schur-complement
//! forms of the bounded-real lemma; Boyd, El Ghaoui, Feron & Balakrishnan 1994, §2.7.3; de
//! Souza & Xie 1992 for discrete time):
//!
//! ```text
//! CT: [AᵀP + PA   PB    Cᵀ ]        DT: [AᵀPA − P   AᵀPB       Cᵀ ]
//!     [BᵀP       −γI    Dᵀ ] ⪯ 0        [BᵀPA       BᵀPB − γI  Dᵀ ] ⪯ 0
//!     [C          D    −γI ]            [C          D          −γI]
//! ```
//!
//! Both are linear in (P, γ), so `min γ` subject to them is an SDP; clarabel solves it with
//! the PSD cone in scaled upper-triangular (svec) form. The model is first brought to balanced
//! coordinates (Gramians equal and diagonal), which keeps the SDP well scaled. Accuracy: that of
//! the interior-point solver, about 1e-7 relative.
//!
//! Needs the `lmi` feature (clarabel's SDP support links BLAS/LAPACK: Debian packages
//! `libopenblas-dev` and `libgfortran-12-dev`).

use crate::error::{HinfError, Result};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::DMatrix;
use sd_model::StateSpace;
// links the system OpenBLAS that clarabel's SDP cone calls
use openblas_src as _;

/// Result of the bounded-real-lemma SDP.
#[derive(Debug, Clone)]
pub struct LmiNorm {
    /// The smallest γ found.
    pub gamma: f64,
    /// Clarabel's status text.
    pub status: String,
}

fn svec_len(k: usize) -> usize {
    k * (k + 1) / 2
}

/// Scaled upper-triangular column-major vectorisation of a symmetric matrix.
fn svec(m: &DMatrix<f64>) -> Vec<f64> {
    let k = m.nrows();
    let mut v = Vec::with_capacity(svec_len(k));
    for j in 0..k {
        for i in 0..=j {
            v.push(if i == j {
                m[(i, j)]
            } else {
                m[(i, j)] * std::f64::consts::SQRT_2
            });
        }
    }
    v
}

/// `min γ` subject to the bounded-real LMI of a stable model.
///
/// # Errors
/// An unstable model (the lemma needs stability), a solver that does not reach optimality.
pub fn hinf_norm_lmi(sys: &StateSpace) -> Result<LmiNorm> {
    let stable = if sys.time().is_continuous() {
        sys.poles()?.iter().all(|p| p.re < 0.0)
    } else {
        sys.poles()?.iter().all(|p| p.norm() < 1.0)
    };
    if !stable {
        return Err(HinfError::InvalidArgument(
            "the bounded-real lemma needs a stable model".into(),
        ));
    }
    let bal = if sys.n() > 0 {
        sys.balanced_truncation(sys.n())
            .map(|b| b.model)
            .unwrap_or_else(|_| sys.clone())
    } else {
        sys.clone()
    };
    // balancing may drop states that are uncontrollable or unobservable
    let n = bal.n();
    let (a, b, c, d) = (bal.a(), bal.b(), bal.c(), bal.d());
    let (nu, ny) = (bal.nu(), bal.ny());
    let k = n + nu + ny;
    let discrete = !bal.time().is_continuous();
    // variables: P entries (i ≤ j), then γ
    let np = svec_len(n);
    let nvar = np + 1;
    let mut cols: Vec<Vec<f64>> = Vec::with_capacity(nvar);
    let mut pcols: Vec<Vec<f64>> = Vec::with_capacity(nvar);
    for j in 0..n {
        for i in 0..=j {
            let mut e = DMatrix::<f64>::zeros(n, n);
            e[(i, j)] = 1.0;
            e[(j, i)] = 1.0;
            let mut m = DMatrix::<f64>::zeros(k, k);
            if discrete {
                m.view_mut((0, 0), (n, n))
                    .copy_from(&(a.transpose() * &e * a - &e));
                let apb = a.transpose() * &e * b;
                m.view_mut((0, n), (n, nu)).copy_from(&apb);
                m.view_mut((n, 0), (nu, n)).copy_from(&apb.transpose());
                m.view_mut((n, n), (nu, nu))
                    .copy_from(&(b.transpose() * &e * b));
            } else {
                m.view_mut((0, 0), (n, n))
                    .copy_from(&(a.transpose() * &e + &e * a));
                let pb = &e * b;
                m.view_mut((0, n), (n, nu)).copy_from(&pb);
                m.view_mut((n, 0), (nu, n)).copy_from(&pb.transpose());
            }
            cols.push(svec(&m));
            pcols.push(svec(&e).iter().map(|v| -v).collect());
        }
    }
    // γ column: −I on the two input/output diagonal blocks
    let mut mg = DMatrix::<f64>::zeros(k, k);
    for i in n..k {
        mg[(i, i)] = -1.0;
    }
    cols.push(svec(&mg));
    pcols.push(vec![0.0; np]);
    // constant part: C, D blocks
    let mut m0 = DMatrix::<f64>::zeros(k, k);
    m0.view_mut((n + nu, 0), (ny, n)).copy_from(c);
    m0.view_mut((0, n + nu), (n, ny)).copy_from(&c.transpose());
    m0.view_mut((n + nu, n), (ny, nu)).copy_from(d);
    m0.view_mut((n, n + nu), (nu, ny)).copy_from(&d.transpose());
    // rows: LMI cone (svec_len(k)) then P ⪰ 0 (np)
    let nl = svec_len(k);
    let rows = nl + np;
    let dense = DMatrix::<f64>::from_fn(rows, nvar, |r, v| {
        if r < nl {
            cols[v][r]
        } else {
            pcols[v][r - nl]
        }
    });
    let mut bvec: Vec<f64> = svec(&m0).iter().map(|v| -v).collect();
    bvec.extend(std::iter::repeat_n(0.0, np));
    let amat = to_csc(&dense);
    let pmat = CscMatrix::<f64>::zeros((nvar, nvar));
    let mut q = vec![0.0; nvar];
    q[np] = 1.0;
    let mut cones = vec![SupportedConeT::PSDTriangleConeT(k)];
    if n > 0 {
        cones.push(SupportedConeT::PSDTriangleConeT(n));
    }
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-10)
        .tol_gap_rel(1e-10)
        .tol_feas(1e-10)
        .build()
        .map_err(|e| HinfError::Numerical(format!("clarabel settings: {e:?}")))?;
    let mut solver = DefaultSolver::new(&pmat, &q, &amat, &bvec, &cones, settings)
        .map_err(|e| HinfError::Numerical(format!("clarabel setup: {e:?}")))?;
    solver.solve();
    let status = solver.solution.status;
    if !matches!(status, SolverStatus::Solved | SolverStatus::AlmostSolved) {
        return Err(HinfError::Numerical(format!(
            "the bounded-real SDP was not solved: {status:?}"
        )));
    }
    Ok(LmiNorm {
        gamma: solver.solution.x[np],
        status: format!("{status:?}"),
    })
}

fn to_csc(m: &DMatrix<f64>) -> CscMatrix<f64> {
    let (r, c) = m.shape();
    let mut colptr = Vec::with_capacity(c + 1);
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    colptr.push(0);
    for j in 0..c {
        for i in 0..r {
            let v = m[(i, j)];
            if v != 0.0 {
                rowval.push(i);
                nzval.push(v);
            }
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(r, c, colptr, rowval, nzval)
}
