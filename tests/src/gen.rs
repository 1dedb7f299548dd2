//! Random model generators for property tests (deterministic from a seed).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use nalgebra::DMatrix;
use sd_model::{SampleTime, StateSpace};

/// A small deterministic RNG (xorshift64*), enough for test matrices: the tests' own, kept
/// apart from the library's [`sd_ident::rng::SplitMix`] because every seeded test case and
/// reported seed range of the suite is defined by this stream (changing it would redraw them
/// all). Stable across versions for the same reason.
pub struct Rng(u64);

impl Rng {
    /// Seeded generator.
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
    /// A matrix of standard normals.
    pub fn matrix(&mut self, r: usize, c: usize) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |_, _| self.normal())
    }
}

/// A real block-diagonal A with the given real poles and complex pairs, hidden by a random
/// well-conditioned similarity.
pub fn with_poles(rng: &mut Rng, real: &[f64], pairs: &[(f64, f64)]) -> DMatrix<f64> {
    with_blocks(rng, 0, real, pairs)
}

/// Like [`with_poles`], with `rigid` double-integrator Jordan blocks `[0 1; 0 0]` first.
pub fn with_blocks(
    rng: &mut Rng,
    rigid: usize,
    real: &[f64],
    pairs: &[(f64, f64)],
) -> DMatrix<f64> {
    let n = 2 * rigid + real.len() + 2 * pairs.len();
    let mut a = DMatrix::zeros(n, n);
    let mut k = 0;
    for _ in 0..rigid {
        a[(k, k + 1)] = 1.0;
        k += 2;
    }
    for &(s, w) in pairs {
        a[(k, k)] = s;
        a[(k, k + 1)] = w;
        a[(k + 1, k)] = -w;
        a[(k + 1, k + 1)] = s;
        k += 2;
    }
    for &r in real {
        a[(k, k)] = r;
        k += 1;
    }
    let t = DMatrix::<f64>::identity(n, n) + rng.matrix(n, n) * (0.3 / (n as f64).sqrt());
    match t.clone().try_inverse() {
        Some(ti) => &t * a * ti,
        None => a,
    }
}

/// A random continuous model with A given.
pub fn model(
    rng: &mut Rng,
    a: DMatrix<f64>,
    nu: usize,
    ny: usize,
    feedthrough: bool,
) -> StateSpace {
    let n = a.nrows();
    let d = if feedthrough {
        rng.matrix(ny, nu)
    } else {
        DMatrix::zeros(ny, nu)
    };
    StateSpace::new(
        a,
        rng.matrix(n, nu),
        rng.matrix(ny, n),
        d,
        SampleTime::Continuous,
    )
    .expect("finite random model")
}
