//! The structured singular value μ for a diagonal complex perturbation, and the simultaneous
//! (multiloop) disk margin it gives.
//!
//! **μ** (Doyle 1982; Packard & Doyle, Automatica 29(1), 1993): for `Δ = diag(δ₁, …, δₙ)`,
//! `δᵢ ∈ ℂ`, `μ(M) = 1/min{‖Δ‖ : det(I − MΔ) = 0}`. Bounds:
//! - *upper*: `μ(M) ≤ inf_D σ̄(DMD⁻¹)` over positive diagonal `D`; `log D ↦ σ̄(e^{X}Me^{−X})` is
//!   convex (Sezginer & Overton, SIAM J. Matrix Anal. Appl. 11(3), 1990), so the infimum is
//!   found by coordinate descent in `log dᵢ` (golden-section line searches, from Osborne's
//!   balancing of `|M|`). For `n ≤ 3` channels the bound *equals* μ (Doyle 1982: `2S + F ≤ 3`
//!   with `F = n` scalar blocks and no repeated ones).
//! - *lower*: `μ(M) = max_Q ρ(QM)` over diagonal unitary `Q` (a complex structure); any `Q`
//!   gives a lower bound. Found by coordinate ascent over the phases (a 72-point scan then a
//!   golden-section refinement per phase). Nonconvex: a lower bound in general.
//!
//! **Simultaneous disk margin** (Seiler, Packard & Gahinet, IEEE CSM 40(3), 2020, balanced
//! disk σ = 0): every input channel `j` (or every output channel) multiplied by its own
//! `fⱼ = (1 + δⱼ/2)/(1 − δⱼ/2)`, `|δⱼ| < α`, at once; the loop stays stable for all of them iff
//! `α ≤ 1/sup_ω μ(S(jω) − I/2)` with `S` the input (output) sensitivity. The unstructured
//! `1/‖S − I/2‖∞` ([`crate::mimo`]) is a lower bound that lets the perturbation couple the
//! channels. The supremum over frequency is taken on a log grid with points clustered at each
//! closed-loop pole's frequency, then refined by golden section around the largest value.

use crate::closed_loop::{sigma_max, ClosedLoop};
use crate::error::Result;
use nalgebra::DMatrix;
use num_complex::Complex64 as C;
use sd_model::{FreqRespEvaluator, SampleTime};
use std::f64::consts::PI;

/// Bounds of μ for a diagonal complex scalar structure.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MuBounds {
    /// `min_D σ̄(DMD⁻¹)` (equal to μ for up to 3 channels).
    pub upper: f64,
    /// `max_Q ρ(QM)` found by the phase search (a lower bound).
    pub lower: f64,
}

/// The minimum of a unimodal `f` on `[a, b]` to a bracket of `tol`
/// ([`sd_model::linalg::golden_min`], as many steps as that takes).
fn golden_min(f: &dyn Fn(f64) -> f64, (a, b): (f64, f64), tol: f64) -> (f64, f64) {
    let shrink = (tol / (b - a).abs().max(tol)).ln() / 0.5f64.mul_add(5f64.sqrt(), -0.5).ln();
    sd_model::linalg::golden_min(f, a, b, shrink.ceil().max(1.0) as usize)
}

/// `σ̄(e^{x}Me^{−x})` for the diagonal scaling `x` (log scale factors).
fn scaled_norm(m: &DMatrix<C>, x: &[f64]) -> f64 {
    let s = DMatrix::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)] * (x[i] - x[j]).exp());
    sigma_max(&s)
}

/// The D-scaled upper bound (module documentation).
fn upper_bound(m: &DMatrix<C>, tol: f64) -> f64 {
    let n = m.nrows();
    // Osborne's balancing of |M| (row and column norms equal) as the start
    let mut x = vec![0.0f64; n];
    for _ in 0..50 {
        for i in 1..n {
            let row: f64 = (0..n)
                .filter(|&j| j != i)
                .map(|j| (m[(i, j)].norm() * (x[i] - x[j]).exp()).powi(2))
                .sum();
            let col: f64 = (0..n)
                .filter(|&j| j != i)
                .map(|j| (m[(j, i)].norm() * (x[j] - x[i]).exp()).powi(2))
                .sum();
            if row > 0.0 && col > 0.0 {
                x[i] += 0.25 * (col / row).ln();
            }
        }
    }
    let mut best = scaled_norm(m, &x);
    for _ in 0..60 {
        let before = best;
        for i in 1..n {
            let xi = x[i];
            let f = |v: f64| {
                let mut y = x.clone();
                y[i] = v;
                scaled_norm(m, &y)
            };
            let (v, fv) = golden_min(&f, (xi - 12.0, xi + 12.0), tol);
            if fv < best {
                x[i] = v;
                best = fv;
            }
        }
        if before - best <= tol * before {
            break;
        }
    }
    best
}

/// `ρ(QM)` with `Q = diag(e^{jφ})`, through the real representation (its spectrum is `QM`'s
/// with the conjugates).
fn rho(m: &DMatrix<C>, phi: &[f64]) -> f64 {
    let q = DMatrix::from_fn(m.nrows(), m.ncols(), |i, j| {
        m[(i, j)] * C::from_polar(1.0, phi[i])
    });
    sd_hinf::riccati::complex::realify(&q)
        .complex_eigenvalues()
        .iter()
        .map(|l| l.norm())
        .fold(0.0, f64::max)
}

/// The phase-search lower bound (module documentation).
fn lower_bound(m: &DMatrix<C>) -> f64 {
    let n = m.nrows();
    let mut phi = vec![0.0; n];
    let mut best = rho(m, &phi);
    for _ in 0..20 {
        let before = best;
        for i in 1..n {
            let f = |v: f64| {
                let mut p = phi.clone();
                p[i] = v;
                -rho(m, &p)
            };
            let step = 2.0 * PI / 72.0;
            let (k, _) = (0..72)
                .map(|k| (k, f(k as f64 * step)))
                .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
            let c = k as f64 * step;
            let (v, fv) = golden_min(&f, (c - step, c + step), 1e-10);
            if -fv > best {
                phi[i] = v;
                best = -fv;
            }
        }
        if best - before <= 1e-13 * best {
            break;
        }
    }
    best
}

/// μ bounds of a square `m` for the diagonal complex structure (module documentation).
pub fn mu_diagonal(m: &DMatrix<C>) -> MuBounds {
    let upper = mu_upper(m);
    if m.nrows() <= 1 {
        return MuBounds {
            upper,
            lower: upper,
        };
    }
    let lower = lower_bound(m).min(upper);
    MuBounds { upper, lower }
}

/// The simultaneous disk margin of one side of a loop.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StructuredDiskMargin {
    /// `1/sup μ_upper`: every channel on this side may vary in its disk at once (guaranteed).
    pub margin: f64,
    /// `1/sup μ_lower`: a disk this large destabilises (the margin lies in
    /// `[margin, margin_upper]`; equal up to the search's rounding for ≤ 3 channels).
    pub margin_upper: f64,
    /// Frequency of the critical μ peak (Hz).
    pub freq_hz: f64,
    /// The guaranteed gain margin `(1 + α/2)/(1 − α/2)` (dB; `inf` for α ≥ 2).
    pub gain_margin_db: f64,
    /// The guaranteed phase margin `2·atan(α/2)` (degrees).
    pub phase_margin_deg: f64,
}

/// The closed loop's input (`S_I = (I + KP)⁻¹`) or output (`S_O = (I + PK)⁻¹`) sensitivity
/// minus `I/2` from `P` and `K` at one frequency.
fn shifted_sensitivity((p, k): (&DMatrix<C>, &DMatrix<C>), input: bool) -> Option<DMatrix<C>> {
    let l = if input { k * p } else { p * k };
    let n = l.nrows();
    let s = (DMatrix::identity(n, n) + l).try_inverse()?;
    Some(s - DMatrix::identity(n, n) * C::new(0.5, 0.0))
}

/// The analysis grid: log-spaced, plus points at every closed-loop pole's frequency.
fn mu_grid(cl: &ClosedLoop) -> Result<Vec<f64>> {
    let poles = cl.closed_loop().poles()?;
    let ts = cl.plant().ts();
    let freqs: Vec<(f64, f64)> = poles
        .iter()
        .map(|p| sd_model::poles::natural_frequency(*p, ts))
        .filter(|(f, _)| f.is_finite() && *f > 0.0)
        .collect();
    let (lo, hi) = match cl.plant().time() {
        SampleTime::Discrete { ts } => (0.5e-6 / ts, 0.5 / ts),
        SampleTime::Continuous => {
            let fmin = freqs.iter().map(|v| v.0).fold(f64::INFINITY, f64::min);
            let fmax = freqs.iter().map(|v| v.0).fold(0.0, f64::max);
            if freqs.is_empty() {
                (1e-3, 1e3)
            } else {
                (fmin * 1e-3, fmax * 1e3)
            }
        }
    };
    let mut f = sd_model::grid(lo, hi, 2000, true)?;
    for (fp, z) in freqs {
        let w = z.abs().clamp(1e-6, 0.5);
        for j in -8i32..=8 {
            let v = fp * (1.0 + f64::from(j) * w / 4.0);
            if v > lo && v < hi {
                f.push(v);
            }
        }
    }
    f.sort_by(f64::total_cmp);
    f.dedup();
    Ok(f)
}

/// The structured simultaneous disk margins of the inputs and of the outputs (module
/// documentation).
///
/// # Errors
/// The closed loop's poles; `I + L` singular on the grid (a closed-loop pole on the boundary).
pub fn structured_disk_margins(cl: &ClosedLoop) -> Result<[StructuredDiskMargin; 2]> {
    let ev_p = FreqRespEvaluator::new(cl.plant())?;
    let ev_k = FreqRespEvaluator::new(cl.controller())?;
    let grid = mu_grid(cl)?;
    // P and K on the grid once, for both sides
    let pk: Vec<(DMatrix<C>, DMatrix<C>)> = grid
        .iter()
        .map(|&f| (ev_p.eval_hz(f), ev_k.eval_hz(f)))
        .collect();
    let singular = |f: f64| {
        crate::AnalysisError::InvalidArgument(format!(
            "I + L is singular at {f} Hz: a closed-loop pole on the stability boundary"
        ))
    };
    let side = |input: bool| -> Result<StructuredDiskMargin> {
        let m_at = |f: f64| {
            let (p, k) = (ev_p.eval_hz(f), ev_k.eval_hz(f));
            shifted_sensitivity((&p, &k), input).ok_or_else(|| singular(f))
        };
        let mut peak = (0.0, f64::NAN, 0usize);
        for (i, (&f, (p, k))) in grid.iter().zip(&pk).enumerate() {
            let m = shifted_sensitivity((p, k), input).ok_or_else(|| singular(f))?;
            let u = mu_upper_to(&m, 1e-6);
            if u > peak.0 {
                peak = (u, f, i);
            }
        }
        // refine between the neighbours of the largest grid value
        let (i, n) = (peak.2, grid.len());
        let (a, b) = (
            grid[i.saturating_sub(1)].ln(),
            grid[(i + 1).min(n - 1)].ln(),
        );
        let neg = |x: f64| m_at(x.exp()).map_or(0.0, |m| -mu_upper(&m));
        let (x, v) = golden_min(&neg, (a, b), 1e-9);
        if -v > peak.0 {
            peak = (-v, x.exp(), i);
        }
        let bounds = mu_diagonal(&m_at(peak.1)?);
        let alpha = 1.0 / bounds.upper;
        let (g, p) = crate::mimo::disk_to_classic(alpha);
        Ok(StructuredDiskMargin {
            margin: alpha,
            margin_upper: 1.0 / bounds.lower.max(f64::MIN_POSITIVE),
            freq_hz: peak.1,
            gain_margin_db: g,
            phase_margin_deg: p,
        })
    };
    Ok([side(true)?, side(false)?])
}

/// The upper bound alone (the frequency sweep does not need the lower one), to a relative
/// `1e-12`.
pub fn mu_upper(m: &DMatrix<C>) -> f64 {
    mu_upper_to(m, 1e-12)
}

/// [`mu_upper`] to a relative tolerance `tol` of the scaling search (the sweep's coarse pass).
fn mu_upper_to(m: &DMatrix<C>, tol: f64) -> f64 {
    if m.nrows() <= 1 {
        return m.iter().next().map_or(0.0, |v| v.norm());
    }
    upper_bound(m, tol)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A diagonal `M` has μ = max |mᵢᵢ| and a rank-one `M = uvᴴ` has μ = Σ|uᵢvᵢ| (both exact
    /// formulas of Packard & Doyle 1993), while σ̄ can be far larger.
    #[test]
    fn closed_forms() {
        let d = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![
            C::new(0.3, 0.4),
            C::new(-2.0, 0.0),
            C::new(0.0, 1.0),
        ]));
        let b = mu_diagonal(&d);
        assert!((b.upper - 2.0).abs() < 1e-9 && (b.lower - 2.0).abs() < 1e-9);
        let u = [C::new(1.0, 0.5), C::new(-0.2, 2.0), C::new(3.0, -1.0)];
        let v = [C::new(0.5, 0.0), C::new(1.0, -1.0), C::new(0.1, 0.3)];
        let m = DMatrix::from_fn(3, 3, |i, j| u[i] * v[j].conj());
        let want: f64 = (0..3).map(|i| (u[i] * v[i].conj()).norm()).sum();
        let b = mu_diagonal(&m);
        assert!((b.upper / want - 1.0).abs() < 1e-6, "{} vs {want}", b.upper);
        assert!((b.lower / want - 1.0).abs() < 1e-6, "{} vs {want}", b.lower);
        assert!(sigma_max(&m) > 1.3 * want);
    }
}
