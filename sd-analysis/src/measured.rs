//! A controller model checked against a *measured* plant: the loop `L = P K` on the FRF's
//! lines, its sensitivities, margins and the Nyquist test — the way an engineer checks a
//! controller before closing the loop on the machine.
//!
//! **On the lines.** `L(f) = P(f)K(f)`, `S = (I + L)⁻¹`, `T = L S` at each measured
//! frequency (the controller's response from its model; a pole of `K` on a line is refused).
//! Peaks of `σ̄(S)`, `σ̄(T)` and the modulus margin `min |1 + L| = 1/max σ̄(S)` are the
//! largest over the lines: between lines they can be higher (a lightly damped mode between
//! two lines is not seen), which is why the line spacing is reported beside them.
//!
//! **Margins (SISO)**, with [`crate::ClosedLoop::margins`]'s definitions: a gain crossover
//! where `|L|` crosses 1 between two lines (located by linear interpolation of `log|L|` in
//! `log f`, the phase there interpolated linearly), phase margin `(∠L mod 360°) − 180°`; a
//! phase crossover where `Im L` changes sign between two lines with `Re L < 0` (located by
//! linear interpolation of `Im L`), gain margin `1/|L|` there (`|L|` interpolated in log).
//! The reported ones are the smallest `|PM|` and the smallest `|log GM|`; crossings outside
//! the measured band are not seen.
//!
//! **Stability**: [`crate::measured_nyquist`], with the plant's integrators and unstable poles
//! as stated, or — for a SISO plant with none stated — its integrators read from the lowest
//! decade of lines: the slope of `log|P|` against `log f` over at most the lowest quarter of
//! the lines, `N = −slope/20 dB per decade` rounded, accepted when within 0.25 of a whole
//! number and when the phase there agrees (`∠P + N·90°` within 45° of 0° or 180°).
//!
//! **A slow loop on a fast FRF**: [`sd_multirate::downsample_frd`] first (Lemma 6's fold sum,
//! no model), then this analysis at the slow rate.

use crate::closed_loop::sigma_max;
use crate::error::{AnalysisError, Result};
use crate::measured_nyquist::{count, low_extension, Ends, MeasuredNyquist};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::{Frd, SampleTime, StateSpace};

/// What the lines cannot tell about the plant.
#[derive(Debug, Clone, Copy, Default)]
pub struct MeasuredPlant {
    /// Poles of the plant at `z = 1` / `s = 0` (a rigid body: 2); `None`: read from the lowest
    /// lines (SISO only; module documentation).
    pub integrators: Option<usize>,
    /// Poles of the plant in the unstable region (0 for a stable or rigid-body stage).
    pub unstable_poles: usize,
}

/// The analysis of a controller on a measured plant (module documentation).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MeasuredAnalysis {
    /// Measured lines used.
    pub lines: usize,
    /// Lowest and highest line (Hz).
    pub band_hz: (f64, f64),
    /// Largest spacing between adjacent lines (Hz).
    pub max_line_spacing_hz: f64,
    /// The plant's integrators used by the Nyquist count.
    pub plant_integrators: usize,
    /// Whether they were read from the lines (not stated).
    pub integrators_from_lines: bool,
    /// The Nyquist verdict.
    pub nyquist: MeasuredNyquist,
    /// Lowest line-to-line crossing of `σ̄(L)` through 1 (Hz; NaN when none).
    pub crossover_hz: f64,
    /// `max σ̄(S)` over the lines (dB) and where.
    pub sensitivity_peak_db: f64,
    /// Its frequency (Hz).
    pub sensitivity_peak_hz: f64,
    /// `max σ̄(T)` over the lines (dB).
    pub complementary_peak_db: f64,
    /// Its frequency (Hz).
    pub complementary_peak_hz: f64,
    /// `1/max σ̄(S)` over the lines.
    pub modulus_margin: f64,
    /// SISO: gain margin (dB; `inf` when no phase crossover is measured; NaN for MIMO).
    pub gain_margin_db: f64,
    /// Its phase crossover (Hz; NaN when none).
    pub gain_margin_hz: f64,
    /// SISO: phase margin (degrees; `inf` when no gain crossover; NaN for MIMO).
    pub phase_margin_deg: f64,
    /// Its gain crossover (Hz; NaN when none).
    pub phase_margin_hz: f64,
    /// SISO: every measured phase crossover `(Hz, gain margin dB)`.
    pub all_phase_crossovers: Vec<(f64, f64)>,
    /// SISO: every measured gain crossover `(Hz, phase margin deg)`.
    pub all_gain_crossovers: Vec<(f64, f64)>,
}

/// The loop's responses on the lines.
#[derive(Debug, Clone)]
pub struct MeasuredResponses {
    /// `L = P K`.
    pub l: Frd,
    /// `S = (I + L)⁻¹`.
    pub s: Frd,
    /// `T = L S`.
    pub t: Frd,
}

/// `K` on `P`'s lines: the analysis and the responses (module documentation).
///
/// # Errors
/// Sample times that differ, shapes that do not close the loop, an empty FRD, a pole of `K`
/// on a line or on the stability boundary away from `z = 1` / `s = 0`, `I + L` singular on
/// a line, a MIMO plant without its integrators stated, or integrators the lowest lines do
/// not show clearly (the message gives the slope and phase found).
pub fn analyze_measured(
    p: &Frd,
    k: &StateSpace,
    plant: MeasuredPlant,
) -> Result<(MeasuredAnalysis, MeasuredResponses)> {
    check_loop(p, k)?;
    let resp = responses(p, k)?;
    let f = p.freq_hz();
    let (k_int, k_unstable) = controller_poles(k)?;
    let (p_int, inferred) = match plant.integrators {
        Some(n) => (n, false),
        None => (plant_integrators(p)?, true),
    };
    let det: Vec<C> = resp
        .l
        .response()
        .iter()
        .map(|l| (DMatrix::identity(l.nrows(), l.nrows()) + l).determinant())
        .collect();
    let top_gain = resp.l.response().last().map_or(0.0, sigma_max);
    let nyquist = match low_extension(&p.response()[0], f[0], p_int, k)? {
        Err(reason) => MeasuredNyquist::Undetermined { reason },
        Ok((mut ext_f, mut ext_det)) => {
            ext_f.extend_from_slice(f);
            ext_det.extend(det);
            let ends = Ends {
                integrators: p_int + k_int,
                open_loop_unstable: plant.unstable_poles + k_unstable,
                nyquist_hz: match p.time() {
                    SampleTime::Discrete { ts } => Some(0.5 / ts),
                    SampleTime::Continuous => None,
                },
                top_gain,
            };
            count(&ext_f, &ext_det, ends)
        }
    };
    let peak = |m: &Frd| {
        m.response()
            .iter()
            .zip(f)
            .map(|(r, &x)| (sigma_max(r), x))
            .fold((0.0, f64::NAN), |a, b| if b.0 > a.0 { b } else { a })
    };
    let (s_peak, s_hz) = peak(&resp.s);
    let (t_peak, t_hz) = peak(&resp.t);
    let gains: Vec<f64> = resp.l.response().iter().map(sigma_max).collect();
    let crossover_hz = (1..f.len())
        .find(|&i| (gains[i - 1] >= 1.0) != (gains[i] >= 1.0))
        .map_or(f64::NAN, |i| log_cross(f, &gains, i));
    let siso = (p.response()[0].nrows(), p.response()[0].ncols()) == (1, 1);
    let m = if siso {
        let l: Vec<C> = resp.l.response().iter().map(|r| r[(0, 0)]).collect();
        margins_on_lines(f, &l)
    } else {
        LineMargins::mimo()
    };
    let analysis = MeasuredAnalysis {
        lines: f.len(),
        band_hz: (f[0], f[f.len() - 1]),
        max_line_spacing_hz: f.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max),
        plant_integrators: p_int,
        integrators_from_lines: inferred,
        nyquist,
        crossover_hz,
        sensitivity_peak_db: 20.0 * s_peak.log10(),
        sensitivity_peak_hz: s_hz,
        complementary_peak_db: 20.0 * t_peak.log10(),
        complementary_peak_hz: t_hz,
        modulus_margin: 1.0 / s_peak,
        gain_margin_db: m.gain_margin_db,
        gain_margin_hz: m.gain_margin_hz,
        phase_margin_deg: m.phase_margin_deg,
        phase_margin_hz: m.phase_margin_hz,
        all_phase_crossovers: m.phase_crossovers,
        all_gain_crossovers: m.gain_crossovers,
    };
    Ok((analysis, resp))
}

/// Sample times, shapes and lines that allow the loop to close.
fn check_loop(p: &Frd, k: &StateSpace) -> Result<()> {
    let bad = |m: String| Err(AnalysisError::InvalidArgument(m));
    let Some(first) = p.response().first() else {
        return bad("the measured plant has no lines".into());
    };
    if !p.time().compatible(&k.time()) {
        return bad(format!(
            "the measured plant's sample time ({}) is not the controller's ({}): analyse a slow \
             controller on a fast FRF by folding the FRF to the controller's rate first \
             (Lemma 6, `--downsample F`)",
            time_text(p.time()),
            time_text(k.time())
        ));
    }
    if (k.nu(), k.ny()) != (first.nrows(), first.ncols()) {
        return bad(format!(
            "the controller is {}x{} but the measured plant is {}x{}: K must be {}x{} (u = −K y)",
            k.ny(),
            k.nu(),
            first.nrows(),
            first.ncols(),
            first.ncols(),
            first.nrows()
        ));
    }
    if p.freq_hz().windows(2).any(|w| w[1] <= w[0]) || p.freq_hz()[0] <= 0.0 {
        return bad(
            "the measured plant's lines must be positive and strictly increasing (a line at \
             0 Hz says nothing about the loop's phase)"
                .into(),
        );
    }
    Ok(())
}

fn time_text(t: SampleTime) -> String {
    match t {
        SampleTime::Continuous => "continuous".into(),
        SampleTime::Discrete { ts } => format!("ts = {ts} s"),
    }
}

/// `L`, `S`, `T` on the plant's lines.
fn responses(p: &Frd, k: &StateSpace) -> Result<MeasuredResponses> {
    let f = p.freq_hz();
    let kr = k.freqresp(f)?;
    let (mut l, mut s, mut t) = (vec![], vec![], vec![]);
    for (i, (pi, ki)) in p.response().iter().zip(kr.response()).enumerate() {
        let li = pi * ki;
        let n = li.nrows();
        let si = (DMatrix::identity(n, n) + &li)
            .try_inverse()
            .filter(|m| m.iter().all(|v| v.is_finite()))
            .ok_or_else(|| {
                AnalysisError::InvalidArgument(format!(
                    "I + L is singular at {} Hz: the loop passes through the critical point",
                    f[i]
                ))
            })?;
        t.push(&li * &si);
        s.push(si);
        l.push(li);
    }
    let frd = |r| Frd::new(f.to_vec(), r, None, p.time());
    Ok(MeasuredResponses {
        l: frd(l)?,
        s: frd(s)?,
        t: frd(t)?,
    })
}

/// The controller's poles at `z = 1` / `s = 0` and in the unstable region; other poles on the
/// boundary are refused (the contour would need a detour there).
fn controller_poles(k: &StateSpace) -> Result<(usize, usize)> {
    let poles = k.poles()?;
    let scale = k.a().norm().max(1.0);
    let tol = 1e-8 * scale;
    let (mut at_one, mut unstable) = (0, 0);
    for p in poles {
        let (boundary, dc, outside) = match k.time() {
            SampleTime::Discrete { .. } => (
                (p.norm() - 1.0).abs() <= tol,
                (p - 1.0).norm() <= tol.sqrt(),
                p.norm() > 1.0,
            ),
            SampleTime::Continuous => (p.re.abs() <= tol, p.norm() <= tol.sqrt(), p.re > 0.0),
        };
        if dc {
            at_one += 1;
        } else if boundary {
            return Err(AnalysisError::InvalidArgument(format!(
                "the controller has a pole on the stability boundary at {p:.6} (not an \
                 integrator): the Nyquist test on measured lines supports boundary poles only \
                 at z = 1 / s = 0"
            )));
        } else if outside {
            unstable += 1;
        }
    }
    Ok((at_one, unstable))
}

/// The plant's integrators read from its lowest lines (SISO; module documentation).
fn plant_integrators(p: &Frd) -> Result<usize> {
    let r = p.response();
    if (r[0].nrows(), r[0].ncols()) != (1, 1) {
        return Err(AnalysisError::InvalidArgument(
            "state the plant's integrators (poles at z = 1 / s = 0; a rigid body has 2) for a \
             MIMO measured plant: they are not read from a MIMO FRF"
                .into(),
        ));
    }
    let f = p.freq_hz();
    let decade = f.partition_point(|&x| x <= 10.0 * f[0]);
    let n = decade.min(f.len() / 4).max(3).min(f.len());
    if n < 3 {
        return Err(AnalysisError::InvalidArgument(
            "too few lines to read the plant's integrators: state them".into(),
        ));
    }
    let xs: Vec<f64> = f[..n].iter().map(|x| x.log10()).collect();
    let ys: Vec<f64> = r[..n]
        .iter()
        .map(|g| 20.0 * g[(0, 0)].norm().log10())
        .collect();
    let (mx, my) = (mean(&xs), mean(&ys));
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    let slope = sxy / sxx;
    let est = -slope / 20.0;
    let nint = est.round();
    let phase = r[0][(0, 0)].arg().to_degrees() + 90.0 * nint;
    let off = (phase - 180.0 * (phase / 180.0).round()).abs();
    if !(est.is_finite() && nint >= 0.0 && (est - nint).abs() <= 0.25 && off <= 45.0) {
        return Err(AnalysisError::InvalidArgument(format!(
            "the plant's integrators are not clear from its lowest {n} lines ({:.3}–{:.3} Hz: \
             slope {slope:.1} dB/decade, phase {:.0}° at the lowest): state them (a rigid \
             body has 2)",
            f[0],
            f[n - 1],
            r[0][(0, 0)].arg().to_degrees()
        )));
    }
    Ok(nint as usize)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Where `g` crosses 1 between lines `i − 1` and `i`, by linear interpolation of `log g` in
/// `log f`.
fn log_cross(f: &[f64], g: &[f64], i: usize) -> f64 {
    let (a, b) = (g[i - 1].ln(), g[i].ln());
    let x = a / (a - b);
    (f[i - 1].ln() + x * (f[i].ln() - f[i - 1].ln())).exp()
}

/// SISO margins read between lines.
struct LineMargins {
    gain_margin_db: f64,
    gain_margin_hz: f64,
    phase_margin_deg: f64,
    phase_margin_hz: f64,
    phase_crossovers: Vec<(f64, f64)>,
    gain_crossovers: Vec<(f64, f64)>,
}

impl LineMargins {
    fn mimo() -> Self {
        LineMargins {
            gain_margin_db: f64::NAN,
            gain_margin_hz: f64::NAN,
            phase_margin_deg: f64::NAN,
            phase_margin_hz: f64::NAN,
            phase_crossovers: vec![],
            gain_crossovers: vec![],
        }
    }
}

/// Gain and phase crossings of `l` between adjacent lines (module documentation).
fn margins_on_lines(f: &[f64], l: &[C]) -> LineMargins {
    let mags: Vec<f64> = l.iter().map(|v| v.norm()).collect();
    let (mut phase_x, mut gain_x) = (vec![], vec![]);
    for i in 1..f.len() {
        let (a, b) = (l[i - 1], l[i]);
        if (a.im > 0.0) != (b.im > 0.0) && (a.re < 0.0 || b.re < 0.0) {
            let x = a.im / (a.im - b.im);
            let re = a.re + x * (b.re - a.re);
            if re < 0.0 {
                let fx = f[i - 1] + x * (f[i] - f[i - 1]);
                let mag = (mags[i - 1].ln() + x * (mags[i].ln() - mags[i - 1].ln())).exp();
                phase_x.push((fx, -20.0 * mag.log10()));
            }
        }
        if (mags[i - 1] >= 1.0) != (mags[i] >= 1.0) {
            let fx = log_cross(f, &mags, i);
            let x = (fx.ln() - f[i - 1].ln()) / (f[i].ln() - f[i - 1].ln());
            let step = (b / a).arg();
            let ph = a.arg() + x * step;
            let pm = ph.to_degrees().rem_euclid(360.0) - 180.0;
            gain_x.push((fx, pm));
        }
    }
    let gm = phase_x
        .iter()
        .copied()
        .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap_or((f64::NAN, f64::INFINITY));
    let pm = gain_x
        .iter()
        .copied()
        .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap_or((f64::NAN, f64::INFINITY));
    LineMargins {
        gain_margin_db: gm.1,
        gain_margin_hz: gm.0,
        phase_margin_deg: pm.1,
        phase_margin_hz: pm.0,
        phase_crossovers: phase_x,
        gain_crossovers: gain_x,
    }
}
