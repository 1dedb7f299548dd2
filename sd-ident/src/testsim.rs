//! Test records shared by the unit tests of the local modal fits.

use num_complex::Complex64 as C;
use std::f64::consts::TAU;

/// The mode `fm` Hz, damping `zeta`, ZOH-sampled at 1 kHz: its pole `λ = e^{pT}` and the
/// output weight `c` of `y = 2 Re(c x)`, `x⁺ = λx + u` (residue `−jω_n/2`).
fn sampled_mode(fm: f64, zeta: f64) -> (C, C) {
    let wn = TAU * fm;
    let p = C::new(-zeta * wn, wn * (1.0 - zeta * zeta).sqrt());
    let lam = (p / 1000.0).exp();
    (lam, C::new(0.0, -wn / 2.0) * (lam - 1.0) / p)
}

/// `n` samples at 1 kHz of one ZOH-sampled mode (`fm` Hz, damping `zeta`, residue giving unit
/// static gain scale `ω_n/2`) simulated in the time domain from rest under white noise `u`,
/// with white output noise of rms 0.05: `(u, y)`, seeded.
pub(crate) fn mode_record(seed: u64, fm: f64, zeta: f64, n: usize) -> (Vec<f64>, Vec<f64>) {
    let (lam, c) = sampled_mode(fm, zeta);
    let mut rng = crate::rng::SplitMix::new(seed);
    let mut x = C::new(0.0, 0.0);
    let (mut u, mut y) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        let uk = rng.normal();
        y.push(2.0 * (c * x).re + 0.05 * rng.normal());
        u.push(uk);
        x = lam * x + uk;
    }
    (u, y)
}

/// [`mode_record`] in a loop: input injection `u = r − k·y`, force noise of rms `w` at the
/// mode's input and output noise of rms 0.05: `(r, u, y)`, seeded.
pub(crate) fn closed_mode_record(
    seed: u64,
    fm: f64,
    zeta: f64,
    n: usize,
    k: f64,
    w: f64,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (lam, c) = sampled_mode(fm, zeta);
    let mut rng = crate::rng::SplitMix::new(seed);
    let mut x = C::new(0.0, 0.0);
    let (mut r, mut u, mut y) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..n {
        let rk = rng.normal();
        let yk = 2.0 * (c * x).re + 0.05 * rng.normal();
        let uk = rk - k * yk;
        r.push(rk);
        u.push(uk);
        y.push(yk);
        x = lam * x + uk + w * rng.normal();
    }
    (r, u, y)
}
