//! The slow-rate bound implied by a fast-rate one (Lemma 6 in the frequency domain).
//!
//! **Math.** Downsampling by `F` (slow period `T = F·h`) maps a fast response to
//! `P_T(f) = Σ_{k<F} P_h(f − k/T)·H_F(f − k/T)/F`, with the slow hold's weight
//! `H_F(θ)/F = (1/F)Σ_{i<F} e^{−jiθ}` (`sd_multirate::hold_weight`). The map is linear, so an
//! error `Δ_h` of the fast model becomes `Δ_T(f) = Σ_k Δ_h(f_k)·H_F(f_k)/F` and
//! `|Δ_T(f)| ≤ Σ_k |H_F(f_k)/F|·a_h(f_k)`: a sum of `F` fold components, each the fast bound
//! at a fold frequency weighted by the hold. The sum is tight when the fold errors add in
//! phase; when one fold dominates (the aliased resonance) it is nearly exact; when errors of
//! similar size and independent phase meet, the true error is nearer the root-sum-square, and
//! the bound is up to `√F` conservative. The slow nominal is the same map of the fast nominal,
//! which equals the Lemma 6 model's response. A multiplicative slow bound is the additive one
//! over `|P̂_T|`. The per-line confidence of the fast bound carries over to each fold
//! component; the union over `F` folds holds with probability at least `1 − F(1 − c)`, and in
//! practice near `c` because the fold components are dominated by one term.

use crate::bound::Bound;
use crate::error::{Result, UncertaintyError};
use num_complex::Complex64 as C;
use sd_multirate::{hold_weight, NonIdeal};
use std::f64::consts::PI;

/// A downsampled bound and the slow lines it could not give.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Downsampled {
    /// The bound at the slow rate (its `residual` and `sigma` are the folded sums, so that
    /// `additive = residual + κ·sigma` still holds).
    pub bound: Bound,
    /// Slow lines (Hz) left out because a fold frequency is not a line of the fast bound.
    pub missing_hz: Vec<f64>,
}

/// The slow bound at `slow_freq_hz` implied by the fast bound `fast` through Lemma 6 with
/// factor `factor` (module documentation).
///
/// # Errors
/// `factor` 0; no slow line whose folds are all on the fast grid.
pub fn downsample(fast: &Bound, factor: usize, slow_freq_hz: &[f64]) -> Result<Downsampled> {
    downsample_nonideal(fast, factor, NonIdeal::ideal(), slow_freq_hz)
}

/// [`downsample_nonideal`] on every line of the fast bound below the slow Nyquist frequency
/// `1/(2·F·h)` (the slow lines a fast bound can give; `sdctl downsample --uncertainty`).
///
/// # Errors
/// As [`downsample_nonideal`].
pub fn downsample_nonideal_all(fast: &Bound, factor: usize, ni: NonIdeal) -> Result<Downsampled> {
    let nyquist = 0.5 / (fast.ts * factor.max(1) as f64);
    let lines: Vec<f64> = fast
        .freq_hz
        .iter()
        .copied()
        .filter(|x| *x < nyquist)
        .collect();
    downsample_nonideal(fast, factor, ni, &lines)
}

/// [`downsample`] through a slow hold that switches `m = αF` fast samples late and a slow
/// sampler that averages the last `q = βF` fast outputs (the rate-tied non-idealities a
/// diagnosis names): each fold's weight becomes
/// `H_F(θ_k)/F · e^{−jmθ_k} · H_q(θ_k)/q`, `θ_k = 2πf_k h`, the frequency-domain form of
/// `sd_multirate::downsample_nonideal` (its response is the nominal here, tested). The delay
/// leaves the bound's weights' magnitudes alone; the averaging lowers the high folds.
///
/// A sensor that averages the *continuous* output (the physical case) is only approximated by
/// the average of fast samples: on the virtual stage with a 0.8 window at 1 kHz the fast-sample
/// nominal covers 8 % of the measured slow lines, while the continuous model's response
/// (`sd_multirate::c2d_nonideal` of the model taken back to continuous time, as the diagnosis
/// does) with these fold weights covers 100 % (`tests/tests/uncertainty.rs`). Replace
/// `bound.nominal` by that response in such a case.
///
/// # Errors
/// As [`downsample`]; fractions that are not whole numbers of fast samples, or a delay beyond
/// one slow period.
pub fn downsample_nonideal(
    fast: &Bound,
    factor: usize,
    ni: NonIdeal,
    slow_freq_hz: &[f64],
) -> Result<Downsampled> {
    if factor == 0 {
        return Err(UncertaintyError::Input(
            "the factor F = T/h must be a positive integer".into(),
        ));
    }
    let samples = |what: &str, x: f64, max: f64| -> Result<usize> {
        let n = x * factor as f64;
        if !(x.is_finite() && (0.0..=max).contains(&x))
            || (n - n.round()).abs() > 1e-9 * factor as f64
        {
            return Err(UncertaintyError::Input(format!(
                "{what} {x} must be a whole number of fast samples in [0, {max}] slow periods \
                 (a multiple of 1/F = {})",
                1.0 / factor as f64
            )));
        }
        Ok(n.round() as usize)
    };
    let m = samples("hold delay", ni.hold_delay, 1.0)?;
    let q = samples("averaging window", ni.averaging, 1.0)?.max(1);
    let t = fast.ts * factor as f64;
    let mut out = Bound {
        ts: t,
        freq_hz: Vec::new(),
        nominal: Vec::new(),
        residual: Vec::new(),
        sigma: Vec::new(),
        additive: Vec::new(),
        ..fast.clone()
    };
    let mut missing = Vec::new();
    'line: for &f in slow_freq_hz {
        let (mut p, mut r, mut s, mut a) = (C::new(0.0, 0.0), 0.0, 0.0, 0.0);
        for k in 0..factor {
            let fk = f - k as f64 / t;
            let Some((i, mirrored)) = sd_model::folded_line(&fast.freq_hz, fk, 1.0 / fast.ts)
            else {
                missing.push(f);
                continue 'line;
            };
            let theta = 2.0 * PI * fk * fast.ts;
            let w = hold_weight(theta, factor)
                * C::from_polar(1.0, -(m as f64) * theta)
                * hold_weight(theta, q);
            let v = fast.nominal[i];
            p += w * if mirrored { v.conj() } else { v };
            let m = w.norm();
            r += m * fast.residual[i];
            s += m * fast.sigma[i];
            a += m * fast.additive[i];
        }
        out.freq_hz.push(f);
        out.nominal.push(p);
        out.residual.push(r);
        out.sigma.push(s);
        out.additive.push(a);
    }
    if out.freq_hz.is_empty() {
        return Err(UncertaintyError::Input(format!(
            "none of the {} slow lines has all its {factor} fold frequencies on the fast grid: \
             measure the fast FRF on a grid that contains f − k/T (e.g. the same line spacing \
             at both rates)",
            slow_freq_hz.len()
        )));
    }
    Ok(Downsampled {
        bound: out,
        missing_hz: missing,
    })
}
