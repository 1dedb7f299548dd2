//! Periodic multisine excitations (Pintelon & Schoukens, *System Identification: A Frequency
//! Domain Approach*, 2nd ed., §5.2).
//!
//! One period of N samples at `fs` has the frequency grid `k·f₀`, `f₀ = fs/N`;
//! `x[n] = Σ_{k∈K} A cos(2π k n/N + φ_k)`, built by one inverse FFT and scaled to the requested
//! rms. Phases:
//! - **random**: φ_k uniform in [0, 2π) from a seed;
//! - **Schroeder**: `φ_k = −π k(k−1)/|K|` over the excited lines (low crest factor for flat
//!   spectra; Schroeder 1970).
//!
//! Line sets:
//! - **full**: every line in [f_min, f_max];
//! - **random-odd**: only odd lines, and in each group of `group` consecutive odd lines one,
//!   chosen at random, is left out as a *detection line*; the even lines stay empty too. Power
//!   at odd detection lines measures odd nonlinear distortion, at even lines even distortion
//!   (the best-linear-approximation framework).
//!
//! **Fold-aware grid**: for a slow rate `f_s`, every frequency that folds onto a slow-rate line
//! is on the grid iff `f_s/f₀` is an integer; [`MultisineSpec::fold_rate_hz`] checks it.

use crate::error::{IdentError, Result};
use crate::rng::SplitMix;
use rustfft::{num_complex::Complex, FftPlanner};
use std::f64::consts::PI;
use std::io::Write;

/// Phase choice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Phases {
    /// Uniform random phases from the seed.
    Random {
        /// Seed of the generator.
        seed: u64,
    },
    /// Schroeder phases.
    Schroeder,
}

/// Which lines are excited.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lines {
    /// All lines in the band.
    Full,
    /// Odd lines, one random detection line left out per group of `group` odd lines.
    RandomOdd {
        /// Group size (≥ 2; 3 is usual).
        group: usize,
        /// Seed for the choice of detection lines.
        seed: u64,
    },
}

/// What to design.
#[derive(Debug, Clone, PartialEq)]
pub struct MultisineSpec {
    /// Sample rate (Hz).
    pub fs: f64,
    /// Samples per period.
    pub period: usize,
    /// Lowest excited frequency (Hz), at least f₀.
    pub f_min: f64,
    /// Highest excited frequency (Hz), below fs/2.
    pub f_max: f64,
    /// Line set.
    pub lines: Lines,
    /// Phases.
    pub phases: Phases,
    /// Rms of one period.
    pub rms: f64,
    /// If set, f₀ must divide this rate (so its fold frequencies are on the grid).
    pub fold_rate_hz: Option<f64>,
}

/// A designed multisine.
#[derive(Debug, Clone)]
pub struct Multisine {
    /// One period.
    pub signal: Vec<f64>,
    /// Excited DFT bins (ascending).
    pub excited: Vec<usize>,
    /// Odd detection bins (random-odd only).
    pub detection_odd: Vec<usize>,
    /// Even bins in the band (random-odd only).
    pub detection_even: Vec<usize>,
    /// Frequency resolution f₀ = fs/N (Hz).
    pub f0: f64,
    /// Sample rate (Hz).
    pub fs: f64,
    /// max|x| / rms.
    pub crest_factor: f64,
}

impl Multisine {
    /// `periods` repetitions of the period (for a transient, count it in).
    pub fn repeat(&self, periods: usize) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.signal.len() * periods);
        for _ in 0..periods {
            out.extend_from_slice(&self.signal);
        }
        out
    }
}

/// Orthogonal multisines for `inputs` inputs (Pintelon & Schoukens, *System Identification*,
/// 2nd ed., §3.7): `inputs` experiments, in experiment e input j plays `ms` with every excited
/// line turned by `2π·j·e/inputs` (for two inputs: `u₁ = s`, `u₂ = ±s`, a Hadamard pattern).
/// At every excited line the excitation matrix (inputs × experiments) is `A_k e^{jφ_k}` times
/// the DFT matrix, `√inputs`-scaled unitary: the inputs are told apart at every line with the
/// best possible conditioning, and each signal keeps `ms`'s amplitude spectrum, so its rms;
/// the crest factor of a turned signal can differ. One period per signal:
/// `[experiment][input]`.
///
/// # Errors
/// No input, or more than the period's length.
pub fn orthogonal(ms: &Multisine, inputs: usize) -> Result<Vec<Vec<Vec<f64>>>> {
    let n = ms.signal.len();
    if inputs == 0 || inputs > n {
        return Err(IdentError::InvalidArgument(format!(
            "{inputs} inputs: need between 1 and the period's {n} samples"
        )));
    }
    let mut planner = FftPlanner::<f64>::new();
    let (fwd, inv) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
    let mut spec: Vec<Complex<f64>> = ms.signal.iter().map(|&v| Complex::new(v, 0.0)).collect();
    fwd.process(&mut spec);
    let turn = |j: usize, e: usize| -> Vec<f64> {
        let phi = std::f64::consts::TAU * ((j * e) % inputs) as f64 / inputs as f64;
        let rot = Complex::from_polar(1.0, phi);
        let mut s = spec.clone();
        for k in 1..n {
            // the lower half turned by e^{jφ}, its mirror by e^{−jφ}: a real signal
            if 2 * k < n {
                s[k] *= rot;
            } else if 2 * k > n {
                s[k] *= rot.conj();
            }
        }
        inv.process(&mut s);
        s.iter().map(|v| v.re / n as f64).collect()
    };
    Ok((0..inputs)
        .map(|e| (0..inputs).map(|j| turn(j, e)).collect())
        .collect())
}

/// Crest factor `max|x|/rms` of a signal (1 for an empty or zero signal).
pub fn crest_factor(x: &[f64]) -> f64 {
    let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt();
    if rms == 0.0 {
        return 1.0;
    }
    x.iter().fold(0.0f64, |m, v| m.max(v.abs())) / rms
}

/// Designs a multisine (module documentation).
///
/// # Errors
/// A non-positive rate, rms or period; a band outside (0, fs/2) or without a line; a group
/// size below 2; a fold rate that f₀ does not divide.
pub fn design(spec: &MultisineSpec) -> Result<Multisine> {
    let bad = |m: String| Err(IdentError::InvalidArgument(m));
    if !(spec.fs.is_finite() && spec.fs > 0.0) {
        return bad(format!("sample rate {} must be > 0", spec.fs));
    }
    if spec.period < 4 {
        return bad(format!("period {} must be at least 4 samples", spec.period));
    }
    if !(spec.rms.is_finite() && spec.rms > 0.0) {
        return bad(format!("rms {} must be > 0", spec.rms));
    }
    let n = spec.period;
    let f0 = spec.fs / n as f64;
    if !(spec.f_min.is_finite() && spec.f_max.is_finite())
        || spec.f_min <= 0.0
        || spec.f_max >= spec.fs / 2.0
        || spec.f_min > spec.f_max
    {
        return bad(format!(
            "band [{}, {}] Hz must satisfy 0 < f_min ≤ f_max < fs/2 = {} Hz",
            spec.f_min,
            spec.f_max,
            spec.fs / 2.0
        ));
    }
    if let Some(rate) = spec.fold_rate_hz {
        let ratio = rate / f0;
        if !(rate.is_finite() && rate > 0.0)
            || (ratio - ratio.round()).abs() > 1e-9 * ratio.max(1.0)
        {
            return bad(format!(
                "f0 = {f0} Hz must divide the slow rate {rate} Hz so that its fold frequencies \
                 lie on the grid; choose the period so that {rate}·N/fs is an integer"
            ));
        }
    }
    let kmin = (spec.f_min / f0).ceil().max(1.0) as usize;
    let kmax = ((spec.f_max / f0).floor() as usize).min(n / 2 - 1);
    if kmin > kmax {
        return bad(format!(
            "no DFT line in [{}, {}] Hz with f0 = {f0} Hz; lengthen the period",
            spec.f_min, spec.f_max
        ));
    }
    let (mut excited, mut det_odd, mut det_even) = (Vec::new(), Vec::new(), Vec::new());
    match spec.lines {
        Lines::Full => excited.extend(kmin..=kmax),
        Lines::RandomOdd { group, seed } => {
            if group < 2 {
                return bad(format!("random-odd group size {group} must be ≥ 2"));
            }
            let mut rng = SplitMix::new(seed);
            let odd: Vec<usize> = (kmin..=kmax).filter(|k| k % 2 == 1).collect();
            for chunk in odd.chunks(group) {
                let skip = if chunk.len() == group {
                    Some(rng.below(group))
                } else {
                    None
                };
                for (i, &k) in chunk.iter().enumerate() {
                    if Some(i) == skip {
                        det_odd.push(k);
                    } else {
                        excited.push(k);
                    }
                }
            }
            det_even.extend((kmin..=kmax).filter(|k| k % 2 == 0));
            if excited.is_empty() {
                return bad("the random-odd design left no excited line; widen the band".into());
            }
        }
    }
    let nk = excited.len();
    let mut rng = match spec.phases {
        Phases::Random { seed } => Some(SplitMix::new(seed)),
        Phases::Schroeder => None,
    };
    let mut spec_c = vec![Complex::new(0.0, 0.0); n];
    for (i, &k) in excited.iter().enumerate() {
        let phi = match rng.as_mut() {
            Some(r) => 2.0 * PI * r.uniform(),
            None => -PI * ((i + 1) * i) as f64 / nk as f64,
        };
        let c = Complex::from_polar(1.0, phi);
        spec_c[k] = c;
        spec_c[n - k] = c.conj();
    }
    FftPlanner::<f64>::new()
        .plan_fft_inverse(n)
        .process(&mut spec_c);
    let mut x: Vec<f64> = spec_c.iter().map(|c| c.re).collect();
    let rms = (x.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
    for v in &mut x {
        *v *= spec.rms / rms;
    }
    let cf = crest_factor(&x);
    Ok(Multisine {
        signal: x,
        excited,
        detection_odd: det_odd,
        detection_even: det_even,
        f0,
        fs: spec.fs,
        crest_factor: cf,
    })
}

/// Writes named columns as CSV with a header row (all columns the same length).
///
/// # Errors
/// Columns of different lengths, or an I/O error of the writer.
pub fn write_csv<W: Write>(mut w: W, columns: &[(&str, &[f64])]) -> Result<()> {
    let len = columns.first().map(|c| c.1.len()).unwrap_or(0);
    if columns.iter().any(|c| c.1.len() != len) {
        return Err(IdentError::InvalidArgument(
            "CSV columns must have the same length".into(),
        ));
    }
    let io = |e: std::io::Error| IdentError::Data(format!("writing CSV: {e}"));
    let header: Vec<&str> = columns.iter().map(|c| c.0).collect();
    writeln!(w, "{}", header.join(",")).map_err(io)?;
    let mut line = String::new();
    for i in 0..len {
        line.clear();
        for (j, c) in columns.iter().enumerate() {
            if j > 0 {
                line.push(',');
            }
            line.push_str(&format!("{:e}", c.1[i]));
        }
        writeln!(w, "{line}").map_err(io)?;
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn spec(lines: Lines, phases: Phases) -> MultisineSpec {
        MultisineSpec {
            fs: 5000.0,
            period: 10_000,
            f_min: 1.0,
            f_max: 2000.0,
            lines,
            phases,
            rms: 2.0,
            fold_rate_hz: Some(1000.0),
        }
    }

    #[test]
    fn spectrum_is_flat_on_the_excited_lines_and_empty_elsewhere() {
        let m = design(&spec(
            Lines::RandomOdd { group: 3, seed: 1 },
            Phases::Random { seed: 2 },
        ))
        .unwrap();
        let n = m.signal.len();
        let mut buf: Vec<Complex<f64>> = m.signal.iter().map(|&v| Complex::new(v, 0.0)).collect();
        FftPlanner::<f64>::new()
            .plan_fft_forward(n)
            .process(&mut buf);
        let amp = buf[m.excited[0]].norm();
        for &k in &m.excited {
            assert!((buf[k].norm() - amp).abs() < 1e-9 * amp);
        }
        for &k in m.detection_odd.iter().chain(&m.detection_even) {
            assert!(buf[k].norm() < 1e-9 * amp);
        }
        let rms = (m.signal.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        assert!((rms - 2.0).abs() < 1e-12);
        assert!(!m.detection_odd.is_empty() && !m.detection_even.is_empty());
        assert!((m.f0 - 0.5).abs() < 1e-15);
    }

    #[test]
    fn schroeder_has_a_lower_crest_factor_than_a_zero_phase_sum() {
        let m = design(&spec(Lines::Full, Phases::Schroeder)).unwrap();
        // all phases zero would give crest factor sqrt(2·K); Schroeder stays near sqrt(2)
        assert!(m.crest_factor < 2.5, "{}", m.crest_factor);
        assert!(design(&MultisineSpec {
            fold_rate_hz: Some(333.3),
            ..spec(Lines::Full, Phases::Schroeder)
        })
        .is_err());
        assert!(design(&MultisineSpec {
            f_max: 2600.0,
            ..spec(Lines::Full, Phases::Schroeder)
        })
        .is_err());
    }
}
