//! Margins and singular values of a MIMO loop (negative feedback `u = −K y`).
//!
//! **Loop at a time.** Breaking only channel j of the input side (the others closed), the loop
//! gain seen there is `l_j = 1/(S_I)_jj − 1`, `S_I = (I + KP)⁻¹` (the diagonal entry of the
//! input sensitivity is the sensitivity of that single loop); likewise at output i with
//! `S_O = (I + PK)⁻¹`. Each `l_j` is realised (`(S_I)_jj` inverted: `A − B D⁻¹C`, …) and its
//! classic margins come from [`ClosedLoop::margins`] (python-control's definitions).
//!
//! **Disk margins** (Blight, Dailey & Gangsaas 1994; Seiler, Packard & Gahinet, IEEE CSM
//! 40(3), 2020), balanced (skew σ = 0): the loop stays stable for every gain and phase change
//! `f ∈ D(α) = {(1 + δ/2)/(1 − δ/2) : |δ| < α}`, with `α = 1/‖S − I/2‖∞`. Per channel with the
//! channel's `(S)_jj`; **simultaneously** on every input (or output) channel with the whole
//! `S`: `1/‖S − I/2‖∞` then bounds the multiloop disk margin from below (it lets the channels'
//! perturbations couple); the structured value, each channel perturbed on its own, is
//! `1/sup μ(S − I/2)` ([`crate::mu`]), reported beside it for two or more channels. A disk margin α gives the gain margin
//! `[(1 − α/2)/(1 + α/2), (1 + α/2)/(1 − α/2)]` (α < 2) and the phase margin `±2·atan(α/2)`.
//!
//! **Singular values** of S, T and KS on a frequency grid, from `P(f)` and `K(f)`
//! ([`ClosedLoop::responses`]).

use crate::closed_loop::ClosedLoop;
use crate::error::{AnalysisError, Result};
use crate::mu::{structured_disk_margins, StructuredDiskMargin};
use nalgebra::DMatrix;
use sd_model::connect::{feedback, series};
use sd_model::StateSpace;

/// Which side of the plant a channel is on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// A plant input (an actuator).
    Input,
    /// A plant output (a sensor).
    Output,
}

/// One channel's loop-at-a-time margins.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ChannelMargins {
    /// Input or output.
    pub side: Side,
    /// The channel (0-based).
    pub channel: usize,
    /// Classic gain margin (dB; `inf` when the loop never crosses the negative real axis).
    pub gain_margin_db: f64,
    /// Classic phase margin (degrees; `inf` when |l| never crosses 1).
    pub phase_margin_deg: f64,
    /// Balanced disk margin α of the channel.
    pub disk_margin: f64,
    /// Its gain margin: the upper end `(1 + α/2)/(1 − α/2)` in dB (`inf` for α ≥ 2).
    pub disk_gain_margin_db: f64,
    /// Its phase margin `2·atan(α/2)` (degrees).
    pub disk_phase_margin_deg: f64,
}

/// Loop-at-a-time margins of every channel and the simultaneous disk margins.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MimoMargins {
    /// Per input channel, then per output channel.
    pub channels: Vec<ChannelMargins>,
    /// `1/‖S_I − I/2‖∞`: every input channel changed at once (a lower bound of the multiloop
    /// disk margin).
    pub simultaneous_input_disk_margin: f64,
    /// `1/‖S_O − I/2‖∞`, on the outputs.
    pub simultaneous_output_disk_margin: f64,
    /// The structured (μ) simultaneous disk margin of the inputs: the channels perturbed
    /// independently ([`crate::mu`]); `None` for a single input (it equals the channel's).
    pub structured_input_disk_margin: Option<StructuredDiskMargin>,
    /// The same on the outputs.
    pub structured_output_disk_margin: Option<StructuredDiskMargin>,
}

/// The singular values of S, T and KS on a grid.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SingularValues {
    /// Frequencies (Hz).
    pub freq_hz: Vec<f64>,
    /// σ(S) per frequency, largest first.
    pub s: Vec<Vec<f64>>,
    /// σ(T).
    pub t: Vec<Vec<f64>>,
    /// σ(KS).
    pub ks: Vec<Vec<f64>>,
}

/// `(1 + α/2)/(1 − α/2)` in dB and `2·atan(α/2)` in degrees.
pub(crate) fn disk_to_classic(alpha: f64) -> (f64, f64) {
    let g = if alpha < 2.0 {
        20.0 * ((1.0 + alpha / 2.0) / (1.0 - alpha / 2.0)).log10()
    } else {
        f64::INFINITY
    };
    (g, 2.0 * (alpha / 2.0).atan().to_degrees())
}

/// `1/‖M − I/2‖∞` of a square sensitivity model.
fn disk_margin(s: &StateSpace) -> Result<f64> {
    let half = DMatrix::identity(s.ny(), s.nu()) * 0.5;
    let shifted = StateSpace::new(
        s.a().clone(),
        s.b().clone(),
        s.c().clone(),
        s.d() - half,
        s.time(),
    )?;
    Ok(1.0 / shifted.hinf_norm()?.value)
}

/// The SISO loop gain `1/s − 1` of a channel's sensitivity `s` (D ≠ 0).
fn loop_of(s: &StateSpace) -> Result<StateSpace> {
    let d = s.d()[(0, 0)];
    if d.abs() < 1e-12 {
        return Err(AnalysisError::InvalidArgument(
            "a channel's sensitivity vanishes at high frequency (an improper loop): no \
             loop-at-a-time margins"
                .into(),
        ));
    }
    let a = s.a() - s.b() * s.c() / d;
    let b = s.b() / d;
    let c = -s.c() / d;
    let dd = DMatrix::from_element(1, 1, 1.0 / d - 1.0);
    Ok(StateSpace::new(a, b, c, dd, s.time())?)
}

/// One channel's margins from its sensitivity `(S)_jj`.
fn channel(s_jj: &StateSpace, side: Side, j: usize) -> Result<ChannelMargins> {
    let l = loop_of(s_jj)?;
    let one = StateSpace::gain(DMatrix::identity(1, 1), l.time())?;
    let m = ClosedLoop::new(&l, &one)?.margins()?;
    let alpha = disk_margin(s_jj)?;
    let (dg, dp) = disk_to_classic(alpha);
    Ok(ChannelMargins {
        side,
        channel: j,
        gain_margin_db: m.gain_margin_db(),
        phase_margin_deg: m.phase_margin_deg,
        disk_margin: alpha,
        disk_gain_margin_db: dg,
        disk_phase_margin_deg: dp,
    })
}

/// Loop-at-a-time and simultaneous disk margins of a loop (module documentation).
///
/// # Errors
/// An unstable closed loop (margins of an unstable loop mean nothing), an improper channel
/// loop, the norms' failures.
pub fn mimo_margins(cl: &ClosedLoop) -> Result<MimoMargins> {
    let (_, stable) = cl.stability()?;
    if !stable {
        return Err(AnalysisError::InvalidArgument(
            "the closed loop is unstable: stabilise it before asking for margins".into(),
        ));
    }
    let (p, k) = (cl.plant(), cl.controller());
    let time = p.time();
    let kp = series(p, k)?;
    let s_in = feedback(
        &StateSpace::gain(DMatrix::identity(p.nu(), p.nu()), time)?,
        &kp,
        -1.0,
    )?;
    let s_out = cl.sensitivity().clone();
    let mut channels = Vec::new();
    for j in 0..p.nu() {
        channels.push(channel(&s_in.select(&[j], &[j])?, Side::Input, j)?);
    }
    for i in 0..p.ny() {
        channels.push(channel(&s_out.select(&[i], &[i])?, Side::Output, i)?);
    }
    let structured = if p.nu() > 1 || p.ny() > 1 {
        Some(structured_disk_margins(cl)?)
    } else {
        None
    };
    let [s_i, s_o] = match structured {
        Some([i, o]) => [Some(i), Some(o)],
        None => [None, None],
    };
    Ok(MimoMargins {
        channels,
        simultaneous_input_disk_margin: disk_margin(&s_in)?,
        simultaneous_output_disk_margin: disk_margin(&s_out)?,
        structured_input_disk_margin: s_i.filter(|_| p.nu() > 1),
        structured_output_disk_margin: s_o.filter(|_| p.ny() > 1),
    })
}

/// σ(S), σ(T), σ(KS) at the frequencies `freq_hz` (Hz).
///
/// # Errors
/// `I + PK` singular at a frequency.
pub fn singular_values(cl: &ClosedLoop, freq_hz: &[f64]) -> Result<SingularValues> {
    let mut out = SingularValues {
        freq_hz: freq_hz.to_vec(),
        s: Vec::new(),
        t: Vec::new(),
        ks: Vec::new(),
    };
    let sv = |m: &DMatrix<num_complex::Complex64>| -> Vec<f64> {
        let mut v: Vec<f64> = m.singular_values().iter().copied().collect();
        v.sort_by(|a, b| b.total_cmp(a));
        v
    };
    for &f in freq_hz {
        let r = cl.responses(f)?;
        out.s.push(sv(&r.s));
        out.t.push(sv(&r.t));
        out.ks.push(sv(&r.ks));
    }
    Ok(out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use sd_model::{append, SampleTime};

    fn ct(a: &[f64], b: &[f64], c: &[f64], d: f64) -> StateSpace {
        let n = a.len().isqrt();
        StateSpace::new(
            DMatrix::from_row_slice(n, n, a),
            DMatrix::from_row_slice(n, 1, b),
            DMatrix::from_row_slice(1, n, c),
            DMatrix::from_element(1, 1, d),
            SampleTime::Continuous,
        )
        .unwrap()
    }

    /// A decoupled 2×2 loop: each channel's loop-at-a-time margins are its SISO loop's.
    #[test]
    fn decoupled_channels_have_their_siso_margins() {
        // p1 = 1/(s(s + 2)), p2 = 4/((s + 1)(s + 3)); k1 = 3, k2 = 2(s + 0.5)/s
        let p1 = ct(&[0.0, 1.0, 0.0, -2.0], &[0.0, 1.0], &[1.0, 0.0], 0.0);
        let p2 = ct(&[0.0, 1.0, -3.0, -4.0], &[0.0, 4.0], &[1.0, 0.0], 0.0);
        let k1 =
            StateSpace::gain(DMatrix::from_element(1, 1, 3.0), SampleTime::Continuous).unwrap();
        let k2 = ct(&[0.0], &[1.0], &[1.0], 2.0);
        let p = append(&p1, &p2).unwrap();
        let k = append(&k1, &k2).unwrap();
        let m = mimo_margins(&ClosedLoop::new(&p, &k).unwrap()).unwrap();
        for (j, (pj, kj)) in [(&p1, &k1), (&p2, &k2)].into_iter().enumerate() {
            let siso = ClosedLoop::new(pj, kj).unwrap();
            let sm = siso.margins().unwrap();
            for side in [Side::Input, Side::Output] {
                let c = m
                    .channels
                    .iter()
                    .find(|c| c.side == side && c.channel == j)
                    .unwrap();
                let close = |a: f64, b: f64| (a == b) || (a - b).abs() <= 1e-6 * b.abs().max(1.0);
                assert!(
                    close(c.gain_margin_db, sm.gain_margin_db()),
                    "{c:?} vs {sm:?}"
                );
                assert!(
                    close(c.phase_margin_deg, sm.phase_margin_deg),
                    "{c:?} vs {sm:?}"
                );
                // the disk margin of a SISO loop from its own sensitivity
                let alpha = disk_margin(siso.sensitivity()).unwrap();
                assert!(close(c.disk_margin, alpha), "{c:?} vs {alpha}");
            }
        }
        // simultaneous margins never exceed any channel's
        let min_ch = m
            .channels
            .iter()
            .map(|c| c.disk_margin)
            .fold(f64::INFINITY, f64::min);
        assert!(m.simultaneous_input_disk_margin <= min_ch * (1.0 + 1e-9));
    }

    /// An integrator loop `k/s` has |S − 1/2| = 1/2 at every frequency: α = 2, an unbounded
    /// gain margin and a 90° phase margin (Seiler et al. 2020, their first example).
    #[test]
    fn integrator_loop_disk_margin() {
        let p = ct(&[0.0], &[1.0], &[1.0], 0.0);
        let k = StateSpace::gain(DMatrix::from_element(1, 1, 5.0), SampleTime::Continuous).unwrap();
        let m = mimo_margins(&ClosedLoop::new(&p, &k).unwrap()).unwrap();
        let c = &m.channels[0];
        assert!((c.disk_margin - 2.0).abs() < 1e-6, "{c:?}");
        assert!((c.disk_phase_margin_deg - 90.0).abs() < 1e-4, "{c:?}");
        assert!(
            c.disk_gain_margin_db > 100.0 || c.disk_gain_margin_db.is_infinite(),
            "{c:?}"
        );
    }

    /// A coupled plant's simultaneous margin is below its channels', and an unstable loop is
    /// refused with a reason.
    #[test]
    fn coupled_loop_and_unstable_loop() {
        let p = StateSpace::new(
            DMatrix::from_row_slice(2, 2, &[-1.0, 0.0, 0.0, -2.0]),
            DMatrix::from_row_slice(2, 2, &[1.0, 0.8, -0.5, 1.0]),
            DMatrix::from_row_slice(2, 2, &[1.0, 0.3, 0.2, 1.0]),
            DMatrix::zeros(2, 2),
            SampleTime::Continuous,
        )
        .unwrap();
        let k = StateSpace::gain(DMatrix::identity(2, 2) * 2.0, SampleTime::Continuous).unwrap();
        let cl = ClosedLoop::new(&p, &k).unwrap();
        let m = mimo_margins(&cl).unwrap();
        let min_in = m
            .channels
            .iter()
            .filter(|c| c.side == Side::Input)
            .map(|c| c.disk_margin)
            .fold(f64::INFINITY, f64::min);
        assert!(
            m.simultaneous_input_disk_margin <= min_in * (1.0 + 1e-9),
            "{m:?}"
        );
        let sv = singular_values(&cl, &[0.01, 1.0, 100.0]).unwrap();
        assert!(sv.s.iter().all(|v| v.len() == 2 && v[0] >= v[1]));
        // S + T = I: σ_max(T) ≤ 1 + σ_max(S)
        assert!(sv
            .t
            .iter()
            .zip(&sv.s)
            .all(|(t, s)| t[0] <= 1.0 + s[0] + 1e-12));
        let bad = StateSpace::gain(DMatrix::identity(2, 2) * -5.0, SampleTime::Continuous).unwrap();
        let e = mimo_margins(&ClosedLoop::new(&p, &bad).unwrap()).unwrap_err();
        assert!(e.to_string().contains("unstable"), "{e}");
    }
}
