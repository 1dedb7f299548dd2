//! What a fit is asked for and what it returns: options, results, modal terms, warnings.

use super::*;

/// Weighting of the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Weighting {
    /// `1/σ_k` from the FRD's variance; relative if it has none (default).
    Variance,
    /// `1/|G_k|`.
    Relative,
    /// 1.
    Uniform,
}

/// Fit settings.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Model order n (states), including the rigid-body poles.
    pub order: usize,
    /// Fixed poles at z = 1 (0, 1 or 2).
    pub rigid_body: usize,
    /// Fit a feedthrough d.
    pub feedthrough: bool,
    /// Weighting.
    pub weighting: Weighting,
    /// SK (pole relocation) iterations.
    pub sk_iterations: usize,
    /// Levenberg–Marquardt iterations (0: SK only).
    pub lm_iterations: usize,
    /// Lowest damping ratio a free complex pole may take (0: no floor). A pole pair whose
    /// continuous equivalent `s = ln(p)/T` has `−Re s/|s|` below it is moved, at the same
    /// natural frequency `|s|`, onto the floor, in every SK and LM step.
    pub min_damping: f64,
    /// Narrowest half-power bandwidth `2ζf_n` (Hz) a free complex pole pair may take (0: no
    /// floor): a pair below it is moved, at the same natural frequency, onto
    /// `ζ = B/(2f_n)` (capped at 0.99), in every SK and LM step, like [`FitOptions::min_damping`].
    /// The line spacing is the resolution of the data: a pair narrower than it is not measured
    /// ([`FitWarning::UnresolvedMode`]; [`crate::stabilization`] sets it).
    pub min_bandwidth_hz: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            order: 8,
            rigid_body: 0,
            feedthrough: true,
            weighting: Weighting::Variance,
            sk_iterations: tol::SK_ITERATIONS,
            lm_iterations: tol::LM_ITERATIONS,
            min_damping: 0.0,
            min_bandwidth_hz: 0.0,
        }
    }
}

/// Progress of a fit (for long fits; the caller decides how to show it).
#[derive(Debug, Clone, PartialEq)]
pub struct FitProgress {
    /// "sk" or "lm".
    pub stage: &'static str,
    /// Iteration within the stage.
    pub iteration: usize,
    /// Current cost V.
    pub cost: f64,
}

/// A fitted model.
#[derive(Debug, Clone)]
pub struct FitResult {
    /// Real modal state-space model at the FRD's sample time.
    pub model: StateSpace,
    /// Final cost V.
    pub cost: f64,
    /// Cost after each SK and accepted LM iteration.
    pub history: Vec<FitProgress>,
    /// The poles (free and fixed).
    pub poles: Vec<C>,
    /// Median of `|G_k − Ĝ_k| / |G_k|` over the data.
    pub median_rel_error: f64,
    /// Each line's term `w_k²|G_k − Ĝ(z_k)|²` of the cost (they sum to `cost`).
    pub line_cost: Vec<f64>,
    /// What the data do not support in this fit ([`FitWarning`]).
    pub warnings: Vec<FitWarning>,
    /// The partial-fraction terms of the model, one per real pole, pole pair and rigid body.
    pub terms: Vec<ModalTerm>,
}

/// One term of a fitted model's partial fractions `Ĝ(z) = Σ terms + d`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModalTerm {
    /// `r/(z − p)`, p real.
    Real {
        /// Pole.
        pole: f64,
        /// Residue.
        residue: f64,
    },
    /// `r/(z − p) + r̄/(z − p̄)`, `p` in the upper half plane.
    Pair {
        /// Pole (upper half plane).
        pole: C,
        /// Its residue.
        residue: C,
    },
    /// The rigid body `Σ_l c_l/(z − 1)^l`.
    Rigid {
        /// `c_1, c_2` (as many as rigid-body poles).
        residues: [f64; 2],
        /// Rigid-body poles (1 or 2).
        count: usize,
    },
}

impl ModalTerm {
    /// The term's response at `z`.
    pub fn eval(&self, z: C) -> C {
        match *self {
            ModalTerm::Real { pole, residue } => residue / (z - pole),
            ModalTerm::Pair { pole, residue } => {
                residue / (z - pole) + residue.conj() / (z - pole.conj())
            }
            ModalTerm::Rigid { residues, count } => {
                let q = 1.0 / (z - 1.0);
                (0..count).map(|l| residues[l] * q.powi(l as i32 + 1)).sum()
            }
        }
    }
}

/// Something a fit's data do not support.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FitWarning {
    /// A pole pair so close to the unit circle that its half-power bandwidth `2ζf` is below
    /// the spacing of the data lines there (`1 − |p| < π·Δf·T`): the lines do not resolve its
    /// peak, so its damping is not measured (a false undamped mode, typically, at high order).
    UnresolvedMode {
        /// Natural frequency `|s|/2π` (Hz).
        freq_hz: f64,
        /// Damping ratio.
        damping: f64,
        /// `1 − |p|`.
        distance_to_unit_circle: f64,
        /// Half-power bandwidth `2ζf` (Hz).
        bandwidth_hz: f64,
        /// Spacing of the data lines around `freq_hz` (Hz).
        line_spacing_hz: f64,
    },
    /// One line carries a large share of the cost: a badly excited or disturbed line steers
    /// the fit.
    DominantLine {
        /// The line (Hz).
        freq_hz: f64,
        /// Its share of the cost.
        share: f64,
        /// `w|G − Ĝ|` there (standard deviations with variance weighting).
        weighted_error: f64,
    },
}

impl std::fmt::Display for FitWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FitWarning::UnresolvedMode {
                freq_hz,
                damping,
                distance_to_unit_circle,
                bandwidth_hz,
                line_spacing_hz,
            } => write!(
                f,
                "pole pair at {freq_hz:.3} Hz with damping {damping:.2e} (|p| = 1 − \
                 {distance_to_unit_circle:.1e}): its half-power bandwidth {bandwidth_hz:.3e} Hz \
                 is below the line spacing {line_spacing_hz:.3} Hz there, so the data do not \
                 measure its damping; lower the order or set --min-damping"
            ),
            FitWarning::DominantLine {
                freq_hz,
                share,
                weighted_error,
            } => write!(
                f,
                "the line at {freq_hz:.3} Hz carries {:.0} % of the cost (weighted error \
                 {weighted_error:.1}): check its excitation and noise, or leave it out",
                100.0 * share
            ),
        }
    }
}

/// A single line's share of the cost above which it is flagged, when it is also this many
/// times the median line's term.
pub(super) const DOMINANT_SHARE: f64 = 0.1;

pub(super) const DOMINANT_OVER_MEDIAN: f64 = 25.0;

/// The warnings of a fit: unresolved modes from the poles and the data lines, dominant lines
/// from the cost terms (a line is flagged only when its weighted error reaches `significant`:
/// 5 with `1/σ` weights, 0.1 % of the median weighted response otherwise, so that a fit at
/// rounding level flags nothing).
pub(super) fn fit_warnings(
    freq_hz: &[f64],
    pf: &Pf,
    ts: f64,
    line_cost: &[f64],
    significant: f64,
) -> Vec<FitWarning> {
    let mut out = Vec::new();
    for (p, _) in &pf.pairs {
        let s = p.ln() / ts;
        let (fn_hz, zeta) = sd_model::poles::natural_frequency(s, None);
        let i = freq_hz.partition_point(|f| *f < fn_hz);
        let gap = |a: usize, b: usize| freq_hz[b] - freq_hz[a];
        let spacing = match (i, freq_hz.len()) {
            (_, n) if n < 2 => f64::INFINITY,
            (0, _) => gap(0, 1),
            (i, n) if i >= n => gap(n - 2, n - 1),
            (i, _) => gap(i - 1, i),
        };
        let bandwidth = 2.0 * zeta * fn_hz;
        if bandwidth < spacing {
            out.push(FitWarning::UnresolvedMode {
                freq_hz: fn_hz,
                damping: zeta,
                distance_to_unit_circle: 1.0 - p.norm(),
                bandwidth_hz: bandwidth,
                line_spacing_hz: spacing,
            });
        }
    }
    let total: f64 = line_cost.iter().sum();
    let med = sd_model::median(line_cost);
    for (f, c) in freq_hz.iter().zip(line_cost) {
        if total > 0.0
            && *c > DOMINANT_SHARE * total
            && *c > DOMINANT_OVER_MEDIAN * med
            && c.sqrt() >= significant
        {
            out.push(FitWarning::DominantLine {
                freq_hz: *f,
                share: c / total,
                weighted_error: c.sqrt(),
            });
        }
    }
    out
}
