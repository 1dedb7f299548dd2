//! The rms a slow controller's loop gives on the multirate problem, phase by phase: where the
//! H∞ criterion of [`crate::multirate`] is a worst case, this is what a simulation with white
//! disturbances measures — at the controller's sample instants and between them.
//!
//! # The math
//!
//! The lifted closed loop `T = F_l(P̄, K)` ([`crate::multirate_plant`], [`crate::lft_lower`])
//! is LTI at the slow period `T`. Driven by unit-variance white `r̃` and `d` at every fast
//! sample (so the lifted `r̄_k`, `d̄_k` are unit white at the slow rate) and unit white `n_k`
//! at every slow sample, its output row `j` has the stationary variance
//! `E|z̄_j|² = (C P Cᵀ + D Dᵀ)_jj` with `P = A P Aᵀ + B Bᵀ` (the discrete H2 norm of that
//! row). Row `p·n_z + i` of `z̄` is `z_i` at the fast instant `kF + p`: phase 0 is the
//! controller's sample instant, phases `1 … F−1` lie between. The sensor noise enters through
//! the lifted column `W_n/√F` (the module's physical-time energies), so the noise a
//! simulation adds at each slow sample has the rms `|W_n|/√F`; the slow effort row carries
//! `√F·W₂ₛ u_k`, reported here without that `√F`.
//!
//! # Accuracy
//!
//! As [`sd_model::StateSpace::h2_norm`] (a Lyapunov solve on balanced states). The unit test
//! checks the rms at the samples, between them and of the slow effort against the fast loop
//! stepped sample by sample over 100 000 slow periods (500 000 fast samples), within 4
//! batch-mean standard errors.

use crate::error::Result;
use crate::multirate::{closed_loop, MultirateWeights};
use sd_model::StateSpace;

/// The stationary rms of the weighted outputs of a slow controller's loop on the multirate
/// problem (module documentation).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MultirateRms {
    /// `phases[p][i]`: the rms of `z_i` (the weighted outputs `[z₁; z₂; z₃]` present, in
    /// [`crate::augw`]'s order) at the fast instants `kF + p`; phase 0 is the sample instant.
    pub phases: Vec<Vec<f64>>,
    /// The rms of `W₂ₛ u_k` per control, when the problem has a slow effort weight.
    pub slow_effort: Vec<f64>,
}

impl MultirateRms {
    /// The rms of output `i` between the samples: over the phases `1 … F−1` (the square root
    /// of the mean of their variances); phase 0's when `F = 1`. `None` when there is no
    /// output `i`.
    pub fn between(&self, i: usize) -> Option<f64> {
        let inner = self.phases.get(1..).filter(|p| !p.is_empty());
        let inner = inner.unwrap_or(&self.phases[..self.phases.len().min(1)]);
        let v = inner
            .iter()
            .map(|p| p.get(i).map(|x| x * x))
            .sum::<Option<f64>>()?;
        (!inner.is_empty()).then(|| (v / inner.len() as f64).sqrt())
    }
    /// The rms of output `i` at the controller's sample instants (phase 0); `None` when there
    /// is no output `i`.
    pub fn at_samples(&self, i: usize) -> Option<f64> {
        self.phases.first()?.get(i).copied()
    }
}

/// The stationary rms of every weighted output at every phase of the slow period for the
/// loop of the slow controller `k` (at `T = factor·h`, `u_k = K·m_k`) on the multirate
/// problem, with unit white exogenous inputs (module documentation). The sample-instant
/// factor `w.at_samples` is not applied: the rms is of the outputs as weighted by `W₁`, `W₂`,
/// `W₃` alone. An unstable loop's rms are infinite.
///
/// # Errors
/// As [`crate::multirate_plant`]; a controller of the wrong size or period.
pub fn multirate_rms(
    g: &StateSpace,
    factor: usize,
    w: &MultirateWeights<'_>,
    k: &StateSpace,
) -> Result<MultirateRms> {
    let plain = MultirateWeights {
        at_samples: None,
        ..*w
    };
    let cl = closed_loop(g, factor, &plain, k)?;
    let nslow = if w.w2_slow.is_some() { g.nu() } else { 0 };
    let nz = (cl.ny() - nslow) / factor;
    let stable = cl.poles()?.iter().all(|z| z.norm() < 1.0);
    let inputs: Vec<usize> = (0..cl.nu()).collect();
    let row = |j: usize| -> Result<f64> {
        if !stable {
            return Ok(f64::INFINITY);
        }
        Ok(cl.select(&inputs, &[j])?.h2_norm()?)
    };
    let phases = (0..factor)
        .map(|ph| {
            (0..nz)
                .map(|i| row(ph * nz + i))
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<Vec<_>>>()?;
    let sf = (factor as f64).sqrt();
    let slow_effort = (0..nslow)
        .map(|i| Ok(row(factor * nz + i)? / sf))
        .collect::<Result<Vec<_>>>()?;
    Ok(MultirateRms {
        phases,
        slow_effort,
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use crate::hinfsyn::HinfOptions;
    use crate::mixsyn::MixsynWeights;
    use crate::multirate::{multirate_hinfsyn, multirate_plant};
    use crate::weights::makeweight;
    use nalgebra::{DMatrix, DVector};
    use sd_model::{c2d, stage::paper_stage, Discretization};

    const H: f64 = 2e-4;
    const F: usize = 5;
    const FORCE: f64 = 0.05;
    const SENSOR: f64 = 0.3e-9;

    /// Standard normal draws (Box–Muller on a 64-bit LCG): the test's own generator.
    struct Normal(u64);
    impl Normal {
        fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn draw(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
    }

    /// The standstill problem on the paper's stage: W₁ = 1e9 per m, a 0.05 N force per fast
    /// sample, 0.3 nm of sensor noise per slow sample, a force weight at the slow rate.
    struct Problem {
        g: StateSpace,
        w1: StateSpace,
        wd: StateSpace,
        wn: DMatrix<f64>,
        w2s: StateSpace,
    }

    impl Problem {
        fn new() -> Problem {
            let g = c2d(&paper_stage(0.01).unwrap(), H, Discretization::Zoh).unwrap();
            let one = |v: f64| StateSpace::gain(DMatrix::from_element(1, 1, v), g.time());
            Problem {
                w1: one(1e9).unwrap(),
                wd: one(FORCE).unwrap(),
                wn: DMatrix::from_element(1, 1, SENSOR * (F as f64).sqrt()),
                w2s: makeweight(1.0, 100.0, 100.0, 400.0, 2, Some(H * F as f64)).unwrap(),
                g,
            }
        }
        fn weights(&self) -> MultirateWeights<'_> {
            MultirateWeights {
                mix: MixsynWeights {
                    w1: Some(&self.w1),
                    w2: None,
                    w3: None,
                    wd: Some(&self.wd),
                },
                wr: None,
                wn: Some(&self.wn),
                w2_slow: Some(&self.w2s),
                at_samples: None,
            }
        }
    }

    /// One discrete block stepped by hand: output now, then the state step.
    fn step(s: &StateSpace, x: &mut DVector<f64>, u: f64) -> f64 {
        let uv = DVector::from_element(1, u);
        let y = (s.c() * &*x + s.d() * &uv)[0];
        *x = s.a() * &*x + s.b() * &uv;
        y
    }

    /// Batch means of a sequence: the mean and its standard error over `nb` batches.
    fn batch_mean(v: &[f64], nb: usize) -> (f64, f64) {
        let len = v.len() / nb;
        let means: Vec<f64> = v
            .chunks(len)
            .take(nb)
            .map(|c| c.iter().sum::<f64>() / len as f64)
            .collect();
        let m = means.iter().sum::<f64>() / nb as f64;
        let var = means.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (nb - 1) as f64;
        (m, (var / nb as f64).sqrt())
    }

    /// The predicted rms at the samples, between them and of the slow effort against the fast
    /// loop simulated sample by sample (white force at every fast sample, white noise at every
    /// slow one) over 100 000 slow periods: each within 4 standard errors of the batch means
    /// (40 batches; a false alarm about 2e-4 for three normal comparisons).
    #[test]
    fn rms_matches_a_simulation_of_the_fast_loop() {
        let pb = Problem::new();
        let w = pb.weights();
        let k = multirate_hinfsyn(&pb.g, F, &w, &HinfOptions::default())
            .unwrap()
            .synthesis
            .controller;
        let r = multirate_rms(&pb.g, F, &w, &k).unwrap();
        assert!(pb.g.d().iter().all(|v| *v == 0.0));
        let (mut x, mut xi, mut xw) = (
            DVector::zeros(pb.g.n()),
            DVector::zeros(k.n()),
            DVector::zeros(pb.w2s.n()),
        );
        let mut rng = Normal(7);
        let (periods, burn) = (100_000, 2_000);
        let (mut at, mut between, mut effort) = (Vec::new(), Vec::new(), Vec::new());
        let mut u = 0.0;
        for kk in 0..periods + burn {
            let mut inner = 0.0;
            for ph in 0..F {
                let e = -(pb.g.c() * &x)[0];
                if ph == 0 {
                    let m = e - SENSOR * rng.draw();
                    u = step(&k, &mut xi, m);
                    let z2 = step(&pb.w2s, &mut xw, u);
                    if kk >= burn {
                        effort.push(z2 * z2);
                        at.push((1e9 * e).powi(2));
                    }
                } else {
                    inner += (1e9 * e).powi(2) / (F - 1) as f64;
                }
                x = pb.g.a() * &x + pb.g.b() * (u + FORCE * rng.draw());
            }
            if kk >= burn {
                between.push(inner);
            }
        }
        for (name, sim, pred) in [
            ("at the samples", &at, r.at_samples(0).unwrap()),
            ("between", &between, r.between(0).unwrap()),
            ("effort", &effort, r.slow_effort[0]),
        ] {
            let (m, se) = batch_mean(sim, 40);
            assert!(
                (m - pred * pred).abs() <= 4.0 * se,
                "{name}: simulated mean square {m:.4e} ± {se:.2e}, predicted {:.4e}",
                pred * pred
            );
        }
    }

    /// The sample-instant factor multiplies phase 0's z₁ rows of the lifted plant and nothing
    /// else; it does not change the rms (which are of the unfactored outputs); bad factors and
    /// a factor without W₁ are refused.
    #[test]
    fn the_sample_factor_weights_phase_zero_only() {
        let pb = Problem::new();
        let w = pb.weights();
        let (p1, _) = multirate_plant(&pb.g, F, &w).unwrap();
        let w3 = MultirateWeights {
            at_samples: Some(3.0),
            ..w
        };
        let (p3, _) = multirate_plant(&pb.g, F, &w3).unwrap();
        let mut c = p1.c().clone();
        let mut d = p1.d().clone();
        c.row_mut(0).scale_mut(3.0);
        d.row_mut(0).scale_mut(3.0);
        assert_eq!(&c, p3.c());
        assert_eq!(&d, p3.d());
        assert_eq!(p1.a(), p3.a());
        assert_eq!(p1.b(), p3.b());
        let k = multirate_hinfsyn(&pb.g, F, &w3, &HinfOptions::default())
            .unwrap()
            .synthesis
            .controller;
        let r = multirate_rms(&pb.g, F, &w, &k).unwrap();
        assert_eq!(multirate_rms(&pb.g, F, &w3, &k).unwrap(), r);
        // no output 5: None, not a panic; an empty result likewise
        assert_eq!((r.at_samples(5), r.between(5)), (None, None));
        let empty = MultirateRms {
            phases: Vec::new(),
            slow_effort: Vec::new(),
        };
        assert_eq!((empty.at_samples(0), empty.between(0)), (None, None));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let wb = MultirateWeights {
                at_samples: Some(bad),
                ..w
            };
            let e = multirate_plant(&pb.g, F, &wb).unwrap_err().to_string();
            assert!(e.contains("positive finite"), "{e}");
        }
        let mut no_w1 = w3;
        no_w1.mix.w1 = None;
        let e = multirate_plant(&pb.g, F, &no_w1).unwrap_err().to_string();
        assert!(e.contains("give W₁"), "{e}");
    }
}
