//! Power spectra of measured or simulated signals.
//!
//! - [`periodogram`]: `Φ(f_k) = c·|Σ w_n x_n e^{−j2πkn/N}|²/(fs Σ w_n²)` with `c = 2` except at
//!   DC and Nyquist (one-sided density in units²/Hz), after removing the mean.
//! - [`welch`]: the average of periodograms of overlapping windowed segments (Welch 1967);
//!   variance of each bin ≈ Φ²/K for K independent segments.
//! - [`cps`]: cumulative power spectrum `CPS(f_k) = Σ_{i≤k} Φ(f_i) Δf`; its last value is the
//!   variance (Parseval, exactly for the rectangular-window periodogram), so
//!   `rms = sqrt(CPS(f_max))`.
//! - [`Spectrum::dominant_hz`]: the frequency of the largest density (DC excluded).

use crate::error::{AnalysisError, Result};
use rustfft::{num_complex::Complex, FftPlanner};
use std::f64::consts::PI;

/// Window functions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Window {
    /// Rectangular (no window).
    Rectangular,
    /// Hann.
    Hann,
    /// Hamming.
    Hamming,
    /// Blackman.
    Blackman,
}

impl Window {
    fn weights(self, n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| {
                let x = 2.0 * PI * i as f64 / n as f64;
                match self {
                    Window::Rectangular => 1.0,
                    Window::Hann => 0.5 - 0.5 * x.cos(),
                    Window::Hamming => 0.54 - 0.46 * x.cos(),
                    Window::Blackman => 0.42 - 0.5 * x.cos() + 0.08 * (2.0 * x).cos(),
                }
            })
            .collect()
    }
}

/// A one-sided power spectral density.
#[derive(Debug, Clone, PartialEq)]
pub struct Spectrum {
    /// Frequencies (Hz), 0 … fs/2.
    pub freq_hz: Vec<f64>,
    /// Density (units²/Hz).
    pub psd: Vec<f64>,
    /// Number of segments averaged.
    pub segments: usize,
}

impl Spectrum {
    /// Frequency of the largest density, DC excluded.
    pub fn dominant_hz(&self) -> f64 {
        (1..self.psd.len())
            .max_by(|&a, &b| self.psd[a].total_cmp(&self.psd[b]))
            .map(|i| self.freq_hz[i])
            .unwrap_or(0.0)
    }
    /// `sqrt(∫ Φ df)`.
    pub fn rms(&self) -> f64 {
        cps(self).last().cloned().unwrap_or(0.0).sqrt()
    }
    /// Band power `∫_{lo}^{hi} Φ df` (bins inside the band).
    pub fn band_power(&self, lo: f64, hi: f64) -> f64 {
        let df = self.df();
        self.freq_hz
            .iter()
            .zip(&self.psd)
            .filter(|(f, _)| **f >= lo && **f < hi)
            .map(|(_, p)| p * df)
            .sum()
    }
    fn df(&self) -> f64 {
        if self.freq_hz.len() > 1 {
            self.freq_hz[1] - self.freq_hz[0]
        } else {
            0.0
        }
    }
}

fn check(x: &[f64], fs: f64, seg: usize) -> Result<()> {
    if !(fs.is_finite() && fs > 0.0) {
        return Err(AnalysisError::InvalidArgument(format!(
            "sample rate {fs} must be > 0"
        )));
    }
    if seg < 2 || seg > x.len() {
        return Err(AnalysisError::InvalidArgument(format!(
            "segment length {seg} must be between 2 and the signal length {}",
            x.len()
        )));
    }
    if x.iter().any(|v| !v.is_finite()) {
        return Err(AnalysisError::InvalidArgument(
            "the signal contains NaN or infinite values".into(),
        ));
    }
    Ok(())
}

/// Welch's averaged periodogram with `segment` samples per segment and fractional `overlap`
/// in [0, 1).
///
/// # Errors
/// A segment longer than the signal or shorter than 2, overlap outside [0, 1), NaN input.
pub fn welch(x: &[f64], fs: f64, segment: usize, overlap: f64, window: Window) -> Result<Spectrum> {
    check(x, fs, segment)?;
    if !(0.0..1.0).contains(&overlap) {
        return Err(AnalysisError::InvalidArgument(format!(
            "overlap {overlap} must be in [0, 1)"
        )));
    }
    let step = ((segment as f64 * (1.0 - overlap)).round() as usize).max(1);
    let w = window.weights(segment);
    let wss: f64 = w.iter().map(|v| v * v).sum();
    let fft = FftPlanner::<f64>::new().plan_fft_forward(segment);
    let nb = segment / 2 + 1;
    let mut acc = vec![0.0; nb];
    let mut count = 0usize;
    let mut buf = vec![Complex::new(0.0, 0.0); segment];
    let mut start = 0;
    while start + segment <= x.len() {
        let s = &x[start..start + segment];
        let mean = s.iter().sum::<f64>() / segment as f64;
        for i in 0..segment {
            buf[i] = Complex::new((s[i] - mean) * w[i], 0.0);
        }
        fft.process(&mut buf);
        for (k, a) in acc.iter_mut().enumerate() {
            let c = if k == 0 || 2 * k == segment { 1.0 } else { 2.0 };
            *a += c * buf[k].norm_sqr() / (fs * wss);
        }
        count += 1;
        start += step;
    }
    Ok(Spectrum {
        freq_hz: (0..nb).map(|k| k as f64 * fs / segment as f64).collect(),
        psd: acc.into_iter().map(|a| a / count as f64).collect(),
        segments: count,
    })
}

/// Periodogram of the whole signal with a window.
///
/// # Errors
/// As [`welch`].
pub fn periodogram(x: &[f64], fs: f64, window: Window) -> Result<Spectrum> {
    welch(x, fs, x.len(), 0.0, window)
}

/// Cumulative power spectrum (module documentation).
pub fn cps(s: &Spectrum) -> Vec<f64> {
    let df = s.df();
    let mut acc = 0.0;
    s.psd
        .iter()
        .map(|p| {
            acc += p * df;
            acc
        })
        .collect()
}

/// Root mean square of a signal (mean removed if `detrend`).
pub fn rms(x: &[f64], detrend: bool) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let m = if detrend {
        x.iter().sum::<f64>() / x.len() as f64
    } else {
        0.0
    };
    sd_model::rms_of(x.iter().map(|v| v - m))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn parseval_and_a_sine() {
        let fs = 1000.0;
        let x: Vec<f64> = (0..4096)
            .map(|n| 2.0 * (2.0 * PI * 125.0 * n as f64 / fs).sin())
            .collect();
        let p = periodogram(&x, fs, Window::Rectangular).unwrap();
        // variance of a sine of amplitude 2 is 2; the rectangular periodogram is exact
        assert!((p.rms() - rms(&x, true)).abs() < 1e-12);
        assert!((p.dominant_hz() - 125.0).abs() < 1e-9);
        let w = welch(&x, fs, 1024, 0.5, Window::Hann).unwrap();
        assert_eq!(w.segments, 7);
        assert!((w.rms() - 2f64.sqrt()).abs() < 1e-3 * 2f64.sqrt());
        assert!(welch(&x, fs, 10_000, 0.5, Window::Hann).is_err());
        assert!(welch(&x, fs, 100, 1.0, Window::Hann).is_err());
    }
}
