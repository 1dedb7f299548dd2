//! The standard closed-loop identification experiment on the virtual stage, shared by the
//! diagnosis and uncertainty tests.

use sd_ident::{Experiment, Lines, MultisineSpec, Phases, Role};
use sd_testbed::{run_identification, Identification, Injection, Noise, NonIdealities, Truth};

/// One closed-loop identification experiment: a PID-like controller (30 Hz with a 1 kHz
/// low-pass above 2 kHz sampling, 20 Hz without below), a full random-phase multisine on the
/// 0.5 Hz grid up to just below Nyquist (2 N rms, input injection), `periods` periods after
/// one transient, white force (0.05 N) and sensor (0.3 nm) noise scaled by `√(rate/5 kHz)`;
/// `fine_steps` sub-steps per period for the fine-step route (`None`: the exact route).
/// `None` when the controller does not stabilize the stage.
#[allow(clippy::too_many_arguments)]
pub fn closed_loop_experiment(
    truth: &Truth,
    name: &str,
    rate: f64,
    ni: NonIdealities,
    seed: u64,
    role: Role,
    periods: usize,
    fine_steps: Option<usize>,
) -> Option<Experiment> {
    let fast = rate > 2000.0;
    let bw = if fast { 30.0 } else { 20.0 };
    let opt = sd_hinf::weights::PidOptions {
        lowpass_ratio: if fast { 1000.0 / bw } else { 0.0 },
        ..Default::default()
    };
    let k = sd_hinf::weights::pid(bw, truth.mass, Some(1.0 / rate), &opt).ok()?;
    let excitation = sd_ident::design(&MultisineSpec {
        fs: rate,
        period: (2.0 * rate) as usize,
        f_min: 0.5,
        f_max: 0.5 * rate - 0.5,
        lines: Lines::Full,
        phases: Phases::Random { seed },
        rms: 2.0,
        fold_rate_hz: Some(1000.0),
    })
    .ok()?;
    let scale = (rate / 5000.0).sqrt();
    let d = run_identification(
        truth,
        &Identification {
            name: name.into(),
            controller: k,
            excitation,
            periods,
            transient_periods: 1,
            injection: Injection::Input,
            noise: Noise {
                force_rms: 0.05 * scale,
                sensor_rms: 0.3e-9 * scale,
                sensor_drift: 0.0,
                seed: seed + 1000,
            },
            nonideal: ni,
            role,
            substeps: None,
            fine_steps,
        },
    )
    .ok()?;
    Some(d.to_experiment())
}
