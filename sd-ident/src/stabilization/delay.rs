//! The input delay of the physical fit ([`super`], module documentation "Input delay"): the
//! delay the training lines want at one order, the fraction at the chosen order with the
//! interval the data cannot tell apart, and the FRD with its input advanced.

use crate::fit::{fit, FitOptions};
use crate::Result;
use sd_model::linalg::golden_min;
use sd_model::Frd;

/// Golden-section steps that shrink a bracket of one sample below 1/100 sample (0.618¹⁰).
const STEPS_PER_SAMPLE: usize = 10;

/// The delay (samples, in `[0, max]`) whose advanced training lines the fit of `fo` follows
/// best: the cost on a half-sample grid, then golden-section search to 1/100 sample within
/// half a sample of the grid's least (a fit that fails counts as infinitely costly).
pub(super) fn best_delay(train: &Frd, fo: &FitOptions, max: usize) -> Result<f64> {
    let cost = |tau: f64| -> f64 {
        advance(train, tau)
            .and_then(|a| fit(&a, fo))
            .map_or(f64::INFINITY, |r| r.cost)
    };
    let t0 = (0..=2 * max)
        .map(|k| k as f64 / 2.0)
        .map(|t| (t, cost(t)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(0.0, |s| s.0);
    let (lo, hi) = ((t0 - 0.5).max(0.0), (t0 + 0.5).min(max as f64));
    Ok(golden_min(cost, lo, hi, STEPS_PER_SAMPLE).0)
}

/// The input delay [`fraction`] chose, the interval of the delays as good within the
/// significance rule, and every delay tried.
pub(super) struct DelayFit {
    pub(super) samples: f64,
    pub(super) interval: (f64, f64),
    pub(super) scan: Vec<(f64, f64)>,
}

/// The input delay's fraction (module documentation of [`super`]) around the delay `w` the
/// order rule chose, on all lines at the chosen order: the cost on a 1/8-sample grid over
/// `[0, max]`, golden section to 1/100 sample within 1/8 of the least; the least replaces `w`
/// only when it beats `V(w)` by the significance rule, and the delays within that rule of the
/// least give the interval.
pub(super) fn fraction(frd: &Frd, fopt: &FitOptions, w: f64, max: usize) -> Result<DelayFit> {
    if max == 0 {
        return Ok(DelayFit {
            samples: 0.0,
            interval: (0.0, 0.0),
            scan: Vec::new(),
        });
    }
    let cost = |tau: f64| -> Result<f64> { Ok(fit(&advance(frd, tau)?, fopt)?.cost) };
    let mut scan: Vec<(f64, f64)> = (0..=8 * max)
        .map(|k| k as f64 / 8.0)
        .chain(std::iter::once(w))
        .map(|t| Ok((t, cost(t)?)))
        .collect::<Result<_>>()?;
    let v_whole = scan
        .iter()
        .find(|s| (s.0 - w).abs() < 1e-9)
        .map_or(f64::INFINITY, |s| s.1);
    let (t0, _) = scan
        .iter()
        .copied()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((w, v_whole));
    let (lo, hi) = ((t0 - 0.125).max(0.0), (t0 + 0.125).min(max as f64));
    let mut refined: Vec<(f64, f64)> = Vec::new();
    golden_min(
        |t| {
            let v = cost(t).unwrap_or(f64::INFINITY);
            refined.push((t, v));
            v
        },
        lo,
        hi,
        STEPS_PER_SAMPLE - 3,
    );
    scan.extend(refined);
    scan.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (t_best, v_best) = scan
        .iter()
        .copied()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((w, v_whole));
    let rel = 5.0 * (2.0 / (2.0 * frd.len() as f64)).sqrt();
    let within: Vec<f64> = scan
        .iter()
        .filter(|s| s.1 <= v_best * (1.0 + rel))
        .map(|s| s.0)
        .collect();
    let interval = (
        within.iter().copied().fold(t_best, f64::min),
        within.iter().copied().fold(t_best, f64::max),
    );
    let samples = if v_best < v_whole * (1.0 - rel) && (t_best - w).abs() > 1e-9 {
        t_best
    } else {
        w
    };
    Ok(DelayFit {
        samples,
        interval,
        scan,
    })
}

/// The FRD with its input advanced by `tau` samples.
pub(super) fn advance(frd: &Frd, tau: f64) -> Result<Frd> {
    crate::advance_inputs(frd, &[tau])
}

#[cfg(test)]
mod tests {
    use crate::stabilization::{physical_fit, StabilizationOptions};
    use num_complex::Complex64 as C;
    use sd_model::Frd;
    use std::f64::consts::PI;

    /// The synthetic FRD of [`tests`] behind a pure delay of 2.4 samples (`e^{−jω·2.4T}`
    /// multiplied into the analytic response, not the fit's `advance`), lines up to 5 % of the
    /// rate: the two modes' free residues let the zeros absorb about a sample either way (the
    /// costs of τ from 1.25 to 4 differ by less than the noise), so the delay is an interval
    /// that holds the truth, a whole-sample estimate in it, and the model with that delay
    /// matches the data's phase on three noise seeds.
    #[test]
    fn delay_absorbed_by_the_zeros_is_an_interval() {
        for seed in [21, 22, 23] {
            let frd = crate::stabilization::tests::synthetic(seed);
            let ts = frd.time().ts().unwrap();
            let tau = 2.4;
            let resp = frd
                .freq_hz()
                .iter()
                .zip(frd.response())
                .map(|(&f, g)| g * C::from_polar(1.0, -2.0 * PI * f * ts * tau))
                .collect();
            let delayed = Frd::new(
                frd.freq_hz().to_vec(),
                resp,
                frd.variance().map(|v| v.to_vec()),
                frd.time(),
            )
            .unwrap();
            let opt = StabilizationOptions {
                max_order: 8,
                rigid_body: Some(2),
                max_delay: 4,
                ..Default::default()
            };
            let r = physical_fit(&delayed, &opt, &mut |_| {}).unwrap();
            eprintln!(
                "seed {seed}: delay {:.3} samples in [{:.3}, {:.3}], order {}, cost per line {:.2}",
                r.delay_samples, r.delay_interval.0, r.delay_interval.1, r.order, r.cost_per_line
            );
            let (lo, hi) = r.delay_interval;
            assert!(lo <= tau && tau <= hi, "{tau} outside [{lo}, {hi}]");
            assert!(lo <= r.delay_samples && r.delay_samples <= hi);
            let (m, phase_err) = r.model_with_delay(delayed.freq_hz()).unwrap();
            let g = m.freqresp(delayed.freq_hz()).unwrap();
            let worst = g
                .response()
                .iter()
                .zip(delayed.response())
                .map(|(a, b)| (a[(0, 0)] / b[(0, 0)]).arg().abs().to_degrees())
                .fold(0.0, f64::max);
            assert!(
                worst < 3.0 + phase_err,
                "phase {worst}° (allpass {phase_err}°)"
            );
        }
    }

    /// A delay the data determine: the exact ZOH response of a rigid body
    /// `T²(z + 1)/(2(z − 1)²)` behind `e^{−jω·2.4T}`, 200 lines up to 45 % of the rate, 0.5 %
    /// complex noise. Strictly proper (a delayed plant is), the rigid body's two residues leave
    /// the numerator no freedom to absorb it: the fraction is found within 0.05 sample and its
    /// interval is narrower than half a sample, on three seeds. (With a feedthrough the
    /// numerator absorbs one whole sample: 3.4 fits as well as 2.4.)
    #[test]
    fn fractional_delay_of_a_rigid_body() {
        let ts = 1e-3;
        let tau = 2.4;
        for seed in [31u64, 32, 33] {
            let mut st = seed;
            let mut gauss = || {
                let mut u = || {
                    st = st
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    ((st >> 11) as f64 + 0.5) / (1u64 << 53) as f64
                };
                let (a, b) = (u(), u());
                (-2.0 * a.ln()).sqrt() * (2.0 * PI * b).cos()
            };
            let freq: Vec<f64> = (1..=200).map(|k| 2.25 * k as f64).collect();
            let mut resp = Vec::new();
            let mut var = Vec::new();
            for &f in &freq {
                let zz = C::from_polar(1.0, 2.0 * PI * f * ts);
                let g = C::new(ts * ts / 2.0, 0.0) * (zz + 1.0) / ((zz - 1.0) * (zz - 1.0))
                    * C::from_polar(1.0, -2.0 * PI * f * ts * tau);
                let sd = 0.005 * g.norm();
                let n = C::new(gauss(), gauss()) * (sd / 2f64.sqrt());
                resp.push(nalgebra::DMatrix::from_element(1, 1, g + n));
                var.push(nalgebra::DMatrix::from_element(1, 1, sd * sd));
            }
            let frd = Frd::new(
                freq,
                resp,
                Some(var),
                sd_model::SampleTime::discrete(ts).unwrap(),
            )
            .unwrap();
            let opt = StabilizationOptions {
                max_order: 4,
                rigid_body: Some(2),
                max_delay: 4,
                feedthrough: false,
            };
            let r = physical_fit(&frd, &opt, &mut |_| {}).unwrap();
            let (lo, hi) = r.delay_interval;
            eprintln!(
                "seed {seed}: delay {:.4} in [{lo:.3}, {hi:.3}], order {}, cost per line {:.2}",
                r.delay_samples, r.order, r.cost_per_line
            );
            assert!((r.delay_samples - tau).abs() < 0.05, "{}", r.delay_samples);
            assert!(hi - lo < 0.5, "[{lo}, {hi}]");
        }
    }
}
