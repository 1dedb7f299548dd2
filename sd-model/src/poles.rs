//! Poles and invariant zeros.
//!
//! Poles: eigenvalues of A (faer's multishift QR). Invariant zeros: the finite generalized
//! eigenvalues of the Rosenbrock pencil `[[A, B], [C, D]] − λ [[I, 0], [0, 0]]` (faer's QZ),
//! following Emami-Naeini & Van Dooren (Automatica 18(4), 1982) for square systems. A
//! non-square system is compressed to square by two different fixed random combinations of its
//! outputs (ny > nu) or inputs (nu > ny); the invariant zeros are the values common to both
//! (generic compressions keep exactly the invariant zeros). A pencil that is singular (normal rank
//! deficient, e.g. an identically-zero channel) is reported as an error.

use crate::error::{ModelError, Result};
use crate::linalg::convert::{eigenvalues, generalized_eigenvalues};
use crate::linalg::expm::norm1;
use crate::ss::StateSpace;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

impl StateSpace {
    /// Poles (eigenvalues of A), sorted by modulus then argument.
    pub fn poles(&self) -> Result<Vec<C>> {
        let mut p = eigenvalues(self.a())?;
        p.sort_by(|a, b| {
            a.norm()
                .total_cmp(&b.norm())
                .then(a.arg().total_cmp(&b.arg()))
        });
        Ok(p)
    }

    /// Invariant zeros (finite), sorted by modulus.
    pub fn zeros(&self) -> Result<Vec<C>> {
        let (ny, nu) = (self.ny(), self.nu());
        if ny == nu {
            return square_zeros(self.a(), self.b(), self.c(), self.d());
        }
        let r = ny.min(nu);
        let mut sets = Vec::new();
        for seed in [0x9e3779b97f4a7c15u64, 0xc2b2ae3d27d4eb4f] {
            let w = pseudo_random(r, ny.max(nu), seed);
            let z = if ny > nu {
                square_zeros(self.a(), self.b(), &(&w * self.c()), &(&w * self.d()))?
            } else {
                square_zeros(
                    self.a(),
                    &(self.b() * w.transpose()),
                    self.c(),
                    &(self.d() * w.transpose()),
                )?
            };
            sets.push(z);
        }
        let scale = norm1(self.a()).max(1.0);
        let mut common: Vec<C> = sets[0]
            .iter()
            .filter(|z| {
                sets[1]
                    .iter()
                    .any(|y| (*y - **z).norm() <= 1e-6 * scale.max(z.norm()))
            })
            .cloned()
            .collect();
        common.sort_by(|a, b| a.norm().total_cmp(&b.norm()));
        Ok(common)
    }
}

fn pseudo_random(r: usize, c: usize, seed: u64) -> DMatrix<f64> {
    let mut s = seed;
    DMatrix::from_fn(r, c, |_, _| {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    })
}

fn square_zeros(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    c: &DMatrix<f64>,
    d: &DMatrix<f64>,
) -> Result<Vec<C>> {
    let n = a.nrows();
    let m = b.ncols();
    let mut p = DMatrix::zeros(n + m, n + m);
    p.view_mut((0, 0), (n, n)).copy_from(a);
    p.view_mut((0, n), (n, m)).copy_from(b);
    p.view_mut((n, 0), (m, n)).copy_from(c);
    p.view_mut((n, n), (m, m)).copy_from(d);
    let mut e = DMatrix::zeros(n + m, n + m);
    e.view_mut((0, 0), (n, n)).fill_with_identity();
    let scale = norm1(&p).max(1.0);
    let ev = generalized_eigenvalues(&p, &e)?;
    let mut out = Vec::new();
    for (alpha, beta) in ev {
        let tiny = 1e3 * f64::EPSILON;
        if alpha.norm() <= tiny * scale && beta.norm() <= tiny {
            return Err(ModelError::Singular {
                what: "the system pencil (normal rank deficient: zeros are undefined, e.g. a zero channel)".into(),
            });
        }
        if beta.norm() * 1e10 * scale > alpha.norm() {
            out.push(alpha / beta);
        }
    }
    out.sort_by(|a, b| a.norm().total_cmp(&b.norm()));
    Ok(out)
}

/// `(natural frequency in Hz, damping ratio)` of a pole: of `p` itself for a continuous model
/// (`ts = None`), of the principal continuous pole `s = ln(p)/ts` for a discrete one;
/// `f = |s|/2π`, `ζ = −Re s/|s|` (ζ = 1 at s = 0). The toolkit's one definition of a pole's
/// frequency (`sdctl poles`, `sdctl d2c`, python-control's `damp`).
pub fn natural_frequency(p: C, ts: Option<f64>) -> (f64, f64) {
    let s = match ts {
        None => p,
        Some(h) => p.ln() / h,
    };
    let f = s.norm() / (2.0 * std::f64::consts::PI);
    let z = if s.norm() == 0.0 {
        1.0
    } else {
        -s.re / s.norm()
    };
    (f, z)
}
