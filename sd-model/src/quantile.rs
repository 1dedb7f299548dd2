//! Quantiles of the normal, χ² and F laws, for the toolkit's statistical tests.

/// The `p` quantile of χ² with `nu` degrees of freedom by Wilson–Hilferty's cube-root normal
/// approximation, `ν(1 − a + z√a)³`, `a = 2/(9ν)`, `z` the normal quantile (relative error
/// below 0.5 % for ν ≥ 20 at p = 0.99; a few per cent at ν = 1–2).
pub fn chi2_quantile(p: f64, nu: f64) -> f64 {
    let z = normal_quantile(p);
    let a = 2.0 / (9.0 * nu);
    nu * (1.0 - a + z * a.sqrt()).max(0.0).powi(3)
}

/// The `p` quantile of Fisher's F law with `(d1, d2)` degrees of freedom by Paulson's
/// cube-root normal approximation (Paulson, "An approximate normalization of the analysis of
/// variance distribution", *Ann. Math. Statist.* 13, 1942; Wilson–Hilferty applied to both χ²
/// terms): with `a = 2/(9d₁)`, `b = 2/(9d₂)`, `y = F^{1/3}` solves
/// `(1 − b)y − (1 − a) = z√(a + by²)`, `z` the normal quantile — the larger root of
/// `[(1 − b)² − z²b]y² − 2(1 − a)(1 − b)y + (1 − a)² − z²a = 0`. Relative error against scipy
/// below 1 % for `d₂ ≥ 18` at p = 0.95 and 0.99 (the unit test's table; `d₂ → ∞` gives
/// [`chi2_quantile`]`/d₁`). `NaN` where the approximation has no root (`d₂` of a few).
pub fn f_quantile(p: f64, d1: f64, d2: f64) -> f64 {
    let z = normal_quantile(p);
    let (a, b) = (2.0 / (9.0 * d1), 2.0 / (9.0 * d2));
    let qa = (1.0 - b).powi(2) - z * z * b;
    let qb = (1.0 - a) * (1.0 - b);
    let qc = (1.0 - a).powi(2) - z * z * a;
    let disc = qb * qb - qa * qc;
    if qa <= 0.0 || disc < 0.0 {
        return f64::NAN;
    }
    let y = if z >= 0.0 {
        (qb + disc.sqrt()) / qa
    } else {
        (qb - disc.sqrt()) / qa
    };
    y.max(0.0).powi(3)
}

/// Standard normal distribution function `Φ(x) = ½ erfc(−x/√2)`, with `erfc` by the Chebyshev
/// fit `erfc(z) ≈ t·exp(−z² + P(t))`, `t = 1/(1 + z/2)`, of Press et al. (*Numerical Recipes*,
/// §6.2: fractional error below 1.2e-7 everywhere); `erfc(−z) = 2 − erfc(z)`.
pub fn normal_cdf(x: f64) -> f64 {
    const P: [f64; 10] = [
        -1.265_512_23,
        1.000_023_68,
        0.374_091_96,
        0.096_784_18,
        -0.186_288_06,
        0.278_868_07,
        -1.135_203_98,
        1.488_515_87,
        -0.822_152_23,
        0.170_872_77,
    ];
    if x.is_nan() {
        return f64::NAN;
    }
    let z = x.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = P.iter().rev().fold(0.0, |acc, c| acc * t + c);
    let erfc = t * (-z * z + poly).exp();
    if x >= 0.0 {
        1.0 - 0.5 * erfc
    } else {
        0.5 * erfc
    }
}

/// Standard normal quantile (Acklam's rational approximation, relative error below 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const CC: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let p = p.clamp(1e-300, 1.0 - 1e-16);
    let tail = |q: f64| {
        (((((CC[0] * q + CC[1]) * q + CC[2]) * q + CC[3]) * q + CC[4]) * q + CC[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_quantiles() {
        // reference values (scipy.stats.norm.ppf)
        for (p, z) in [
            (0.5, 0.0),
            (0.99, 2.326_347_874_040_841),
            (0.999, 3.090_232_306_167_813),
            (0.01, -2.326_347_874_040_841),
            (0.975, 1.959_963_984_540_054),
        ] {
            assert!((normal_quantile(p) - z).abs() < 1e-8, "{p}");
        }
    }

    #[test]
    fn chi2_quantiles() {
        // scipy.stats.chi2.ppf(0.99, ν)
        for (nu, q) in [(2.0, 9.210_340_4), (8.0, 20.090_235), (60.0, 88.379_419)] {
            let c = chi2_quantile(0.99, nu);
            assert!((c - q).abs() / q < 0.03, "ν {nu}: {c} vs {q}");
        }
    }

    #[test]
    fn f_quantiles() {
        // (p, d1, d2, scipy.stats.f.ppf): `python3 tools/f_quantile_reference.py`
        for (p, d1, d2, q) in [
            (0.99, 12.0, 18.0, 3.3706078722906936),
            (0.99, 12.0, 36.0, 2.7231545539664856),
            (0.99, 12.0, 72.0, 2.4418872922670385),
            (0.99, 12.0, 144.0, 2.3104838646727712),
            (0.99, 12.0, 1000.0, 2.2025175498112253),
            (0.99, 2.0, 20.0, 5.848931924611135),
            (0.99, 20.0, 40.0, 2.3688761223373955),
            (0.95, 12.0, 18.0, 2.3420667980454337),
            (0.95, 12.0, 36.0, 2.032703132994987),
            (0.95, 12.0, 72.0, 1.8892420972854038),
            (0.95, 12.0, 144.0, 1.8199620490509407),
            (0.95, 12.0, 1000.0, 1.7618466053968536),
            (0.95, 2.0, 20.0, 3.4928284767356312),
            (0.95, 20.0, 40.0, 1.8388593490242169),
        ] {
            let c = f_quantile(p, d1, d2);
            assert!((c - q).abs() / q < 0.01, "F({d1}, {d2}) at {p}: {c} vs {q}");
        }
        // d2 → ∞: the χ² quantile over d1
        let c = f_quantile(0.99, 12.0, 1e12);
        assert!((c - chi2_quantile(0.99, 12.0) / 12.0).abs() < 1e-6, "{c}");
    }

    #[test]
    fn normal_distribution_function() {
        // reference values: ½·erfc(−x/√2) by Python's math.erfc
        for (x, p) in [
            (-4.0, 3.167_124_183_311_998e-5),
            (-2.326_347_874_040_841, 0.01),
            (-1.0, 0.158_655_253_931_457_05),
            (0.0, 0.5),
            (0.5, 0.691_462_461_274_013_1),
            (1.281_551_565_544_600_4, 0.9),
            (3.0, 0.998_650_101_968_369_9),
        ] {
            let c = normal_cdf(x);
            // the fit's fractional error in erfc (1.2e-7) bounds Φ's error on either side
            assert!(
                (c - p).abs() <= 1.2e-7 * p.min(1.0 - p) + 1e-15,
                "Φ({x}) = {c}, want {p}"
            );
        }
        assert!(normal_cdf(f64::NAN).is_nan());
    }
}
