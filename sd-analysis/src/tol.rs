//! Grid sizes and tolerances of this crate, in one place.

/// Log-spaced points of the frequency grid on which crossings are bracketed.
pub const GRID_POINTS: usize = 20_000;
/// Extra points placed around each lightly damped pole (ζ < 0.2) of the loop.
pub const RESONANCE_POINTS: usize = 200;
/// Bisection/golden-section steps refining a crossing or a minimum (to machine precision).
pub const REFINE_STEPS: usize = 200;
