//! Whether a point of the complex plane is a pole of `G(s) = C(sI − A)⁻¹B + D`: the frequency
//! response there is infinite, not the huge finite number that rounding makes of it.
//!
//! **Criterion.** `s` is a pole to working precision when it lies within `100·n·ε·max(|λ|,
//! ‖T‖)` of a computed eigenvalue `λ`; a defective eigenvalue's computed copies (one block of
//! the reduced form, split by rounding by about `ε^{1/m}`) stand for their mean, which is
//! accurate to `O(ε‖A‖)` (the trace of the block is well conditioned). A small singular value of
//! `sI − A` alone is no test: a point 3·10⁻³ from a rigid body's triple pole at z = 1 in a
//! non-normal realization lies in the `10·n·ε·‖A‖`-pseudospectrum (Trefethen & Embree,
//! *Spectra and Pseudospectra*, 2005) and its response is finite and accurate to 1e-8
//! (`tests/tests/model_ops.rs`).
//!
//! **Which entries.** Entry `(i, j)` is infinite when a singular pair `(u, v)` of the near-null
//! space of `sI − A` reaches both its output and its input: `|cᵢ·v| > √ε·‖cᵢ‖` and
//! `|uᴴbⱼ| > √ε·‖bⱼ‖` (the pairs with `σ` within ten times the smallest, or below
//! `τ = 10·n·ε·‖A‖_F`). A mode that is uncontrollable from input `j` or unobservable at
//! output `i` is no pole of that entry (a removable singularity, where the solve divides 0
//! by 0): the entry is the mean of its values at `s + δ·iᵏ`, `k = 0..3`
//! ([`PoleGuard::circle`]).
//!
//! **Cost.** The singular value decomposition (O(n³)) runs only at points within those radii;
//! the eigenvalues whose radius does not reach the frequency axis are not looked at.

use crate::time::SampleTime;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// Relative backward error within which a point is a pole (module documentation).
const TAU: f64 = 10.0;

/// The model's eigenvalues with the radius within which a point is checked, and `A`, `B`, `C`
/// for the check.
#[derive(Debug, Clone)]
pub(crate) struct PoleGuard {
    /// The eigenvalues (a defective one's copies as their mean) within their radius of the
    /// frequency axis (jω or the unit circle), with that radius: only they can be hit.
    on_axis: Vec<(C, f64)>,
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    tau: f64,
    scale: f64,
}

impl PoleGuard {
    /// The guard of a model with computed eigenvalues `eig`, each with the index of the
    /// cluster (block of the reduced form) it belongs to.
    ///
    /// `scale` is the norm of the (balanced) matrix the eigenvalues were computed from.
    pub(crate) fn new(
        (a, b, c): (&DMatrix<f64>, &DMatrix<f64>, &DMatrix<f64>),
        eig: &[(C, usize)],
        scale: f64,
        time: SampleTime,
    ) -> Self {
        let n = a.nrows();
        let an = a.norm();
        let eig: Vec<(C, f64)> = eig
            .iter()
            .map(|&(l, block)| {
                let size = l.norm().max(scale);
                let m = eig.iter().filter(|e| e.1 == block).count();
                let floor = 100.0 * n as f64 * f64::EPSILON * size;
                // a defective eigenvalue's computed copies are split by rounding by about
                // ε^{1/m}, but their mean is accurate to O(ε‖A‖) (the trace of the block):
                // the copies within that reach stand for their mean
                let reach = 10.0 * f64::EPSILON.powf(1.0 / m.max(1) as f64) * size;
                let copies: Vec<C> = eig
                    .iter()
                    .filter(|e| e.1 == block && (e.0 - l).norm() <= reach)
                    .map(|e| e.0)
                    .collect();
                let mean = copies.iter().sum::<C>() / copies.len().max(1) as f64;
                (mean, floor)
            })
            .collect();
        // the frequency axis (jω or the unit circle) passes within the radius of few
        let on_axis = eig
            .into_iter()
            .filter(|&(l, r)| match time {
                SampleTime::Continuous => l.re.abs() <= r,
                SampleTime::Discrete { .. } => (l.norm() - 1.0).abs() <= r,
            })
            .collect();
        PoleGuard {
            on_axis,
            a: a.clone(),
            b: b.clone(),
            c: c.clone(),
            tau: TAU * n as f64 * f64::EPSILON * an,
            scale,
        }
    }

    /// Sets the entries of `g` (column-major ny×nu) for which `s`, a point of the frequency
    /// axis, is a pole to `+∞`.
    pub(crate) fn mark(&self, s: C, g: &mut [C]) -> AtPole {
        if !self.on_axis.iter().any(|&(l, r)| (s - l).norm() <= r) {
            return AtPole::No;
        }
        let n = self.a.nrows();
        let m = DMatrix::<C>::from_fn(n, n, |i, j| {
            let v = C::new(-self.a[(i, j)], 0.0);
            if i == j {
                v + s
            } else {
                v
            }
        });
        let svd = m.svd(true, true);
        let (Some(u), Some(vt)) = (&svd.u, &svd.v_t) else {
            return AtPole::No;
        };
        let (ny, nu) = (self.c.nrows(), self.b.ncols());
        let tol = f64::EPSILON.sqrt();
        // the singular pairs of the (near-)null space: all within 10× the smallest (a pole of
        // multiplicity k in a MIMO model has k of them)
        let smallest = svd
            .singular_values
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        for (k, &sv) in svd.singular_values.iter().enumerate() {
            if sv > (10.0 * smallest).max(self.tau) {
                continue;
            }
            // the right null vector is row k of Vᴴ conjugated, the left one column k of U
            let v: Vec<C> = (0..n).map(|t| vt[(k, t)].conj()).collect();
            for i in 0..ny {
                let ci = self.c.row(i);
                let cv: C = (0..n).map(|t| v[t] * ci[t]).sum();
                if cv.norm() <= tol * ci.norm() {
                    continue;
                }
                for j in 0..nu {
                    let bj = self.b.column(j);
                    let ub: C = (0..n).map(|t| u[(t, k)].conj() * bj[t]).sum();
                    if ub.norm() > tol * bj.norm() {
                        g[j * ny + i] = C::new(f64::INFINITY, 0.0);
                    }
                }
            }
        }
        AtPole::Eigenvalue
    }

    /// Radius of the circle whose mean gives an entry's value at an eigenvalue that is no
    /// pole of it (a removable singularity): the mean of an analytic function over the four
    /// points `s + δ·iᵏ` is its value at `s` to `O(δ⁴)`.
    /// `δ = 10⁻⁶·max(|s|, ‖T‖)`: the neighbouring poles are much further, and a rounding
    /// residue `ε‖r‖` of the removable pole adds only `ε‖r‖/δ`.
    pub(crate) fn circle(&self, s: C) -> f64 {
        1e-6 * s.norm().max(self.scale)
    }
}

/// What [`PoleGuard::mark`] found at a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum AtPole {
    /// No eigenvalue there.
    No,
    /// An eigenvalue of `A` (to working precision): the entries it is a pole of are `+∞`; the
    /// others must be evaluated around it ([`PoleGuard::circle`]).
    Eigenvalue,
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn guard(a: &[f64], n: usize, b: &[f64], c: &[f64]) -> PoleGuard {
        let a = DMatrix::from_row_slice(n, n, a);
        let b = DMatrix::from_row_slice(n, b.len() / n, b);
        let c = DMatrix::from_row_slice(c.len() / n, n, c);
        let eig: Vec<(C, usize)> = a
            .clone()
            .complex_eigenvalues()
            .iter()
            .map(|&l| (l, n))
            .collect();
        let scale = a.norm();
        let time = if a[(0, 0)] == 1.0 {
            SampleTime::Discrete { ts: 1e-3 }
        } else {
            SampleTime::Continuous
        };
        PoleGuard::new((&a, &b, &c), &eig, scale, time)
    }

    #[test]
    fn a_double_integrator_is_a_pole_at_one_and_nowhere_near() {
        let g = guard(&[1.0, 1e-3, 0.0, 1.0], 2, &[0.0, 1e-3], &[1.0, 0.0]);
        let mut out = [C::new(0.0, 0.0)];
        assert_eq!(g.mark(C::new(1.0, 0.0), &mut out), AtPole::Eigenvalue);
        assert!(out[0].re.is_infinite());
        let mut out = [C::new(0.0, 0.0)];
        let z = C::from_polar(1.0, std::f64::consts::TAU * 0.5e-3);
        assert_eq!(g.mark(z, &mut out), AtPole::No);
        assert_eq!(out[0], C::new(0.0, 0.0));
    }

    #[test]
    fn an_uncontrollable_mode_is_no_pole_of_the_entry() {
        // two integrators, input 1 drives the first only, output 1 reads both
        let g = guard(
            &[0.0, 0.0, 0.0, -1.0],
            2,
            &[1.0, 0.0, 0.0, 1.0],
            &[1.0, 1.0],
        );
        let mut out = [C::new(5.0, 0.0); 2];
        assert_eq!(g.mark(C::new(0.0, 0.0), &mut out), AtPole::Eigenvalue);
        assert!(out[0].re.is_infinite());
        assert_eq!(out[1], C::new(5.0, 0.0));
    }

    #[test]
    fn an_undamped_mode_at_its_frequency() {
        let w = std::f64::consts::TAU * 10.0;
        let g = guard(&[0.0, 1.0, -w * w, 0.0], 2, &[0.0, 1.0], &[1.0, 0.0]);
        let mut out = [C::new(0.0, 0.0)];
        assert_eq!(g.mark(C::new(0.0, w), &mut out), AtPole::Eigenvalue);
        assert!(out[0].re.is_infinite());
        // a millihertz off the mode is a finite (large) response
        let mut out = [C::new(0.0, 0.0)];
        let off = C::new(0.0, w + std::f64::consts::TAU * 1e-3);
        assert_eq!(g.mark(off, &mut out), AtPole::No);
    }
}
