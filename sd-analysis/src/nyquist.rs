//! The generalised Nyquist criterion of a MIMO loop (negative feedback `u = −K y`), and its
//! characteristic loci.
//!
//! **Criterion** (MacFarlane & Postlethwaite, Int. J. Control 25(1), 1977; Skogestad &
//! Postlethwaite, *Multivariable Feedback Control*, 2nd ed., Theorem 4.9). For realisations of
//! P and K with characteristic polynomials `χ_P`, `χ_K` and the closed loop's `χ_cl`,
//!
//! ```text
//! det(I + P(z)K(z)) = det(I + D_P D_K) · χ_cl(z) / (χ_P(z) χ_K(z)),
//! ```
//!
//! a rational function of equal numerator and denominator degree. By the argument principle
//! along a contour Γ that leaves the unstable region on its right (the circle `|z| = 1 + δ`
//! counterclockwise for a discrete loop; the line `Re s = δ` upwards, closed by a large
//! arc through the right half-plane, for a continuous one), the counterclockwise
//! encirclements `N` of the origin by `det(I + L)` satisfy `N = P − Z`: `P` open-loop poles
//! (of P and K) and `Z` closed-loop poles in the unstable region. The loop is stable iff
//! `Z = P − N = 0`. The small offset `δ` puts poles on the stability boundary (integrators,
//! `z = 1` or `s = 0`) on the stable side, as the usual indentation does.
//!
//! **Computation.** `det(I + P K)` is evaluated from the frequency responses of P and K (not
//! from the closed loop's poles), on half the contour (real systems are conjugate-symmetric,
//! and both ends of the half lie on the real axis): a grid clustered around the projection
//! of every open- and closed-loop pole onto the contour (at distances from 1/16 to 2¹⁶ times
//! the pole's distance to it, where the phase turns), a uniform and a logarithmic grid, each
//! step halved until it turns the argument by less than π/8. The count is then compared with
//! the closed-loop eigenvalues in the same region (`agrees`): an independent check of the
//! closed loop's realisation and of the encirclement count.
//!
//! **Characteristic loci**: the eigenvalues of `L(f) = P(f)K(f)` along the frequency axis,
//! matched from one frequency to the next by nearest distance (for a plot; the criterion
//! itself does not need them).

use crate::closed_loop::ClosedLoop;
use crate::error::{AnalysisError, Result};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::FreqRespEvaluator;
use std::f64::consts::PI;

/// Relative offset δ of the contour from the stability boundary.
const CONTOUR_OFFSET: f64 = 1e-8;
/// Largest argument change of `det(I + L)` accepted between two contour points (radians).
const MAX_TURN: f64 = PI / 8.0;
/// Largest number of halvings of one contour step.
const MAX_HALVINGS: usize = 48;

/// The generalised Nyquist criterion of a loop (module documentation).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Nyquist {
    /// Counterclockwise encirclements `N` of the origin by `det(I + L)` along the contour.
    pub encirclements: i64,
    /// Open-loop poles (of P and K) in the unstable region, `P`.
    pub open_loop_unstable: usize,
    /// Closed-loop poles in the unstable region by the criterion, `Z = P − N`.
    pub closed_loop_unstable: i64,
    /// Closed-loop poles in the unstable region counted from the closed loop's eigenvalues.
    pub closed_loop_unstable_eigenvalues: usize,
    /// Whether the two counts agree.
    pub agrees: bool,
    /// Stable by the criterion (`Z = 0`).
    pub stable: bool,
    /// The contour's offset δ from the stability boundary (`|z| = 1 + δ`, or `Re s = δ` in
    /// rad/s).
    pub contour_offset: f64,
    /// How far the accumulated argument was from a whole number of turns (a numerical check;
    /// ≪ 1 when the contour was resolved).
    pub turn_residual: f64,
    /// Evaluations of `det(I + P K)`.
    pub evaluations: usize,
}

/// The half contour: a point of the complex plane for each parameter value (an angle, an
/// imaginary part or an arc's fraction).
type Param = dyn Fn(f64) -> C;

/// `det(I + P(x)K(x))` at a point of the complex plane.
fn det_at(ev_p: &FreqRespEvaluator, ev_k: &FreqRespEvaluator, x: C) -> C {
    let p = ev_p.eval_at(x);
    let k = ev_k.eval_at(x);
    let n = p.nrows();
    (DMatrix::<C>::identity(n, n) + p * k).determinant()
}

/// The argument change of `d` along `t[0..]` with each step halved while it turns by more
/// than [`MAX_TURN`]; counts evaluations.
fn accumulated_turn(
    t: &[f64],
    point: &Param,
    det: &dyn Fn(C) -> C,
    evals: &mut usize,
) -> Result<f64> {
    let eval = |x: f64, evals: &mut usize| -> Result<C> {
        *evals += 1;
        let d = det(point(x));
        if d.re.is_finite() && d.im.is_finite() && d.norm() > 0.0 {
            Ok(d)
        } else {
            Err(AnalysisError::InvalidArgument(format!(
                "det(I + PK) is {d} on the Nyquist contour at {}: a pole on the contour (move \
                 it off the stability boundary)",
                point(x)
            )))
        }
    };
    let mut total = 0.0;
    let mut prev = eval(t[0], evals)?;
    for w in t.windows(2) {
        let end = eval(w[1], evals)?;
        // stack of (a, b, d(a), d(b)) pieces still to resolve, left to right
        let mut stack = vec![(w[0], w[1], prev, end, 0usize)];
        while let Some((a, b, da, db, depth)) = stack.pop() {
            let turn = (db / da).arg();
            if turn.abs() <= MAX_TURN || depth >= MAX_HALVINGS || b - a <= f64::EPSILON * b.abs() {
                total += turn;
                continue;
            }
            let m = 0.5 * (a + b);
            let dm = eval(m, evals)?;
            // the right half is resolved after the left one
            stack.push((m, b, dm, db, depth + 1));
            stack.push((a, m, da, dm, depth + 1));
        }
        prev = end;
    }
    Ok(total)
}

/// Points clustered around each pole's projection `c` (distance `d` to the contour) on
/// `[lo, hi]`, and the sorted union with `base`.
fn clustered(base: Vec<f64>, near: &[(f64, f64)], lo: f64, hi: f64) -> Vec<f64> {
    let mut t = base;
    for &(c, d) in near {
        let d = d.max(1e-14 * c.abs().max(1.0));
        t.push(c);
        for e in 0..=40 {
            let off = d * 2f64.powf(f64::from(e) / 2.0 - 4.0);
            t.push(c - off);
            t.push(c + off);
        }
    }
    t.retain(|x| x.is_finite() && *x >= lo && *x <= hi);
    t.push(lo);
    t.push(hi);
    t.sort_by(f64::total_cmp);
    t.dedup();
    t
}

/// The generalised Nyquist criterion of the loop (module documentation).
///
/// # Errors
/// A pole on the contour (`det(I + PK)` zero or infinite there), the pole computations.
pub fn generalized_nyquist(cl: &ClosedLoop) -> Result<Nyquist> {
    let (p, k) = (cl.plant(), cl.controller());
    let (ev_p, ev_k) = cl.evaluators();
    let mut open = p.poles()?;
    open.extend(k.poles()?);
    let closed = cl.closed_loop().poles()?;
    let det = |x: C| det_at(ev_p, ev_k, x);
    let mut evals = 0;
    let discrete = !p.time().is_continuous();
    let scale = open
        .iter()
        .chain(&closed)
        .map(|s| s.norm())
        .fold(1.0, f64::max);
    // δ: relative to the unit circle, or to the largest pole magnitude (rad/s)
    let delta = if discrete {
        CONTOUR_OFFSET
    } else {
        CONTOUR_OFFSET * scale
    };
    let unstable = |z: &C| {
        if discrete {
            z.norm() > 1.0 + delta
        } else {
            z.re > delta
        }
    };
    let turn = if discrete {
        let rho = 1.0 + delta;
        let near: Vec<(f64, f64)> = open
            .iter()
            .chain(&closed)
            .filter(|z| z.norm() > 0.0)
            .map(|z| (z.arg().abs(), (z.norm() - rho).abs()))
            .collect();
        let mut base: Vec<f64> = (0..=1024).map(|i| PI * f64::from(i) / 1024.0).collect();
        base.extend((1..=60).flat_map(|e| {
            let x = PI * 10f64.powf(-f64::from(e) / 4.0);
            [x, PI - x]
        }));
        let t = clustered(base, &near, 0.0, PI);
        let point = move |th: f64| C::from_polar(rho, th);
        accumulated_turn(&t, &point, &det, &mut evals)?
    } else {
        let big = 1e4 * scale;
        // the line Re s = δ from 0 to j·big (parameter: the imaginary part)…
        let near: Vec<(f64, f64)> = open
            .iter()
            .chain(&closed)
            .map(|s| (s.im.abs(), (s.re - delta).abs()))
            .collect();
        let mut base: Vec<f64> = (0..=1024).map(|i| big * f64::from(i) / 1024.0).collect();
        base.extend((0..=96).map(|e| scale * 10f64.powf(f64::from(e) / 8.0 - 8.0)));
        let t = clustered(base, &near, 0.0, big);
        let line = move |w: f64| C::new(delta, w);
        let on_line = accumulated_turn(&t, &line, &det, &mut evals)?;
        // …then the arc δ + big·e^{jφ} from φ = π/2 down to 0
        let u: Vec<f64> = (0..=256).map(|i| f64::from(i) / 256.0).collect();
        let arc = move |u: f64| C::new(delta, 0.0) + C::from_polar(big, 0.5 * PI * (1.0 - u));
        on_line + accumulated_turn(&u, &arc, &det, &mut evals)?
    };
    // the whole contour turns twice the half's argument (conjugate symmetry)
    let turns = 2.0 * turn / (2.0 * PI);
    let encirclements = turns.round() as i64;
    let open_unstable = open.iter().filter(|z| unstable(z)).count();
    let eig = closed.iter().filter(|z| unstable(z)).count();
    let z = open_unstable as i64 - encirclements;
    Ok(Nyquist {
        encirclements,
        open_loop_unstable: open_unstable,
        closed_loop_unstable: z,
        closed_loop_unstable_eigenvalues: eig,
        agrees: z == eig as i64,
        stable: z == 0,
        contour_offset: delta,
        turn_residual: (turns - turns.round()).abs(),
        evaluations: evals,
    })
}

/// The characteristic loci: the eigenvalues of `L(f) = P(f)K(f)` at `freq_hz`, one vector
/// per locus (matched between neighbouring frequencies by nearest distance).
///
/// # Errors
/// A non-square loop.
pub fn characteristic_loci(cl: &ClosedLoop, freq_hz: &[f64]) -> Result<Vec<Vec<C>>> {
    let (ev_p, ev_k) = cl.evaluators();
    let n = cl.plant().ny();
    let mut loci: Vec<Vec<C>> = vec![Vec::with_capacity(freq_hz.len()); n];
    for &f in freq_hz {
        let l = ev_p.eval_hz(f) * ev_k.eval_hz(f);
        let mut eig: Vec<C> = l
            .schur()
            .eigenvalues()
            .map_or_else(Vec::new, |v| v.iter().copied().collect());
        if eig.len() != n {
            return Err(AnalysisError::InvalidArgument(format!(
                "no eigenvalues of the {n}x{n} loop gain at {f} Hz"
            )));
        }
        // greedy nearest matching to the previous point of each locus
        for locus in loci.iter_mut() {
            let pick = match locus.last() {
                Some(last) => (0..eig.len())
                    .min_by(|&a, &b| (eig[a] - last).norm().total_cmp(&(eig[b] - last).norm()))
                    .unwrap_or(0),
                None => 0,
            };
            locus.push(eig.swap_remove(pick));
        }
    }
    Ok(loci)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use sd_model::{SampleTime, StateSpace};

    fn siso(a: &[f64], b: &[f64], c: &[f64], d: f64, time: SampleTime) -> StateSpace {
        let n = b.len();
        StateSpace::new(
            DMatrix::from_row_slice(n, n, a),
            DMatrix::from_row_slice(n, 1, b),
            DMatrix::from_row_slice(1, n, c),
            DMatrix::from_element(1, 1, d),
            time,
        )
        .unwrap()
    }

    fn gain(g: f64, time: SampleTime) -> StateSpace {
        StateSpace::gain(DMatrix::from_element(1, 1, g), time).unwrap()
    }

    /// `1/(z − 1.5)` under `u = −k y`: the closed-loop pole is `1.5 − k`, stable for
    /// `0.5 < k < 2.5`; the plant's unstable pole must be encircled once counterclockwise.
    #[test]
    fn unstable_plant_stabilised_by_a_gain() {
        let t = SampleTime::Discrete { ts: 1e-3 };
        let p = siso(&[1.5], &[1.0], &[1.0], 0.0, t);
        for (k, z) in [(1.0, 0), (0.2, 1), (2.7, 1)] {
            let n = generalized_nyquist(&ClosedLoop::new(&p, &gain(k, t)).unwrap()).unwrap();
            assert_eq!(n.open_loop_unstable, 1, "{n:?}");
            assert_eq!(n.closed_loop_unstable, z, "k = {k}: {n:?}");
            assert!(n.agrees && n.turn_residual < 1e-6, "{n:?}");
        }
    }

    /// A double integrator (continuous and its ZOH) with a PD controller: the poles at the
    /// boundary count as stable (the contour's indentation), no encirclement; the same loop
    /// with the wrong sign of the derivative is unstable with two closed-loop poles outside.
    #[test]
    fn double_integrator_with_pd() {
        let ct = SampleTime::Continuous;
        let p = siso(&[0.0, 1.0, 0.0, 0.0], &[0.0, 1.0], &[1.0, 0.0], 0.0, ct);
        // K = 4 + 3s/(s/100 + 1), proper
        let k = siso(&[-100.0], &[1.0], &[-30_000.0], 304.0, ct);
        let n = generalized_nyquist(&ClosedLoop::new(&p, &k).unwrap()).unwrap();
        assert_eq!(
            (n.open_loop_unstable, n.closed_loop_unstable),
            (0, 0),
            "{n:?}"
        );
        assert!(n.agrees && n.stable, "{n:?}");
        let bad = siso(&[-100.0], &[1.0], &[30_000.0], -296.0, ct);
        let n = generalized_nyquist(&ClosedLoop::new(&p, &bad).unwrap()).unwrap();
        assert!(n.agrees && !n.stable, "{n:?}");
        let h = 1e-3;
        let pd = sd_model::c2d(&p, h, sd_model::Discretization::Zoh).unwrap();
        let kd =
            sd_model::c2d(&k, h, sd_model::Discretization::Tustin { prewarp_hz: None }).unwrap();
        let n = generalized_nyquist(&ClosedLoop::new(&pd, &kd).unwrap()).unwrap();
        assert!(n.agrees && n.stable && n.turn_residual < 1e-6, "{n:?}");
    }

    /// A small deterministic generator (splitmix64) for the property test.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        }
        fn matrix(&mut self, r: usize, c: usize, s: f64) -> DMatrix<f64> {
            DMatrix::from_fn(r, c, |_, _| s * self.next())
        }
    }

    /// Property: on random 2×2 loops (3-state plants with poles on both sides of the
    /// boundary, 1-state controllers, continuous and discrete) the count of the criterion
    /// equals the closed-loop eigenvalues' (cases with a closed-loop pole within 1e-6 of the
    /// boundary are skipped: there the count is decided by rounding).
    #[test]
    fn counts_agree_with_eigenvalues_on_random_loops() {
        let mut rng = Rng(2026);
        let (mut checked, mut unstable, mut encircled) = (0, 0, 0);
        for case in 0..240 {
            let discrete = case % 2 == 0;
            let time = if discrete {
                SampleTime::Discrete { ts: 1e-3 }
            } else {
                SampleTime::Continuous
            };
            let a = rng.matrix(3, 3, if discrete { 0.6 } else { 1.0 });
            let p = StateSpace::new(
                a,
                rng.matrix(3, 2, 1.0),
                rng.matrix(2, 3, 1.0),
                rng.matrix(2, 2, 0.1),
                time,
            )
            .unwrap();
            let k = StateSpace::new(
                rng.matrix(2, 2, if discrete { 0.6 } else { 1.5 }),
                rng.matrix(2, 2, 1.0),
                rng.matrix(2, 2, 1.0),
                rng.matrix(2, 2, 1.0),
                time,
            )
            .unwrap();
            let Ok(cl) = ClosedLoop::new(&p, &k) else {
                continue;
            };
            let poles = cl.closed_loop().poles().unwrap();
            let margin = poles
                .iter()
                .map(|z| {
                    if discrete {
                        (z.norm() - 1.0).abs()
                    } else {
                        z.re.abs()
                    }
                })
                .fold(f64::INFINITY, f64::min);
            if margin < 1e-6 {
                continue;
            }
            let n = generalized_nyquist(&cl).unwrap();
            assert!(n.agrees, "case {case}: {n:?}, closed-loop poles {poles:?}");
            assert!(n.turn_residual < 1e-3, "case {case}: {n:?}");
            checked += 1;
            unstable += usize::from(!n.stable);
            encircled += usize::from(n.encirclements != 0);
        }
        println!("{checked} loops checked, {unstable} unstable, {encircled} with encirclements");
        // both outcomes occur often enough for the test to mean something
        assert!(
            checked > 200 && unstable > 30 && checked - unstable > 30,
            "{checked} {unstable}"
        );
    }

    /// A lightly damped discrete mode (ζ = 1e-4) whose loop circles the critical point: the
    /// refinement resolves the resonance.
    #[test]
    fn lightly_damped_mode() {
        let h = 1e-3;
        let w = 2.0 * PI * 120.0;
        let zeta = 1e-4;
        let ct = siso(
            &[0.0, 1.0, -w * w, -2.0 * zeta * w],
            &[0.0, w * w],
            &[1.0, 0.0],
            0.0,
            SampleTime::Continuous,
        );
        let p = sd_model::c2d(&ct, h, sd_model::Discretization::Zoh).unwrap();
        let t = SampleTime::Discrete { ts: h };
        for k in [0.5, -1.5, 3.0] {
            let n = generalized_nyquist(&ClosedLoop::new(&p, &gain(k, t)).unwrap()).unwrap();
            assert!(n.agrees && n.turn_residual < 1e-6, "k = {k}: {n:?}");
        }
        let loci = characteristic_loci(
            &ClosedLoop::new(&p, &gain(0.5, t)).unwrap(),
            &[10.0, 120.0, 400.0],
        )
        .unwrap();
        assert_eq!(loci.len(), 1);
        assert!(loci[0][1].norm() > 100.0, "{loci:?}");
    }
}
