//! Closed-loop identification experiments on the virtual stage, shared by the diagnosis and
//! uncertainty tests: the general one ([`identification_experiment`]) and the standard one
//! ([`closed_loop_experiment`]), its FRF ([`closed_loop_frf`]) and the low-order model the
//! uncertainty tests bound ([`rigid_body_and_one_mode`]).

use sd_ident::{frf_periodic, Experiment, Lines, MultisineSpec, PeriodicOptions, Phases, Role};
use sd_model::{Frd, StateSpace};
use sd_testbed::{run_identification, Identification, Injection, Noise, NonIdealities, Truth};

/// The settings of an identification experiment that tests vary.
#[derive(Debug, Clone, Copy)]
pub struct ExperimentSpec {
    /// The PID-like controller's bandwidth (Hz).
    pub bandwidth_hz: f64,
    /// Its second-order low-pass (Hz), or none.
    pub lowpass_hz: Option<f64>,
    /// Excitation rms (N, input injection).
    pub rms: f64,
    /// White force and sensor noise rms (N, m).
    pub noise: (f64, f64),
    /// The slow rate the multisine's lines fold onto (Hz).
    pub fold_rate_hz: f64,
    /// Which lines of the 0.5 Hz grid are excited.
    pub lines: Lines,
    /// Periods after the one transient period.
    pub periods: usize,
    /// Sub-steps per period of the fine-step route (`None`: the exact route).
    pub fine_steps: Option<usize>,
}

/// One closed-loop identification experiment: the PID-like controller of `spec`, a
/// random-phase multisine (seed `seed`) on the 0.5 Hz grid up to just below Nyquist, input
/// injection, one transient period, white force and sensor noise (seed `seed + 1000`).
/// `None` when the controller does not stabilize the stage.
pub fn identification_experiment(
    truth: &Truth,
    name: &str,
    rate: f64,
    spec: &ExperimentSpec,
    ni: NonIdealities,
    seed: u64,
    role: Role,
) -> Option<Experiment> {
    let opt = sd_hinf::weights::PidOptions {
        lowpass_ratio: spec.lowpass_hz.map_or(0.0, |f| f / spec.bandwidth_hz),
        ..Default::default()
    };
    let k = sd_hinf::weights::pid(spec.bandwidth_hz, truth.mass, Some(1.0 / rate), &opt).ok()?;
    let excitation = sd_ident::design(&MultisineSpec {
        fs: rate,
        period: (2.0 * rate) as usize,
        f_min: 0.5,
        f_max: 0.5 * rate - 0.5,
        lines: spec.lines,
        phases: Phases::Random { seed },
        rms: spec.rms,
        fold_rate_hz: Some(spec.fold_rate_hz),
    })
    .ok()?;
    let d = run_identification(
        truth,
        &Identification {
            name: name.into(),
            controller: k,
            excitation,
            periods: spec.periods,
            transient_periods: 1,
            injection: Injection::Input,
            noise: Noise {
                force_rms: spec.noise.0,
                sensor_rms: spec.noise.1,
                sensor_drift: 0.0,
                seed: seed + 1000,
            },
            nonideal: ni,
            role,
            substeps: None,
            fine_steps: spec.fine_steps,
        },
    )
    .ok()?;
    Some(d.to_experiment())
}

/// The standard experiment: a PID-like controller (30 Hz with a 1 kHz low-pass above 2 kHz
/// sampling, 20 Hz without below), a full multisine of 2 N rms folding onto 1 kHz, `periods`
/// periods, white force (0.05 N) and sensor (0.3 nm) noise scaled by `√(rate/5 kHz)`;
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
    let scale = (rate / 5000.0).sqrt();
    let spec = ExperimentSpec {
        bandwidth_hz: if fast { 30.0 } else { 20.0 },
        lowpass_hz: fast.then_some(1000.0),
        rms: 2.0,
        noise: (0.05 * scale, 0.3e-9 * scale),
        fold_rate_hz: 1000.0,
        lines: Lines::Full,
        periods,
        fine_steps,
    };
    identification_experiment(truth, name, rate, &spec, ni, seed, role)
}

/// The trusted-line FRF of the standard experiment (7 periods, the fine-step route with 50
/// sub-steps).
pub fn closed_loop_frf(truth: &Truth, rate: f64, ni: NonIdealities, seed: u64) -> Frd {
    let e = closed_loop_experiment(truth, "x", rate, ni, seed, Role::Validation, 7, Some(50))
        .expect("the standard controller stabilises the stage");
    let opt = PeriodicOptions::new(e.spec.period_samples.unwrap_or(1), 1);
    let est = frf_periodic(rate, e.r.as_deref(), &e.u, &e.y, &opt).expect("FRF");
    est.trusted_frd().expect("trusted lines")
}

/// A deliberately low-order model of a measured FRF: the rigid body and one mode (order 4,
/// strictly proper); it misses the higher modes, which is what a bound must show.
pub fn rigid_body_and_one_mode(frd: &Frd) -> StateSpace {
    sd_ident::fit(
        frd,
        &sd_ident::FitOptions {
            order: 4,
            rigid_body: 2,
            feedthrough: false,
            ..Default::default()
        },
    )
    .expect("order-4 fit")
    .model
}
