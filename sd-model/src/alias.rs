//! Where a continuous frequency appears after sampling, and what folds onto a sampled one.
//!
//! Sampling at `fs` maps a continuous frequency `f` to `|f − k·fs|` with `k = round(f/fs)`, a
//! value in [0, fs/2] (the paper's example: 653 Hz at 1 kHz appears at 347 Hz, k = 1). Conversely
//! a frequency `f_a ∈ [0, fs/2]` receives every `k·fs ± f_a`.

use crate::error::{ModelError, Result};

/// Where a continuous frequency lands after sampling.
#[derive(Debug, Clone, PartialEq)]
pub struct Alias {
    /// The continuous frequency (Hz).
    pub freq_hz: f64,
    /// The sample rate (Hz).
    pub rate_hz: f64,
    /// The apparent frequency in [0, rate/2] (Hz).
    pub alias_hz: f64,
    /// The folding index k = round(f / fs).
    pub fold_index: i64,
    /// True if the spectrum is mirrored (f above the nearest multiple k·fs is not mirrored).
    pub mirrored: bool,
}

fn check(v: f64, what: &str, allow_zero: bool) -> Result<()> {
    if !v.is_finite() || v < 0.0 || (!allow_zero && v == 0.0) {
        return Err(ModelError::InvalidArgument(format!(
            "{what} = {v} must be finite and {}",
            if allow_zero { ">= 0" } else { "> 0" }
        )));
    }
    Ok(())
}

/// `f − fs·round(f/fs)`: the signed frequency in `[−fs/2, fs/2]` that `f` (Hz, any sign) lands
/// on when sampled at `fs` (its absolute value is the alias). The one fold of the workspace;
/// no argument checks (callers pass finite values, `fs > 0`).
pub fn fold(f: f64, fs: f64) -> f64 {
    f - fs * (f / fs).round()
}

/// The index of `f` among the increasing line frequencies `freq_hz`, when one lies within
/// `tol` of it. The one line lookup of the workspace.
pub fn line_index(freq_hz: &[f64], f: f64, tol: f64) -> Option<usize> {
    let i = freq_hz.partition_point(|&x| x < f - tol);
    (i < freq_hz.len() && (freq_hz[i] - f).abs() <= tol).then_some(i)
}

/// The line of a grid measured at rate `fs` (lines in `[0, fs/2]`, increasing) that a signed
/// frequency `f` folds onto, and whether it lands mirrored (a negative frequency: the response
/// there is the conjugate). `None` when no line lies within `1e-6·fs/len` of the fold.
pub fn folded_line(freq_hz: &[f64], f: f64, fs: f64) -> Option<(usize, bool)> {
    let g = fold(f, fs);
    let tol = 1e-6 * fs / freq_hz.len().max(1) as f64;
    line_index(freq_hz, g.abs(), tol).map(|i| (i, g < 0.0))
}

/// The alias of `freq_hz` at sample rate `rate_hz`.
pub fn alias(freq_hz: f64, rate_hz: f64) -> Result<Alias> {
    check(freq_hz, "frequency", true)?;
    check(rate_hz, "sample rate", false)?;
    let k = (freq_hz / rate_hz).round();
    let d = freq_hz - k * rate_hz;
    Ok(Alias {
        freq_hz,
        rate_hz,
        alias_hz: d.abs(),
        fold_index: k as i64,
        mirrored: d < 0.0,
    })
}

/// Every continuous frequency up to `max_hz` that appears at `alias_hz` after sampling at
/// `rate_hz`: `k·fs ± f_a`, ascending.
pub fn folding_frequencies(alias_hz: f64, rate_hz: f64, max_hz: f64) -> Result<Vec<f64>> {
    check(alias_hz, "frequency", true)?;
    check(rate_hz, "sample rate", false)?;
    check(max_hz, "maximum frequency", true)?;
    let a = alias(alias_hz, rate_hz)?.alias_hz;
    let mut out = Vec::new();
    let kmax = (max_hz / rate_hz).ceil() as i64 + 1;
    for k in 0..=kmax {
        for f in [k as f64 * rate_hz - a, k as f64 * rate_hz + a] {
            if f >= -1e-12
                && f <= max_hz * (1.0 + 1e-12)
                && !out.iter().any(|g: &f64| (g - f).abs() < 1e-9 * rate_hz)
            {
                out.push(f.max(0.0));
            }
        }
    }
    out.sort_by(f64::total_cmp);
    Ok(out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    #[test]
    fn paper_example() {
        let a = alias(653.0, 1000.0).unwrap();
        assert!((a.alias_hz - 347.0).abs() < 1e-12 && a.fold_index == 1 && a.mirrored);
        let f = folding_frequencies(347.0, 1000.0, 2500.0).unwrap();
        assert_eq!(f.len(), 5);
        assert!(
            (f[0] - 347.0).abs() < 1e-9
                && (f[1] - 653.0).abs() < 1e-9
                && (f[2] - 1347.0).abs() < 1e-9
        );
        assert!(alias(1.0, 0.0).is_err() && alias(f64::NAN, 1.0).is_err());
    }
}
