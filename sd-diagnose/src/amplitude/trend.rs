//! Trends of a mode's frequency and damping in the relative amplitude, whether a mode moves,
//! and the kind the moving modes name (module documentation of [`super`]).

use super::*;

/// Weighted least squares of `p(ρ) = a + b·ρ^k` over points `(ρ, p, σ)`, written as the
/// trend `p_ref + c(ρ^k − 1)` (`p_ref = a + b`, `c = b`), and its weighted residual.
///
/// `nonneg` constrains `a, b ≥ 0` (non-negative least squares over the two columns: the
/// unconstrained solution when feasible, else the better feasible one-column fit). That is a
/// friction-damped corner's physics: `2πm·f = c_v + c_eq(ρ)`, a viscous part and an
/// amplitude-dependent part that are both non-negative (Coulomb friction under a
/// Gaussian-like velocity of rms σ has the equivalent damping `c_eq = √(2/π)·F_c/σ`, Bussgang;
/// k = −1), so a corner can neither cross zero nor fall under a law that rises.
pub(super) fn trend_fit(pts: &[(f64, f64, f64)], k: i32, nonneg: bool) -> Option<(Trend, f64)> {
    let n = pts.len();
    if n < 2 {
        return None;
    }
    let w = |i: usize| 1.0 / pts[i].2.max(f64::MIN_POSITIVE);
    let g = DVector::from_fn(n, |i, _| pts[i].1 * w(i));
    // columns: 0 the constant a, 1 the amplitude term b·ρ^k
    let solve = |cols: &[usize]| -> Option<([f64; 2], [[f64; 2]; 2], f64)> {
        let x = DMatrix::from_fn(n, cols.len(), |i, j| {
            w(i) * if cols[j] == 0 { 1.0 } else { pts[i].0.powi(k) }
        });
        let ls = lstsq(&x, &g).ok()?;
        let chi2 = (&g - &x * &ls.x).norm_squared();
        let (mut c, mut cov) = ([0.0; 2], [[0.0; 2]; 2]);
        for (j, &cj) in cols.iter().enumerate() {
            c[cj] = ls.x[j];
            for (l, &cl) in cols.iter().enumerate() {
                cov[cj][cl] = ls.cov[(j, l)];
            }
        }
        Some((c, cov, chi2))
    };
    let (c, cov, chi2) = match solve(&[0, 1])? {
        full if !nonneg || (full.0[0] >= 0.0 && full.0[1] >= 0.0) => full,
        _ => [solve(&[1]), solve(&[0])]
            .into_iter()
            .flatten()
            .filter(|(c, _, _)| c[0] >= 0.0 && c[1] >= 0.0)
            .min_by(|x, y| x.2.total_cmp(&y.2))?,
    };
    let free = if nonneg {
        c.iter().filter(|v| **v != 0.0).count().max(1)
    } else {
        2
    };
    // the points' scatter beyond their errors widens the trend's
    let scale = if n > free {
        (chi2 / (n - free) as f64).max(1.0)
    } else {
        1.0
    };
    Some((
        Trend {
            exponent: k,
            at_reference: c[0] + c[1],
            at_reference_std: ((cov[0][0] + 2.0 * cov[0][1] + cov[1][1]) * scale)
                .max(0.0)
                .sqrt(),
            slope: c[1],
            slope_std: (cov[1][1] * scale).sqrt(),
            covariance: (cov[0][1] + cov[1][1]) * scale,
        },
        chi2,
    ))
}

/// The trend: exponent `default` (2 for a mode, the cubic-stiffness backbone; −1 for a
/// friction-damped rigid body's corner, `c_eq ∝ 1/amplitude`) unless another exponent of
/// [`EXPONENTS`] lowers the weighted residual by more than the `1 − alpha` quantile of χ²₁
/// (the data must insist on a different law; with two points every exponent fits exactly and
/// the default stays). `nonneg`: the corner's constrained form ([`trend_fit`]).
pub(super) fn best_trend(
    pts: &[(f64, f64, f64)],
    alpha: f64,
    default: i32,
    nonneg: bool,
) -> Option<Trend> {
    let (first, c0) = trend_fit(pts, default, nonneg)?;
    let margin = normal_quantile(1.0 - alpha / 2.0).powi(2);
    let mut best = (first, c0);
    if pts.len() > 2 {
        for k in EXPONENTS.iter().filter(|k| **k != default) {
            if let Some((t, c)) = trend_fit(pts, *k, nonneg) {
                if c < best.1 && c0 - c > margin {
                    best = (t, c);
                }
            }
        }
    }
    Some(best.0)
}

/// Largest ratio between the highest and the lowest response per force of a moving pair over
/// the levels ([`proportional`]).
pub(super) const RESPONSE_SPREAD: f64 = 2.0;

/// Whether a pair's amplitude ratios follow its force ratios (`(force, amplitude)` per level,
/// each relative to the model experiment): the response per force in the mode's band (around
/// its fitted pole) stays within [`RESPONSE_SPREAD`] over the levels. A stiffness
/// nonlinearity moves the resonance a few per cent and keeps its peak, so its response per
/// force hardly changes; a level fit that wandered to another feature, or a band the noise
/// dominates, breaks the proportion, and its "trend" is no amplitude law. The factor 2 was set
/// on development seeds (`diagnose_levels` header); the level tests check its outcome.
pub(super) fn proportional(per_force: &[(f64, f64)]) -> bool {
    let (lo, hi) = per_force
        .iter()
        .map(|(f, a)| a / f)
        .fold((f64::INFINITY, 0.0f64), |(l, h), x| (l.min(x), h.max(x)));
    per_force.len() < 2 || hi <= RESPONSE_SPREAD * lo
}

/// Whether values `(p, σ)` differ beyond their errors (χ² against the weighted mean).
pub(super) fn moves(vals: &[(f64, f64)], alpha: f64) -> bool {
    let w: Vec<f64> = vals
        .iter()
        .map(|v| 1.0 / v.1.max(f64::MIN_POSITIVE).powi(2))
        .collect();
    let sw: f64 = w.iter().sum();
    let mean = vals.iter().zip(&w).map(|(v, w)| v.0 * w).sum::<f64>() / sw;
    let chi2: f64 = vals
        .iter()
        .zip(&w)
        .map(|(v, w)| (v.0 - mean).powi(2) * w)
        .sum();
    let dof = vals.len().saturating_sub(1);
    // χ²_ν/ν is Gamma(ν/2, 1)/(ν/2)
    dof > 0 && chi2 / dof as f64 > threshold(dof as f64 / 2.0, alpha)
}

impl Trend {
    /// The value at relative amplitude `rho` and its standard error.
    pub fn at(&self, rho: f64) -> (f64, f64) {
        let g = rho.powi(self.exponent) - 1.0;
        let v = self.at_reference_std.powi(2)
            + 2.0 * g * self.covariance
            + g * g * self.slope_std.powi(2);
        (self.at_reference + self.slope * g, v.max(0.0).sqrt())
    }

    /// The sign of `dp/dρ` when the slope differs from zero beyond `z` standard errors.
    fn direction(&self, z: f64) -> i32 {
        if self.slope.abs() <= z * self.slope_std {
            0
        } else if (self.slope * self.exponent as f64) > 0.0 {
            1
        } else {
            -1
        }
    }
}

/// `kind` and `damping_trend` of the moving pairs: the dominant one (the largest frequency
/// or damping slope relative to its error) decides, at `z` standard errors; `corner_trend`
/// likewise of the moving real poles' corners.
pub(crate) fn kinds(modes: &[MovingMode], z: f64) -> (FreqTrend, DampingTrend, CornerTrend) {
    let dominant = |pole: PoleKind,
                    moves: &dyn Fn(&MovingMode) -> bool,
                    t: &dyn Fn(&MovingMode) -> Trend| {
        modes
            .iter()
            .filter(|m| m.pole == pole && moves(m))
            .max_by(|a, b| {
                let k = |m: &MovingMode| t(m).slope.abs() / t(m).slope_std.max(f64::MIN_POSITIVE);
                k(a).total_cmp(&k(b))
            })
            .map_or(0, |m| t(m).direction(z))
    };
    let f = match dominant(PoleKind::Pair, &|m| m.frequency_moves, &|m| {
        m.frequency.clone()
    }) {
        1 => FreqTrend::Hardening,
        -1 => FreqTrend::Softening,
        _ => FreqTrend::None,
    };
    let d = match dominant(PoleKind::Pair, &|m| m.damping_moves, &|m| m.damping.clone()) {
        1 => DampingTrend::Increasing,
        -1 => DampingTrend::Decreasing,
        _ => DampingTrend::None,
    };
    let c = match dominant(PoleKind::Real, &|m| m.frequency_moves, &|m| {
        m.frequency.clone()
    }) {
        1 => CornerTrend::Rising,
        -1 => CornerTrend::Falling,
        _ => CornerTrend::None,
    };
    (f, d, c)
}

/// Per candidate (module documentation, **Trend**): its frequency and damping trends over
/// the levels whose fit determines it, and whether each moves (χ² at `alpha` over twice the
/// candidates); a candidate with fewer than two such levels, or points the weighted fit
/// cannot use, keeps its linear pole.
pub(super) fn candidate_trends(
    basis: &ModalBasis,
    cand: &[usize],
    fits: &[&LevelFit],
    reference: &[f64],
    alpha: f64,
) -> Vec<(Trend, Trend, bool, bool)> {
    let a_mode = alpha / (2.0 * cand.len().max(1) as f64);
    let mut trends = Vec::new();
    for m in 0..cand.len() {
        let rho = |f: &LevelFit| f.amplitude[m] / reference[m].max(f64::MIN_POSITIVE);
        let lin = natural(basis.poles()[cand[m]], [[0.0; 2]; 2]);
        // levels where the fit determines the mode (module documentation)
        // (and whose amplitude was measured: a positive finite ratio)
        let good: Vec<&&LevelFit> = fits
            .iter()
            .filter(|f| determined(f.modal[m], lin) && rho(f).is_finite() && rho(f) > 0.0)
            .collect();
        let fp: Vec<(f64, f64, f64)> = good
            .iter()
            .map(|f| (rho(f), f.modal[m].0, f.modal[m].2))
            .collect();
        let zp: Vec<(f64, f64, f64)> = good
            .iter()
            .map(|f| (rho(f), f.modal[m].1, f.modal[m].3))
            .collect();
        let fallback = Trend {
            exponent: EXPONENTS[0],
            at_reference: lin.0,
            at_reference_std: f64::INFINITY,
            slope: 0.0,
            slope_std: f64::INFINITY,
            covariance: 0.0,
        };
        // the pole keeps its linear value
        let linear = || {
            let zfall = Trend {
                at_reference: lin.1,
                ..fallback.clone()
            };
            (fallback.clone(), zfall, false, false)
        };
        if fp.len() < 2 {
            trends.push(linear());
            continue;
        }
        let default = if basis.is_rigid_damping(cand[m]) {
            -1
        } else {
            EXPONENTS[0]
        };
        // points the weighted fit cannot use (equal amplitudes, a zero error): the pole
        // keeps its linear value
        let Some(ft) = best_trend(&fp, alpha, default, basis.is_rigid_damping(cand[m])) else {
            trends.push(linear());
            continue;
        };
        let zt = if basis.is_real(cand[m]) {
            // a real pole's damping is 1 at every amplitude
            Trend {
                at_reference: 1.0,
                at_reference_std: 0.0,
                slope_std: 0.0,
                ..fallback.clone()
            }
        } else {
            best_trend(&zp, alpha, EXPONENTS[0], false).unwrap_or_else(|| Trend {
                at_reference: lin.1,
                ..fallback.clone()
            })
        };
        let fm = moves(&fp.iter().map(|p| (p.1, p.2)).collect::<Vec<_>>(), a_mode);
        // a real pole has no damping of its own (ζ = 1); a damping without a trend does
        // not move
        let zm = !basis.is_real(cand[m])
            && zt.slope_std.is_finite()
            && moves(&zp.iter().map(|p| (p.1, p.2)).collect::<Vec<_>>(), a_mode);
        trends.push((ft, zt, fm, zm));
    }
    trends
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn trend_recovers_a_quadratic_backbone() {
        let pts: Vec<(f64, f64, f64)> = [1.0, 2.0, 4.0, 8.0]
            .iter()
            .map(|&r: &f64| (r, 100.0 + 0.05 * (r * r - 1.0), 0.01))
            .collect();
        let t = best_trend(&pts, 0.01, 2, false).unwrap();
        assert_eq!(t.exponent, 2);
        assert!((t.slope - 0.05).abs() < 1e-9 && (t.at_reference - 100.0).abs() < 1e-9);
        assert_eq!(t.direction(3.0), 1);
        let (v, _) = t.at(3.0);
        assert!((v - 100.4).abs() < 1e-9);
    }
}
