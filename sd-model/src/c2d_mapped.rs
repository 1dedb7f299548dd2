//! The pole-zero mapped and impulse-invariant discretizations ([`crate::Discretization::Matched`],
//! [`crate::Discretization::Impulse`]).
//!
//! **Matched pole-zero** (Franklin, Powell & Workman, *Digital Control of Dynamic Systems*,
//! 3rd ed., §6.3.3), SISO: every pole `p` goes to `e^{pT}`, every finite zero `z` to `e^{zT}`;
//! of the `r = n − m` zeros at infinity `r − 1` go to `z = −1` (the Nyquist frequency, where a
//! continuous response vanishes) and one stays at infinity, so the result is strictly proper
//! like a sampled plant (a proper model with `m = n` keeps all its zeros). The gain matches
//! the low-frequency term: with `k` poles and `l` zeros at `s = 0`,
//! `G(s) ≈ c·s^{l−k}` and `G_d(z) ≈ c·((z − 1)/T)^{l−k}` (at DC for `k = l = 0`; a rigid body's
//! `1/(ms²)` keeps its `T²/m` scale). python-control's `matched` maps no zero to −1 and
//! matches the DC gain only (it cannot take a pole at 0).
//!
//! **Impulse-invariant** (MATLAB's and scipy's `impulse`): `G_d(z) = T·Σ_{k≥0} h(kT) z^{−k}`
//! with `h(t) = C e^{At} B`, i.e. `A_d = e^{AT}`, `B_d = A_d B T`, `C_d = C`, `D_d = C B T`;
//! defined for strictly proper models only (the impulse of a feedthrough has no samples).

use crate::error::{ModelError, Result};
use crate::linalg::expm;
use crate::ss::StateSpace;
use crate::tf::TransferFunction;
use crate::time::SampleTime;
use num_complex::Complex64 as C;

/// Roots within this of `s = 0` (relative to `1/T`) count as at the origin.
const AT_ORIGIN: f64 = 1e-9;

/// Matched pole-zero discretization (module documentation).
pub(crate) fn matched(sys: &StateSpace, ts: f64) -> Result<StateSpace> {
    if sys.nu() != 1 || sys.ny() != 1 {
        return Err(ModelError::InvalidArgument(format!(
            "the matched pole-zero mapping is defined for SISO models; this one is {}x{}: \
             discretize each channel separately or use zoh",
            sys.ny(),
            sys.nu()
        )));
    }
    let poles = sys.poles()?;
    let zeros = sys.zeros()?;
    let (n, m) = (poles.len(), zeros.len());
    let origin = |r: &C| r.norm() * ts <= AT_ORIGIN;
    let (kp, kz) = (
        poles.iter().filter(|p| origin(p)).count(),
        zeros.iter().filter(|z| origin(z)).count(),
    );
    // the continuous gain K of K·Π(s − z)/Π(s − p), from one evaluation away from every root
    let radius = poles
        .iter()
        .chain(&zeros)
        .fold(1.0 / ts, |a: f64, r| a.max(r.norm()));
    let s_star = C::new(0.3 * radius, 2.1 * radius);
    let g_star = sys.eval_direct(s_star)?[(0, 0)];
    let prod = |roots: &[C], at: C| roots.iter().fold(C::new(1.0, 0.0), |a, r| a * (at - r));
    let k_c = g_star * prod(&poles, s_star) / prod(&zeros, s_star);
    if !(k_c.norm().is_finite()) || k_c.norm() == 0.0 {
        return Err(ModelError::InvalidArgument(
            "the model's gain is zero or not finite: nothing to match".into(),
        ));
    }
    // c of the low-frequency term c·s^(l−k)
    let nonzero =
        |roots: &[C]| -> Vec<C> { roots.iter().filter(|r| !origin(r)).copied().collect() };
    let at_zero = |roots: &[C]| roots.iter().fold(C::new(1.0, 0.0), |a, r| a * (-r));
    let c = k_c * at_zero(&nonzero(&zeros)) / at_zero(&nonzero(&poles));
    // the discrete roots
    let map = |r: &C| {
        if origin(r) {
            C::new(1.0, 0.0)
        } else {
            (r * ts).exp()
        }
    };
    let zp: Vec<C> = poles.iter().map(map).collect();
    let mut zz: Vec<C> = zeros.iter().map(map).collect();
    if n > m {
        zz.extend(std::iter::repeat_n(C::new(-1.0, 0.0), n - m - 1));
    }
    // K_d from c = K_d·T^(l−k)·Π'(1 − ζ)/Π'(1 − π), the products over roots other than z = 1
    // (the origin's roots were mapped to exactly 1)
    let not_one = |rs: &[C]| -> Vec<C> {
        rs.iter()
            .filter(|r| **r != C::new(1.0, 0.0))
            .copied()
            .collect()
    };
    let at_one = |rs: &[C]| {
        rs.iter()
            .fold(C::new(1.0, 0.0), |a, r| a * (C::new(1.0, 0.0) - r))
    };
    let power = kz as i32 - kp as i32;
    let k_d = c / (ts.powi(power) * at_one(&not_one(&zz)) / at_one(&not_one(&zp)));
    let num = real_poly(&zz, k_d, "numerator")?;
    let den = real_poly(&zp, C::new(1.0, 0.0), "denominator")?;
    TransferFunction::new(num, den, SampleTime::discrete(ts)?)?.to_ss()
}

/// The real coefficients (descending) of `k·Π(x − r)`; the roots must come in conjugate pairs.
fn real_poly(roots: &[C], k: C, what: &str) -> Result<Vec<f64>> {
    let mut p = vec![k];
    for r in roots {
        let mut q = vec![C::new(0.0, 0.0); p.len() + 1];
        for (i, c) in p.iter().enumerate() {
            q[i] += c;
            q[i + 1] -= c * r;
        }
        p = q;
    }
    let scale = p.iter().fold(0.0f64, |a, c| a.max(c.norm()));
    if p.iter().any(|c| c.im.abs() > 1e-8 * scale) {
        return Err(ModelError::NotConverged {
            what: format!(
                "the matched {what}: the model's roots are not in conjugate pairs to 1e-8"
            ),
        });
    }
    Ok(p.iter().map(|c| c.re).collect())
}

/// Impulse-invariant discretization (module documentation).
pub(crate) fn impulse(sys: &StateSpace, ts: f64) -> Result<StateSpace> {
    if sys.d().iter().any(|v| *v != 0.0) {
        return Err(ModelError::InvalidArgument(
            "the impulse-invariant mapping is defined for strictly proper models (D = 0): the \
             impulse of a feedthrough has no samples; use zoh or tustin"
                .into(),
        ));
    }
    let ad = expm(&(sys.a() * ts))?;
    let bd = &ad * sys.b() * ts;
    let dd = sys.c() * sys.b() * ts;
    StateSpace::new(ad, bd, sys.c().clone(), dd, SampleTime::discrete(ts)?)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use crate::{c2d, Discretization, StateSpace, TransferFunction};
    use nalgebra::DMatrix;
    use num_complex::Complex64 as C;

    fn tf(num: &[f64], den: &[f64]) -> StateSpace {
        TransferFunction::new(num.to_vec(), den.to_vec(), crate::SampleTime::Continuous)
            .unwrap()
            .to_ss()
            .unwrap()
    }

    fn sorted(mut v: Vec<C>) -> Vec<C> {
        v.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
        v
    }

    /// `(s² + 2s + 101)/(s³ + 3s² + 10s + 5)` at 10 ms: the discrete poles are `e^{pT}`, the
    /// zeros `e^{zT}` (none to −1: relative degree 1), the DC gains equal.
    #[test]
    fn matched_maps_poles_zeros_and_dc_gain() {
        let g = tf(&[1.0, 2.0, 101.0], &[1.0, 3.0, 10.0, 5.0]);
        let ts = 0.01;
        let gd = c2d(&g, ts, Discretization::Matched).unwrap();
        let want_p = sorted(g.poles().unwrap().iter().map(|p| (p * ts).exp()).collect());
        let got_p = sorted(gd.poles().unwrap());
        for (a, b) in want_p.iter().zip(&got_p) {
            assert!((a - b).norm() < 1e-9, "{a} vs {b}");
        }
        let want_z = sorted(g.zeros().unwrap().iter().map(|z| (z * ts).exp()).collect());
        let got_z = sorted(gd.zeros().unwrap());
        assert_eq!(got_z.len(), 2);
        for (a, b) in want_z.iter().zip(&got_z) {
            assert!((a - b).norm() < 1e-8, "{a} vs {b}");
        }
        let (dc, dcd) = (
            g.eval_direct(C::new(0.0, 0.0)).unwrap()[(0, 0)],
            gd.eval_direct(C::new(1.0, 0.0)).unwrap()[(0, 0)],
        );
        assert!((dc - dcd).norm() < 1e-10 * dc.norm(), "{dc} vs {dcd}");
    }

    /// A rigid body with a mode, `1/(20 s²) + 0.1/(s² + 2·0.01·ω s + ω²)` (ω = 2π·653) at
    /// 5 kHz: two poles at z = 1, relative degree 2 so one zero at −1, and the low-frequency
    /// term `1/(ms²)` kept: `G_d(z)·((z − 1)/T)²` → `1/20` as z → 1 (checked at 0.01 Hz).
    #[test]
    fn matched_keeps_a_rigid_body_scale() {
        let w = 2.0 * std::f64::consts::PI * 653.0;
        let rb = tf(&[1.0 / 20.0], &[1.0, 0.0, 0.0]);
        let md = tf(&[0.1], &[1.0, 2.0 * 0.01 * w, w * w]);
        let g = crate::parallel(&rb, &md).unwrap();
        let ts = 2e-4;
        let gd = c2d(&g, ts, Discretization::Matched).unwrap();
        let zs = gd.zeros().unwrap();
        assert!(zs.iter().any(|z| (z + 1.0).norm() < 1e-6), "{zs:?}");
        let z = C::new(0.0, 2.0 * std::f64::consts::PI * 0.01 * ts).exp();
        let lead = gd.eval_direct(z).unwrap()[(0, 0)] * ((z - 1.0) / ts).powi(2);
        assert!((lead - C::new(0.05, 0.0)).norm() < 1e-4 * 0.05, "{lead}");
        let mimo =
            StateSpace::gain(DMatrix::identity(2, 2), crate::SampleTime::Continuous).unwrap();
        assert!(c2d(&mimo, ts, Discretization::Matched).is_err());
    }

    /// The impulse-invariant model's impulse response is `T·h(kT)`, `h(t) = C e^{At} B`
    /// evaluated by one exponential per sample (another form than the recursion); a
    /// feedthrough is refused.
    #[test]
    fn impulse_invariant_samples_the_impulse_response() {
        let g = tf(&[1.0, 2.0, 101.0], &[1.0, 3.0, 10.0, 5.0]);
        let ts = 0.05;
        let gd = c2d(&g, ts, Discretization::Impulse).unwrap();
        let mut u = DMatrix::zeros(40, 1);
        u[(0, 0)] = 1.0;
        let y = gd.simulate(&u, None).unwrap().y;
        for k in 0..40 {
            let e = crate::linalg::expm(&(g.a() * (k as f64 * ts))).unwrap();
            let h = (g.c() * e * g.b())[(0, 0)] * ts;
            assert!(
                (y[(k, 0)] - h).abs() <= 1e-12 * (1.0 + h.abs()),
                "{k}: {} vs {h}",
                y[(k, 0)]
            );
        }
        let with_d = tf(&[1.0, 1.0], &[1.0, 2.0]);
        assert!(c2d(&with_d, ts, Discretization::Impulse).is_err());
    }
}
