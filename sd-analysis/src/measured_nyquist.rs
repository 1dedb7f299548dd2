//! The Nyquist test of a loop whose plant is known only on measured lines.
//!
//! **Criterion.** As in [`crate::nyquist`]: along the contour that leaves the unstable region
//! on its right (the unit circle counterclockwise, the imaginary axis upwards), with poles on
//! the stability boundary at `z = 1` / `s = 0` kept on the stable side by a small detour
//! around them, the counterclockwise winding `W` of `det(I + L)` about the origin gives the
//! closed loop's unstable poles `Z = P − W` (`P` the open-loop poles in the unstable region).
//!
//! **From lines.** Only `0 < f_min ≤ f ≤ f_max` is measured, so the contour is closed with
//! what physics fixes at its ends:
//! - *low end*: below the lowest line `f_min` the plant is extended by its low-frequency
//!   asymptote with `N_P` integrators — `P(f) = P(f_min)·(f_min/f)^{N_P}`, for a SISO plant
//!   with its phase moved (linearly in `log f`) to the nearest `−N_P·90° + k·180°` — and the
//!   controller is evaluated from its model, on a log grid from `f_0` (a thousandth of the
//!   lowest of `f_min` and the controller's pole and zero frequencies) up to `f_min`. The loop
//!   gain must stay above 2 there (else the count would rest on the extension: measure
//!   lower). With `N` loop poles at `z = 1` (`s = 0`) — the plant's integrators (a rigid body
//!   is two) and the controller's — `det L ~ c·(jω)^{−N}` as `ω → 0⁺` with `c` real, so at
//!   `f_0` the argument of `det(I + L)` must be within 45° of some `−Nπ/2 + mπ`; the detour
//!   around the `N` poles turns it by `−Nπ`.
//! - *high end*: discrete time, `det(I + L)` is real at the Nyquist frequency, so its
//!   argument is a multiple of `π`; continuous time, a strictly proper plant makes
//!   `det(I + L) → 1`, a multiple of `2π`. The top line must be within 45° of that value and
//!   either close to the Nyquist frequency (≥ 0.95 of it) or have `σ̄(L) < 1/2` (no
//!   encirclement can hide above it).
//! - *between lines*: the argument is unwrapped line to line, which assumes that it turns by
//!   less than 120° between adjacent lines; a larger step makes the verdict undetermined at
//!   that frequency (measure a finer grid there).
//!
//! The mirror half (negative frequencies) turns the argument by the same amount, so
//! `W = (2·(φ_end − φ_0) − Nπ)/2π`, an integer by construction.

use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::poles::natural_frequency;
use sd_model::StateSpace;
use std::f64::consts::PI;

/// Largest argument step between adjacent lines that the unwrapping trusts (radians).
pub const MAX_LINE_STEP: f64 = 2.0 * PI / 3.0;
/// Largest distance of an end line's argument from its closing value (radians).
pub const MAX_END_OFFSET: f64 = PI / 4.0;

/// The Nyquist verdict on measured lines.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "verdict", rename_all = "snake_case")]
pub enum MeasuredNyquist {
    /// The contour is closed: `Z = P − W` closed-loop poles in the unstable region.
    Counted {
        /// Counterclockwise winding `W` of `det(I + L)`.
        encirclements: i64,
        /// Open-loop poles in the unstable region `P` (the plant's, as stated, and the
        /// controller's).
        open_loop_unstable: usize,
        /// `Z = P − W`.
        closed_loop_unstable: i64,
        /// `Z = 0`.
        stable: bool,
        /// Loop poles at `z = 1` / `s = 0` used at the low end, `N`.
        loop_integrators: usize,
        /// Largest argument step between adjacent lines (degrees).
        largest_step_deg: f64,
    },
    /// The lines do not determine the count (the reason says what to measure).
    Undetermined {
        /// Why, with the frequency and the figure.
        reason: String,
    },
}

/// What the Nyquist count needs besides the lines.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ends {
    /// Loop poles at `z = 1` / `s = 0`, `N`.
    pub integrators: usize,
    /// Open-loop poles in the unstable region, `P`.
    pub open_loop_unstable: usize,
    /// The Nyquist frequency (discrete time), `None` for continuous time.
    pub nyquist_hz: Option<f64>,
    /// `σ̄(L)` at the top line.
    pub top_gain: f64,
}

/// The count from `det(I + L)` on increasing lines `freq_hz` (module documentation).
pub(crate) fn count(freq_hz: &[f64], det: &[C], ends: Ends) -> MeasuredNyquist {
    let undetermined = |reason: String| MeasuredNyquist::Undetermined { reason };
    let (Some(&f_lo), Some(&f_hi), Some(first)) = (freq_hz.first(), freq_hz.last(), det.first())
    else {
        return undetermined("no lines".into());
    };
    if let Some(i) = det.iter().position(|d| d.norm() == 0.0) {
        return undetermined(format!(
            "det(I + L) is 0 at {} Hz: the loop is on the stability boundary there",
            freq_hz[i]
        ));
    }
    // low end: the nearest −Nπ/2 + mπ to the first line's argument
    let n = ends.integrators as f64;
    let a0 = first.arg();
    let m = ((a0 + n * PI / 2.0) / PI).round();
    let phi0 = m * PI - n * PI / 2.0;
    if (a0 - phi0).abs() > MAX_END_OFFSET {
        return undetermined(format!(
            "the lowest line ({f_lo:.4} Hz) is not yet in the low-frequency asymptote of {} \
             loop integrator(s): det(I + L) has phase {:.1}°, {:.1}° from the nearest {:.0}° \
             + k·180°; measure lower frequencies or state the plant's integrators",
            ends.integrators,
            a0.to_degrees(),
            (a0 - phi0).to_degrees().abs(),
            -90.0 * n
        ));
    }
    // unwrap line to line
    let (mut phi, mut largest) = (a0, 0.0f64);
    for i in 1..det.len() {
        let step = (det[i] / det[i - 1]).arg();
        if step.abs() > MAX_LINE_STEP {
            return undetermined(format!(
                "det(I + L) turns by {:.0}° between the lines at {:.4} and {:.4} Hz: too coarse \
                 to follow it around the critical point; measure a finer grid there",
                step.to_degrees(),
                freq_hz[i - 1],
                freq_hz[i]
            ));
        }
        largest = largest.max(step.abs());
        phi += step;
    }
    // high end
    let (unit, near_end) = match ends.nyquist_hz {
        Some(nyq) => (PI, f_hi >= 0.95 * nyq),
        None => (2.0 * PI, false),
    };
    if !near_end && ends.top_gain >= 0.5 {
        return undetermined(format!(
            "the top line ({f_hi:.4} Hz) still has σ̄(L) = {:.3} ≥ 0.5{}: the loop may encircle \
             the critical point above it; measure up to {}",
            ends.top_gain,
            ends.nyquist_hz.map_or(String::new(), |n| format!(
                " and is below 0.95 of Nyquist ({n} Hz)"
            )),
            if ends.nyquist_hz.is_some() {
                "the Nyquist frequency"
            } else {
                "where the loop gain is small"
            }
        ));
    }
    let phi_end = (phi / unit).round() * unit;
    if (phi - phi_end).abs() > MAX_END_OFFSET {
        return undetermined(format!(
            "at the top line ({f_hi:.4} Hz) det(I + L) has phase {:.1}°, {:.1}° from the \
             closing value {:.0}°{}",
            phi.to_degrees(),
            (phi - phi_end).to_degrees().abs(),
            phi_end.to_degrees(),
            if ends.nyquist_hz.is_some() {
                " (real at the Nyquist frequency): measure up to it"
            } else {
                " (1 at infinite frequency): measure higher"
            }
        ));
    }
    let turns = (2.0 * (phi_end - phi0) - n * PI) / (2.0 * PI);
    let w = turns.round() as i64;
    let z = ends.open_loop_unstable as i64 - w;
    MeasuredNyquist::Counted {
        encirclements: w,
        open_loop_unstable: ends.open_loop_unstable,
        closed_loop_unstable: z,
        stable: z == 0,
        loop_integrators: ends.integrators,
        largest_step_deg: largest.to_degrees(),
    }
}

/// Points of the extension grid below the lowest line.
const EXTENSION_POINTS: usize = 400;
/// Least loop gain `σ_min(L)` accepted on the extension.
pub const MIN_EXTENSION_GAIN: f64 = 2.0;

/// The extension's frequencies and `det(I + L)` there, or why the count cannot rest on it.
pub(crate) type Extension = std::result::Result<(Vec<f64>, Vec<C>), String>;

/// The loop below the lowest line (module documentation): frequencies from `f_0` up to (not
/// including) `f_min`, and `det(I + L)` there; `Err` with the reason when the loop gain
/// falls below [`MIN_EXTENSION_GAIN`] on it.
pub(crate) fn low_extension(
    p_min: &DMatrix<C>,
    f_min: f64,
    plant_integrators: usize,
    k: &StateSpace,
) -> crate::error::Result<Extension> {
    let ts = k.ts();
    let corner = k
        .poles()?
        .into_iter()
        .chain(k.zeros()?)
        .map(|z| natural_frequency(z, ts).0)
        .filter(|f| f.is_finite() && *f > 1e-9 * f_min)
        .fold(f_min, f64::min);
    let f0 = 1e-3 * corner;
    let grid: Vec<f64> = (0..EXTENSION_POINTS)
        .map(|i| f0 * (f_min / f0).powf(i as f64 / EXTENSION_POINTS as f64))
        .collect();
    let kr = k.freqresp(&grid)?;
    let n = plant_integrators as f64;
    let siso = p_min.len() == 1;
    let (a_min, lattice) = if siso {
        let a = p_min[(0, 0)].arg();
        let m = ((a + n * PI / 2.0) / PI).round();
        (a, m * PI - n * PI / 2.0)
    } else {
        (0.0, 0.0)
    };
    let mut det = Vec::with_capacity(grid.len());
    for (&f, kf) in grid.iter().zip(kr.response()) {
        let x = (f_min / f).ln() / (f_min / f0).ln();
        let rot = if siso { x * (lattice - a_min) } else { 0.0 };
        let pf = p_min.map(|v| v * C::from_polar((f_min / f).powf(n), rot));
        let l = &pf * kf;
        let gain = if l.len() == 1 {
            l[(0, 0)].norm()
        } else {
            l.clone().singular_values().min()
        };
        if gain < MIN_EXTENSION_GAIN {
            return Ok(Err(format!(
                "below the lowest line ({f_min:.4} Hz) the loop gain of the plant's \
                 {plant_integrators}-integrator asymptote with the controller falls to {gain:.3} \
                 at {f:.4} Hz: the count would rest on the extension; measure lower frequencies"
            )));
        }
        det.push((DMatrix::identity(l.nrows(), l.nrows()) + l).determinant());
    }
    Ok(Ok((grid, det)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `L = k/(z − 1)`: closed-loop pole `1 − k`, stable for `0 < k < 2`.
    #[test]
    fn integrator_loop_counts() {
        let f: Vec<f64> = (1..=500).map(f64::from).collect();
        let ts = 1e-3;
        for (k, unstable) in [(0.5, 0), (1.9, 0), (2.5, 1), (3.0, 1)] {
            let det: Vec<C> = f
                .iter()
                .map(|&x| {
                    let z = C::from_polar(1.0, 2.0 * PI * x * ts);
                    1.0 + k / (z - 1.0)
                })
                .collect();
            let ends = Ends {
                integrators: 1,
                open_loop_unstable: 0,
                nyquist_hz: Some(500.0),
                top_gain: k / 2.0,
            };
            match count(&f, &det, ends) {
                MeasuredNyquist::Counted {
                    closed_loop_unstable,
                    ..
                } => assert_eq!(closed_loop_unstable, unstable, "k = {k}"),
                other => panic!("k = {k}: {other:?}"),
            }
        }
    }
}
