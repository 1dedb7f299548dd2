//! The chordal distance between a model and a measured FRF: the data's side of Vinnicombe's
//! ν-gap.
//!
//! **Math.** At each line `κ(f) = |P̂ − G| / (√(1 + |P̂|²)·√(1 + |G|²))`, the chordal distance of
//! the two responses projected on the Riemann sphere (SISO). The ν-gap is
//! `δ_ν(P̂, P) = max_ω κ(ω)` when the winding-number condition holds (`1 + P*P̂` has no net
//! change of argument around the unit circle, beyond the difference of the two plants'
//! unstable poles), and 1 otherwise (Vinnicombe, *Uncertainty and Feedback*, 2001, §3.2). A
//! measured FRF cannot show the winding condition (it needs the plant's poles): the maximum
//! over the measured lines is the ν-gap to the measured plant *if* the condition holds, and a
//! lower bound on it between the lines. With loopshaping weights the distance is taken between
//! the shaped responses `W P̂` and `W G`, which is what the design's stability margin
//! `ε = 1/γ` protects: a controller with `b_{P̂,K} > δ_ν(P̂, P)` stabilises P (Vinnicombe, Thm.
//! 3.8).

use crate::error::{Result, UncertaintyError};
use num_complex::Complex64 as C;
use sd_model::{Frd, StateSpace};

/// The chordal distance between a model and a measurement over the measured lines.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct ChordalGap {
    /// `max_k κ(f_k)`.
    pub max: f64,
    /// Its line (Hz).
    pub at_hz: f64,
    /// Lines compared.
    pub lines: usize,
}

/// `κ(a, b)` of two complex responses.
pub fn chordal(a: C, b: C) -> f64 {
    (a - b).norm() / ((1.0 + a.norm_sqr()).sqrt() * (1.0 + b.norm_sqr()).sqrt())
}

/// The largest chordal distance between `model` and `measured` on the measured lines, both
/// shaped by `weight` where given (module documentation).
///
/// # Errors
/// Not SISO, different sample times, an empty measurement, a failed frequency response.
pub fn chordal_gap(
    model: &StateSpace,
    measured: &Frd,
    weight: Option<&StateSpace>,
) -> Result<ChordalGap> {
    if model.nu() != 1 || model.ny() != 1 || measured.is_empty() {
        return Err(UncertaintyError::Input(
            "the ν-gap to a measurement needs a SISO model and a non-empty SISO FRF".into(),
        ));
    }
    if !model.time().compatible(&measured.time()) {
        return Err(UncertaintyError::Input(
            "the model and the measured FRF must have the same sample time".into(),
        ));
    }
    let f = measured.freq_hz();
    let p = model.freqresp(f)?;
    let w: Vec<C> = match weight {
        Some(w) => w
            .freqresp(f)?
            .response()
            .iter()
            .map(|m| m[(0, 0)])
            .collect(),
        None => vec![C::new(1.0, 0.0); f.len()],
    };
    let mut best = ChordalGap {
        max: 0.0,
        at_hz: f[0],
        lines: f.len(),
    };
    for (i, (pm, g)) in p.response().iter().zip(measured.response()).enumerate() {
        let k = chordal(w[i] * pm[(0, 0)], w[i] * g[(0, 0)]);
        if k > best.max {
            best.max = k;
            best.at_hz = f[i];
        }
    }
    Ok(best)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn chordal_distance_is_a_metric_on_the_sphere() {
        let (a, b) = (C::new(1.0, 2.0), C::new(-0.5, 0.3));
        assert_eq!(chordal(a, a), 0.0);
        assert!((chordal(a, b) - chordal(b, a)).abs() < 1e-15);
        // 0 and ∞ are antipodes: distance 1
        assert!((chordal(C::new(0.0, 0.0), C::new(1e12, 0.0)) - 1.0).abs() < 1e-9);
        // 1 and −1: |2| / (√2·√2) = 1
        assert!((chordal(C::new(1.0, 0.0), C::new(-1.0, 0.0)) - 1.0).abs() < 1e-15);
    }
}
