//! Alias maps between rates.
//!
//! - Where a continuous frequency appears at a sample rate: [`sd_model::alias()`] (re-exported as
//!   [`appears_at()`]); e.g. 653 Hz at 1 kHz appears at 347 Hz.
//! - Which fast-rate frequencies fold onto a slow-rate one, and how strongly the slow hold
//!   passes them ([`fold_map`]). With `T = F·h`, a slow frequency `f` receives the fast
//!   frequencies `f_k = f − k/T`, k = 0…F−1 (taken modulo the fast rate), weighted in Lemma 6's
//!   folding identity
//!
//!   `P_d(e^{j2πfT}) = Σ_k P_h(e^{j2πf_k h}) · H_F(e^{j2πf_k h})/F`,
//!   `H_F(z) = Σ_{i<F} z^{−i}`, `|H_F(e^{jθ})|/F = |sin(Fθ/2) / (F sin(θ/2))|`,
//!
//!   so the hold weight is 1 at k = 0 and falls towards the fast Nyquist frequency.

use crate::error::{check_factor, MultirateError, Result};
use num_complex::Complex64 as C;
use std::f64::consts::PI;

pub use sd_model::alias as appears_at;

/// One fast-rate frequency folding onto a slow-rate frequency.
#[derive(Debug, Clone, PartialEq)]
pub struct FoldTerm {
    /// k in `f_k = f − k/T`.
    pub k: usize,
    /// `f_k` as a signed frequency in (−fast rate/2, fast rate/2] (Hz).
    pub signed_hz: f64,
    /// `|f_k|`, the fast-rate frequency in [0, fast Nyquist] (Hz).
    pub fast_hz: f64,
    /// `H_F(e^{j2πf_k h})/F`, the slow hold's complex weight.
    pub hold: C,
    /// `|H_F|/F` ∈ [0, 1].
    pub weight: f64,
}

/// `H_F(e^{jθ})/F = (1/F) Σ_{i<F} e^{−jiθ}` in closed form (exact at θ = 0 mod 2π).
pub fn hold_weight(theta: f64, factor: usize) -> C {
    let f = factor as f64;
    // H_F is 2π-periodic in θ: reduce to δ ∈ [−π, π] first
    let delta = theta - 2.0 * PI * (theta / (2.0 * PI)).round();
    let half = 0.5 * delta;
    // sin is relatively accurate for tiny arguments, so only δ = 0 needs its limit
    let mag = if half == 0.0 {
        1.0
    } else {
        (f * half).sin() / (f * half.sin())
    };
    C::from_polar(mag, -(f - 1.0) * half)
}

/// The F fast frequencies that fold onto `slow_hz` at the slow rate `slow_rate_hz = 1/T`, with
/// the fast rate `F/T`, in order k = 0…F−1.
///
/// # Errors
/// Non-finite or negative frequencies, a rate ≤ 0, F = 0.
pub fn fold_map(slow_hz: f64, slow_rate_hz: f64, factor: usize) -> Result<Vec<FoldTerm>> {
    check_factor(factor)?;
    if !(slow_rate_hz.is_finite() && slow_rate_hz > 0.0) {
        return Err(MultirateError::InvalidArgument(format!(
            "slow sample rate {slow_rate_hz} Hz must be finite and > 0"
        )));
    }
    if !slow_hz.is_finite() {
        return Err(MultirateError::InvalidArgument(format!(
            "frequency {slow_hz} Hz must be finite"
        )));
    }
    let fast = slow_rate_hz * factor as f64;
    let h = 1.0 / fast;
    Ok((0..factor)
        .map(|k| {
            let fk = slow_hz - k as f64 * slow_rate_hz;
            let signed = fk - fast * (fk / fast).round();
            let hold = hold_weight(2.0 * PI * fk * h, factor);
            FoldTerm {
                k,
                signed_hz: signed,
                fast_hz: signed.abs(),
                hold,
                weight: hold.norm(),
            }
        })
        .collect())
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_equals_the_sum() {
        for f in 1..=9usize {
            for &th in &[
                0.0,
                1e-9,
                0.3,
                1.0,
                PI,
                2.0 * PI,
                2.5,
                -1.2,
                4.0 * PI + 1e-13,
            ] {
                let sum: C = (0..f)
                    .map(|i| C::from_polar(1.0, -(i as f64) * th))
                    .sum::<C>()
                    / f as f64;
                let cf = hold_weight(th, f);
                assert!((sum - cf).norm() < 1e-12, "F {f} θ {th}: {sum} vs {cf}");
            }
        }
    }

    #[test]
    fn paper_fold() {
        // 347 Hz at 1 kHz receives 653 Hz from the 5 kHz model, weighted by the slow hold
        let m = fold_map(347.0, 1000.0, 5).unwrap();
        assert_eq!(m.len(), 5);
        assert!((m[0].fast_hz - 347.0).abs() < 1e-9 && m[0].weight > m[1].weight);
        assert!((m[1].fast_hz - 653.0).abs() < 1e-9);
        let th = 2.0 * PI * 653.0 / 5000.0;
        let w = ((5.0 * th / 2.0).sin() / (5.0 * (th / 2.0).sin())).abs();
        assert!((m[1].weight - w).abs() < 1e-14);
        let mut fs: Vec<f64> = m.iter().map(|t| t.fast_hz).collect();
        fs.sort_by(f64::total_cmp);
        for (a, b) in fs.iter().zip([347.0, 653.0, 1347.0, 1653.0, 2347.0]) {
            assert!((a - b).abs() < 1e-9);
        }
        assert!(fold_map(1.0, 0.0, 5).is_err() && fold_map(f64::NAN, 1.0, 5).is_err());
    }
}
