//! Ripples: pole pairs of a physical fit that are no modes of their own.
//!
//! A pair at the bandwidth floor ([`FLOOR_RESOLUTION`]: the fit would have made it narrower
//! than the lines resolve) inside a broader resonance's half-power band (`|f − f_o| <
//! ζ_o f_o`, `ζ_o < 1/√2`, the broader pair not at the floor itself), whose own term at its
//! frequency is below that pair's term there (`|t(e^{jωT})| < |t_o(e^{jωT})|`), has no peak
//! of its own in the response: an experimental modal analyst would not name it. Such poles
//! are what a fit spends on what repeats from period to period — a structure's stochastic
//! nonlinear distortion, which a full multisine of one realization leaves out of the
//! variance the fit weighs by (on the level suite's full multisines, beside a softening or
//! hardening mode). A lightly damped mode of its own is not one: resolved, or as strong as
//! its neighbour at its frequency, or outside its half-power band.

use super::{ModeKind, PhysicalMode};
use crate::fit::ModalTerm;
use num_complex::Complex64 as C;
use std::f64::consts::TAU;

/// A pair at most this far above the bandwidth floor (its half-power bandwidth over the line
/// spacing, [`PhysicalMode::resolution`]) sits at the floor.
pub const FLOOR_RESOLUTION: f64 = 1.01;

/// A pair has a resonance peak below this damping (`1/√2`): only such a pair's half-power
/// band can hold a ripple.
const RESONANT: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Which of `modes` (with their `terms`, sampled at `ts`) are ripples (module
/// documentation); `false` for every term that is no pair.
pub(super) fn ripples(modes: &[PhysicalMode], terms: &[ModalTerm], ts: f64) -> Vec<bool> {
    let at = |t: &ModalTerm, f: f64| t.eval(C::from_polar(1.0, TAU * f * ts)).norm();
    let floored = |m: &PhysicalMode| m.resolution.is_some_and(|r| r <= FLOOR_RESOLUTION);
    let pairs: Vec<(&PhysicalMode, &ModalTerm)> = modes
        .iter()
        .zip(terms)
        .filter(|(m, _)| m.kind == ModeKind::Pair)
        .collect();
    modes
        .iter()
        .zip(terms)
        .map(|(m, t)| {
            if m.kind != ModeKind::Pair || !floored(m) {
                return false;
            }
            let own = at(t, m.freq_hz);
            pairs.iter().any(|&(o, u)| {
                o.damping < RESONANT
                    && !floored(o)
                    && (o.freq_hz - m.freq_hz).abs() < o.damping * o.freq_hz
                    && own < at(u, m.freq_hz)
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pair `(f, ζ)` with residue magnitude `r` at `ts` (the z-domain pole `e^{sT}`), its
    /// bandwidth over a 1 Hz line spacing.
    fn pair(f: f64, zeta: f64, r: f64, ts: f64) -> (PhysicalMode, ModalTerm) {
        let w = TAU * f;
        let s = C::new(-zeta * w, w * (1.0 - zeta * zeta).sqrt());
        let mode = PhysicalMode {
            kind: ModeKind::Pair,
            freq_hz: f,
            damping: zeta,
            residue: [r, 0.0],
            share: 0.0,
            stable_orders: 10,
            frequency_orders: 10,
            in_band: true,
            resolution: Some(2.0 * zeta * f / 1.0),
            ripple: false,
        };
        let term = ModalTerm::Pair {
            pole: (s * ts).exp(),
            residue: C::new(0.0, -r),
        };
        (mode, term)
    }

    /// A pole at the bandwidth floor 2 Hz beside a ζ = 0.006 mode at 1524 Hz with a
    /// two-hundredth of its residue is a ripple; as strong as the mode, outside its
    /// half-power band, or resolved, it is a mode.
    #[test]
    fn a_floored_weak_pole_inside_a_mode_is_a_ripple() {
        let ts = 1.0 / 10_000.0;
        let floor = 0.5 / 1522.0; // 2ζf = 1 Hz: the line spacing
        let strong = pair(1524.0, 0.006, 1e-10, ts);
        let cases = [
            (pair(1522.0, floor, 5e-13, ts), true),
            (pair(1522.0, floor, 5e-11, ts), false),
            (pair(1560.0, 0.5 / 1560.0, 5e-13, ts), false),
            (pair(1522.0, 0.001, 5e-13, ts), false),
        ];
        for (weak, ripple) in cases {
            let modes = [strong.0.clone(), weak.0.clone()];
            let terms = [strong.1, weak.1];
            assert_eq!(
                ripples(&modes, &terms, ts),
                vec![false, ripple],
                "{:?}",
                weak.0
            );
        }
    }
}
