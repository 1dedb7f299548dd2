//! A mode's amplitude in a record: the DFT of the steady output (and input) and the rms in a
//! mode's band; a friction corner's share of the velocity (module documentation of
//! [`super`]).

use super::*;

/// Rms of `x` sampled at `fs` in the band `[lo, hi]` Hz ([`Spectrum::band_rms`]).
#[cfg(test)]
pub(super) fn band_rms(x: &[f64], fs: f64, lo: f64, hi: f64) -> f64 {
    Spectrum::of(x, fs).band_rms((lo, hi), false)
}

/// The one-sided power spectrum of a record, computed once for many band rms.
pub(crate) struct Spectrum {
    /// `|X_k|²` of the windowed DFT, `k = 0..=N/2`.
    power: Vec<f64>,
    df: f64,
    n: f64,
}

impl Spectrum {
    /// The power of the Hann-windowed DFT of `x` sampled at `fs` (window normalised to unit
    /// mean square, `Σw²/N = 3/8`) after the mean and the linear trend are removed. The
    /// window matters for non-periodic records: a rectangular one leaks the large
    /// low-frequency motion of a stage (whose record does not end where it starts) over
    /// every band with a level set by chance, which the Hann window's `1/f³` side-lobes
    /// suppress; whole periods of a periodic record lose nothing but the band edges' half
    /// bins.
    pub(crate) fn of(x: &[f64], fs: f64) -> Self {
        let n = x.len();
        if n < 4 {
            return Spectrum {
                power: Vec::new(),
                df: 1.0,
                n: 1.0,
            };
        }
        let nf = n as f64;
        let mean = x.iter().sum::<f64>() / nf;
        let tc = (nf - 1.0) / 2.0;
        let slope = x
            .iter()
            .enumerate()
            .map(|(i, v)| (i as f64 - tc) * (v - mean))
            .sum::<f64>()
            / (0..n).map(|i| (i as f64 - tc).powi(2)).sum::<f64>();
        let norm = (8.0f64 / 3.0).sqrt();
        let mut buf: Vec<C> = x
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let w = norm * (1.0 - (TAU * i as f64 / nf).cos()) / 2.0;
                C::new(w * (v - mean - slope * (i as f64 - tc)), 0.0)
            })
            .collect();
        rustfft::FftPlanner::new()
            .plan_fft_forward(n)
            .process(&mut buf);
        Spectrum {
            power: buf[..=n / 2].iter().map(|c| c.norm_sqr()).collect(),
            df: fs / nf,
            n: nf,
        }
    }

    /// Rms in the band `[lo, hi]` Hz, or with `derivative` the rms of the time derivative
    /// (each line's power times `(2πf)²`: the velocity of a position record).
    pub(crate) fn band_rms(&self, (lo, hi): (f64, f64), derivative: bool) -> f64 {
        if self.power.is_empty() || hi.is_nan() || lo.is_nan() || hi < lo {
            return 0.0;
        }
        let k0 = (lo / self.df).ceil().max(1.0) as usize;
        let k1 = ((hi / self.df).floor().max(0.0) as usize).min(self.power.len() - 1);
        let power: f64 = (k0..=k1)
            .map(|k| {
                let w = if derivative {
                    (TAU * k as f64 * self.df).powi(2)
                } else {
                    1.0
                };
                w * self.power[k]
            })
            .sum();
        (2.0 * power).sqrt() / self.n
    }
}

/// The spectra of an experiment's steady input and output.
pub(crate) struct Records {
    pub(super) u: Spectrum,
    pub(super) y: Spectrum,
}

impl Records {
    pub(crate) fn of(e: &Experiment) -> Self {
        let start = e.spec.skip_periods * e.spec.period_samples.unwrap_or(0);
        let fs = e.spec.sample_rate_hz;
        Records {
            u: Spectrum::of(&e.u[start.min(e.u.len())..], fs),
            y: Spectrum::of(&e.y[start.min(e.y.len())..], fs),
        }
    }
}

/// The band of a pole ([`band`]).
pub(super) fn band_of(s: C) -> (f64, f64) {
    let n = natural(s, [[0.0; 2]; 2]);
    band(n.0, n.1)
}

/// The band of a mode: `f(1 ± max(3ζ, 2 %))`; of a real pole (a corner `f`), `[f/3, 3f]`.
pub(super) fn band(f: f64, z: f64) -> (f64, f64) {
    if is_real_pole(z) {
        return (f / 3.0, 3.0 * f);
    }
    let w = (3.0 * z).max(0.02);
    (f * (1.0 - w), f * (1.0 + w))
}

/// The amplitude a candidate is driven at in output record `y`: for a pair, the rms of `y`
/// in the band of the pair `at` (its frequency at this level); for a friction-damped rigid
/// body's corner, the rms *velocity* of `y` from its lowest line up to three times the linear
/// corner (at most half the lowest pair's frequency), over the square root of the share of
/// the velocity's power the band holds at the corner `at`: Coulomb friction `F·sign(v)` acts
/// on a Gaussian velocity as the viscous damping `√(2/π)·F/σ_v` (Bussgang), and the velocity
/// of a damped rigid body is flat to its corner and falls as `1/f` above (`1/(1 + (f/f_c)²)`
/// in power, whose share below `B` is `(2/π)·atan(B/f_c)`).
pub(super) fn mode_amplitude(basis: &ModalBasis, pm: usize, at: C, y: &Spectrum) -> f64 {
    if !basis.is_rigid_damping(pm) {
        return y.band_rms(band_of(at), false);
    }
    let top = corner_top(basis, pm);
    y.band_rms((0.0, top), true) / corner_share(top, at).sqrt()
}

/// The top of a friction corner's velocity band: three times the linear corner, at most half
/// the lowest pair's frequency (Hz).
pub(super) fn corner_top(basis: &ModalBasis, pm: usize) -> f64 {
    let poles = basis.poles();
    let corner = natural(poles[pm], [[0.0; 2]; 2]).0;
    let lowest_pair = (0..poles.len())
        .filter(|&j| !basis.is_real(j))
        .map(|j| natural(poles[j], [[0.0; 2]; 2]).0)
        .fold(f64::INFINITY, f64::min);
    (3.0 * corner).min(0.5 * lowest_pair)
}

/// The share `(2/π)·atan(top/f_c)` of a first-order velocity spectrum `1/(1 + (f/f_c)²)`
/// below `top` at the corner `at` of a level: the band's power over it is the whole
/// velocity's.
pub(super) fn corner_share(top: f64, at: C) -> f64 {
    let fc = natural(at, [[0.0; 2]; 2]).0.max(f64::MIN_POSITIVE);
    (std::f64::consts::FRAC_2_PI * (top / fc).atan()).max(1e-3)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn band_rms_of_a_sine() {
        let fs = 1000.0;
        let x: Vec<f64> = (0..1000)
            .map(|k| {
                2.0 * (TAU * 50.0 * k as f64 / fs).sin() + 0.5 * (TAU * 200.0 * k as f64 / fs).sin()
            })
            .collect();
        // whole periods: exact but for the removed trend's share of the sines (≤ 1e-3)
        assert!((band_rms(&x, fs, 45.0, 55.0) / (2.0 / 2f64.sqrt()) - 1.0).abs() < 1e-3);
        assert!((band_rms(&x, fs, 190.0, 210.0) / (0.5 / 2f64.sqrt()) - 1.0).abs() < 1e-3);
        // the derivative's rms: 2πf times the amplitude over √2, both sines together
        let v = ((TAU * 50.0 * 2.0).powi(2) + (TAU * 200.0 * 0.5).powi(2)).sqrt() / 2f64.sqrt();
        let got = Spectrum::of(&x, fs).band_rms((0.0, 300.0), true);
        assert!((got / v - 1.0).abs() < 1e-3, "{got} {v}");
    }

    #[test]
    fn band_rms_ignores_the_leakage_of_slow_motion() {
        let fs = 1000.0;
        let x: Vec<f64> = (0..3000)
            .map(|k| {
                let t = k as f64 / fs;
                1e-3 * (TAU * 150.0 * t).sin() + (TAU * 0.13 * t).sin() + 0.3 * t * t
            })
            .collect();
        let b = band_rms(&x, fs, 140.0, 160.0);
        assert!((b / (1e-3 / 2f64.sqrt()) - 1.0).abs() < 0.01, "{b}");
    }
}
