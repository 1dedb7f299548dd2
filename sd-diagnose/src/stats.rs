//! The calibrated line-by-line statistic.
//!
//! **One line.** A prediction `P̂` of a measured FRF value `P` is judged by
//! `x = |P − P̂|²/(σ̂²_meas + σ̂²_pred)`. With Gaussian errors and *known* variances `x` is
//! exponential (mean 1). The variances are estimated, though: a periodic FRF's from the
//! `2(M − 1)` noise bins between two harmonics of the whole-record DFT (M steady periods, so
//! `ν = 4(M − 1)` real degrees of freedom), an LPM estimate's from the local residual
//! (`ν = 2(2n + 1 − q)` for a window of `2n + 1` lines and `q` local parameters). A sum of
//! variance estimates with their own degrees of freedom gets Satterthwaite's effective
//! `ν = (Σ vᵢ)²/Σ(vᵢ²/νᵢ)` (Satterthwaite, Biometrics Bulletin 2, 1946). Then `x ~ F(2, ν)`,
//! whose survival function is `(1 + 2x/ν)^(−ν/2)`: mean `ν/(ν − 2)` (1.33 for three periods),
//! infinite variance below ν = 4 — an average of raw `x` is not calibrated.
//!
//! **The score** `s = (ν/2) ln(1 + 2x/ν) = −ln P(X > x)` is, under "the prediction is right",
//! exactly exponential with mean 1 for every ν (→ `x` as ν → ∞). The statistic is the mean score
//! over the K lines; for independent lines `K·s̄ ~ Gamma(K, 1)`.
//!
//! **Correlated lines.** LPM estimates at neighbouring lines share their window: the error at
//! line k is approximately `Σ_r w(r) V(k+r)/X(k+r)` with `w` the centre row of the local
//! polynomial's hat matrix, so neighbouring errors correlate with `ρ(d) = Σ_r w(r)w(r+d)/Σ w²`
//! and scores (squared magnitudes) with `ρ(d)²`. The statistic's variance is inflated by
//! `c = Σ_d ρ(d)²` and it is judged as `c·Gamma(K/c, 1)/K` (K/c effective lines). Periodic
//! estimates at different harmonics are independent (`c = 1`). A fitted model's prediction
//! errors are shared by all lines through its p parameters: the part `M = Σ σ²_pred/σ²` of the
//! score sum fluctuates like `M·χ²_p/p`, so the sum's variance is `c(K − M) + 2M²/p` and the
//! effective number of lines `K' = K²/(c(K − M) + 2M²/p)`.
//!
//! **Threshold** at false-alarm probability α: the `1 − α` quantile of `Gamma(K', 1)/K'`,
//! `K' = K/c`, by the Wilson–Hilferty cube-root approximation of the χ² quantile
//! (`χ²_ν(p) ≈ ν(1 − 2/(9ν) + z_p √(2/(9ν)))³`; within 0.5 % of scipy's Gamma quantiles for
//! K ≥ 10 at p = 0.99, unit test `gamma_thresholds`).
//! Several tests in one verdict share α (Bonferroni).

use num_complex::Complex64 as C;
use serde::Serialize;

/// One line of a comparison.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Line {
    pub(crate) f: f64,
    pub(crate) meas: C,
    pub(crate) pred: C,
    /// Measured variance plus the prediction's.
    pub(crate) var: f64,
    /// Effective real degrees of freedom of `var` (infinite: known).
    pub(crate) dof: f64,
    /// Share of `var` that comes from a fitted parametric prediction (its errors are shared by
    /// all lines through its parameters).
    pub(crate) shared: f64,
    /// Parameters of that prediction (0: none).
    pub(crate) params: usize,
}

impl Line {
    /// `|P − P̂|²/var`.
    pub(crate) fn chi2(&self) -> f64 {
        (self.meas - self.pred).norm_sqr() / self.var
    }

    /// The exponential score `(ν/2) ln(1 + 2x/ν)` (module documentation).
    pub(crate) fn score(&self) -> f64 {
        score(self.chi2(), self.dof)
    }
}

/// Half-width (lines) of the moving mean that gives a variance estimate's expected size
/// (`lemma6::compare`, [`crate::data::Estimate::expected_var`]): sd-ident's, one for both.
pub(crate) const VAR_SMOOTHING: usize = sd_ident::EXPECTED_VAR_HALF_WIDTH;

/// `(ν/2) ln(1 + 2x/ν)`, `x` for infinite ν.
pub(crate) fn score(x: f64, dof: f64) -> f64 {
    if dof.is_finite() && dof > 0.0 {
        0.5 * dof * (2.0 * x / dof).ln_1p()
    } else {
        x
    }
}

/// Satterthwaite's effective degrees of freedom of a sum of variance estimates `(v, ν)`.
pub(crate) fn satterthwaite(parts: &[(f64, f64)]) -> f64 {
    let sum: f64 = parts.iter().map(|p| p.0).sum();
    let den: f64 = parts
        .iter()
        .filter(|p| p.0 > 0.0 && p.1.is_finite())
        .map(|p| p.0 * p.0 / p.1)
        .sum();
    if den > 0.0 {
        sum * sum / den
    } else {
        f64::INFINITY
    }
}

/// A statistic with its calibration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Statistic {
    /// Mean score over the lines (1 at the noise level).
    pub value: f64,
    /// Lines.
    pub lines: usize,
    /// Effective independent lines `K/c`.
    pub effective_lines: f64,
    /// The threshold at the false-alarm probability used.
    pub threshold: f64,
}

impl Statistic {
    /// `value ≤ threshold`.
    pub fn passes(&self) -> bool {
        self.value <= self.threshold
    }

    /// Two statistics on disjoint lines taken together.
    pub(crate) fn pool(&self, other: &Statistic, alpha: f64) -> Statistic {
        let k = self.lines + other.lines;
        if k == 0 {
            return *self;
        }
        let keff = self.effective_lines + other.effective_lines;
        Statistic {
            value: (self.value * self.lines as f64 + other.value * other.lines as f64) / k as f64,
            lines: k,
            effective_lines: keff,
            threshold: threshold(keff, alpha),
        }
    }
}

/// A set of lines and its correlation inflation `c` (1 for independent lines).
pub(crate) type LineSet<'a> = (&'a [Line], f64);

/// The pooled statistic of several sets at false-alarm probability `alpha`. No lines: an
/// infinite value.
pub(crate) fn statistic<'a>(sets: impl IntoIterator<Item = LineSet<'a>>, alpha: f64) -> Statistic {
    let (mut s, mut k) = (0.0, 0usize);
    let (mut noise_var, mut shared, mut params) = (0.0, 0.0, 0usize);
    for (lines, c) in sets {
        s += lines.iter().map(Line::score).sum::<f64>();
        k += lines.len();
        for l in lines {
            noise_var += c.max(1.0) * (1.0 - l.shared);
            shared += l.shared;
            params = params.max(l.params);
        }
    }
    if k == 0 {
        return Statistic {
            value: f64::INFINITY,
            lines: 0,
            effective_lines: 0.0,
            threshold: f64::INFINITY,
        };
    }
    // a fitted prediction's errors are p-dimensional: their part of the sum fluctuates like
    // M·χ²_p/p (variance 2M²/p), not like M independent lines
    let var = noise_var
        + if params > 0 {
            2.0 * shared * shared / params as f64
        } else {
            0.0
        };
    let keff = (k as f64 * k as f64 / var.max(f64::MIN_POSITIVE)).min(k as f64);
    Statistic {
        value: s / k as f64,
        lines: k,
        effective_lines: keff,
        threshold: threshold(keff, alpha),
    }
}

/// The `1 − alpha` quantile of `Gamma(k, 1)/k` (module documentation).
pub(crate) fn threshold(k: f64, alpha: f64) -> f64 {
    let nu = 2.0 * k.max(0.5);
    sd_model::chi2_quantile(1.0 - alpha.clamp(1e-12, 0.5), nu) / nu
}

/// Correlation inflation `c = Σ_d ρ(d)²` of estimates from a local polynomial of degree `r`
/// over `2n + 1` lines (module documentation).
pub(crate) fn lpm_inflation(n: usize, degree: usize) -> f64 {
    let rho = sd_ident::lpm_polynomial_correlation(n, degree);
    // Σ over d = −2n … 2n: ρ(0)² once, every other lag twice
    rho.iter()
        .enumerate()
        .map(|(d, r)| if d == 0 { r * r } else { 2.0 * r * r })
        .sum()
}

/// `Err` unless `alpha` is a false-alarm probability in (0, 0.5].
pub(crate) fn check_alpha(alpha: f64) -> crate::Result<()> {
    if alpha > 0.0 && alpha <= 0.5 {
        Ok(())
    } else {
        Err(crate::DiagnoseError::Setup(format!(
            "alpha {alpha} is a false-alarm probability: give one in (0, 0.5], e.g. 0.01"
        )))
    }
}

/// The lines inside any of `bands` (all of them when there are no bands).
pub(crate) fn in_bands(lines: Vec<Line>, bands: &[(f64, f64)]) -> Vec<Line> {
    if bands.is_empty() {
        return lines;
    }
    lines
        .into_iter()
        .filter(|l| bands.iter().any(|(lo, hi)| l.f >= *lo && l.f <= *hi))
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn gamma_thresholds() {
        // scipy.stats.gamma.ppf(0.99, k)/k
        for (k, q) in [
            (10.0, 1.878_311_7),
            (100.0, 1.247_225_6),
            (2000.0, 1.052_752_9),
        ] {
            let t = threshold(k, 0.01);
            assert!((t - q).abs() / q < 5e-3, "k {k}: {t} vs {q}");
        }
    }

    /// The score of an F(2, ν) variable is exponential: Monte Carlo mean 1 and P(s > 4.605) =
    /// 1 % at ν = 4 (three-sigma bounds for 200 000 draws).
    #[test]
    fn scores_are_exponential() {
        let mut state = 7u64;
        let mut unif = || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        let nu = 4.0;
        let n = 200_000;
        let (mut mean, mut tail) = (0.0, 0usize);
        for _ in 0..n {
            // F(2, 4) = (χ²₂/2)/(χ²₄/4): χ²₂/2 = −ln U, χ²₄/4 = (−ln U₁ − ln U₂)/2
            let num = -(1.0 - unif()).ln();
            let den = (-(1.0 - unif()).ln() - (1.0 - unif()).ln()) / 2.0;
            let s = score(num / den, nu);
            mean += s / n as f64;
            tail += usize::from(s > (100.0f64).ln());
        }
        assert!((mean - 1.0).abs() < 3.0 / (n as f64).sqrt(), "{mean}");
        let rate = tail as f64 / n as f64;
        assert!(
            (rate - 0.01).abs() < 3.0 * (0.01 * 0.99 / n as f64).sqrt(),
            "{rate}"
        );
    }

    #[test]
    fn lpm_inflation_of_the_default_window() {
        let c = lpm_inflation(4, 2);
        assert!(c > 1.5 && c < 9.0, "{c}");
        assert!((lpm_inflation(0, 0) - 1.0).abs() < 1e-12);
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod lpm_mc {
    use super::*;

    fn gauss(state: &mut u64) -> f64 {
        let mut u = || {
            *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = *state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            (((z ^ (z >> 31)) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (-2.0 * u().ln()).sqrt() * (std::f64::consts::TAU * u()).cos()
    }

    /// On pure noise the LPM's scores average 1, and their correlation between neighbouring
    /// lines (which also share the variance estimate, not only the error) inflates the
    /// variance of their mean by no more than the error-based `c` of [`lpm_inflation`]: the
    /// threshold is not too tight (Monte Carlo on 50 000 lines: 2.8 against 3.1).
    #[test]
    fn lpm_score_autocorrelation() {
        let n = 100_000;
        let mut st = 11u64;
        let x = nalgebra::DMatrix::from_fn(n, 1, |_, _| gauss(&mut st));
        let z = nalgebra::DMatrix::from_fn(n, 1, |_, _| gauss(&mut st));
        let est = sd_ident::lpm(1.0, &x, &z, &sd_ident::LpmOptions::default()).unwrap();
        let var = est.frd.variance().unwrap();
        let s: Vec<f64> = est
            .frd
            .response()
            .iter()
            .zip(var)
            .map(|(g, v)| score(g[(0, 0)].norm_sqr() / v[(0, 0)], 6.0))
            .collect();
        let k = s.len();
        let m = s.iter().sum::<f64>() / k as f64;
        let v = s.iter().map(|x| (x - m).powi(2)).sum::<f64>() / k as f64;
        let mut c = 1.0;
        for d in 1..20 {
            let r: f64 =
                (0..k - d).map(|i| (s[i] - m) * (s[i + d] - m)).sum::<f64>() / (k - d) as f64 / v;
            c += 2.0 * r;
        }
        let c_err = lpm_inflation(4, 2);
        // the mean of k scores with inflation c has standard error √(c/k)
        assert!(
            (m - 1.0).abs() < 4.0 * (c_err / k as f64).sqrt(),
            "mean {m}"
        );
        assert!(
            c > 1.5 && c <= 1.05 * c_err,
            "score inflation {c} vs {c_err}"
        );
    }
}
