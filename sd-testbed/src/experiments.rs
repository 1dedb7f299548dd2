//! Experiments on the virtual stage, producing data in the docs/formats.md format.
//!
//! - **Identification** ([`run_identification`]): closed loop with a stabilizing discrete
//!   controller at the experiment's rate (checked on the exact LTI model; an unstable loop is an
//!   error), a periodic multisine injected at the plant input (`u = r − K y`) or as a reference
//!   (`u = K(r − y)`), white force noise at the plant input and white sensor noise, transient
//!   periods first. Columns `r`, `u`, `y`.
//! - **Standstill** ([`run_standstill`]): reference zero, a slow controller (period F·h) around
//!   the plant simulated at the fast period h, force and sensor noise at the fast rate; the
//!   measured error is recorded at both rates (the paper's Fig. 6).
//!
//! Noise is seeded (SplitMix64), so every experiment is reproducible. The library returns the
//! data and the CSV/TOML texts; `sdctl testbed` writes the files.

use crate::error::{Result, TestbedError};
use crate::sim::{NonIdealities, PlantSim};
use crate::truth::Truth;
use nalgebra::DVector;
use sd_ident::rng::SplitMix;
use sd_ident::{Multisine, Role};
use sd_model::{SampleTime, StateSpace};
use std::fmt::Write as _;

/// Where the excitation enters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Injection {
    /// Added to the controller output: `u = r − K y`.
    Input,
    /// As the reference: `u = K(r − y)`.
    Reference,
}

/// Noise levels (rms per sample) and the seed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// White force noise at the plant input (N).
    pub force_rms: f64,
    /// White sensor noise on the measurement (m).
    pub sensor_rms: f64,
    /// A drifting sensor offset: a random walk with this rms step per sample (m; 0: none).
    pub sensor_drift: f64,
    /// Seed of the generator.
    pub seed: u64,
}

/// An identification experiment.
#[derive(Debug, Clone)]
pub struct Identification {
    /// Unique name.
    pub name: String,
    /// Controller at the experiment's rate (its ts is the nominal sample period).
    pub controller: StateSpace,
    /// One period of excitation at that rate.
    pub excitation: Multisine,
    /// Periods recorded in total.
    pub periods: usize,
    /// Leading transient periods (to skip in the estimate).
    pub transient_periods: usize,
    /// Injection point.
    pub injection: Injection,
    /// Noise.
    pub noise: Noise,
    /// Non-idealities.
    pub nonideal: NonIdealities,
    /// Role in a diagnosis.
    pub role: Role,
    /// Integrator substeps per period for a nonlinear truth (default: automatic).
    pub substeps: Option<usize>,
    /// Simulate a linear truth by the fine-step route with this many sub-steps per period
    /// ([`PlantSim::fine_step`]) instead of the exact discretisation (`None`: exact).
    pub fine_steps: Option<usize>,
}

/// A standstill experiment.
#[derive(Debug, Clone)]
pub struct Standstill {
    /// Name (files `<name>_fast.csv`, `<name>_slow.csv`).
    pub name: String,
    /// Slow controller (period F·h).
    pub controller: StateSpace,
    /// F.
    pub factor: usize,
    /// Fast samples to simulate.
    pub samples: usize,
    /// Noise at the fast rate.
    pub noise: Noise,
    /// Non-idealities of the slow loop, as fractions of the controller's period T = F·h: the
    /// hold switches α·T late and the controller's sensor averages over the last β·T (clock
    /// error and quantization as in the identification experiments). The fast record samples
    /// the position ideally (the error between the controller's samples).
    pub nonideal: NonIdealities,
}

/// Recorded signals of one experiment.
#[derive(Debug, Clone)]
pub struct ExperimentData {
    /// Name.
    pub name: String,
    /// Nominal sample rate (Hz), as written in the manifest.
    pub rate_hz: f64,
    /// Samples per period (periodic excitation).
    pub period: Option<usize>,
    /// Transient periods.
    pub skip_periods: usize,
    /// Reference / excitation, if any.
    pub r: Option<Vec<f64>>,
    /// Plant input as commanded.
    pub u: Vec<f64>,
    /// Measured output.
    pub y: Vec<f64>,
    /// Role.
    pub role: Role,
}

fn controller_check(k: &StateSpace) -> Result<f64> {
    let ts = k.ts().ok_or_else(|| {
        TestbedError::Config(
            "the controller must be a discrete model (its ts sets the rate)".into(),
        )
    })?;
    if k.nu() != 1 || k.ny() != 1 {
        return Err(TestbedError::Config("the controller must be SISO".into()));
    }
    Ok(ts)
}

/// Checks that K stabilizes the exact LTI model of the truth at its rate.
fn check_stable(truth: &Truth, k: &StateSpace, ni: &NonIdealities) -> Result<()> {
    let ts = k.ts().unwrap_or(1.0) * (1.0 + ni.clock_error);
    let pd = sd_multirate::c2d_nonideal(
        &truth.linear_model()?,
        ts,
        sd_multirate::NonIdeal {
            hold_delay: ni.hold_delay,
            averaging: ni.averaging,
        },
    )?;
    let pd = StateSpace::new(
        pd.a().clone(),
        pd.b().clone(),
        pd.c().clone(),
        pd.d().clone(),
        k.time(),
    )?;
    let cl = sd_model::connect::feedback(&pd, k, -1.0)?;
    let r = cl.poles()?.iter().map(|z| z.norm()).fold(0.0, f64::max);
    if r >= 1.0 {
        return Err(TestbedError::Unstable(format!(
            "the identification controller does not stabilize the stage (closed-loop spectral \
             radius {r:.6}); lower its bandwidth or add a notch/low-pass"
        )));
    }
    Ok(())
}

struct Controller {
    a: nalgebra::DMatrix<f64>,
    b: DVector<f64>,
    c: DVector<f64>,
    d: f64,
    x: DVector<f64>,
}

impl Controller {
    fn new(k: &StateSpace) -> Self {
        Controller {
            a: k.a().clone(),
            b: k.b().column(0).into_owned(),
            c: k.c().row(0).transpose(),
            d: k.d()[(0, 0)],
            x: DVector::zeros(k.n()),
        }
    }
    fn step(&mut self, e: f64) -> f64 {
        let out = self.c.dot(&self.x) + self.d * e;
        let xn = &self.a * &self.x + &self.b * e;
        self.x = xn;
        out
    }
}

/// Runs an identification experiment (module documentation).
///
/// # Errors
/// Invalid truth, controller or non-idealities; a controller that does not stabilize the stage.
pub fn run_identification(truth: &Truth, exp: &Identification) -> Result<ExperimentData> {
    let ts = controller_check(&exp.controller)?;
    let fs = 1.0 / ts;
    if (exp.excitation.fs - fs).abs() > 1e-9 * fs {
        return Err(TestbedError::Config(format!(
            "the excitation is designed for {} Hz but the controller runs at {fs} Hz",
            exp.excitation.fs
        )));
    }
    if exp.periods <= exp.transient_periods {
        return Err(TestbedError::Config(
            "periods must exceed transient_periods".into(),
        ));
    }
    check_stable(truth, &exp.controller, &exp.nonideal)?;
    let mut plant = match exp.fine_steps {
        Some(n) => PlantSim::fine_step(truth, ts, &exp.nonideal, n)?,
        None => PlantSim::new(truth, ts, &exp.nonideal, exp.substeps, false)?,
    };
    let mut k = Controller::new(&exp.controller);
    let mut rng = SplitMix::new(exp.noise.seed);
    let r = exp.excitation.repeat(exp.periods);
    let mut u = Vec::with_capacity(r.len());
    let mut y = Vec::with_capacity(r.len());
    let mut drift = 0.0;
    for &rk in &r {
        if exp.noise.sensor_drift > 0.0 {
            drift += exp.noise.sensor_drift * rng.normal();
        }
        let ym = plant.measure() + exp.noise.sensor_rms * rng.normal() + drift;
        let uk = match exp.injection {
            Injection::Input => rk - k.step(ym),
            Injection::Reference => k.step(rk - ym),
        };
        plant.step(uk + exp.noise.force_rms * rng.normal());
        u.push(uk);
        y.push(ym);
    }
    Ok(ExperimentData {
        name: exp.name.clone(),
        rate_hz: fs,
        period: Some(exp.excitation.signal.len()),
        skip_periods: exp.transient_periods,
        r: Some(r),
        u,
        y,
        role: exp.role,
    })
}

/// Runs a standstill experiment; returns the fast-rate and the slow-rate records.
///
/// # Errors
/// Invalid settings; a controller period that is not F·h is impossible by construction.
pub fn run_standstill(truth: &Truth, exp: &Standstill) -> Result<(ExperimentData, ExperimentData)> {
    let t = controller_check(&exp.controller)?;
    if exp.factor == 0 {
        return Err(TestbedError::Config("factor must be ≥ 1".into()));
    }
    let h = t / exp.factor as f64;
    let ni = exp.nonideal;
    ni.validate()?;
    // αT = (m + φ)h: m whole fast samples of input delay, the fast hold switching φh late;
    // βT = (q + r)h: q whole fast windows and the last r of the one before (exact for any α, β)
    let split = |x: f64| {
        let whole = (x + 1e-9).floor();
        (whole as usize, (x - whole).max(0.0))
    };
    let f = exp.factor as f64;
    let (m, phi) = split(ni.hold_delay * f);
    let (q, r) = split(ni.averaging * f);
    let base = NonIdealities {
        hold_delay: phi,
        averaging: 0.0,
        ..ni
    };
    let sim =
        |averaging: f64| PlantSim::new(truth, h, &NonIdealities { averaging, ..base }, None, false);
    let mut plant = sim(0.0)?;
    let mut full = if q > 0 { Some(sim(1.0)?) } else { None };
    let mut part = if r > 0.0 { Some(sim(r)?) } else { None };
    let mut k = Controller::new(&exp.controller);
    let mut rng = SplitMix::new(exp.noise.seed);
    let n = exp.samples;
    let (mut uf, mut yf, mut us, mut ys) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::new(),
        Vec::new(),
    );
    let mut uk = 0.0;
    // the commanded input over the last m fast samples (the delayed hold), the last q full
    // windows and the last q + 1 partial ones (the averaging sensor)
    let mut pending: std::collections::VecDeque<f64> =
        std::collections::VecDeque::from(vec![0.0; m]);
    let mut fulls: std::collections::VecDeque<f64> = std::collections::VecDeque::from(vec![0.0; q]);
    let mut parts: std::collections::VecDeque<f64> =
        std::collections::VecDeque::from(vec![0.0; q + 1]);
    for j in 0..n {
        let noise = exp.noise.sensor_rms * rng.normal();
        let ym = plant.measure() + noise;
        if let Some(p) = &full {
            fulls.pop_front();
            fulls.push_back(p.measure());
        }
        if let Some(p) = &part {
            parts.pop_front();
            parts.push_back(p.measure());
        }
        if j % exp.factor == 0 {
            let sensed = if q > 0 || r > 0.0 {
                (fulls.iter().sum::<f64>() + r * parts[0]) / (q as f64 + r) + noise
            } else {
                ym
            };
            uk = -k.step(sensed);
            us.push(uk);
            ys.push(sensed);
        }
        pending.push_back(uk);
        let applied = pending.pop_front().unwrap_or(uk);
        let force = applied + exp.noise.force_rms * rng.normal();
        plant.step(force);
        if let Some(p) = &mut full {
            p.step(force);
        }
        if let Some(p) = &mut part {
            p.step(force);
        }
        uf.push(applied);
        yf.push(ym);
    }
    let mk = |suffix: &str, rate: f64, u: Vec<f64>, y: Vec<f64>| ExperimentData {
        name: format!("{}_{suffix}", exp.name),
        rate_hz: rate,
        period: None,
        skip_periods: 0,
        r: None,
        u,
        y,
        role: Role::Validation,
    };
    Ok((mk("fast", 1.0 / h, uf, yf), mk("slow", 1.0 / t, us, ys)))
}

impl ExperimentData {
    /// The CSV text (header `t,r,u,y` or `t,u,y`).
    pub fn csv(&self) -> String {
        let mut s = String::with_capacity(self.u.len() * 64);
        let dt = 1.0 / self.rate_hz;
        if self.r.is_some() {
            s.push_str("t,r,u,y\n");
        } else {
            s.push_str("t,u,y\n");
        }
        for i in 0..self.u.len() {
            let _ = match &self.r {
                Some(r) => writeln!(
                    s,
                    "{:e},{:e},{:e},{:e}",
                    i as f64 * dt,
                    r[i],
                    self.u[i],
                    self.y[i]
                ),
                None => writeln!(s, "{:e},{:e},{:e}", i as f64 * dt, self.u[i], self.y[i]),
            };
        }
        s
    }

    /// The experiment as `sd-ident` reads it from this data's manifest entry and CSV.
    pub fn to_experiment(&self) -> sd_ident::Experiment {
        sd_ident::Experiment {
            spec: sd_ident::ExperimentSpec {
                name: self.name.clone(),
                file: format!("{}.csv", self.name),
                sample_rate_hz: self.rate_hz,
                period_samples: self.period,
                skip_periods: self.skip_periods,
                reference: self.r.as_ref().map(|_| "r".to_string()),
                input: "u".into(),
                output: "y".into(),
                role: self.role,
                extra: Default::default(),
            },
            r: self.r.clone(),
            u: self.u.clone(),
            y: self.y.clone(),
            extra: Default::default(),
        }
    }

    /// The `[[experiment]]` table of this experiment (file `<name>.csv`; docs/formats.md).
    fn manifest_table(&self) -> toml::Table {
        let mut t = toml::Table::new();
        let mut put = |k: &str, v: toml::Value| {
            t.insert(k.into(), v);
        };
        put("name", self.name.clone().into());
        put("file", format!("{}.csv", self.name).into());
        put("sample_rate_hz", self.rate_hz.into());
        if let Some(p) = self.period {
            put("period_samples", (p as i64).into());
            put("skip_periods", (self.skip_periods as i64).into());
        }
        if self.r.is_some() {
            put("reference", "r".into());
        }
        put("input", "u".into());
        put("output", "y".into());
        if self.role == Role::Model {
            put("role", "model".into());
        }
        t
    }
}

/// A manifest listing the experiments.
///
/// Written with the `toml` serializer, so any experiment name is quoted and escaped.
pub fn manifest(experiments: &[ExperimentData]) -> String {
    manifest_of(experiments.iter().map(ExperimentData::manifest_table))
}

/// A manifest of `[[experiment]]` tables (single- and multi-axis alike).
pub(crate) fn manifest_of(tables: impl Iterator<Item = toml::Table>) -> String {
    let mut doc = toml::Table::new();
    doc.insert(
        "experiment".into(),
        toml::Value::Array(tables.map(toml::Value::Table).collect()),
    );
    toml::to_string(&doc).unwrap_or_default()
}

/// The files `sdctl testbed` (and `sdtoolkit.testbed(out=...)`) write, as (file name, text):
/// each experiment's `<name>.csv`, the manifest `experiments.toml` and the continuous truth
/// `truth.json` (model JSON).
///
/// # Errors
/// The truth model cannot be written as JSON.
pub fn output_files(data: &[ExperimentData], truth: &StateSpace) -> Result<Vec<(String, String)>> {
    let mut files: Vec<(String, String)> = data
        .iter()
        .map(|d| (format!("{}.csv", d.name), d.csv()))
        .collect();
    files.push(("experiments.toml".into(), manifest(data)));
    files.push(("truth.json".into(), sd_model::model_to_json_string(truth)?));
    Ok(files)
}

/// The continuous truth (linear part) as a model, for export.
pub fn truth_model(truth: &Truth) -> Result<StateSpace> {
    let m = truth.linear_model()?;
    Ok(StateSpace::new(
        m.a().clone(),
        m.b().clone(),
        m.c().clone(),
        m.d().clone(),
        SampleTime::Continuous,
    )?
    .with_name("virtual stage truth (linear part)"))
}
