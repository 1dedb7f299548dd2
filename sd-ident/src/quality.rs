//! Data quality: what an FRF estimate should not be trusted for, from its input SNR per line
//! and from the record itself.
//!
//! - **No excitation** (periodic data, two or more periods): the median input SNR
//!   `|Ū|²/σ²_Ū` over the lines found is below [`NO_EXCITATION_SNR`].
//! - **Feedback only** (any record): the input is a deterministic causal function of the
//!   output, as in a closed loop without excitation (a standstill record): least squares of
//!   `u_t` on `u_{t−1…t−8}` and `y_{t…t−8}` leaves less than [`FEEDBACK_ONLY_RESIDUAL`] of the
//!   input's variance unexplained. A controller is deterministic, so then the residual is at
//!   rounding level; an external excitation entering the input (a reference, a disturbance, an
//!   open-loop signal) leaves its own innovation, of the order of its variance. Sensor noise
//!   is what separates the two directions: noise-free open-loop data of a plant with a direct
//!   feedthrough (`y_t` depends on `u_t`) would read as feedback too. An input its own past
//!   predicts (a sine) gives no answer.
//! - **Low input SNR** per line: below [`MIN_INPUT_SNR`] a ratio estimate is biased and its
//!   variance formula fails.

use crate::error::{IdentError, Result};
use crate::frf::MIN_INPUT_SNR;
use sd_model::{median, Frd};

/// Median input SNR below which a record counts as not excited at all: a line without
/// excitation has `|Ū|²/σ²_Ū` of order 1 (the mean of M noisy periods over its own variance), a
/// multisine line hundreds to millions.
pub const NO_EXCITATION_SNR: f64 = 10.0;

/// A warning about the data behind an FRF estimate: the estimate exists, but all or part of it
/// should not be read as the plant's.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum DataWarning {
    /// The input at the "excited" lines is at its own noise level: the record carries no
    /// periodic excitation, and `Ȳ/Ū` is whatever relation noise and feedback impose (`−1/K`
    /// in a loop with controller K), not the plant.
    NoExcitation {
        /// Median `|Ū|²/σ²_Ū` over the lines.
        median_input_snr: f64,
        /// Lines estimated.
        lines: usize,
    },
    /// The input is a deterministic function of the output (a closed loop without
    /// excitation, such as a standstill record): any estimate of `Y/U` is `−1/controller`.
    FeedbackOnly {
        /// Share of the input's variance its own past and the output do not explain.
        unexplained: f64,
    },
    /// Lines whose input SNR is below [`MIN_INPUT_SNR`]: their ratio is biased and their
    /// variance formula does not hold.
    LowInputSnr {
        /// How many.
        lines: usize,
        /// Of how many lines.
        of: usize,
        /// The first few of them (Hz).
        freq_hz: Vec<f64>,
        /// Whether they were left out of the written estimate.
        excluded: bool,
    },
}

impl std::fmt::Display for DataWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DataWarning::NoExcitation {
                median_input_snr,
                lines,
            } => write!(
                f,
                "no excitation: at the {lines} strongest input lines the input is at its own \
                 noise level (median |Ū|²/σ²_Ū = {median_input_snr:.2}, an excited line reads \
                 ≫ {MIN_INPUT_SNR}); the ratio Y/U is not the plant (in a loop it is −1/controller): \
                 excite the plant, or check the period and the columns"
            ),
            DataWarning::FeedbackOnly { unexplained } => write!(
                f,
                "no excitation: the input is the controller's reaction to the measured output \
                 (its own past and the output explain all but {unexplained:.1e} of its variance), \
                 so Y/U is −1/controller, not the plant: record with an excitation (a reference \
                 or an injected input)"
            ),
            DataWarning::LowInputSnr {
                lines,
                of,
                freq_hz,
                excluded,
            } => {
                let list: Vec<String> = freq_hz.iter().map(|f| format!("{f:.2}")).collect();
                write!(
                    f,
                    "{lines} of {of} lines have an input SNR below {MIN_INPUT_SNR} (biased ratio, \
                     no valid variance), e.g. {} Hz: {}",
                    list.join(", "),
                    if *excluded {
                        "left out (--keep-low-snr keeps them)"
                    } else {
                        "kept as asked"
                    }
                )
            }
        }
    }
}

/// Unexplained share of the input variance below which a record counts as feedback only.
pub const FEEDBACK_ONLY_RESIDUAL: f64 = 1e-6;

/// Orders of the regression of [`feedback_only`]: past inputs, and present and past outputs.
const FEEDBACK_ORDER: usize = 8;

/// The share of the input's variance that its own past and the output's present and past do
/// not explain (least squares, the toolkit's solver; module documentation). An input held over
/// `F` samples (a slower controller recorded at a fast rate: it changes only every `F`-th
/// sample) is regressed at its switching instants, on its own past switching values and on
/// every output sample of the last `8F` (the controller's sampler may sit at any phase). `None`
/// for a record too short (fewer than 10 rows per regressor), without input variance, or whose
/// input its own past already predicts to 1e-3 (a sine or a few-line excitation: deterministic,
/// so the output cannot be shown to drive it).
///
/// # Errors
/// Signals of different lengths.
pub fn input_unexplained_by_output(u: &[f64], y: &[f64]) -> Result<Option<f64>> {
    if u.len() != y.len() {
        return Err(IdentError::Data(format!(
            "input and output have different lengths ({} and {})",
            u.len(),
            y.len()
        )));
    }
    let (hold, phase) = hold_factor(u);
    let p = FEEDBACK_ORDER;
    let (ny, cols) = (p * hold + 1, 1 + p + p * hold + 1);
    let first = p * hold + phase;
    let n = u.len();
    if n <= first {
        return Ok(None);
    }
    let rows = (n - first).div_ceil(hold);
    if rows < 10 * cols {
        return Ok(None);
    }
    let at = |r: usize| first + r * hold;
    let target: Vec<f64> = (0..rows).map(|r| u[at(r)]).collect();
    let mean = target.iter().sum::<f64>() / rows as f64;
    let var: f64 = target.iter().map(|v| (v - mean).powi(2)).sum();
    if !(var > 0.0 && var.is_finite()) {
        return Ok(None);
    }
    let a = nalgebra::DMatrix::from_fn(rows, cols, |r, c| {
        let t = at(r);
        match c {
            0 => 1.0,
            c if c <= p => u[t - c * hold],
            c => y[t - (c - p - 1).min(ny - 1)],
        }
    });
    let b = nalgebra::DVector::from_vec(target);
    let unexplained = |a: &nalgebra::DMatrix<f64>| -> Result<f64> {
        let ls = sd_model::linalg::lstsq(a, &b)?;
        Ok((a * &ls.x - &b).norm_squared() / var)
    };
    // an input its own past predicts (a sine, a few lines) is a deterministic excitation: the
    // output has nothing left to explain, and the test says nothing
    if unexplained(&a.columns(0, p + 1).into_owned())? < OWN_PAST_PREDICTS {
        return Ok(None);
    }
    Ok(Some(unexplained(&a)?))
}

/// Unexplained share below which the input's own past predicts it (then
/// [`input_unexplained_by_output`] gives no answer).
const OWN_PAST_PREDICTS: f64 = 1e-3;

/// The hold factor of a signal that changes only every `F`-th sample (the greatest common
/// divisor of the distances between its changes, when it changes at least ten times), and the
/// phase of its first change; `(1, 0)` otherwise.
fn hold_factor(u: &[f64]) -> (usize, usize) {
    let changes: Vec<usize> = (1..u.len()).filter(|&t| u[t] != u[t - 1]).collect();
    if changes.len() < 10 {
        return (1, 0);
    }
    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }
    let f = changes[1..].iter().fold(0, |g, &c| gcd(g, c - changes[0]));
    if f > 1 {
        (f, changes[0] % f)
    } else {
        (1, 0)
    }
}

/// [`DataWarning::FeedbackOnly`] when the record's input is explained by its output.
///
/// # Errors
/// As [`input_unexplained_by_output`].
pub fn feedback_only(u: &[f64], y: &[f64]) -> Result<Option<DataWarning>> {
    Ok(input_unexplained_by_output(u, y)?
        .filter(|r| *r < FEEDBACK_ONLY_RESIDUAL)
        .map(|unexplained| DataWarning::FeedbackOnly { unexplained }))
}

/// `frd` at the lines whose input SNR `snr[i]` reaches [`MIN_INPUT_SNR`] (periodic
/// [`crate::FrfEstimate::input_snr`], or [`crate::lpm_closed_loop_snr`]'s).
///
/// # Errors
/// No line is trusted (the error says what the record lacks).
pub fn trusted(frd: &Frd, snr: &[f64]) -> Result<Frd> {
    if !snr.iter().any(|s| *s >= MIN_INPUT_SNR) {
        return Err(IdentError::Data(format!(
            "no line has an input SNR of {MIN_INPUT_SNR} or more (median {:.2}): the record is \
             not excited at the lines found",
            median(snr)
        )));
    }
    Ok(frd.select(|i| snr.get(i).is_none_or(|s| *s >= MIN_INPUT_SNR))?)
}

/// Least normalised autocorrelation at which [`likely_period`] takes a lag for a period.
pub const PERIOD_CORRELATION: f64 = 0.95;

/// The period (samples) a periodic excitation `x` repeats with: the least lag `τ ≥ 2`, with at
/// least two repeats in the record, at which the unbiased normalised autocorrelation of the
/// mean-free signal `Σ_t x_t x_{t+τ} / Σ x² · N/(N − τ)` reaches [`PERIOD_CORRELATION`]
/// (computed by FFT, `O(N log N)`); `None` for a record that does not repeat. A transient in
/// the first period lowers the correlation only by its share of the record.
pub fn likely_period(x: &[f64]) -> Option<usize> {
    let n = x.len();
    if n < 8 || x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let m = (2 * n).next_power_of_two();
    let mut buf: Vec<num_complex::Complex64> = (0..m)
        .map(|t| num_complex::Complex64::new(if t < n { x[t] - mean } else { 0.0 }, 0.0))
        .collect();
    let mut planner = rustfft::FftPlanner::<f64>::new();
    planner.plan_fft_forward(m).process(&mut buf);
    buf.iter_mut()
        .for_each(|v| *v = num_complex::Complex64::new(v.norm_sqr(), 0.0));
    planner.plan_fft_inverse(m).process(&mut buf);
    let energy = buf[0].re;
    if energy <= 0.0 {
        return None;
    }
    (2..=n / 2)
        .find(|&tau| buf[tau].re / energy * n as f64 / (n - tau) as f64 >= PERIOD_CORRELATION)
}

/// The data-quality warnings of an estimate from its per-line input SNR: no excitation (median
/// SNR below [`NO_EXCITATION_SNR`], checked when `excitation_check`), and lines below
/// [`MIN_INPUT_SNR`] (`excluded`: whether they are left out of what the caller writes).
pub fn snr_warnings(
    frd: &Frd,
    snr: &[f64],
    excitation_check: bool,
    excluded: bool,
) -> Vec<DataWarning> {
    let mut out = Vec::new();
    let med = median(snr);
    if excitation_check && med < NO_EXCITATION_SNR {
        out.push(DataWarning::NoExcitation {
            median_input_snr: med,
            lines: snr.len(),
        });
    }
    let low: Vec<f64> = snr
        .iter()
        .zip(frd.freq_hz())
        .filter(|(s, _)| **s < MIN_INPUT_SNR)
        .map(|(_, f)| *f)
        .collect();
    if !low.is_empty() {
        out.push(DataWarning::LowInputSnr {
            lines: low.len(),
            of: snr.len(),
            freq_hz: low.iter().take(5).copied().collect(),
            excluded,
        });
    }
    out
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A mass-spring-damper at 1 kHz (Euler form) in a loop with a PD controller
    /// `u = −(kp y + kd (y − y₋₁)) + r`, sensor noise on y; the input held over `hold` samples.
    fn record(r_rms: f64, hold: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut rng = crate::rng::SplitMix::new(seed);
        let (mut x, mut v, mut y_prev, mut u) = (0.0, 0.0, 0.0, 0.0);
        let (mut us, mut ys) = (Vec::new(), Vec::new());
        for t in 0..20_000 {
            let y = x + 1e-3 * rng.normal();
            if t % hold == 0 {
                u = -(50.0 * y + 400.0 * (y - y_prev)) + r_rms * rng.normal();
            }
            y_prev = y;
            us.push(u);
            ys.push(y);
            let a = u - 20.0 * x - 0.5 * v;
            v += 1e-3 * a;
            x += 1e-3 * v;
        }
        (us, ys)
    }

    #[test]
    fn feedback_without_excitation_is_told_from_an_excited_loop() {
        for hold in [1, 5] {
            let (u, y) = record(0.0, hold, 1);
            let r = input_unexplained_by_output(&u, &y).unwrap().unwrap();
            assert!(r < 1e-20, "hold {hold}: {r}");
            assert!(matches!(
                feedback_only(&u, &y).unwrap(),
                Some(DataWarning::FeedbackOnly { .. })
            ));
            // a reference 1 % of the controller's effort is enough to tell
            let (u, y) = record(0.01, hold, 2);
            let r = input_unexplained_by_output(&u, &y).unwrap().unwrap();
            assert!(r > 1e-4, "hold {hold}: {r}");
            assert!(feedback_only(&u, &y).unwrap().is_none());
        }
        // open loop: white input through a strictly proper plant, with sensor noise
        let mut rng = crate::rng::SplitMix::new(3);
        let u: Vec<f64> = (0..5000).map(|_| rng.normal()).collect();
        let mut x = 0.0;
        let y: Vec<f64> = u
            .iter()
            .map(|v| {
                let y = x + 1e-3 * rng.normal();
                x = 0.9 * x + v;
                y
            })
            .collect();
        assert!(input_unexplained_by_output(&u, &y).unwrap().unwrap() > 0.5);
        // a sine: its own past predicts it, no answer
        let u: Vec<f64> = (0..5000).map(|t| (0.1 * t as f64).sin()).collect();
        assert_eq!(input_unexplained_by_output(&u, &y).unwrap(), None);
        // too short, constant, or mismatched
        assert_eq!(
            input_unexplained_by_output(&u[..50], &y[..50]).unwrap(),
            None
        );
        assert_eq!(
            input_unexplained_by_output(&vec![1.0; 5000], &y).unwrap(),
            None
        );
        assert!(input_unexplained_by_output(&u, &y[..10]).is_err());
    }
}

#[cfg(test)]
mod period_tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// Eight periods of 1000 samples: lines 1..100 with seeded random phases.
    fn periodic() -> Vec<f64> {
        let mut rng = crate::rng::SplitMix::new(5);
        let phases: Vec<f64> = (0..100)
            .map(|_| rng.uniform() * std::f64::consts::TAU)
            .collect();
        (0..8000)
            .map(|t| {
                (1..=100)
                    .map(|k| {
                        (std::f64::consts::TAU * k as f64 * t as f64 / 1000.0 + phases[k - 1]).cos()
                    })
                    .sum()
            })
            .collect()
    }

    #[test]
    fn the_period_of_a_multisine_and_none_for_noise() {
        assert_eq!(likely_period(&periodic()), Some(1000));
        let mut rng = crate::rng::SplitMix::new(6);
        let noise: Vec<f64> = (0..8000).map(|_| rng.normal()).collect();
        assert_eq!(likely_period(&noise), None);
        assert_eq!(likely_period(&[1.0; 4]), None);
    }

    /// `period_samples = 700` for a record that repeats every 1000: the refusal names 1000.
    #[test]
    fn a_wrong_period_is_named() {
        let u = periodic();
        let y: Vec<f64> = (0..u.len())
            .map(|t| if t > 0 { 0.5 * u[t - 1] } else { 0.0 })
            .collect();
        let exp = crate::Experiment {
            spec: crate::ExperimentSpec {
                name: "ms".into(),
                file: "ms.csv".into(),
                sample_rate_hz: 1000.0,
                period_samples: Some(700),
                skip_periods: 1,
                reference: None,
                input: "u".into(),
                output: "y".into(),
                role: crate::Role::Model,
                extra: Default::default(),
            },
            r: None,
            u,
            y,
            extra: Default::default(),
        };
        let e = crate::estimate_experiment(&exp, &crate::FrfRequest::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("repeats every 1000 samples"), "{e}");
    }
}
