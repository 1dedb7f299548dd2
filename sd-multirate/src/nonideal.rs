//! Rate-tied non-idealities: a hold that switches late and a sampler that averages.
//!
//! Both are tied to the sample period, so they change with the rate: one continuous model with
//! one pair (α, β) predicts experiments at 5 kHz and at 1 kHz. A continuous filter or a fixed
//! delay common to all rates is part of the plant instead (Lemma 6 stays exact for it).
//!
//! **Delayed hold** (fraction α ∈ [0, 1] of the period h, τ = αh; Franklin, Powell & Workman,
//! *Digital Control of Dynamic Systems*, §4.3.4): on `[kh, kh+τ)` the plant still sees
//! `u_{k−1}`, on `[kh+τ, (k+1)h)` it sees `u_k`:
//! `x_{k+1} = Φ x_k + Γ₀ u_k + Γ₁ u_{k−1}`, `Γ₀ = ∫₀^{h−τ} e^{As} ds B`,
//! `Γ₁ = e^{A(h−τ)} ∫₀^τ e^{As} ds B`.
//!
//! **Averaging sampler** (fraction β ∈ [0, 1], window `L = βh` ending at the sample instant):
//! `y_k = (1/L) ∫_{kh−L}^{kh} y(t) dt`, which depends on the state and inputs of the previous
//! period: `y_k = C̄ x_{k−1} + D̄ u_{k−1} (+ D̄' u_{k−2} under a delayed hold)`,
//! `C̄ = (1/L) C ∫_{h−L}^{h} e^{As} ds`.
//!
//! **Exact computation (CT model).** Over one period the augmented state
//! `v = [x; z; u_prev; u_cur]` (z the running output integral, reset each period) obeys
//! `v̇ = M_s v` with `M_s` constant on each segment between the breakpoints `{0, τ, h−L, h}`
//! (which input is applied; whether z integrates). The period map is the product of ≤ 3 block
//! exponentials `e^{M_s d_s}` (Van Loan 1978), so every integral above is exact to expm
//! accuracy and no difference of large integrals (cancellation) is ever formed; z starts at
//! zero and only accumulates inside the window.
//!
//! **Resulting discrete model** (state `[x_k; u_{k−1} if α > 0; w_k if β > 0]`):
//! `x_{k+1} = T_xx x_k + T_xp u_{k−1} + T_xc u_k`, `w_{k+1} = (T_zx x_k + T_zp u_{k−1} + T_zc u_k)/L`;
//! output `y_k = w_k` with β > 0, else `y_k = C x_k + D u(kh)` where the input seen at the
//! sample instant is `u_{k−1}` for α > 0 (the switch comes τ later) and `u_k` for α = 0. The
//! first n states are the continuous state at the sample instants, the same coordinates as the
//! ideal ZOH model; α = β = 0 returns exactly [`sd_model::c2d()`] with ZOH.
//! Accuracy: that of expm; within 1e-8 of a brute-force fine-step simulation
//! (`tests/tests/nonideal_sim.rs`).
//!
//! **From a fast discrete model** ([`downsample_nonideal`]): the slow hold switches `m = αF`
//! fast samples late, and the slow sampler returns the mean of the last `q = βF` fast output
//! samples `y_h(kT), y_h(kT−h), …, y_h(kT−(q−1)h)` (a sensor read at the fast rate and
//! averaged by the slow controller). Both need αF and βF to be whole numbers: the fast model
//! knows nothing between its samples, so a CT model is needed for other fractions. With a fast
//! model that is the ZOH of a CT model, the delayed hold is exactly [`c2d_nonideal`] at T; the
//! discrete average is the rectangle rule of the continuous one.

use crate::downsample::downsample;
use crate::error::{check_factor, require_discrete, MultirateError, Result};
use crate::tol::WHOLE_SAMPLES_TOL;
use nalgebra::DMatrix;
use sd_model::linalg::expm;
use sd_model::{c2d, Discretization, ModelError, SampleTime, StateSpace};

/// The rate-tied non-idealities of a sampled-data loop, as fractions of the sample period.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NonIdeal {
    /// α ∈ [0, [`MAX_HOLD_DELAY`]]: the hold switches α·T after the sample instant (0: ideal
    /// ZOH). Beyond one period, α = m + φ with m whole periods of input delay and φ ∈ (0, 1].
    pub hold_delay: f64,
    /// β ∈ [0, 1]: the sampler averages the output over the last β·T before the instant
    /// (0: ideal sampler).
    pub averaging: f64,
}

impl NonIdeal {
    /// The ideal ZOH and sampler.
    pub fn ideal() -> Self {
        Self::default()
    }
    /// A delayed hold only.
    pub fn hold_delay(alpha: f64) -> Self {
        NonIdeal {
            hold_delay: alpha,
            averaging: 0.0,
        }
    }
    /// An averaging sampler only.
    pub fn averaging(beta: f64) -> Self {
        NonIdeal {
            hold_delay: 0.0,
            averaging: beta,
        }
    }
    /// True when both fractions are zero.
    pub fn is_ideal(&self) -> bool {
        self.hold_delay == 0.0 && self.averaging == 0.0
    }
    /// Checks that the hold delay is finite and in [0, [`MAX_HOLD_DELAY`]] and the averaging
    /// window finite and in [0, 1].
    pub fn validate(&self) -> Result<()> {
        for (what, v, max) in [
            ("hold delay", self.hold_delay, MAX_HOLD_DELAY),
            ("averaging window", self.averaging, 1.0),
        ] {
            if !(v.is_finite() && (0.0..=max).contains(&v)) {
                return Err(MultirateError::InvalidFraction {
                    what,
                    value: v,
                    why: format!("as a fraction of the sample period it must be in [0, {max}]"),
                });
            }
        }
        Ok(())
    }

    /// Whole periods of input delay and the remaining fraction φ ∈ [0, 1] of the hold delay
    /// (`α = m + φ`; α ≤ 1 gives m = 0).
    pub fn split_delay(&self) -> (usize, f64) {
        if self.hold_delay <= 1.0 {
            return (0, self.hold_delay);
        }
        let m = self.hold_delay.ceil() - 1.0;
        (m as usize, self.hold_delay - m)
    }
}

/// The longest hold delay accepted, in sample periods.
pub const MAX_HOLD_DELAY: f64 = 4.0;

/// `sys` preceded by `m` whole periods of input delay (registers after the plant's state, so
/// the first states stay the continuous state at the sample instants).
fn with_input_delay(sys: StateSpace, m: usize) -> Result<StateSpace> {
    Ok(sd_model::whole_input_delay(&sys, m)?)
}

/// Exact discretisation of a continuous model at period `ts` with a delayed hold and/or an
/// averaging sampler (see the module documentation for the model and its state).
///
/// # Errors
/// A discrete-time model, an invalid `ts`, fractions outside [0, 1] or not finite.
pub fn c2d_nonideal(sys: &StateSpace, ts: f64, ni: NonIdeal) -> Result<StateSpace> {
    ni.validate()?;
    let (whole, frac) = ni.split_delay();
    if whole > 0 {
        let inner = c2d_nonideal(
            sys,
            ts,
            NonIdeal {
                hold_delay: frac,
                ..ni
            },
        )?;
        return with_input_delay(inner, whole);
    }
    if ni.is_ideal() {
        return Ok(c2d(sys, ts, Discretization::Zoh)?);
    }
    if !sys.time().is_continuous() {
        return Err(ModelError::WrongDomain {
            operation: "c2d with a delayed hold or averaging sampler".into(),
            expected: "continuous-time".into(),
            found: "discrete-time".into(),
        }
        .into());
    }
    let time = SampleTime::discrete(ts)?;
    let (n, nu, ny) = (sys.n(), sys.nu(), sys.ny());
    let delayed = ni.hold_delay > 0.0;
    let averaged = ni.averaging > 0.0;
    let tau = ni.hold_delay * ts;
    let win = ni.averaging * ts;
    let a_start = ts - win;
    // augmented v = [x (n); z (nz); u_prev (np); u_cur (nu)]
    let nz = if averaged { ny } else { 0 };
    let np = if delayed { nu } else { 0 };
    let (iz, ip, ic) = (n, n + nz, n + nz + np);
    let m = ic + nu;
    let mut bps = vec![0.0, ts];
    if delayed && tau < ts {
        bps.push(tau);
    }
    if averaged && a_start > 0.0 {
        bps.push(a_start);
    }
    bps.sort_by(f64::total_cmp);
    bps.dedup();
    let mut t = DMatrix::<f64>::identity(m, m);
    for w in bps.windows(2) {
        let (t0, t1) = (w[0], w[1]);
        let dur = t1 - t0;
        if dur <= 0.0 {
            continue;
        }
        let prev = delayed && t0 < tau;
        let integrating = averaged && t0 >= a_start;
        let mut gen = DMatrix::<f64>::zeros(m, m);
        gen.view_mut((0, 0), (n, n)).copy_from(sys.a());
        let col = if prev { ip } else { ic };
        gen.view_mut((0, col), (n, nu)).copy_from(sys.b());
        if integrating {
            gen.view_mut((iz, 0), (ny, n)).copy_from(sys.c());
            gen.view_mut((iz, col), (ny, nu)).copy_from(sys.d());
        }
        let e = expm(&(gen * dur))?;
        t = e * t;
    }
    let nx = n + np + nz;
    // discrete state ξ = [x; u_prev (np); w (nz)]
    let (jp, jw) = (n, n + np);
    let mut ad = DMatrix::<f64>::zeros(nx, nx);
    let mut bd = DMatrix::<f64>::zeros(nx, nu);
    ad.view_mut((0, 0), (n, n))
        .copy_from(&t.view((0, 0), (n, n)));
    if delayed {
        ad.view_mut((0, jp), (n, nu))
            .copy_from(&t.view((0, ip), (n, nu)));
        bd.view_mut((jp, 0), (nu, nu)).fill_with_identity();
    }
    bd.view_mut((0, 0), (n, nu))
        .copy_from(&t.view((0, ic), (n, nu)));
    let mut cd = DMatrix::<f64>::zeros(ny, nx);
    let mut dd = DMatrix::<f64>::zeros(ny, nu);
    if averaged {
        let s = 1.0 / win;
        ad.view_mut((jw, 0), (ny, n))
            .copy_from(&(t.view((iz, 0), (ny, n)) * s));
        if delayed {
            ad.view_mut((jw, jp), (ny, nu))
                .copy_from(&(t.view((iz, ip), (ny, nu)) * s));
        }
        bd.view_mut((jw, 0), (ny, nu))
            .copy_from(&(t.view((iz, ic), (ny, nu)) * s));
        cd.view_mut((0, jw), (ny, ny)).fill_with_identity();
    } else {
        cd.view_mut((0, 0), (ny, n)).copy_from(sys.c());
        if delayed {
            cd.view_mut((0, jp), (ny, nu)).copy_from(sys.d());
        } else {
            dd.copy_from(sys.d());
        }
    }
    let out = StateSpace::new(ad, bd, cd, dd, time)?;
    Ok(out.with_labels_of(sys))
}

/// Whole number of fast samples `frac·F`, or an error.
fn whole_samples(what: &'static str, frac: f64, factor: usize) -> Result<usize> {
    let x = frac * factor as f64;
    let r = x.round();
    if (x - r).abs() > WHOLE_SAMPLES_TOL * factor as f64 {
        return Err(MultirateError::InvalidFraction {
            what,
            value: frac,
            why: format!(
                "from a fast discrete model it must be a whole number of fast samples \
                 (a multiple of 1/F = {}); use c2d_nonideal on a continuous model for other values",
                1.0 / factor as f64
            ),
        });
    }
    Ok(r as usize)
}

/// The slow model at `T = F·h` of a fast discrete model `p_h` with a slow hold that switches
/// `αF` fast samples late and a slow sampler that averages the last `βF` fast output samples
/// (module documentation). Ideal fractions give [`downsample`] (Lemma 6).
///
/// State `[x_k; u_{k−1} if αF > 0; w_k if βF > 1]` where `w_k` is the sum of the previous
/// period's last `βF − 1` fast outputs.
///
/// # Errors
/// A continuous model, an invalid factor, fractions outside [0, 1] or not multiples of 1/F.
pub fn downsample_nonideal(p_h: &StateSpace, factor: usize, ni: NonIdeal) -> Result<StateSpace> {
    let op = if ni.hold_delay == 0.0 && ni.averaging == 0.0 {
        "downsample"
    } else {
        "downsample with a delayed hold or averaging sampler"
    };
    let h = require_discrete(p_h, op)?;
    check_factor(factor)?;
    ni.validate()?;
    if ni.hold_delay > 1.0 {
        return Err(MultirateError::InvalidFraction {
            what: "hold delay",
            value: ni.hold_delay,
            why: "from a fast discrete model it must be in [0, 1]; use c2d_nonideal on a \
                  continuous model for longer delays"
                .into(),
        });
    }
    let m = whole_samples("hold delay", ni.hold_delay, factor)?;
    let q = whole_samples("averaging window", ni.averaging, factor)?.max(1);
    if m == 0 && q == 1 {
        return downsample(p_h, factor);
    }
    let (n, nu, ny) = (p_h.n(), p_h.nu(), p_h.ny());
    let (a, b, c, d) = (p_h.a(), p_h.b(), p_h.c(), p_h.d());
    // x at fast step j = X x_k + Bp u_prev + Bc u_cur
    let mut x = DMatrix::<f64>::identity(n, n);
    let mut bp = DMatrix::<f64>::zeros(n, nu);
    let mut bc = DMatrix::<f64>::zeros(n, nu);
    // sum of fast outputs at steps F−q+1 … F−1 (become w_{k+1})
    let mut wx = DMatrix::<f64>::zeros(ny, n);
    let mut wp = DMatrix::<f64>::zeros(ny, nu);
    let mut wc = DMatrix::<f64>::zeros(ny, nu);
    for j in 0..factor {
        let prev = j < m;
        if j + q > factor {
            wx += c * &x;
            wp += c * &bp;
            wc += c * &bc;
            if prev {
                wp += d;
            } else {
                wc += d;
            }
        }
        x = a * &x;
        bp = a * &bp;
        bc = a * &bc;
        if prev {
            bp += b;
        } else {
            bc += b;
        }
    }
    let delayed = m > 0;
    let averaged = q > 1;
    let np = if delayed { nu } else { 0 };
    let nz = if averaged { ny } else { 0 };
    let nx = n + np + nz;
    let (jp, jw) = (n, n + np);
    let mut ad = DMatrix::<f64>::zeros(nx, nx);
    let mut bd = DMatrix::<f64>::zeros(nx, nu);
    ad.view_mut((0, 0), (n, n)).copy_from(&x);
    bd.view_mut((0, 0), (n, nu)).copy_from(&bc);
    if delayed {
        ad.view_mut((0, jp), (n, nu)).copy_from(&bp);
        bd.view_mut((jp, 0), (nu, nu)).fill_with_identity();
    }
    if averaged {
        ad.view_mut((jw, 0), (ny, n)).copy_from(&wx);
        if delayed {
            ad.view_mut((jw, jp), (ny, nu)).copy_from(&wp);
        }
        bd.view_mut((jw, 0), (ny, nu)).copy_from(&wc);
    }
    // y_k = (1/q) (C x_k + D u(kT) + w_k), u(kT) = u_{k−1} if delayed else u_k
    let s = 1.0 / q as f64;
    let mut cd = DMatrix::<f64>::zeros(ny, nx);
    let mut dd = DMatrix::<f64>::zeros(ny, nu);
    cd.view_mut((0, 0), (ny, n)).copy_from(&(c * s));
    if delayed {
        cd.view_mut((0, jp), (ny, nu)).copy_from(&(d * s));
    } else {
        dd.copy_from(&(d * s));
    }
    if averaged {
        cd.view_mut((0, jw), (ny, ny))
            .copy_from(&(DMatrix::<f64>::identity(ny, ny) * s));
    }
    let out = StateSpace::new(ad, bd, cd, dd, SampleTime::discrete(h * factor as f64)?)?;
    Ok(out.with_labels_of(p_h))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn plant() -> StateSpace {
        sd_model::stage::paper_stage(0.01).unwrap()
    }

    #[test]
    fn ideal_fractions_give_the_zoh_model() {
        let p = plant();
        let a = c2d_nonideal(&p, 1e-3, NonIdeal::ideal()).unwrap();
        let b = c2d(&p, 1e-3, Discretization::Zoh).unwrap();
        assert_eq!(a.a(), b.a());
    }

    #[test]
    fn full_period_delay_is_one_sample_delay() {
        // α = 1: x_{k+1} = Φ x_k + Γ u_{k−1}
        let p = plant();
        let z = c2d(&p, 1e-3, Discretization::Zoh).unwrap();
        let dl = c2d_nonideal(&p, 1e-3, NonIdeal::hold_delay(1.0)).unwrap();
        let n = p.n();
        assert!((dl.a().view((0, 0), (n, n)) - z.a()).norm() < 1e-12 * z.a().norm());
        assert!((dl.a().view((0, n), (n, 1)) - z.b()).norm() < 1e-12 * z.b().norm());
        assert!(dl.b().view((0, 0), (n, 1)).norm() == 0.0);
        // response = z^{-1} · ZOH response
        let f = 123.0;
        let g1 = dl.freqresp(&[f]).unwrap().response()[0][(0, 0)];
        let g0 = z.freqresp(&[f]).unwrap().response()[0][(0, 0)];
        let zinv = num_complex::Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f * 1e-3);
        assert!((g1 - g0 * zinv).norm() < 1e-10 * g0.norm());
    }

    #[test]
    fn fast_model_route_matches_continuous_route_for_delays() {
        // a delay of m fast samples from the 5 kHz ZOH model equals the CT computation at 1 kHz
        let p = plant();
        let ph = c2d(&p, 2e-4, Discretization::Zoh).unwrap();
        for m in 0..=5 {
            let alpha = m as f64 / 5.0;
            let ni = NonIdeal::hold_delay(alpha);
            let from_dt = downsample_nonideal(&ph, 5, ni).unwrap();
            let from_ct = c2d_nonideal(&p, 1e-3, ni).unwrap();
            let fr = [3.0, 100.0, 347.0, 480.0];
            let a = from_dt.freqresp(&fr).unwrap();
            let b = from_ct.freqresp(&fr).unwrap();
            for i in 0..fr.len() {
                let (x, y) = (a.response()[i][(0, 0)], b.response()[i][(0, 0)]);
                assert!((x - y).norm() < 1e-9 * y.norm(), "m = {m}, f = {}", fr[i]);
            }
        }
    }

    #[test]
    fn refuses_bad_fractions() {
        let p = plant();
        assert!(c2d_nonideal(&p, 1e-3, NonIdeal::hold_delay(MAX_HOLD_DELAY + 0.5)).is_err());
        assert!(c2d_nonideal(&p, 1e-3, NonIdeal::hold_delay(-0.1)).is_err());
        assert!(c2d_nonideal(&p, 1e-3, NonIdeal::averaging(1.2)).is_err());
        assert!(c2d_nonideal(&p, 1e-3, NonIdeal::averaging(f64::NAN)).is_err());
        let ph = c2d(&p, 2e-4, Discretization::Zoh).unwrap();
        assert!(downsample_nonideal(&ph, 5, NonIdeal::hold_delay(0.3)).is_err());
        assert!(downsample_nonideal(&ph, 5, NonIdeal::hold_delay(1.4)).is_err());
        assert!(c2d_nonideal(&ph, 1e-3, NonIdeal::hold_delay(0.3)).is_err());
    }
}
