//! Lifting: an F-periodic fast-rate system as an LTI system at the slow rate, and back.
//!
//! For a fast model `(A, B, C, D)` at period h and `T = F·h`, stack one slow period of signals,
//! `ū_k = [u(kF); …; u(kF+F−1)]`, `ȳ_k` likewise (Bamieh, Pearson, Francis & Tannenbaum 1991;
//! Chen & Francis, *Optimal Sampled-Data Control Systems*, §8.1):
//!
//! ```text
//! x_{k+1} = A^F x_k + [A^{F−1}B … AB B] ū_k
//! ȳ_k     = col_i(C A^i) x_k + D̄ ū_k,   D̄_ij = D (i = j), C A^{i−j−1} B (i > j), 0 (i < j)
//! ```
//!
//! The lifted model is LTI at T with F·nu inputs and F·ny outputs; its state is the fast state at
//! the slow instants, so its poles are those of `A^F`. Going back ([`PeriodicSystem::unlift`])
//! gives an F-periodic fast-rate system with time-varying state dimension: at phase i the state
//! is `[x_k; u(kF); …; u(kF+i−1)]` (the inputs of the period so far), which reproduces any lifted
//! model exactly — `lift(unlift(L)) = L` entry for entry. [`lift`] builds the matrices by the
//! recursion `x_{i+1} = A x_i + B u_i` (F products with A), no powers formed separately.

use crate::error::{check_factor, require_discrete, MultirateError, Result};
use nalgebra::{DMatrix, DVector};
use sd_model::{SampleTime, StateSpace};

/// The lifted model of a fast discrete model over `factor` samples (module documentation).
///
/// # Errors
/// A continuous model, an invalid factor.
pub fn lift(p_h: &StateSpace, factor: usize) -> Result<StateSpace> {
    require_discrete(p_h, "lift")?;
    check_factor(factor)?;
    PeriodicSystem::from_lti(p_h, factor)?.lift()
}

/// One phase of a periodic system: maps the state at fast step `kF+i` (dimension `n_i`) to the
/// state at `kF+i+1` (dimension `n_{i+1}`, with `n_F = n_0`).
#[derive(Debug, Clone, PartialEq)]
pub struct Phase {
    /// `n_{i+1} × n_i`.
    pub a: DMatrix<f64>,
    /// `n_{i+1} × nu`.
    pub b: DMatrix<f64>,
    /// `ny × n_i`.
    pub c: DMatrix<f64>,
    /// `ny × nu`.
    pub d: DMatrix<f64>,
}

/// A fast-rate F-periodic linear system `x_{i+1} = A_i x_i + B_i u_i`, `y_i = C_i x_i + D_i u_i`
/// (phase index `i mod F`), possibly with time-varying state dimension.
#[derive(Debug, Clone, PartialEq)]
pub struct PeriodicSystem {
    phases: Vec<Phase>,
    ts: f64,
}

impl PeriodicSystem {
    /// Checks the phase shapes: `n_{i+1}` from `a`'s rows must match the next phase's columns,
    /// common nu and ny, finite entries.
    pub fn new(phases: Vec<Phase>, ts: f64) -> Result<Self> {
        SampleTime::discrete(ts)?;
        let f = phases.len();
        check_factor(f)?;
        let nu = phases[0].b.ncols();
        let ny = phases[0].c.nrows();
        for (i, p) in phases.iter().enumerate() {
            let ni = p.a.ncols();
            let nn = phases[(i + 1) % f].a.ncols();
            let ok = p.a.nrows() == nn
                && p.b.nrows() == nn
                && p.b.ncols() == nu
                && p.c.ncols() == ni
                && p.c.nrows() == ny
                && p.d.nrows() == ny
                && p.d.ncols() == nu;
            if !ok {
                return Err(MultirateError::InvalidArgument(format!(
                    "periodic system phase {i}: shapes a {}x{}, b {}x{}, c {}x{}, d {}x{} do not \
                     chain (a must be n_(i+1) x n_i with nu = {nu}, ny = {ny})",
                    p.a.nrows(),
                    p.a.ncols(),
                    p.b.nrows(),
                    p.b.ncols(),
                    p.c.nrows(),
                    p.c.ncols(),
                    p.d.nrows(),
                    p.d.ncols()
                )));
            }
            for (m, what) in [(&p.a, "a"), (&p.b, "b"), (&p.c, "c"), (&p.d, "d")] {
                if m.iter().any(|v| !v.is_finite()) {
                    return Err(MultirateError::InvalidArgument(format!(
                        "periodic system phase {i}: {what} has a NaN or infinite entry"
                    )));
                }
            }
        }
        Ok(PeriodicSystem { phases, ts })
    }

    /// An LTI fast model seen as F-periodic (F identical phases).
    pub fn from_lti(p: &StateSpace, factor: usize) -> Result<Self> {
        let ts = require_discrete(p, "periodic system from an LTI model")?;
        check_factor(factor)?;
        let ph = Phase {
            a: p.a().clone(),
            b: p.b().clone(),
            c: p.c().clone(),
            d: p.d().clone(),
        };
        Ok(PeriodicSystem {
            phases: vec![ph; factor],
            ts,
        })
    }

    /// The period F (number of phases).
    pub fn period(&self) -> usize {
        self.phases.len()
    }
    /// The fast sampling period h.
    pub fn ts(&self) -> f64 {
        self.ts
    }
    /// Number of inputs.
    pub fn nu(&self) -> usize {
        self.phases[0].b.ncols()
    }
    /// Number of outputs.
    pub fn ny(&self) -> usize {
        self.phases[0].c.nrows()
    }
    /// The phases.
    pub fn phases(&self) -> &[Phase] {
        &self.phases
    }

    /// The lifted LTI model at `T = F·h`.
    pub fn lift(&self) -> Result<StateSpace> {
        let f = self.period();
        let (nu, ny) = (self.nu(), self.ny());
        let n0 = self.phases[0].a.ncols();
        let mut phi = DMatrix::<f64>::identity(n0, n0);
        let mut gam = DMatrix::<f64>::zeros(n0, f * nu);
        let mut cl = DMatrix::<f64>::zeros(f * ny, n0);
        let mut dl = DMatrix::<f64>::zeros(f * ny, f * nu);
        for (i, p) in self.phases.iter().enumerate() {
            cl.view_mut((i * ny, 0), (ny, n0)).copy_from(&(&p.c * &phi));
            let cg = &p.c * &gam;
            dl.view_mut((i * ny, 0), (ny, f * nu)).copy_from(&cg);
            let mut blk = dl.view_mut((i * ny, i * nu), (ny, nu));
            blk += &p.d;
            let mut ng = &p.a * &gam;
            let mut col = ng.view_mut((0, i * nu), (p.b.nrows(), nu));
            col += &p.b;
            gam = ng;
            phi = &p.a * &phi;
        }
        Ok(StateSpace::new(
            phi,
            gam,
            cl,
            dl,
            SampleTime::discrete(self.ts * f as f64)?,
        )?)
    }

    /// The fast-rate periodic system of a lifted model with F·nu inputs and F·ny outputs
    /// (module documentation).
    ///
    /// # Errors
    /// A continuous model, input/output counts not divisible by F, an invalid factor.
    pub fn unlift(lifted: &StateSpace, factor: usize) -> Result<Self> {
        let t = require_discrete(lifted, "unlift")?;
        check_factor(factor)?;
        if lifted.nu() % factor != 0 || lifted.ny() % factor != 0 {
            return Err(MultirateError::InvalidArgument(format!(
                "a lifted model over F = {factor} needs input and output counts divisible by F, \
                 got {} inputs and {} outputs",
                lifted.nu(),
                lifted.ny()
            )));
        }
        let (nu, ny, n) = (lifted.nu() / factor, lifted.ny() / factor, lifted.n());
        let (al, bl, cl, dl) = (lifted.a(), lifted.b(), lifted.c(), lifted.d());
        let mut phases = Vec::with_capacity(factor);
        for i in 0..factor {
            let ni = n + i * nu;
            let mut c = DMatrix::<f64>::zeros(ny, ni);
            c.view_mut((0, 0), (ny, n))
                .copy_from(&cl.view((i * ny, 0), (ny, n)));
            for j in 0..i {
                c.view_mut((0, n + j * nu), (ny, nu))
                    .copy_from(&dl.view((i * ny, j * nu), (ny, nu)));
            }
            let d = dl.view((i * ny, i * nu), (ny, nu)).into_owned();
            let (a, b) = if i + 1 < factor {
                let nn = ni + nu;
                let mut a = DMatrix::<f64>::zeros(nn, ni);
                a.view_mut((0, 0), (ni, ni)).fill_with_identity();
                let mut b = DMatrix::<f64>::zeros(nn, nu);
                b.view_mut((ni, 0), (nu, nu)).fill_with_identity();
                (a, b)
            } else {
                let mut a = DMatrix::<f64>::zeros(n, ni);
                a.view_mut((0, 0), (n, n)).copy_from(al);
                a.view_mut((0, n), (n, i * nu))
                    .copy_from(&bl.view((0, 0), (n, i * nu)));
                let b = bl.view((0, i * nu), (n, nu)).into_owned();
                (a, b)
            };
            phases.push(Phase { a, b, c, d });
        }
        PeriodicSystem::new(phases, t / factor as f64)
    }

    /// Simulates from phase 0 with the given initial state (zero if `None`); `u` is N×nu, one
    /// row per fast sample; returns N×ny.
    pub fn simulate(&self, u: &DMatrix<f64>, x0: Option<&DVector<f64>>) -> Result<DMatrix<f64>> {
        if u.ncols() != self.nu() {
            return Err(MultirateError::InvalidArgument(format!(
                "input signal has {} columns, the system has {} inputs",
                u.ncols(),
                self.nu()
            )));
        }
        if u.iter().any(|v| !v.is_finite()) {
            return Err(MultirateError::InvalidArgument(
                "input signal contains a NaN or infinite value".into(),
            ));
        }
        let n0 = self.phases[0].a.ncols();
        let mut x = match x0 {
            Some(x) if x.len() != n0 => {
                return Err(MultirateError::InvalidArgument(format!(
                    "initial state has {} entries, phase 0 has {n0} states",
                    x.len()
                )))
            }
            Some(x) => x.clone(),
            None => DVector::zeros(n0),
        };
        let f = self.period();
        let mut y = DMatrix::zeros(u.nrows(), self.ny());
        for k in 0..u.nrows() {
            let p = &self.phases[k % f];
            let uk = u.row(k).transpose();
            let yk = &p.c * &x + &p.d * &uk;
            y.row_mut(k).copy_from(&yk.transpose());
            x = &p.a * &x + &p.b * &uk;
        }
        Ok(y)
    }
}

/// Stacks a fast signal (N×m, N a multiple of F) into its lifted form (N/F × F·m).
pub fn stack(signal: &DMatrix<f64>, factor: usize) -> Result<DMatrix<f64>> {
    check_factor(factor)?;
    if signal.nrows() % factor != 0 {
        return Err(MultirateError::InvalidArgument(format!(
            "signal length {} is not a multiple of F = {factor}",
            signal.nrows()
        )));
    }
    let m = signal.ncols();
    let rows = signal.nrows() / factor;
    Ok(DMatrix::from_fn(rows, factor * m, |k, j| {
        signal[(k * factor + j / m, j % m)]
    }))
}

/// Inverse of [`stack`]: (N/F × F·m) back to (N × m).
pub fn unstack(lifted: &DMatrix<f64>, factor: usize) -> Result<DMatrix<f64>> {
    check_factor(factor)?;
    if lifted.ncols() % factor != 0 {
        return Err(MultirateError::InvalidArgument(format!(
            "lifted signal width {} is not a multiple of F = {factor}",
            lifted.ncols()
        )));
    }
    let m = lifted.ncols() / factor;
    Ok(DMatrix::from_fn(lifted.nrows() * factor, m, |t, j| {
        lifted[(t / factor, (t % factor) * m + j)]
    }))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use sd_model::{c2d, Discretization};

    fn fast() -> StateSpace {
        let p = sd_model::stage::paper_stage(0.01).unwrap();
        let ph = c2d(&p, 2e-4, Discretization::Zoh).unwrap();
        // add feedthrough so D̄ is exercised
        StateSpace::new(
            ph.a().clone(),
            ph.b().clone(),
            ph.c().clone(),
            DMatrix::from_element(1, 1, 1e-7),
            ph.time(),
        )
        .unwrap()
    }

    fn input(n: usize) -> DMatrix<f64> {
        DMatrix::from_fn(n, 1, |k, _| ((k * 7919 % 113) as f64 - 56.0) / 56.0)
    }

    #[test]
    fn lifted_simulation_equals_fast_simulation() {
        let p = fast();
        let f = 5;
        let l = lift(&p, f).unwrap();
        assert!((l.ts().unwrap() - 1e-3).abs() < 1e-18);
        let u = input(400);
        let y = p.simulate(&u, None).unwrap().y;
        let yl = l.simulate(&stack(&u, f).unwrap(), None).unwrap().y;
        let y2 = unstack(&yl, f).unwrap();
        assert!((&y - &y2).norm() <= 1e-10 * y.norm());
        // the periodic system of the lifted model behaves like the fast model
        let per = PeriodicSystem::unlift(&l, f).unwrap();
        let y3 = per.simulate(&u, None).unwrap();
        assert!((&y - &y3).norm() <= 1e-10 * y.norm());
    }

    #[test]
    fn lift_of_unlift_is_exact() {
        let l = lift(&fast(), 4).unwrap();
        let back = PeriodicSystem::unlift(&l, 4).unwrap().lift().unwrap();
        assert_eq!(back.a(), l.a());
        assert_eq!(back.b(), l.b());
        assert_eq!(back.c(), l.c());
        assert_eq!(back.d(), l.d());
    }

    #[test]
    fn bad_shapes_are_errors() {
        let l = lift(&fast(), 4).unwrap();
        assert!(PeriodicSystem::unlift(&l, 3).is_err());
        assert!(stack(&DMatrix::zeros(7, 1), 2).is_err());
        let per = PeriodicSystem::from_lti(&fast(), 2).unwrap();
        assert!(per.simulate(&DMatrix::zeros(4, 2), None).is_err());
        let mut ph = per.phases().to_vec();
        ph[1].c = DMatrix::zeros(1, 3);
        assert!(PeriodicSystem::new(ph, 1e-3).is_err());
        assert!(PeriodicSystem::new(vec![], 1e-3).is_err());
    }
}
