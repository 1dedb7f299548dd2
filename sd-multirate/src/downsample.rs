//! Lemma 6 of Oomen, van de Wal & Bosgra (ACC 2007): a fast discrete model seen through a slow
//! zero-order hold and a slow ideal sampler.
//!
//! With `P_h = (A, B, C, D)` at period `h` and the input held for `F` fast samples, the model at
//! `T = F·h` is
//!
//! ```text
//! [A B; 0 I]^F = [A^F  Σ_{i<F} A^i B; 0  I],   P_d = (A^F, Σ_{i<F} A^i B, C, D)
//! ```
//!
//! in the **same state coordinates**, so `downsample(c2d(P_c, h), F)` equals `c2d(P_c, F·h)`
//! matrix by matrix (Lemma 5 then Lemma 6 is Lemma 5 at the slow rate).
//!
//! **Method.** The block matrix is powered by binary exponentiation on the pair `(X, Y)` with
//! `[X Y; 0 I]·[X' Y'; 0 I] = [XX'  XY' + Y; 0 I]` (the identity block is never formed, so it
//! stays exact), at most `2⌊log₂F⌋` products, in the model's own coordinates. The products are
//! componentwise stable, `|fl(X^F) − X^F| ≲ (F−1)·γ_n·|X|^F` (Higham, *Accuracy and Stability
//! of Numerical Algorithms*, §3.5), a bound invariant under diagonal scaling — so balancing
//! would not help, and physical (position/velocity) coordinates are as good as any. What must
//! be avoided is a badly conditioned *realization*: the powers of a companion form lose all
//! accuracy for lightly damped order-60 models, so none is ever formed. Measured on the tests
//! (`tests/tests/properties_multirate.rs`, `tests/tests/multirate_stage.rs`): matrices within
//! 1e-10 relative of `c2d(P_c, F·h)` for random models with n ≤ 20, the 60-state stage's
//! frequency response within 1e-8 over 0–500 Hz.
//!
//! The non-ideal variants (a delayed slow hold, an averaging slow sampler) from a fast model are
//! in [`crate::nonideal::downsample_nonideal`].

use crate::error::{check_factor, require_discrete, MultirateError, Result};
use faer::Mat;
use nalgebra::DMatrix;
use sd_model::linalg::convert::{from_faer, to_faer};
use sd_model::{SampleTime, StateSpace};

/// Lemma 6: the model at `T = F·h` of a fast discrete model `p_h` whose input is held for
/// `factor` fast samples and whose output is sampled every `factor` fast samples.
///
/// Names and signal names are kept. `factor = 1` returns the model unchanged.
///
/// # Errors
/// A continuous-time model, `factor = 0` or above [`crate::tol::MAX_FACTOR`].
pub fn downsample(p_h: &StateSpace, factor: usize) -> Result<StateSpace> {
    let h = require_discrete(p_h, "downsample (Lemma 6)")?;
    check_factor(factor)?;
    let (x, y) = power_held_blocks(p_h.a(), p_h.b(), factor);
    let sys = StateSpace::new(
        x,
        y,
        p_h.c().clone(),
        p_h.d().clone(),
        SampleTime::discrete(h * factor as f64)?,
    )?;
    Ok(sys.with_labels_of(p_h))
}

/// [`power_held`] block by block when `A` is block diagonal (a modal form,
/// [`sd_model::linalg::blocks`]): each `[Aᵢ Bᵢ; 0 I]^F` alone, by the same binary powering
/// (O(Σ nᵢ³ log F) instead of O(n³ log F)).
pub(crate) fn power_held_blocks(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    factor: usize,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, nu) = (a.nrows(), b.ncols());
    let groups = sd_model::linalg::blocks::components(a);
    if !sd_model::linalg::blocks::worth_splitting(&groups, n) {
        return power_held(a, b, factor);
    }
    let mut x = DMatrix::zeros(n, n);
    let mut y = DMatrix::zeros(n, nu);
    // factor ≤ MAX_FACTOR (checked by the callers) fits a u32
    let f = u32::try_from(factor).unwrap_or(u32::MAX);
    for g in &groups {
        // one input and a 1×1 or 2×2 block (a modal form's real pole or mode): the augmented
        // [Aᵢ Bᵢ; 0 1] on the stack, powered by nalgebra's binary powering (its zero and one
        // rows stay exact, so the blocks are the pair powering's to the last bit)
        if nu == 1 && g.len() == 1 {
            let i = g[0];
            let m = nalgebra::Matrix2::new(a[(i, i)], b[(i, 0)], 0.0, 1.0).pow(f);
            x[(i, i)] = m[(0, 0)];
            y[(i, 0)] = m[(0, 1)];
            continue;
        }
        if nu == 1 && g.len() == 2 {
            let (i, j) = (g[0], g[1]);
            #[rustfmt::skip]
            let m = nalgebra::Matrix3::new(
                a[(i, i)], a[(i, j)], b[(i, 0)],
                a[(j, i)], a[(j, j)], b[(j, 0)],
                0.0, 0.0, 1.0,
            )
            .pow(f);
            x[(i, i)] = m[(0, 0)];
            x[(i, j)] = m[(0, 1)];
            x[(j, i)] = m[(1, 0)];
            x[(j, j)] = m[(1, 1)];
            y[(i, 0)] = m[(0, 2)];
            y[(j, 0)] = m[(1, 2)];
            continue;
        }
        let (xg, yg) = power_small(
            &a.select_rows(g).select_columns(g),
            &b.select_rows(g),
            factor,
        );
        sd_model::linalg::blocks::scatter((&mut x, &mut y), g, (&xg, &yg));
    }
    (x, y)
}

/// `(X, Y)` of `[A B; 0 I]^F` by binary powering on the pair, for any matrix type with
/// products and sums (nalgebra for small blocks, faer for large ones): `[X Y; 0 I]·[X' Y'; 0 I]
/// = [XX'  XY' + Y; 0 I]`, the identity block never formed; `None` for `F = 0`.
fn binary_power<M: Clone>(a: M, b: M, factor: usize) -> Option<(M, M)>
where
    for<'a> &'a M: std::ops::Mul<&'a M, Output = M> + std::ops::Add<&'a M, Output = M>,
{
    // result R = (Xr, Yr), starts as the identity; base = (Xb, Yb) = (A, B)
    let (mut xb, mut yb) = (a, b);
    let mut acc: Option<(M, M)> = None;
    let mut f = factor;
    loop {
        if f & 1 == 1 {
            acc = Some(match acc {
                None => (xb.clone(), yb.clone()),
                // R ← R·base = [Xr Xb, Xr Yb + Yr]
                Some((xr, yr)) => (&xr * &xb, &(&xr * &yb) + &yr),
            });
        }
        f >>= 1;
        if f == 0 {
            break;
        }
        // base ← base² = [Xb², Xb Yb + Yb]
        let ny = &(&xb * &yb) + &yb;
        xb = &xb * &xb;
        yb = ny;
    }
    acc
}

/// [`power_held`] with nalgebra products (small blocks: no conversion to faer).
fn power_small(a: &DMatrix<f64>, b: &DMatrix<f64>, factor: usize) -> (DMatrix<f64>, DMatrix<f64>) {
    binary_power(a.clone(), b.clone(), factor).unwrap_or_else(|| {
        (
            DMatrix::identity(a.nrows(), a.nrows()),
            DMatrix::zeros(b.nrows(), b.ncols()),
        )
    })
}

/// `(A^F, Σ_{i<F} A^i B)` by binary powering of `[A B; 0 I]` (faer products).
pub(crate) fn power_held(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    factor: usize,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, nu) = (a.nrows(), b.ncols());
    match binary_power::<Mat<f64>>(to_faer(a), to_faer(b), factor) {
        Some((x, y)) => (from_faer(x.as_ref()), from_faer(y.as_ref())),
        None => (DMatrix::identity(n, n), DMatrix::zeros(n, nu)),
    }
}

/// Checks `T = F·h` between a slow and a fast discrete model and returns `(h, T)`.
pub(crate) fn check_rates(
    fast: &StateSpace,
    slow: &StateSpace,
    factor: usize,
) -> Result<(f64, f64)> {
    let h = require_discrete(fast, "multirate analysis (fast plant)")?;
    let t = require_discrete(slow, "multirate analysis (slow controller)")?;
    check_factor(factor)?;
    let want = h * factor as f64;
    if ((t - want) / want).abs() > crate::tol::RATE_MATCH_TOL {
        return Err(MultirateError::RateMismatch {
            detail: format!(
                "the slow model has ts = {t} s but F·h = {factor}·{h} = {want} s; \
                 resample one of them or change F"
            ),
        });
    }
    Ok((h, t))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use sd_model::{c2d, Discretization};

    fn rel(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
        (a - b).norm() / b.norm().max(1e-300)
    }

    /// The 60-state stage's ZOH is block diagonal: Lemma 6 block by block equals the dense
    /// powering (and the ZOH at the slow rate) to rounding.
    #[test]
    fn blockwise_powering_equals_dense() {
        let pc = sd_model::stage::stage60().unwrap();
        let pd = c2d(&pc, 2e-4, Discretization::Zoh).unwrap();
        for f in [2usize, 5, 17] {
            let (xb, yb) = power_held_blocks(pd.a(), pd.b(), f);
            let (xd, yd) = power_held(pd.a(), pd.b(), f);
            assert!(rel(&xb, &xd) < 1e-13 && rel(&yb, &yd) < 1e-12, "F = {f}");
            let slow = c2d(&pc, 2e-4 * f as f64, Discretization::Zoh).unwrap();
            assert!(
                rel(&xb, slow.a()) < 1e-10 && rel(&yb, slow.b()) < 1e-10,
                "F = {f}"
            );
        }
    }

    #[test]
    fn matches_naive_powers_on_a_small_model() {
        let a = DMatrix::from_row_slice(2, 2, &[0.9, 0.2, -0.1, 0.7]);
        let b = DMatrix::from_row_slice(2, 1, &[1.0, 0.5]);
        for f in 1..=13 {
            let (x, y) = power_held(&a, &b, f);
            let mut xn = DMatrix::identity(2, 2);
            let mut yn = DMatrix::zeros(2, 1);
            for _ in 0..f {
                yn = &xn * &b + yn;
                xn = &xn * &a;
            }
            assert!(rel(&x, &xn) < 1e-14 && rel(&y, &yn) < 1e-14, "F = {f}");
        }
    }

    #[test]
    fn paper_mode_appears_at_347_hz_with_damping_scaled() {
        // 653 Hz, ζ = 0.01 mode (with the rigid body) at 5 kHz, F = 5 → 1 kHz
        let p = sd_model::stage::paper_stage(0.01).unwrap();
        let ph = c2d(&p, 2e-4, Discretization::Zoh).unwrap();
        let pd = downsample(&ph, 5).unwrap();
        assert!((pd.ts().unwrap() - 1e-3).abs() < 1e-18);
        let (_, modes) = sd_model::d2c_with_aliases(&pd, 3000.0).unwrap();
        let m = modes
            .iter()
            .find(|m| m.freq_hz > 1.0)
            .expect("the resonance survives downsampling");
        // exact: the real part σ = ζω₁ is kept, the damped frequency folds to 1000 − f_d
        let w1 = 2.0 * std::f64::consts::PI * 653.0;
        let sigma = 0.01 * w1;
        let fd = 653.0 * (1.0f64 - 1e-4).sqrt();
        let wa = 2.0 * std::f64::consts::PI * (1000.0 - fd);
        let zeta_exact = sigma / (sigma * sigma + wa * wa).sqrt();
        assert!((m.freq_hz - 347.0).abs() < 0.1, "{}", m.freq_hz);
        assert!(
            (m.damping - zeta_exact).abs() < 1e-9 * zeta_exact,
            "{} vs {zeta_exact}",
            m.damping
        );
        let ratio = m.damping / 0.01;
        assert!(
            (ratio / (653.0 / 347.0) - 1.0).abs() < 1e-3,
            "ratio {ratio}"
        );
        // 653 Hz is among the alias candidates of the 347 Hz mode
        assert!(m.candidates.iter().any(|&(f, _)| (f - 653.0).abs() < 0.1));
    }

    #[test]
    fn refuses_bad_input() {
        let p = sd_model::stage::paper_stage(0.01).unwrap();
        assert!(downsample(&p, 2).is_err());
        let ph = c2d(&p, 2e-4, Discretization::Zoh).unwrap();
        assert!(downsample(&ph, 0).is_err());
        assert!(downsample(&ph, 1_000_000).is_err());
        let same = downsample(&ph, 1).unwrap();
        assert_eq!(same.a(), ph.a());
    }
}
