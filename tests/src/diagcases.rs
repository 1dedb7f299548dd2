//! Seeded diagnosis cases on the virtual stage, for the held-out hidden-effect suite and the
//! calibration of the verdict.
//!
//! The linear cases are produced by the testbed's **fine-step route** (sub-step ZOH, the hold
//! switching and the trapezoidal sensor average on a grid of 50 sub-steps per period, the true
//! period with the clock error): another numerical form than the diagnosis's hypotheses (block
//! exponentials of `c2d_nonideal`). The nonlinear ones by the Lawson–RK4 integrator.
//!
//! Everything is drawn from the seed: a random plant (mass 5–50 kg, one or two modes between
//! 0.6× the slow rate and 0.4× the fast rate, ζ 0.005–0.03), fast rate 4/5/6 kHz, factor 2–5 (one that divides the rate),
//! 2–10 steady periods of a random-phase multisine on the 1 Hz grid (or one record of a
//! non-periodic excitation, estimated by the LPM), input or reference injection, white or
//! drifting (random-walk) sensor noise, noise levels over a decade.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use crate::gen::Rng;
use sd_ident::{Experiment, Lines, MultisineSpec, Phases, Role};
use sd_testbed::{run_identification, Identification, Injection, Noise, NonIdealities, Truth};

/// Sub-steps per period of the fine-step route.
pub const FINE_STEPS: usize = 50;

/// The hidden effect of a case.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Effect {
    /// Nothing.
    None,
    /// A first-order sensor filter common to both rates (Hz).
    Filter(f64),
    /// Hold delay (fraction of each period).
    Delay(f64),
    /// Averaging window (fraction).
    Averaging(f64),
    /// Clock error of the slow experiment.
    Clock(f64),
    /// Hold delay and averaging window.
    DelayAveraging(f64, f64),
    /// Hold delay and clock error.
    DelayClock(f64, f64),
    /// Cubic stiffness of the first mode, seen at two excitation levels.
    Cubic,
}

impl Effect {
    /// The cause the diagnosis should name.
    pub fn expected(&self) -> &'static str {
        match self {
            Effect::None | Effect::Filter(_) => "none",
            Effect::Delay(_) => "hold_delay",
            Effect::Averaging(_) => "averaging_sampler",
            Effect::Clock(_) => "clock_error",
            Effect::DelayAveraging(..) => "averaging_sampler+hold_delay",
            Effect::DelayClock(..) => "clock_error+hold_delay",
            Effect::Cubic => "nonlinearity",
        }
    }

    /// A short label of the kind (the confusion matrix's rows).
    pub fn kind(&self) -> &'static str {
        match self {
            Effect::None => "none",
            Effect::Filter(_) => "common filter",
            Effect::Delay(_) => "hold delay",
            Effect::Averaging(_) => "averaging",
            Effect::Clock(_) => "clock error",
            Effect::DelayAveraging(..) => "delay + averaging",
            Effect::DelayClock(..) => "delay + clock",
            Effect::Cubic => "cubic stiffness",
        }
    }

    fn nonideal(&self) -> NonIdealities {
        let (hold_delay, averaging, clock_error) = match *self {
            Effect::Delay(a) => (a, 0.0, 0.0),
            Effect::Averaging(b) => (0.0, b, 0.0),
            Effect::Clock(e) => (0.0, 0.0, e),
            Effect::DelayAveraging(a, b) => (a, b, 0.0),
            Effect::DelayClock(a, e) => (a, 0.0, e),
            _ => (0.0, 0.0, 0.0),
        };
        NonIdealities {
            hold_delay,
            averaging,
            clock_error,
            quantization: 0.0,
        }
    }
}

/// How the data are recorded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Recording {
    /// Steady periods (after one transient period); for a non-periodic record its length in
    /// periods.
    pub steady: usize,
    /// Reference (true) or input injection.
    pub reference: bool,
    /// Random-walk sensor drift on (its step rms relative to the white sensor noise: 0.05).
    pub drift: bool,
    /// Periodic multisine (true) or one non-periodic record (LPM).
    pub periodic: bool,
    /// A level case's periodic multisine excites every line of its band (a full random-phase
    /// multisine, one realization: no detection lines, so the nonlinear distortion cannot be
    /// measured, as in a ground vibration test); else random-odd with detection lines.
    pub full: bool,
}

impl Recording {
    /// Four steady periods of a periodic multisine, input injection, white sensor noise: the
    /// level suites' periodic recording.
    pub const PERIODIC: Recording = Recording {
        steady: 4,
        reference: false,
        drift: false,
        periodic: true,
        full: false,
    };
    /// [`Recording::PERIODIC`] with every line of the band excited.
    pub const FULL: Recording = Recording {
        full: true,
        ..Recording::PERIODIC
    };
    /// [`Recording::PERIODIC`] as one non-periodic record as long as its periods (LPM).
    pub const NOISE: Recording = Recording {
        periodic: false,
        ..Recording::PERIODIC
    };
}

/// A generated case.
#[derive(Debug, Clone)]
pub struct Case {
    /// The hidden effect.
    pub effect: Effect,
    /// The recording.
    pub recording: Recording,
    /// Fast rate and factor.
    pub rates: (f64, usize),
    /// The experiments (the model experiment first).
    pub experiments: Vec<Experiment>,
}

struct Stage {
    truth: Truth,
    fast_rate: f64,
    factor: usize,
    noise: f64,
}

fn stage(r: &mut Rng) -> Stage {
    let fast_rate = [4000.0, 5000.0, 6000.0][(r.uniform() * 3.0) as usize % 3];
    // a factor that divides the rate: both records of one second then hold whole samples and
    // share the 1 Hz line grid
    let divisors: Vec<usize> = (2..=5).filter(|f| fast_rate as usize % f == 0).collect();
    let factor = divisors[(r.uniform() * divisors.len() as f64) as usize % divisors.len()];
    let slow_rate = fast_rate / factor as f64;
    let mass = r.range(5.0, 50.0);
    let nmodes = 1 + (r.uniform() * 2.0) as usize % 2;
    let modes = (0..nmodes)
        .map(|_| sd_testbed::ModeSpec {
            freq_hz: r.range(0.6 * slow_rate, 0.4 * fast_rate),
            zeta: r.range(0.005, 0.03),
            residue: r.range(0.3, 2.0),
            cubic: 0.0,
        })
        .collect();
    Stage {
        truth: Truth {
            mass,
            modes,
            ..Truth::default()
        },
        fast_rate,
        factor,
        noise: r.range(0.3, 3.0),
    }
}

struct Exp<'a> {
    name: &'a str,
    /// Full multisine, or odd with detection lines.
    lines: Lines,
    rate: f64,
    rms: f64,
    ni: NonIdealities,
    seed: u64,
    role: Role,
    /// A non-periodic excitation of its own (filtered noise) in place of the multisine: one
    /// record, estimated by the LPM.
    signal: Option<Vec<f64>>,
    /// Samples per period (default: one second's).
    period: Option<usize>,
}

/// One closed-loop experiment; `None` when the loop is unstable.
fn identify(st: &Stage, rec: &Recording, x: &Exp<'_>) -> Option<Experiment> {
    let ts = 1.0 / x.rate;
    let bw = 10.0;
    let opt = sd_hinf::weights::PidOptions {
        lowpass_ratio: 0.2 * x.rate / bw,
        ..Default::default()
    };
    let k = sd_hinf::weights::pid(bw, st.truth.mass, Some(ts), &opt).ok()?;
    let period = x.period.unwrap_or(x.rate as usize);
    let periods = if rec.periodic { 1 + rec.steady } else { 1 };
    let len = if rec.periodic {
        period
    } else {
        period * (1 + rec.steady)
    };
    // a reference of the position that makes about the same force as `rms` N would
    let wc = 2.0 * std::f64::consts::PI * bw;
    let rms = if rec.reference {
        x.rms / (st.truth.mass * wc * wc)
    } else {
        x.rms
    };
    let excitation = x.signal.as_ref().map(|sig| sd_ident::Multisine {
        signal: sig.clone(),
        excited: Vec::new(),
        detection_odd: Vec::new(),
        detection_even: Vec::new(),
        f0: x.rate / sig.len() as f64,
        fs: x.rate,
        crest_factor: sd_ident::crest_factor(sig),
    });
    let excitation = match excitation {
        Some(e) => e,
        None => sd_ident::design(&MultisineSpec {
            fs: x.rate,
            period: len,
            f_min: x.rate / len as f64,
            f_max: 0.5 * x.rate - x.rate / len as f64,
            lines: x.lines,
            phases: Phases::Random { seed: x.seed },
            rms,
            fold_rate_hz: Some(st.fast_rate / st.factor as f64),
        })
        .ok()?,
    };
    let periods = if x.signal.is_some() { 1 } else { periods };
    let scale = (x.rate / 5000.0).sqrt();
    let sensor = 0.1e-9 * st.noise * scale;
    let mut d = run_identification(
        &st.truth,
        &Identification {
            name: x.name.into(),
            controller: k,
            excitation,
            periods,
            transient_periods: if rec.periodic && x.signal.is_none() {
                1
            } else {
                0
            },
            injection: if rec.reference {
                Injection::Reference
            } else {
                Injection::Input
            },
            noise: Noise {
                force_rms: 0.02 * st.noise * x.rms * scale,
                sensor_rms: sensor,
                sensor_drift: if rec.drift { 0.05 * sensor } else { 0.0 },
                seed: x.seed + 1000,
            },
            nonideal: x.ni,
            role: x.role,
            substeps: None,
            fine_steps: (!st.truth.is_nonlinear()).then_some(FINE_STEPS),
        },
    )
    .ok()?;
    if !rec.periodic || x.signal.is_some() {
        d.period = None;
    }
    Some(d.to_experiment())
}

/// The case of `seed` with the given effect and recording (`None`: the drawn plant's loop is
/// unstable).
pub fn build(seed: u64, effect: Effect, rec: Recording) -> Option<Case> {
    let mut r = Rng::new(seed * 7919 + 17);
    let mut st = stage(&mut r);
    match effect {
        Effect::Filter(fc) => st.truth.sensor_filters.push(
            sd_model::TransferFunction::new(
                vec![1.0],
                vec![1.0 / (2.0 * std::f64::consts::PI * fc), 1.0],
                sd_model::SampleTime::Continuous,
            )
            .ok()?
            .to_ss()
            .ok()?,
        ),
        Effect::Cubic => {
            let m0 = &st.truth.modes[0];
            let w = 2.0 * std::f64::consts::PI * m0.freq_hz;
            let q = m0.residue * 4.0 / (st.truth.mass * w * w * 2.0 * m0.zeta) * 0.05;
            st.truth.modes[0].cubic = 0.3 / (q * q);
        }
        _ => {}
    }
    let ni = effect.nonideal();
    // the model experiment's clock is the reference: only the slow one is off
    let fast_ni = NonIdealities {
        clock_error: 0.0,
        ..ni
    };
    let slow_rate = st.fast_rate / st.factor as f64;
    let mut exps = vec![
        identify(
            &st,
            &rec,
            &Exp {
                lines: Lines::Full,
                name: "fast",
                rate: st.fast_rate,
                rms: 0.5,
                ni: fast_ni,
                seed: seed * 3 + 1,
                role: Role::Model,
                signal: None,
                period: None,
            },
        )?,
        identify(
            &st,
            &rec,
            &Exp {
                lines: Lines::Full,
                name: "slow",
                rate: slow_rate,
                rms: 0.5,
                ni,
                seed: seed * 3 + 2,
                role: Role::Validation,
                signal: None,
                period: None,
            },
        )?,
    ];
    if effect == Effect::Cubic {
        exps.push(identify(
            &st,
            &rec,
            &Exp {
                lines: Lines::Full,
                name: "fast_high",
                rate: st.fast_rate,
                rms: 4.0,
                ni: fast_ni,
                seed: seed * 3 + 3,
                role: Role::Validation,
                signal: None,
                period: None,
            },
        )?);
    }
    Some(Case {
        effect,
        recording: rec,
        rates: (st.fast_rate, st.factor),
        experiments: exps,
    })
}

/// [`build`] plus one more validation experiment at another whole fraction of the fast rate
/// (the smallest divisor of the rate from 2 to 10 other than the case's factor; its own noise
/// and phase seed), with the same hidden effect: data a rate-tied extension fitted on the
/// case's two experiments has never seen. Rate-tied effects only (`None` for a filter or
/// cubic stiffness, which change the drawn truth).
pub fn with_another_rate(seed: u64, effect: Effect, rec: Recording) -> Option<(Case, Experiment)> {
    if matches!(effect, Effect::Filter(_) | Effect::Cubic) {
        return None;
    }
    let case = build(seed, effect, rec)?;
    let mut r = Rng::new(seed * 7919 + 17);
    let st = stage(&mut r);
    let factor = (2..=10usize).find(|f| *f != st.factor && st.fast_rate as usize % f == 0)?;
    let x = identify(
        &st,
        &rec,
        &Exp {
            lines: Lines::Full,
            name: "other_rate",
            rate: st.fast_rate / factor as f64,
            rms: 0.5,
            ni: effect.nonideal(),
            seed: seed * 3 + 5,
            role: Role::Validation,
            signal: None,
            period: None,
        },
    )?;
    Some((case, x))
}

/// The experiment a diagnosis proposed (`sd_diagnose::NextExperiment`) run on the case of
/// `seed` with the same hidden effect: rate `rate`, `period` samples per period, `steady`
/// periods after one transient, the case's excitation level and injection, its own noise and
/// phases. Rate-tied effects only (`None` otherwise, or when the loop is unstable).
pub fn proposed(
    seed: u64,
    effect: Effect,
    rec: Recording,
    (rate, period, steady): (f64, usize, usize),
) -> Option<Experiment> {
    if matches!(effect, Effect::Filter(_) | Effect::Cubic) || !rec.periodic {
        return None;
    }
    let mut r = Rng::new(seed * 7919 + 17);
    let st = stage(&mut r);
    identify(
        &st,
        &Recording { steady, ..rec },
        &Exp {
            lines: Lines::Full,
            name: "proposed",
            rate,
            rms: 0.5,
            ni: effect.nonideal(),
            seed: seed * 3 + 7,
            role: Role::Validation,
            signal: None,
            period: Some(period),
        },
    )
}

/// +1 or −1 with equal probability.
pub fn sign(r: &mut Rng) -> f64 {
    if r.uniform() < 0.5 {
        -1.0
    } else {
        1.0
    }
}

/// A random recording: 3–8 steady periods, either injection, drift in 30 %, non-periodic in
/// 20 % of the cases (`periodic_only` for the nonlinear cases).
pub fn random_recording(r: &mut Rng, periodic_only: bool) -> Recording {
    Recording {
        steady: 3 + (r.uniform() * 6.0) as usize % 6,
        reference: r.uniform() < 0.5,
        drift: r.uniform() < 0.3,
        periodic: periodic_only || r.uniform() >= 0.2,
        full: false,
    }
}

/// The hidden-effect case of `seed`: the effect kind cycles with the seed, its size and the
/// recording are drawn; plants whose loop is unstable are redrawn.
pub fn hidden_effect(seed: u64) -> Case {
    for attempt in 0..20u64 {
        let mut r = Rng::new(seed * 104_729 + attempt * 31 + 5);
        let effect = match seed % 8 {
            0 => Effect::None,
            1 => Effect::Filter(0.0), // frequency set below from the drawn rate
            2 => Effect::Delay(r.range(0.05, 1.5)),
            3 => Effect::Averaging(r.range(0.2, 1.0)),
            4 => Effect::Clock(sign(&mut r) * r.range(0.002, 0.02)),
            5 => Effect::DelayAveraging(r.range(0.1, 0.8), r.range(0.3, 1.0)),
            6 => Effect::DelayClock(r.range(0.1, 1.0), sign(&mut r) * r.range(0.003, 0.02)),
            _ => Effect::Cubic,
        };
        let rec = random_recording(&mut r, effect == Effect::Cubic);
        let effect = match effect {
            Effect::Filter(_) => Effect::Filter(r.range(1200.0, 2400.0)),
            e => e,
        };
        if let Some(c) = build(seed * 20 + attempt, effect, rec) {
            return c;
        }
    }
    panic!("no stable plant for seed {seed}")
}

/// A consistent case for the calibration: no effect (or a common filter), `steady` periods
/// (2–10), periodic or not, either injection, white or drifting noise, all from the seed.
pub fn consistent(seed: u64) -> Case {
    for attempt in 0..20u64 {
        let mut r = Rng::new(seed * 15_485_863 + attempt * 7 + 3);
        let rec = Recording {
            steady: 2 + (r.uniform() * 9.0) as usize % 9,
            reference: r.uniform() < 0.5,
            drift: r.uniform() < 0.5,
            periodic: r.uniform() >= 0.25,
            full: false,
        };
        let effect = if r.uniform() < 0.2 {
            Effect::Filter(r.range(1200.0, 2400.0))
        } else {
            Effect::None
        };
        if let Some(c) = build(seed * 20 + attempt + 7_000_000, effect, rec) {
            return c;
        }
    }
    panic!("no stable plant for seed {seed}")
}

/// Relative frequency shift of the nonlinear mode at a level case's highest level: hardening
/// 5 %, softening 2.5 % (a softening spring's stiffness `1 + 3κq²` turns negative at the
/// peaks of a larger response and the mode escapes).
pub const SHIFT: (f64, f64) = (0.05, 0.025);

/// The amplitude behaviour of a level case.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LevelEffect {
    /// A linear stage.
    Linear,
    /// Cubic stiffness κ > 0 on the first mode.
    Hardening,
    /// Cubic stiffness κ < 0 on the first mode.
    Softening,
    /// A linear stage whose first mode's frequency rises 1 % per experiment (time, not
    /// amplitude); the last experiment repeats the first level.
    Drift,
    /// As [`LevelEffect::Drift`] without the repeat: only the absence of distortion at the
    /// non-excited lines tells the drift from an amplitude effect.
    DriftLevels,
    /// Coulomb friction on the rigid body ([`COULOMB`] of the first level's force rms).
    Coulomb,
}

/// Coulomb friction force of a [`LevelEffect::Coulomb`] case relative to the first level's
/// force rms (0.5 N).
pub const COULOMB: f64 = 0.2;

/// A case at several excitation levels, all at the fast rate.
#[derive(Debug, Clone)]
pub struct LevelCase {
    /// The behaviour.
    pub effect: LevelEffect,
    /// The recording.
    pub recording: Recording,
    /// Excitation levels (relative to the first, the model experiment).
    pub levels: Vec<f64>,
    /// The first mode's linear frequency (Hz).
    pub mode_hz: f64,
    /// The experiments (the model experiment first), named `level_<l>`.
    pub experiments: Vec<Experiment>,
    /// The truth each experiment ran on, in their order (the modes' truth:
    /// [`crate::modal_truth`]).
    pub truths: Vec<Truth>,
}

/// Rms of the steady output of `e` in the band `[lo, hi]` Hz, Hann-windowed (the diagnosis
/// computes its own).
fn band_rms_of(e: &Experiment, lo: f64, hi: f64) -> f64 {
    let start = e.spec.skip_periods * e.spec.period_samples.unwrap_or(0);
    let y = &e.y[start..];
    let n = y.len();
    // Hann window (unit mean square) on the mean-free record: a non-periodic record's slow
    // motion does not leak into the band
    let mean = y.iter().sum::<f64>() / n as f64;
    let mut buf: Vec<num_complex::Complex64> = y
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let w = (1.0 - (std::f64::consts::TAU * i as f64 / n as f64).cos()) / 2.0;
            num_complex::Complex64::new((8.0f64 / 3.0).sqrt() * w * (v - mean), 0.0)
        })
        .collect();
    rustfft::FftPlanner::new()
        .plan_fft_forward(n)
        .process(&mut buf);
    let df = e.spec.sample_rate_hz / n as f64;
    let p: f64 = (1..n / 2)
        .filter(|k| (lo..=hi).contains(&(*k as f64 * df)))
        .map(|k| buf[k].norm_sqr())
        .sum();
    (2.0 * p).sqrt() / n as f64
}

/// Gaussian white noise of `n` samples through a second-order Butterworth low-pass at
/// `0.4·fs` (bilinear transform), scaled to unit rms: a non-periodic excitation (no line grid,
/// leakage everywhere), estimated by the LPM.
pub fn filtered_noise(seed: u64, n: usize) -> Vec<f64> {
    let mut r = Rng::new(seed * 6_700_417 + 11);
    // bilinear Butterworth, cut-off ratio 0.4: K = tan(π·0.4)
    let k = (std::f64::consts::PI * 0.4).tan();
    let q = std::f64::consts::FRAC_1_SQRT_2;
    let norm = 1.0 / (1.0 + k / q + k * k);
    let b = [k * k * norm, 2.0 * k * k * norm, k * k * norm];
    let a = [2.0 * (k * k - 1.0) * norm, (1.0 - k / q + k * k) * norm];
    let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
    let mut out: Vec<f64> = (0..n)
        .map(|_| {
            let x = r.normal();
            let y = b[0] * x + b[1] * x1 + b[2] * x2 - a[0] * y1 - a[1] * y2;
            (x2, x1, y2, y1) = (x1, x, y1, y);
            y
        })
        .collect();
    let s = sd_model::rms(&out).max(f64::MIN_POSITIVE);
    out.iter_mut().for_each(|v| *v /= s);
    out
}

/// The stage of a level case and its first mode as drawn (a second mode within 15 % of the
/// first dropped: two modes that close trade their frequencies and dampings in a fit; the
/// diagnosis keeps such pairs linear).
fn level_stage(seed: u64) -> (Stage, sd_testbed::ModeSpec) {
    let mut r = Rng::new(seed * 104_729 + 5);
    let mut st = stage(&mut r);
    let m0 = st.truth.modes[0].clone();
    if st.truth.modes.len() > 1
        && (st.truth.modes[1].freq_hz / st.truth.modes[0].freq_hz - 1.0).abs() < 0.15
    {
        st.truth.modes.truncate(1);
    }
    (st, m0)
}

/// Sizes the first mode's cubic stiffness so that its equivalent-linearisation shift
/// `Δω/ω ≈ 1.5κσ²` (σ the mode's rms in its band, measured on `base`, a linear run at the
/// first level, scaled to the highest level `top`) reaches [`SHIFT`].
fn size_cubic(st: &mut Stage, effect: LevelEffect, base: &Experiment, top: f64) {
    let m0 = &st.truth.modes[0];
    let w = (3.0 * m0.zeta).max(0.02);
    let sigma = band_rms_of(base, m0.freq_hz * (1.0 - w), m0.freq_hz * (1.0 + w)) * top;
    let shift = match effect {
        LevelEffect::Hardening => SHIFT.0,
        LevelEffect::Softening => -SHIFT.1,
        _ => return,
    };
    st.truth.modes[0].cubic = shift / (1.5 * sigma * sigma);
}

/// The level case of `seed`: the drawn stage (one or two modes at least 15 % apart), the first
/// mode made amplitude-dependent by cubic stiffness (`size_cubic`), one experiment per level
/// at 0.5 N rms × level (the model experiment first). Periodic recordings: random-phase odd
/// multisines with one detection line per group of three odd lines (the same lines at every
/// level, a new phase realisation per experiment). Non-periodic: one record of
/// [`filtered_noise`] per level, as long as the periodic recording's periods together. The
/// nonlinear truth runs through the testbed's Lawson–RK4 integrator; `None` when a loop is
/// unstable.
pub fn level_case(
    seed: u64,
    effect: LevelEffect,
    levels: &[f64],
    rec: Recording,
) -> Option<LevelCase> {
    let top = levels.iter().cloned().fold(1.0, f64::max);
    level_case_sized(seed, effect, levels, rec, top)
}

/// [`level_case`] with the cubic stiffness sized for the level `top` (levels above it move
/// the mode further than [`SHIFT`]: data beyond the sized range).
pub fn level_case_sized(
    seed: u64,
    effect: LevelEffect,
    levels: &[f64],
    rec: Recording,
    top: f64,
) -> Option<LevelCase> {
    level_case_realization(seed, effect, levels, rec, top, 0)
}

/// [`level_case_sized`] with another realization of the excitation and the noise (`0`: the
/// seed's own) on the same stage: repeated experiments for the spread of an estimate.
pub fn level_case_realization(
    seed: u64,
    effect: LevelEffect,
    levels: &[f64],
    rec: Recording,
    top: f64,
    realization: u64,
) -> Option<LevelCase> {
    let (mut st, m0) = level_stage(seed);
    let noise_seed = |k: usize| seed * 11 + k as u64 + realization * 1_000_003;
    let len = st.fast_rate as usize * (1 + rec.steady);
    let exp = |st: &Stage, l: f64, k: usize| Exp {
        lines: if rec.full {
            Lines::Full
        } else {
            Lines::RandomOdd {
                group: 3,
                seed: seed + 77,
            }
        },
        name: "",
        rate: st.fast_rate,
        rms: 0.5 * l,
        ni: NonIdealities::default(),
        seed: noise_seed(k),
        role: if k == 0 {
            Role::Model
        } else {
            Role::Validation
        },
        signal: (!rec.periodic).then(|| {
            filtered_noise(noise_seed(k), len)
                .into_iter()
                .map(|v| v * 0.5 * l)
                .collect()
        }),
        period: None,
    };
    if matches!(effect, LevelEffect::Hardening | LevelEffect::Softening) {
        let base = identify(&st, &rec, &exp(&st, 1.0, 0))?;
        size_cubic(&mut st, effect, &base, top);
    }
    if effect == LevelEffect::Coulomb {
        st.truth.coulomb = COULOMB * 0.5;
    }
    if std::env::var_os("LEVEL_TRUTH").is_some() {
        eprintln!("truth {:?} rate {}", st.truth, st.fast_rate);
    }
    let mut list: Vec<f64> = levels.to_vec();
    if effect == LevelEffect::Drift {
        list.push(1.0);
    }
    let mut experiments = Vec::new();
    let mut truths = Vec::new();
    for (k, &l) in list.iter().enumerate() {
        let mut stk = Stage {
            truth: st.truth.clone(),
            ..st
        };
        if matches!(effect, LevelEffect::Drift | LevelEffect::DriftLevels) {
            stk.truth.modes[0].freq_hz = m0.freq_hz * (1.0 + 0.01 * k as f64);
        }
        let name = if k == levels.len() {
            format!("level_{l}_repeat")
        } else {
            format!("level_{l}")
        };
        let x = Exp {
            name: &name,
            ..exp(&stk, l, k)
        };
        let e = identify(&stk, &rec, &x)?;
        if e.y.iter().any(|v| !v.is_finite()) {
            return None;
        }
        experiments.push(e);
        truths.push(stk.truth);
    }
    Some(LevelCase {
        effect,
        recording: rec,
        levels: list,
        mode_hz: m0.freq_hz,
        experiments,
        truths,
    })
}

/// Level and rate changed together: the model experiment at 1×, a fast experiment at `high`×
/// and a slower one (the drawn factor) at `high`×, all periodic random-phase odd multisines
/// with detection lines; every experiment's hold switches `delay` of its own sample period
/// late. `Hardening` sizes the first mode's cubic stiffness as [`level_case`] does.
pub fn level_rate_case(
    seed: u64,
    effect: LevelEffect,
    high: f64,
    delay: f64,
    rec: Recording,
) -> Option<LevelCase> {
    let (mut st, m0) = level_stage(seed);
    let ni = NonIdealities {
        hold_delay: delay,
        ..NonIdealities::default()
    };
    let exp = |name: &'static str, rate: f64, l: f64, k: u64| Exp {
        lines: Lines::RandomOdd {
            group: 3,
            seed: seed + 77,
        },
        name,
        rate,
        rms: 0.5 * l,
        ni,
        seed: seed * 17 + k,
        role: if k == 0 {
            Role::Model
        } else {
            Role::Validation
        },
        signal: None,
        period: None,
    };
    let fast = st.fast_rate;
    if effect == LevelEffect::Hardening {
        let base = identify(&st, &rec, &exp("base", fast, 1.0, 0))?;
        size_cubic(&mut st, effect, &base, high);
    }
    let slow = fast / st.factor as f64;
    let experiments = [
        exp("fast_1", fast, 1.0, 0),
        exp("fast_high", fast, high, 1),
        exp("slow_high", slow, high, 2),
    ]
    .iter()
    .map(|x| identify(&st, &rec, x).filter(|e| e.y.iter().all(|v| v.is_finite())))
    .collect::<Option<Vec<_>>>()?;
    Some(LevelCase {
        effect,
        recording: rec,
        levels: vec![1.0, high, high],
        mode_hz: m0.freq_hz,
        truths: vec![st.truth.clone(); experiments.len()],
        experiments,
    })
}

/// One non-periodic record of [`filtered_noise`] whose amplitude steps through `levels`
/// (0.5 N rms × level, each for `1 + rec.steady` seconds), the model experiment: the diagnosis
/// must cut it into pieces of constant amplitude itself. Hardening/softening as in
/// [`level_case`] (sized on a linear record at the first level), Coulomb friction likewise.
pub fn rising_case(
    seed: u64,
    effect: LevelEffect,
    levels: &[f64],
    rec: Recording,
) -> Option<LevelCase> {
    stepped_case(seed, effect, levels, rec, 1.0)
}

/// [`rising_case`] as burst random: in each level's `1 + rec.steady` seconds the force is on
/// for the first 60 % and exactly zero for the rest (the free decay), as modal tests record.
/// The diagnosis must cut at the level changes only and keep every decay with its burst.
pub fn burst_case(
    seed: u64,
    effect: LevelEffect,
    levels: &[f64],
    rec: Recording,
) -> Option<LevelCase> {
    stepped_case(seed, effect, levels, rec, 0.6)
}

/// One record stepping through `levels`, excited for the fraction `duty` of each level.
fn stepped_case(
    seed: u64,
    effect: LevelEffect,
    levels: &[f64],
    rec: Recording,
    duty: f64,
) -> Option<LevelCase> {
    let (mut st, m0) = level_stage(seed);
    let piece = st.fast_rate as usize * (1 + rec.steady);
    let on = (duty * piece as f64).round() as usize;
    let noise = filtered_noise(seed * 13 + 1, piece * levels.len());
    let signal = |ls: &[f64]| -> Vec<f64> {
        noise
            .iter()
            .enumerate()
            .take(piece * ls.len())
            .map(|(i, v)| {
                if i % piece < on {
                    v * 0.5 * ls[i / piece]
                } else {
                    0.0
                }
            })
            .collect()
    };
    let rate = st.fast_rate;
    let exp = |ls: &[f64], name: &'static str| Exp {
        lines: Lines::Full,
        name,
        rate,
        rms: 0.5,
        ni: NonIdealities::default(),
        seed: seed * 13 + 2,
        role: Role::Model,
        signal: Some(signal(ls)),
        period: None,
    };
    let top = levels.iter().cloned().fold(1.0, f64::max);
    if matches!(effect, LevelEffect::Hardening | LevelEffect::Softening) {
        let base = identify(&st, &rec, &exp(&levels[..1], "base"))?;
        size_cubic(&mut st, effect, &base, top);
    }
    if effect == LevelEffect::Coulomb {
        st.truth.coulomb = COULOMB * 0.5;
    }
    let e = identify(&st, &rec, &exp(levels, "rising"))?;
    if e.y.iter().any(|v| !v.is_finite()) {
        return None;
    }
    Some(LevelCase {
        effect,
        recording: rec,
        levels: levels.to_vec(),
        mode_hz: m0.freq_hz,
        experiments: vec![e],
        truths: vec![st.truth],
    })
}

/// `f` of every seed, the seeds split over every core, results in seed order.
pub fn per_seed<T: Send>(seeds: std::ops::Range<u64>, f: impl Fn(u64) -> T + Sync) -> Vec<T> {
    let all: Vec<u64> = seeds.collect();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let chunk = all.len().div_ceil(threads).max(1);
    let f = &f;
    std::thread::scope(|sc| {
        let handles: Vec<_> = all
            .chunks(chunk)
            .map(|c| sc.spawn(move || c.iter().map(|&s| f(s)).collect::<Vec<_>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    })
}
