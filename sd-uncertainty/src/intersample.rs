//! The intersample error of a slow loop around a fast plant, bounded over every plant inside a
//! fast-rate uncertainty: what the slow samples do not show, under what the data say the model
//! gets wrong.
//!
//! **Math.** The loop of [`sd_multirate::MultirateLoop`]: fast plant `P` at period h, slow
//! controller `K` at `T = F·h` behind a zero-order hold, an ideal slow sampler, a force `d` at
//! the plant input and a sensor disturbance `n` at its output. With `f_k = f − k/T`
//! (k = 0…F−1), the hold's weight `η_k = H_F(f_k)/F`, `P_d = Σ_k η_k P(f_k)` (Lemma 6 in the
//! frequency domain), `S_d = 1/(1 + K P_d)` and `Φ_v = |P|²Φ_d + Φ_n`, the fast error's
//! (time-averaged) density is
//!
//! ```text
//! Φ_z(f) = |1 − g|² Φ_v(f) + |g|² Σ_{k≥1} Φ_v(f_k),     g = η_0 P(f) K S_d
//! ```
//!
//! and `1 − g = S_d (1 + K r)` with `r = P_d − η_0 P(f)`, the part of the slow plant that
//! folds in from the other frequencies. An additive perturbation `P + Δ` with
//! `|Δ(f)| ≤ w(f)` on the fast unit circle (multiplicative: `w = |P|·w_×`) moves `P_d` by at
//! most `w_d = Σ_k |η_k| w(f_k)` (the downsampled bound) and `r` by at most
//! `w_r = Σ_{k≥1} |η_k| w(f_k)`. While `|K S_d| w_d < 1` (robust stability of the slow loop,
//! small gain), `|S_{d,Δ}| ≤ |S_d|/(1 − |K S_d| w_d)`, and every factor above has a bound:
//!
//! ```text
//! Φ_z,Δ(f) ≤ [|S_d|(|1 + K r| + |K| w_r)/δ]² Φ̄_v(f) + [(|P| + w)|η_0||K S_d|/δ]² Σ_{k≥1} Φ̄_v(f_k)
//! δ = 1 − |K S_d| w_d,    Φ̄_v = (|P| + w)² Φ_d + Φ_n
//! ```
//!
//! for every stable `Δ` inside the bound at once (each term at its own worst case, so the
//! bound is attained only where one term dominates and the worst phases line up). The
//! sensitivity factor keeps its cancellation: at low frequencies the bound follows `|S_d|`, not
//! `|P|`. The rms bound integrates the density bound (an upper bound on every perturbed
//! plant's rms). Follows the harmonic-transfer view of Bamieh & Pearson (1992) and the
//! small-gain argument of Zhou, Doyle & Glover (1996, Thm. 9.1) applied per fold line.
//!
//! **Accuracy.** The nominal density equals [`sd_multirate::MultirateLoop::error_spectrum_fast`]
//! to rounding (checked in the tests); the bound holds on 200 random plants inside the weight
//! (`tests` below), with the densities from `error_spectrum_fast` of each perturbed plant.

use crate::bound::Form;
use crate::error::{Result, UncertaintyError};
use num_complex::Complex64 as C;
use sd_analysis::rms_of_density;
use sd_model::{FreqRespEvaluator, SampleTime, StateSpace};
use sd_multirate::{hold_weight, MultirateLoop};
use std::f64::consts::TAU;

/// The intersample error bounded over an uncertainty set.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RobustIntersample {
    /// The uncertainty's form (what `Δ` perturbs).
    pub form: Form,
    /// Fast-rate frequencies (Hz), up to the fast Nyquist frequency.
    pub fast_hz: Vec<f64>,
    /// The nominal plant's fast error density at `fast_hz`.
    pub nominal_psd: Vec<f64>,
    /// Its upper bound over every plant inside the weight (`None` when the slow loop is not
    /// robustly stable against the downsampled weight: `slow_margin ≤ 1`).
    pub bound_psd: Option<Vec<f64>>,
    /// Nominal rms of the fast error.
    pub rms_nominal: f64,
    /// Upper bound of the fast error's rms over the set (`None` as `bound_psd`).
    pub rms_bound: Option<f64>,
    /// `1/max_f |K S_d|·w_d(f)`: the largest scaling of the fast weight the slow loop
    /// tolerates (> 1 robustly stable).
    pub slow_margin: f64,
    /// Where the bound exceeds the nominal density most (Hz).
    pub worst_hz: Option<f64>,
    /// That largest ratio (bound over nominal density).
    pub worst_ratio: Option<f64>,
}

/// The responses at one fast frequency the bound needs.
struct At {
    nominal: f64,
    /// `(|S_d|(|1 + K r| + |K| w_r), (|P| + w)|η_0||K S_d|, |K S_d| w_d)`.
    factors: (f64, f64, f64),
    /// `Φ̄_v(f)` and `Σ_{k≥1} Φ̄_v(f_k)`.
    phi_bar: (f64, f64),
}

/// Checks the models: SISO, discrete, the weight at the plant's period.
fn check(p_fast: &StateSpace, k: &StateSpace, weight: &StateSpace) -> Result<f64> {
    for (what, m) in [("plant", p_fast), ("controller", k), ("weight", weight)] {
        if m.nu() != 1 || m.ny() != 1 {
            return Err(UncertaintyError::Input(format!(
                "the {what} is {}x{}: the intersample bound needs SISO models",
                m.ny(),
                m.nu()
            )));
        }
    }
    let h = match p_fast.time() {
        SampleTime::Discrete { ts } => ts,
        SampleTime::Continuous => {
            return Err(UncertaintyError::Input(
                "the fast plant must be discrete (period h)".into(),
            ))
        }
    };
    match weight.time() {
        SampleTime::Discrete { ts } if (ts - h).abs() <= 1e-9 * h => Ok(h),
        _ => Err(UncertaintyError::Input(format!(
            "the weight must be discrete at the fast plant's period {h} s: give the fast-rate \
             uncertainty (from `sdctl uncertainty` on the fast FRF), not a downsampled one"
        ))),
    }
}

/// Evaluators of the plant, the controller and the weight.
struct Eval {
    p: FreqRespEvaluator,
    k: FreqRespEvaluator,
    w: FreqRespEvaluator,
    form: Form,
    factor: usize,
    h: f64,
}

impl Eval {
    fn p(&self, f: f64) -> C {
        self.p.eval_hz(f)[(0, 0)]
    }

    /// The additive bound at `f` (Hz, signed).
    fn w(&self, f: f64) -> f64 {
        let w = self.w.eval_hz(f)[(0, 0)].norm();
        match self.form {
            Form::Additive => w,
            Form::Multiplicative => w * self.p(f).norm(),
        }
    }

    fn at(&self, f: f64, phi_d: &dyn Fn(f64) -> f64, phi_n: &dyn Fn(f64) -> f64) -> At {
        let t = self.h * self.factor as f64;
        let fs = 1.0 / self.h;
        let terms: Vec<(C, C, f64, f64)> = (0..self.factor)
            .map(|k| {
                let fk = f - k as f64 / t;
                let fa = sd_model::fold(fk, fs).abs();
                (
                    hold_weight(TAU * fk * self.h, self.factor),
                    self.p(fk),
                    self.w(fk),
                    fa,
                )
            })
            .collect();
        let pd: C = terms.iter().map(|(eta, p, _, _)| eta * p).sum();
        let (eta0, p0, w0, _) = terms[0];
        let r = pd - eta0 * p0;
        let kk = self.k.eval_hz(f)[(0, 0)];
        let s = C::new(1.0, 0.0) / (C::new(1.0, 0.0) + kk * pd);
        let g = eta0 * p0 * kk * s;
        let phi = |p: f64, w: f64, fa: f64| (p + w).powi(2) * phi_d(fa) + phi_n(fa);
        let phi_nom: Vec<f64> = terms
            .iter()
            .map(|(_, p, _, fa)| phi(p.norm(), 0.0, *fa))
            .collect();
        let phi_bar: Vec<f64> = terms
            .iter()
            .map(|(_, p, w, fa)| phi(p.norm(), *w, *fa))
            .collect();
        let others = |v: &[f64]| v.iter().skip(1).sum::<f64>();
        let nominal =
            (C::new(1.0, 0.0) - g).norm_sqr() * phi_nom[0] + g.norm_sqr() * others(&phi_nom);
        let wd: f64 = terms.iter().map(|(eta, _, w, _)| eta.norm() * w).sum();
        let wr = wd - eta0.norm() * w0;
        let ks = (kk * s).norm();
        At {
            nominal,
            factors: (
                s.norm() * ((C::new(1.0, 0.0) + kk * r).norm() + kk.norm() * wr),
                (p0.norm() + w0) * eta0.norm() * ks,
                ks * wd,
            ),
            phi_bar: (phi_bar[0], others(&phi_bar)),
        }
    }
}

/// The fast error of the loop `(p_fast, k)` (slow period `factor·h`) and its bound over every
/// plant inside `weight` (`|Δ| ≤ |W|`, in `form`'s units, at the fast rate), for one-sided
/// densities `phi_d` (force) and `phi_n` (sensor), on `points` linear frequencies up to the
/// fast Nyquist frequency (module documentation).
///
/// # Errors
/// Models that are not SISO, not discrete, or the weight at another period; a controller
/// period that is not `factor·h`; a nominal loop that is unstable; non-finite densities.
pub fn robust_intersample(
    p_fast: &StateSpace,
    k: &StateSpace,
    factor: usize,
    (weight, form): (&StateSpace, Form),
    phi_d: &dyn Fn(f64) -> f64,
    phi_n: &dyn Fn(f64) -> f64,
    points: usize,
) -> Result<RobustIntersample> {
    let h = check(p_fast, k, weight)?;
    let lp = MultirateLoop::new(p_fast, k, factor)?;
    let radius = lp.spectral_radius()?;
    if radius.is_nan() || radius >= 1.0 {
        return Err(UncertaintyError::Input(format!(
            "the nominal multirate loop is unstable (closed-loop spectral radius {radius:.6}): \
             an intersample bound needs a stabilising controller"
        )));
    }
    let ev = Eval {
        p: FreqRespEvaluator::new(p_fast)?,
        k: FreqRespEvaluator::new(k)?,
        w: FreqRespEvaluator::new(weight)?,
        form,
        factor,
        h,
    };
    let n = points.max(8);
    let fast_hz: Vec<f64> = (1..=n)
        .map(|i| 0.5 / h * i as f64 / n as f64 * (1.0 - 1e-9))
        .collect();
    let at: Vec<At> = fast_hz.iter().map(|&f| ev.at(f, phi_d, phi_n)).collect();
    let nominal_psd: Vec<f64> = at.iter().map(|a| a.nominal).collect();
    if nominal_psd.iter().any(|v| !v.is_finite()) {
        return Err(UncertaintyError::Input(
            "the nominal error density is not finite on the grid (a disturbance density that \
             is not finite, or a closed-loop pole on the unit circle)"
                .into(),
        ));
    }
    let loading = at.iter().map(|a| a.factors.2).fold(0.0, f64::max);
    let slow_margin = 1.0 / loading.max(f64::MIN_POSITIVE);
    let bound_psd = (slow_margin > 1.0).then(|| {
        at.iter()
            .map(|a| {
                let d = 1.0 - a.factors.2;
                (a.factors.0 / d).powi(2) * a.phi_bar.0 + (a.factors.1 / d).powi(2) * a.phi_bar.1
            })
            .collect::<Vec<f64>>()
    });
    let worst = bound_psd.as_ref().and_then(|b| {
        b.iter()
            .zip(&nominal_psd)
            .zip(&fast_hz)
            .map(|((b, nom), f)| (b / nom.max(f64::MIN_POSITIVE), *f))
            .max_by(|x, y| x.0.total_cmp(&y.0))
    });
    Ok(RobustIntersample {
        form,
        rms_nominal: rms_of_density(&fast_hz, &nominal_psd),
        rms_bound: bound_psd.as_ref().map(|b| rms_of_density(&fast_hz, b)),
        worst_hz: worst.map(|w| w.1),
        worst_ratio: worst.map(|w| w.0),
        fast_hz,
        nominal_psd,
        bound_psd,
        slow_margin,
    })
}

/// The slow loop's robust-stability margin on the fast bound's own lines beside the weight's
/// ([`slow_margin_on_lines`]).
#[derive(Debug, Clone, serde::Serialize)]
pub struct LinesMargin {
    /// `1/max |K S_d|·a_T` over the slow lines, `a_T` the fast bound downsampled
    /// ([`crate::downsample()`]): what `sdctl analyze --uncertainty` reports on the downsampled
    /// bound (> 1 robustly stable on the lines).
    pub margin: f64,
    /// Where that maximum is (Hz).
    pub worst_hz: f64,
    /// How many slow lines (those whose folds are all fast lines).
    pub lines: usize,
    /// `max w_d/a_T` over those lines: how far the weight's downsampled bound lies above the
    /// lines' (the weight overbounds every line and fills the gaps between them, so ≥ 1 up to
    /// fit tolerance); the margin with the weight is lower by up to this factor.
    pub weight_over_bound: f64,
    /// Where (Hz).
    pub weight_over_bound_hz: f64,
}

/// The slow loop's margin on the lines of `bound` (the fast-rate bound the weight overbounds)
/// and how conservative `weight` is there: the reason [`RobustIntersample::slow_margin`] (with
/// the weight, between the lines too) can say "not robustly stable" where the lines say
/// "robustly stable". The slow lines are the fast lines below the slow Nyquist frequency whose
/// `factor` folds are all lines; `|K S_d|` with `S_d = 1/(1 + K P_d)`, `P_d` the downsampled
/// nominal.
///
/// # Errors
/// As [`robust_intersample`]; a bound at another period than the plant's; no slow line whose
/// folds are all lines.
pub fn slow_margin_on_lines(
    p_fast: &StateSpace,
    k: &StateSpace,
    factor: usize,
    bound: &crate::Bound,
    weight: &StateSpace,
) -> Result<LinesMargin> {
    let h = check(p_fast, k, weight)?;
    if (bound.ts - h).abs() > 1e-9 * h {
        return Err(UncertaintyError::Input(format!(
            "the bound is at period {} s and the fast plant at {h} s: give the fast-rate bound",
            bound.ts
        )));
    }
    let slow_nyq = 0.5 / (h * factor as f64);
    let slow: Vec<f64> = bound
        .freq_hz
        .iter()
        .copied()
        .filter(|&f| f > 0.0 && f < slow_nyq * (1.0 - 1e-9))
        .collect();
    let d = crate::downsample(bound, factor, &slow)?;
    let ev = Eval {
        p: FreqRespEvaluator::new(p_fast)?,
        k: FreqRespEvaluator::new(k)?,
        w: FreqRespEvaluator::new(weight)?,
        form: bound.form,
        factor,
        h,
    };
    let t = h * factor as f64;
    let (mut load, mut worst_hz, mut over, mut over_hz) = (0.0f64, f64::NAN, 0.0f64, f64::NAN);
    for ((&f, &a), &pd) in d
        .bound
        .freq_hz
        .iter()
        .zip(&d.bound.additive)
        .zip(&d.bound.nominal)
    {
        let kk = ev.k.eval_hz(f)[(0, 0)];
        let ks = (kk / (C::new(1.0, 0.0) + kk * pd)).norm();
        if ks * a > load {
            (load, worst_hz) = (ks * a, f);
        }
        let wd: f64 = (0..factor)
            .map(|q| {
                let fk = f - q as f64 / t;
                hold_weight(TAU * fk * h, factor).norm() * ev.w(fk)
            })
            .sum();
        if a > 0.0 && wd / a > over {
            (over, over_hz) = (wd / a, f);
        }
    }
    Ok(LinesMargin {
        margin: 1.0 / load.max(f64::MIN_POSITIVE),
        worst_hz,
        lines: d.bound.freq_hz.len(),
        weight_over_bound: over,
        weight_over_bound_hz: over_hz,
    })
}
