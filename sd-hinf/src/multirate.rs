//! Multirate H∞ synthesis for the intersample error: the slow-rate controller that is best for
//! the error *between* its samples, designed on a fast-rate model.
//!
//! # The problem
//!
//! A fast discrete plant `G` at period `h` (the identified model), a controller `K` at
//! `T = F·h` that samples the measured error at the slow instants and holds its output over
//! `F` fast samples. In fast time, with the loop and weights of [`crate::augw`] (negative
//! feedback, `u_k = K·m_k`):
//!
//! ```text
//! y = G(u + W_d d),  e = W_r r̃ − y,  z₁ = W₁e,  z₂ = W₂u,  z₃ = W₃y     (fast rate)
//! m_k = e(kF) − W_n n_k,   u(kF + i) = u_k  (i = 0 … F−1)              (slow rate)
//! ```
//!
//! `d` is a fast force disturbance (its content above the slow Nyquist frequency included),
//! `r = W_r r̃` a smooth reference or output disturbance (a motion system's setpoints are
//! band-limited), `n` the sensor noise at the slow samples. The objective is the induced norm
//! of the periodic closed loop from `(r̃, d, n)` to `(z₁, z₂, z₃)` with every fast signal
//! counted at every *fast* sample: everything the error does between the controller's samples
//! counts. Energies are in physical time (`Σ|x|²·h` for a fast signal, `Σ|x|²·T` for a slow
//! one), so the slow noise's column carries `1/√F`. A single-rate mixed-sensitivity design at
//! `T` with the same weights sees only the samples.
//!
//! Why the reference is shaped and fast, not the held sequence `r_k`: a staircase `r` makes
//! `e = r − y` a sawtooth between the samples (`y` cannot jump) whose size is `i·h·ẏ`, so
//! `W₁`'s large low-frequency gain would charge every controller for the reference's own
//! steps, from far below the crossover; and an unshaped fast `r` enters `e` directly at phases the sampler never sees. With
//! no `W_r` the problem is disturbance rejection only (`W_d`, `W_n`).
//!
//! # Lifting makes it LTI
//!
//! Stacking one slow period of the fast signals, `d̄_k = [d(kF); …; d(kF+F−1)]`, `r̄_k` and `z̄_k`
//! likewise, is an isometry of ℓ₂ (the same numbers, regrouped), and turns the F-periodic loop
//! into an LTI loop at `T` (Chen & Francis, *Optimal Sampled-Data Control Systems*, 1995,
//! ch. 8; Chen & Qiu, "H∞ design of general multirate sampled-data control systems",
//! *Automatica* 30(7), 1994). The lifted generalized plant is built in three steps: the fast
//! plant `P_f` with inputs `[r̃; d; u]` and outputs `[z; e]` ([`crate::augw`], `W_r` in
//! series with its reference), its lift over
//! `F` (`sd_multirate::lift`: state matrix `Aᶠ`, `D̄` block lower triangular), then the hold
//! (every phase's `u` is the one slow `u_k`: the input map sums the lifted `B` and `D`
//! columns of `u` over the phases) and the sampler (`m_k` is phase 0's `e` row), with the
//! noise column `−W_n/√F`. The result has `F·(n_r + n_d) + n_n` exogenous inputs, `n_u`
//! controls, `F·n_z` performance outputs and `n_y` measurements; its state is `P_f`'s at the
//! slow instants. Because lifting is an isometry, [`hinfsyn()`](crate::hinfsyn()) on it
//! minimizes exactly the fast-rate norm above, and [`multirate_norm`] evaluates any slow
//! controller on the same criterion (loopshaping or single-rate designs included).
//!
//! # Conditions and accuracy
//!
//! `D₂₁` is phase 0's feedthrough to `m` from `r̃` (`W_r`'s, zero when it is strictly
//! proper) and `−W_n/√F`: without a `W_r` with an invertible feedthrough, a nonzero `W_n`
//! keeps it of full row rank ([`hinfsyn()`](crate::hinfsyn()) refuses a rank-deficient one);
//! `D₁₂` has full column rank when `W₂` has a nonzero feedthrough. The controller may have a
//! feedthrough: it acts at the instant it samples, as a single-rate controller at `T` does.
//! The lifted plant is exact (products of the fast matrices, no approximation); the unit test
//! checks it against the fast loop simulated sample by sample to `1e-8` of the largest
//! output (2 000 fast samples through a weight with a DC gain of 1e5).

use crate::error::{HinfError, Result};
use crate::hinfsyn::{hinfsyn, HinfOptions, HinfSynthesis};
use crate::lft::{lft_lower, Partition};
use crate::mixsyn::{augw, MixsynWeights};
use nalgebra::DMatrix;
use sd_model::StateSpace;

/// The weights of the multirate problem (module documentation): the mixed-sensitivity
/// weights of [`crate::augw`] — `W₁` on the fast error, `W₂` on the held control, `W₃` on the
/// fast output, `W_d` on a fast input disturbance — all discrete at the fast rate; the
/// reference's shaping `W_r` (fast rate, optional: without it the problem is disturbance
/// rejection only); the sensor noise's gain `W_n` at the slow samples (optional).
#[derive(Debug, Clone, Copy)]
pub struct MultirateWeights<'a> {
    /// `W₁`, `W₂`, `W₃`, `W_d` at the fast rate.
    pub mix: MixsynWeights<'a>,
    /// The smooth reference (or output disturbance) `r = W_r r̃` (ny×ny, fast rate), or none.
    pub wr: Option<&'a StateSpace>,
    /// The sensor noise's gain at the slow samples (ny×ny), or none.
    pub wn: Option<&'a DMatrix<f64>>,
    /// `W₂` on the controller's output samples `u_k` (nu×nu, discrete at the *slow* period
    /// `T`), or none: the effort counted at the slow rate as a single-rate design counts it,
    /// instead of (or beside) `mix.w2` on the held control at every fast sample, which also
    /// charges the hold's steps.
    pub w2_slow: Option<&'a StateSpace>,
    /// `W₁`'s extra factor at the controller's sample instants (phase 0 of `z̄`), or none
    /// (= 1: every fast sample counts alike). Above 1 the error *at* the samples counts more
    /// than between them: the design moves towards the single-rate one (which counts only
    /// the samples) — the handle of a design that must stay no worse at the samples.
    pub at_samples: Option<f64>,
}

/// The lifted generalized plant at `T = factor·h` and its partition (module documentation):
/// inputs `[r̄ (F·ny, with W_r); d̄ (F·nu, with W_d); n_k (ny, with W_n); u_k (nu)]`,
/// outputs `[z̄ (F·nz); z₂ₛ (nu, with the slow W₂); m_k (ny)]`, phase by phase
/// (`z̄ = [z(kF); …; z(kF+F−1)]`, each `z` the weighted outputs `[z₁; z₂; z₃]` present).
///
/// # Errors
/// A continuous plant, a factor below 1, weights of the wrong size or sample time (as
/// [`crate::augw`]), a `W_n` of the wrong shape or with a non-finite entry, no exogenous
/// input at all.
pub fn multirate_plant(
    g: &StateSpace,
    factor: usize,
    w: &MultirateWeights<'_>,
) -> Result<(StateSpace, Partition)> {
    if !g.time().is_discrete() {
        return Err(HinfError::InvalidArgument(
            "the multirate design needs the fast plant in discrete time (its period h = T/F): \
             discretize it at the fast rate first"
                .into(),
        ));
    }
    if factor == 0 {
        return Err(HinfError::InvalidArgument(
            "the rate factor F must be at least 1 (T = F·h)".into(),
        ));
    }
    let (ny, nu) = (g.ny(), g.nu());
    if let Some(wn) = w.wn {
        check_wn(wn, ny)?;
    }
    let nz1 = check_at_samples(w)?;
    if w.wr.is_none() && w.mix.wd.is_none() && w.wn.is_none() {
        return Err(HinfError::InvalidArgument(
            "the multirate problem needs an exogenous input: a reference (W_r), an input \
             disturbance (W_d) or sensor noise (W_n)"
                .into(),
        ));
    }
    let pf = fast_plant(g, w)?;
    let lifted = sd_multirate::lift(&pf, factor)
        .map_err(|e| HinfError::InvalidArgument(format!("lifting the fast plant: {e}")))?;
    let nr = if w.wr.is_some() { ny } else { 0 };
    let nd = if w.mix.wd.is_some() { nu } else { 0 };
    let nn = if w.wn.is_some() { ny } else { 0 };
    let nz = pf.ny() - ny;
    let (np_in, np_out) = (nr + nd + nu, nz + ny);
    // the input map from [r̄; d̄; n_k; u_k] to the lifted [r_0; d_0; u_0; r_1; …]: every phase
    // has its own r and d and the one held u_k
    let (at_d, at_n) = (factor * nr, factor * (nr + nd));
    let at_u = at_n + nn;
    let mut m_in = DMatrix::<f64>::zeros(factor * np_in, at_u + nu);
    for i in 0..factor {
        let row = i * np_in;
        m_in.view_mut((row, i * nr), (nr, nr)).fill_with_identity();
        m_in.view_mut((row + nr, at_d + i * nd), (nd, nd))
            .fill_with_identity();
        m_in.view_mut((row + nr + nd, at_u), (nu, nu))
            .fill_with_identity();
    }
    // the output rows: every phase's z, then phase 0's e (the sampler)
    let mut rows: Vec<usize> = (0..factor)
        .flat_map(|i| (0..nz).map(move |r| i * np_out + r))
        .collect();
    rows.extend((0..ny).map(|r| nz + r));
    let b = lifted.b() * &m_in;
    let mut c = lifted.c().select_rows(rows.iter());
    let mut d = lifted.d().select_rows(rows.iter()) * &m_in;
    if let Some(a) = w.at_samples {
        // phase 0's z₁ rows come first
        c.rows_mut(0, nz1).scale_mut(a);
        d.rows_mut(0, nz1).scale_mut(a);
    }
    if let Some(wn) = w.wn {
        // a slow input's samples are worth F fast ones (physical-time energies)
        let inv = 1.0 / (factor as f64).sqrt();
        d.view_mut((factor * nz, at_n), (ny, ny))
            .copy_from(&(-wn * inv));
    }
    let p = StateSpace::new(lifted.a().clone(), b, c, d, lifted.time())?;
    let p = match w.w2_slow {
        Some(w2s) => with_slow_effort(&p, w2s, factor, factor * nz, nu)?,
        None => p,
    };
    Ok((
        p,
        Partition {
            nmeas: ny,
            ncon: nu,
        },
    ))
}

/// The fast plant with inputs `[r̃; d; u]` (`r̃` only with `W_r`) and outputs `[z; e]`.
fn fast_plant(g: &StateSpace, w: &MultirateWeights<'_>) -> Result<StateSpace> {
    let ny = g.ny();
    let (aug, _) = augw(g, &w.mix)?;
    let outputs: Vec<usize> = (0..aug.ny()).collect();
    match w.wr {
        None => {
            let keep: Vec<usize> = (ny..aug.nu()).collect();
            Ok(aug.select(&keep, &outputs)?)
        }
        Some(wr) => {
            if wr.nu() != ny || wr.ny() != ny || !wr.time().compatible(&g.time()) {
                return Err(HinfError::InvalidArgument(format!(
                    "W_r must be {ny}x{ny} at the fast plant's period, got {}x{} with {}",
                    wr.ny(),
                    wr.nu(),
                    wr.time()
                )));
            }
            let rest = aug.nu() - ny;
            let pass = StateSpace::gain(DMatrix::identity(rest, rest), g.time())?;
            let shaped = sd_model::append(wr, &pass)?;
            Ok(sd_model::series(&shaped, &aug)?)
        }
    }
}

/// Appends `z₂ₛ = √F·W₂ₛ·u_k` to the lifted plant's performance outputs (before the
/// measurements; the `√F`: a slow signal's samples are worth F fast ones).
fn with_slow_effort(
    p: &StateSpace,
    w2s: &StateSpace,
    factor: usize,
    nzl: usize,
    nu: usize,
) -> Result<StateSpace> {
    if w2s.nu() != nu || w2s.ny() != nu || !w2s.time().compatible(&p.time()) {
        return Err(HinfError::InvalidArgument(format!(
            "the slow effort weight must be {nu}x{nu} at the controller's period T = {:e} s, \
             got {}x{} with {}",
            p.ts().unwrap_or(f64::NAN),
            w2s.ny(),
            w2s.nu(),
            w2s.time()
        )));
    }
    let (n, nw, ni) = (p.n(), w2s.n(), p.nu());
    let ny = p.ny() - nzl;
    let sf = (factor as f64).sqrt();
    let at_u = ni - nu;
    let mut a = DMatrix::<f64>::zeros(n + nw, n + nw);
    a.view_mut((0, 0), (n, n)).copy_from(p.a());
    a.view_mut((n, n), (nw, nw)).copy_from(w2s.a());
    let mut b = DMatrix::<f64>::zeros(n + nw, ni);
    b.view_mut((0, 0), (n, ni)).copy_from(p.b());
    b.view_mut((n, at_u), (nw, nu)).copy_from(w2s.b());
    let (rows, nzs) = (p.ny() + nu, nzl + nu);
    let mut c = DMatrix::<f64>::zeros(rows, n + nw);
    let mut d = DMatrix::<f64>::zeros(rows, ni);
    c.view_mut((0, 0), (nzl, n)).copy_from(&p.c().rows(0, nzl));
    d.view_mut((0, 0), (nzl, ni)).copy_from(&p.d().rows(0, nzl));
    c.view_mut((nzl, n), (nu, nw)).copy_from(&(w2s.c() * sf));
    d.view_mut((nzl, at_u), (nu, nu)).copy_from(&(w2s.d() * sf));
    c.view_mut((nzs, 0), (ny, n))
        .copy_from(&p.c().rows(nzl, ny));
    d.view_mut((nzs, 0), (ny, ni))
        .copy_from(&p.d().rows(nzl, ny));
    Ok(StateSpace::new(a, b, c, d, p.time())?)
}

/// The rows of `z₁` (W₁'s outputs), after checking the sample-instant factor: finite and
/// positive, and only with a `W₁`.
fn check_at_samples(w: &MultirateWeights<'_>) -> Result<usize> {
    let nz1 = w.mix.w1.map_or(0, |w1| w1.ny());
    match w.at_samples {
        Some(a) if !(a.is_finite() && a > 0.0) => Err(HinfError::InvalidArgument(format!(
            "the error's factor at the sample instants must be a positive finite number, got {a}"
        ))),
        Some(_) if nz1 == 0 => Err(HinfError::InvalidArgument(
            "a factor at the sample instants weights the error W₁e: give W₁ as well".into(),
        )),
        _ => Ok(nz1),
    }
}

fn check_wn(wn: &DMatrix<f64>, ny: usize) -> Result<()> {
    if wn.nrows() != ny || wn.ncols() != ny {
        return Err(HinfError::InvalidArgument(format!(
            "the sensor-noise weight W_n must be {ny}x{ny} (one per measurement), got {}x{}",
            wn.nrows(),
            wn.ncols()
        )));
    }
    if wn.iter().any(|v| !v.is_finite()) {
        return Err(HinfError::InvalidArgument(
            "the sensor-noise weight W_n has a NaN or infinite entry".into(),
        ));
    }
    Ok(())
}

/// The result of [`multirate_hinfsyn`].
#[derive(Debug, Clone)]
pub struct MultirateSynthesis {
    /// The synthesis on the lifted plant; its controller runs at `T`, `u_k = K·m_k` (negative
    /// feedback on the measured error), and its `achieved_norm` is the fast-rate norm.
    pub synthesis: HinfSynthesis,
    /// The lifted generalized plant it was designed on.
    pub plant: StateSpace,
    /// The rate factor F.
    pub factor: usize,
}

/// Multirate H∞ synthesis: [`multirate_plant`], then [`hinfsyn()`](crate::hinfsyn()).
///
/// # Errors
/// As [`multirate_plant`] and [`hinfsyn()`](crate::hinfsyn()).
pub fn multirate_hinfsyn(
    g: &StateSpace,
    factor: usize,
    w: &MultirateWeights<'_>,
    opt: &HinfOptions,
) -> Result<MultirateSynthesis> {
    let (p, part) = multirate_plant(g, factor, w)?;
    let synthesis = hinfsyn(&p, part, opt)?;
    Ok(MultirateSynthesis {
        synthesis,
        plant: p,
        factor,
    })
}

/// Multirate H2 synthesis on the same lifted plant: [`multirate_plant`], then
/// [`h2syn`](crate::h2syn). With white unit-variance `r̃`, `d` at every fast sample and `n` at
/// every slow sample, the lifted H2 norm squared is `F` times the mean over the fast samples
/// of `E|z|²`: the controller minimizes the weighted rms of the error *at every fast sample*
/// (a single-rate H2 design minimizes it at the slow samples only).
///
/// # Errors
/// As [`multirate_plant`] and [`h2syn`](crate::h2syn).
pub fn multirate_h2syn(
    g: &StateSpace,
    factor: usize,
    w: &MultirateWeights<'_>,
) -> Result<(crate::h2::H2Synthesis, StateSpace)> {
    let (p, part) = multirate_plant(g, factor, w)?;
    let r = crate::h2::h2syn(&p, part)?;
    Ok((r, p))
}

/// The fast-rate weighted norm of the loop of a slow controller `k` (at `T = factor·h`, used
/// as `u_k = K·m_k`) on the multirate problem — the criterion [`multirate_hinfsyn`] minimizes
/// — with whether that loop is stable (an unstable loop's norm is infinite: returned as
/// `f64::INFINITY`).
///
/// # Errors
/// As [`multirate_plant`]; a controller of the wrong size or period.
pub fn multirate_norm(
    g: &StateSpace,
    factor: usize,
    w: &MultirateWeights<'_>,
    k: &StateSpace,
) -> Result<f64> {
    let h = closed_loop(g, factor, w, k)?.hinf_norm()?;
    Ok(if h.stable { h.value } else { f64::INFINITY })
}

/// The lifted closed loop of the slow controller `k` on the multirate problem: inputs
/// `[r̄; d̄; n_k]`, outputs `[z̄; z₂ₛ]` ([`multirate_plant`]'s exogenous and performance
/// channels).
///
/// # Errors
/// As [`multirate_plant`]; a controller of the wrong size or period.
pub(crate) fn closed_loop(
    g: &StateSpace,
    factor: usize,
    w: &MultirateWeights<'_>,
    k: &StateSpace,
) -> Result<StateSpace> {
    let (p, part) = multirate_plant(g, factor, w)?;
    if !k.time().compatible(&p.time()) {
        return Err(HinfError::InvalidArgument(format!(
            "the controller's period must be the slow period T = {} · h = {:e} s",
            factor,
            p.ts().unwrap_or(f64::NAN)
        )));
    }
    lft_lower(&p, k, part)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use crate::weights::makeweight;
    use nalgebra::DVector;
    use sd_model::{c2d, stage::paper_stage, Discretization};

    const H: f64 = 2e-4;
    const F: usize = 5;

    fn gain(v: f64, g: &StateSpace) -> StateSpace {
        StateSpace::gain(DMatrix::from_element(1, 1, v), g.time()).unwrap()
    }

    /// The paper's stage at 5 kHz and mixed-sensitivity-like weights at the fast rate.
    fn problem() -> (StateSpace, StateSpace, StateSpace, StateSpace, DMatrix<f64>) {
        let g = c2d(&paper_stage(0.01).unwrap(), H, Discretization::Zoh).unwrap();
        let w1 = makeweight(1e5, 60.0, 1.0, 0.6, 2, Some(H)).unwrap();
        let w2 = gain(3e-8, &g);
        let wd = gain(1.0, &g);
        (g, w1, w2, wd, DMatrix::from_element(1, 1, 1e-4))
    }

    /// One discrete block stepped by hand.
    struct Block<'a> {
        s: &'a StateSpace,
        x: DVector<f64>,
    }
    impl<'a> Block<'a> {
        fn new(s: &'a StateSpace) -> Self {
            Block {
                s,
                x: DVector::zeros(s.n()),
            }
        }
        /// Output now (needs the input when the block has a feedthrough), then the state step.
        fn step(&mut self, u: f64) -> f64 {
            let uv = DVector::from_element(1, u);
            let y = (self.s.c() * &self.x + self.s.d() * &uv)[0];
            self.x = self.s.a() * &self.x + self.s.b() * &uv;
            y
        }
    }

    fn weights<'a>(
        w1: &'a StateSpace,
        w2: &'a StateSpace,
        wd: &'a StateSpace,
        wr: Option<&'a StateSpace>,
        wn: Option<&'a DMatrix<f64>>,
    ) -> MultirateWeights<'a> {
        MultirateWeights {
            mix: MixsynWeights {
                w1: Some(w1),
                w2: Some(w2),
                w3: None,
                wd: Some(wd),
            },
            wr,
            wn,
            w2_slow: None,
            at_samples: None,
        }
    }

    fn uniform(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    }

    /// The lifted plant reproduces the fast-rate loop simulated sample by sample (plant and
    /// weights at h, the controller at T = F·h with a hold and a sampler): the lifted closed
    /// loop's outputs, unstacked, equal the fast z₁, z₂ to rounding; and no input's fast-rate
    /// energy gain exceeds the achieved norm.
    #[test]
    fn lifted_loop_is_the_fast_loop() {
        let (g, w1, w2, wd, wn) = problem();
        let wr = crate::weights::lowpass(250.0, 0.7, Some(H)).unwrap();
        let w = weights(&w1, &w2, &wd, Some(&wr), Some(&wn));
        let r = multirate_hinfsyn(&g, F, &w, &HinfOptions::default()).unwrap();
        let s = &r.synthesis;
        assert!(s.closed_loop_stable);
        assert!(s.achieved_norm <= s.gamma * (1.0 + 1e-6));
        let k = &s.controller;
        let cl = lft_lower(&r.plant, k, Partition { nmeas: 1, ncon: 1 }).unwrap();
        let slow = 400;
        let mut seed = 7u64;
        let rt: Vec<f64> = (0..slow * F).map(|_| uniform(&mut seed)).collect();
        let d: Vec<f64> = (0..slow * F).map(|_| uniform(&mut seed)).collect();
        let n: Vec<f64> = (0..slow).map(|_| uniform(&mut seed)).collect();
        // the fast loop, sample by sample
        let (mut wrb, mut gb, mut w1b, mut w2b, mut wdb, mut kb) = (
            Block::new(&wr),
            Block::new(&g),
            Block::new(&w1),
            Block::new(&w2),
            Block::new(&wd),
            Block::new(k),
        );
        let mut z_fast = Vec::new();
        let mut u = 0.0;
        for j in 0..slow * F {
            let v_d = wdb.step(d[j]);
            // the plant is strictly proper: y(j) does not depend on u(j)
            let e = wrb.step(rt[j]) - (g.c() * &gb.x)[0];
            if j % F == 0 {
                u = kb.step(e - wn[(0, 0)] * n[j / F]);
            }
            gb.step(u + v_d);
            z_fast.push((w1b.step(e), w2b.step(u)));
        }
        // the lifted loop: inputs [r̄; d̄; √F·n] (physical-time energies)
        let sf = (F as f64).sqrt();
        let mut input = DMatrix::zeros(slow, 2 * F + 1);
        for kk in 0..slow {
            for i in 0..F {
                input[(kk, i)] = rt[kk * F + i];
                input[(kk, F + i)] = d[kk * F + i];
            }
            input[(kk, 2 * F)] = sf * n[kk];
        }
        let out = cl.simulate(&input, None).unwrap().y;
        let scale = z_fast
            .iter()
            .map(|z| z.0.abs().max(z.1.abs()))
            .fold(0.0, f64::max);
        let mut worst = 0.0f64;
        for kk in 0..slow {
            for i in 0..F {
                let (z1, z2) = z_fast[kk * F + i];
                worst = worst
                    .max((out[(kk, 2 * i)] - z1).abs())
                    .max((out[(kk, 2 * i + 1)] - z2).abs());
            }
        }
        assert!(
            worst <= 1e-8 * scale,
            "lifted vs fast loop: {worst:e} of {scale:e}"
        );
        let e_in: f64 = F as f64 * n.iter().map(|v| v * v).sum::<f64>()
            + rt.iter().chain(&d).map(|v| v * v).sum::<f64>();
        let e_out: f64 = z_fast.iter().map(|z| z.0 * z.0 + z.1 * z.1).sum();
        assert!((e_out / e_in).sqrt() <= s.achieved_norm * (1.0 + 1e-9));
    }

    /// Each design is best on its own criterion (the standstill problem on the paper's stage:
    /// the error in nm at every fast sample, a 0.05 N force disturbance per fast sample, 0.3 nm
    /// of sensor noise and a force weight rising above 100 Hz on the controller's samples).
    /// The multirate controller's fast-rate norm is at most the single-rate design's (designed
    /// at T on the downsampled plant with the same weights); the single-rate controller's norm
    /// at the samples (`F = 1` on the downsampled plant) is at most the multirate one's.
    #[test]
    fn each_design_is_best_on_its_own_criterion() {
        let g = c2d(&paper_stage(0.01).unwrap(), H, Discretization::Zoh).unwrap();
        let gs = sd_multirate::downsample(&g, F).unwrap();
        let w2s = makeweight(1.0, 100.0, 100.0, 400.0, 2, Some(H * F as f64)).unwrap();
        let problem_at = |plant: &StateSpace, f: usize| -> (StateSpace, StateSpace, DMatrix<f64>) {
            let one = |v: f64| StateSpace::gain(DMatrix::from_element(1, 1, v), plant.time());
            let wn = DMatrix::from_element(1, 1, 0.3e-9 * (f as f64).sqrt());
            (one(1e9).unwrap(), one(0.05).unwrap(), wn)
        };
        let (w1f, wdf, wnf) = problem_at(&g, F);
        let fast = MultirateWeights {
            mix: MixsynWeights {
                w1: Some(&w1f),
                w2: None,
                w3: None,
                wd: Some(&wdf),
            },
            wr: None,
            wn: Some(&wnf),
            w2_slow: Some(&w2s),
            at_samples: None,
        };
        let (w1s, wds, wns) = problem_at(&gs, 1);
        let slow = MultirateWeights {
            mix: MixsynWeights {
                w1: Some(&w1s),
                w2: None,
                w3: None,
                wd: Some(&wds),
            },
            wr: None,
            wn: Some(&wns),
            w2_slow: Some(&w2s),
            at_samples: None,
        };
        let multi = multirate_hinfsyn(&g, F, &fast, &HinfOptions::default()).unwrap();
        let single = multirate_hinfsyn(&gs, 1, &slow, &HinfOptions::default()).unwrap();
        let (km, ks) = (&multi.synthesis.controller, &single.synthesis.controller);
        let fast_m = multirate_norm(&g, F, &fast, km).unwrap();
        let fast_s = multirate_norm(&g, F, &fast, ks).unwrap();
        let slow_m = multirate_norm(&gs, 1, &slow, km).unwrap();
        let slow_s = multirate_norm(&gs, 1, &slow, ks).unwrap();
        println!(
            "worst-case standstill error (nm per unit disturbance): at every 5 kHz sample \
             multirate {fast_m:.3}, single-rate {fast_s:.3}; at the 1 kHz samples multirate \
             {slow_m:.3}, single-rate {slow_s:.3}"
        );
        assert!((fast_m - multi.synthesis.achieved_norm).abs() <= 1e-6 * fast_m);
        assert!(fast_m <= fast_s * (1.0 + 1e-3), "{fast_m} vs {fast_s}");
        assert!(slow_s <= slow_m * (1.0 + 1e-3), "{slow_s} vs {slow_m}");
    }

    #[test]
    fn bad_input_is_refused() {
        let (g, w1, w2, wd, _) = problem();
        let two = DMatrix::from_element(2, 2, 1.0);
        let w = weights(&w1, &w2, &wd, None, Some(&two));
        let e = multirate_plant(&g, F, &w).unwrap_err().to_string();
        assert!(e.contains("1x1"), "{e}");
        let nan = DMatrix::from_element(1, 1, f64::NAN);
        let w = weights(&w1, &w2, &wd, None, Some(&nan));
        assert!(multirate_plant(&g, F, &w).is_err());
        let w = weights(&w1, &w2, &wd, None, None);
        assert!(multirate_plant(&g, 0, &w).is_err());
        let cont = paper_stage(0.01).unwrap();
        assert!(multirate_plant(&cont, F, &w)
            .unwrap_err()
            .to_string()
            .contains("discrete"));
        let w1s = makeweight(1e5, 60.0, 1.0, 0.6, 2, Some(H * 2.0)).unwrap();
        let w = weights(&w1s, &w2, &wd, None, None);
        assert!(multirate_plant(&g, F, &w).is_err(), "W1 at another rate");
    }

    /// A static effort weight counts the same on the held control at every fast sample and
    /// on the controller's samples with `√F` (the held value repeats F times): both
    /// assemblies give the same γ_min; a dynamic one differs (the hold's steps).
    #[test]
    fn slow_effort_matches_a_static_fast_one() {
        let (g, w1, w2, wd, wn) = problem();
        let fast = weights(&w1, &w2, &wd, None, Some(&wn));
        let w2s = StateSpace::gain(
            DMatrix::from_element(1, 1, 3e-8),
            sd_model::SampleTime::discrete(H * F as f64).unwrap(),
        )
        .unwrap();
        let mut slow = weights(&w1, &w2, &wd, None, Some(&wn));
        slow.mix.w2 = None;
        slow.w2_slow = Some(&w2s);
        let a = multirate_hinfsyn(&g, F, &fast, &HinfOptions::default()).unwrap();
        let b = multirate_hinfsyn(&g, F, &slow, &HinfOptions::default()).unwrap();
        let (ga, gb) = (a.synthesis.gamma_min, b.synthesis.gamma_min);
        assert!((ga - gb).abs() <= 2e-3 * ga, "{ga} vs {gb}");
        assert_eq!(b.plant.ny(), F + 2);
        // the wrong period is refused
        slow.w2_slow = Some(&w2);
        assert!(multirate_plant(&g, F, &slow).is_err());
    }
}
