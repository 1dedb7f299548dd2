//! Tolerances and iteration limits of this crate, in one place.

/// Relative asymmetry above which Q or R is refused (below, it is symmetrised).
pub const SYMMETRY: f64 = 1e-10;
/// A Cholesky pivot below this times the largest one counts as singular R.
pub const SPD_PIVOT: f64 = 1e-7;
/// Doubling stops when `‖H_{k+1} − H_k‖ ≤ DOUBLING_STOP·‖H_{k+1}‖`.
pub const DOUBLING_STOP: f64 = 1e-15;
/// Doubling also stops when the relative change is below this and at most the 1.5th power
/// of the previous one (quadratic convergence: the next change would be about its square).
pub const DOUBLING_QUADRATIC: f64 = 1e-10;
/// Most doubling steps (convergence is quadratic: 64 covers ρ(A − BK) up to 1 − 1e-17).
pub const MAX_DOUBLING: usize = 64;
/// The condition estimate's Smith sum stops when a step adds less than this relative (the
/// estimate is then good to about this; a solution's sum runs to ε).
pub const CONDITION_SUM: f64 = 1e-6;
/// Newton refinement stops below this relative residual.
pub const NEWTON_STOP: f64 = 1e-16;
/// In the H∞ existence tests, Hamiltonian eigenvalues with `|Re λ| ≤ AXIS·‖H‖` count as on
/// the imaginary axis (a level at the optimum); the user-level CARE splits by sign instead.
pub const AXIS: f64 = 1e-13;
/// Most Newton refinement steps.
pub const MAX_NEWTON: usize = 8;
/// Pencil eigenvalues within this of the unit circle (relative to |λ| for the axis) are on it.
pub const CIRCLE: f64 = 1e-9;
/// `|β| ≤ INFINITE_EIG·|α|`: an infinite generalized eigenvalue.
pub const INFINITE_EIG: f64 = 1e-12;
/// PBH rank test: smallest singular value below this times the data norm.
pub const PBH: f64 = 1e-10;
/// Relative agreement required between γ_min from the discrete Riccati equations and from the
/// bilinear continuous problem.
pub const GAMMA_AGREE: f64 = 1e-6;
/// Relative CARE residual up to which the DARE solutions are taken as the solutions of the
/// bilinear continuous problem (they are the same matrices; above it the CAREs are solved).
pub const BILINEAR_RESIDUAL: f64 = 1e-10;
/// H∞ synthesis: D₁₂ (D₂₁) counts as rank deficient when its smallest singular value is below
/// this times its largest (or than the plant's D when that is zero).
pub const RANK: f64 = 1e-10;
/// H∞ synthesis: X∞, Y∞ count as positive semidefinite down to this (or 100·κ·ε, κ the
/// Riccati condition estimate, if larger) times their scale.
pub const PSD: f64 = 1e-9;
/// H∞ synthesis: the achieved closed-loop norm may exceed γ by this factor (the norm's own
/// relative accuracy is about 1e-10).
pub const ACHIEVED: f64 = 1e-6;
/// H∞ synthesis: the default relative tolerance of the γ iteration.
pub const GAMMA_TOL: f64 = 1e-3;
/// H∞ synthesis: the up-front refusal of an unstabilizable/undetectable plant needs the PBH
/// smallest singular value below this times the balanced `‖A‖` (roundoff level: a rigid body
/// measured in metres next to 1e4-sized weight states sits near 1e-10 and is detectable).
pub const PBH_REFUSE: f64 = 1e-13;
