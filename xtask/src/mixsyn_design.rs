//! The paper stage's mixed-sensitivity controller at 1 kHz (issue #41 item 3), designed on the
//! same 1 kHz design model as the loopshaping Controller 1.
//!
//! Weights (units: position in m, force in N):
//! - `W₁` on S: `makeweight(1e5, 60 Hz, 1, 0.6)` of order 2 (+40 dB/decade like the double
//!   integrator's S) times a peak of 2.5 at the aliased 347 Hz resonance (the inverse of a
//!   notch, zero damping 0.2 over pole damping 0.08): |S| ≤ γ/|W₁|, i.e. −100 dB·γ at low
//!   frequency, 0 dB·γ at 60 Hz, +4.4 dB·γ above and −3.5 dB·γ at 347 Hz — the paper's "low
//!   controller gain at the aliased peak" asked for through S;
//! - `W₂ = 3e-8 N⁻¹` on KS (the force per metre of reference): the controller's gain stays
//!   near 3e7 N/m at high frequency;
//! - `W_d = 1 N` on an input force disturbance: the process sensitivity SG joins the
//!   objective and makes the rigid body (at z = 1) reachable from the exogenous inputs, which
//!   the Riccati formulas need.

use sd_hinf::weights::{makeweight, notch};
use sd_hinf::{mixsyn, HinfOptions, MixsynWeights};
use sd_model::{SampleTime, StateSpace};

/// W₁'s low-frequency gain, crossover (Hz) and high-frequency gain.
pub const W1: (f64, f64, f64) = (1e5, 60.0, 0.6);
/// W₁'s peak at the aliased resonance: frequency (Hz), zero and pole damping of the inverted
/// notch (peak gain = their ratio).
pub const W1_PEAK: (f64, f64, f64) = (347.0, 0.2, 0.08);
/// W₂ (N⁻¹).
pub const W2: f64 = 3e-8;
/// W_d (N).
pub const WD: f64 = 1.0;

/// An H∞ design and its figures (the mixed-sensitivity and the multirate ones).
pub struct Design {
    /// The controller for negative feedback on the measured error.
    pub controller: StateSpace,
    /// γ the controller was built for (= γ_min of the iteration).
    pub gamma: f64,
    /// The achieved closed-loop norm of the weighted stack.
    pub achieved: f64,
    /// States of the generalized plant.
    pub plant_states: usize,
    /// Wall time of the synthesis (s).
    pub seconds: f64,
}

/// A 1×1 static weight.
pub(crate) fn gain(v: f64, time: SampleTime) -> Result<StateSpace, String> {
    StateSpace::gain(nalgebra::DMatrix::from_element(1, 1, v), time).map_err(|e| e.to_string())
}

/// Mixed-sensitivity synthesis on the 1 kHz design model.
pub fn design(p_design: &StateSpace) -> Result<Design, String> {
    let err = |e: sd_hinf::HinfError| e.to_string();
    let ts = p_design.ts();
    let shape = makeweight(W1.0, W1.1, 1.0, W1.2, 2, ts).map_err(err)?;
    let peak = notch(W1_PEAK.0, W1_PEAK.1, W1_PEAK.2, ts).map_err(err)?;
    let w1 = sd_model::series(&shape, &peak).map_err(|e| e.to_string())?;
    let w2 = gain(W2, p_design.time())?;
    let wd = gain(WD, p_design.time())?;
    let w = MixsynWeights {
        w1: Some(&w1),
        w2: Some(&w2),
        w3: None,
        wd: Some(&wd),
    };
    let t = std::time::Instant::now();
    let (r, p) = mixsyn(p_design, &w, &HinfOptions::default()).map_err(err)?;
    Ok(Design {
        controller: r.controller,
        gamma: r.gamma,
        achieved: r.achieved_norm,
        plant_states: p.n(),
        seconds: t.elapsed().as_secs_f64(),
    })
}
