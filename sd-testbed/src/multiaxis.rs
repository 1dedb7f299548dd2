//! The multi-axis virtual stage: several actuators and sensors, modes shared by every
//! channel.
//!
//! ```text
//! q̈_k + 2ζ_kω_k q̇_k + ω_k² q_k = b_kᵀ F        (mode k; ω_k = 0: a rigid-body mode)
//! y = Σ_k c_k q_k                               (sensor displacements, m)
//! ```
//!
//! `b_k` (1/kg, one entry per actuator) is the modal force a newton of each actuator gives
//! mode k per unit modal mass; `c_k` (one entry per sensor) the displacement of each sensor
//! per unit modal coordinate. Every mode's residue matrix `c_k b_kᵀ` has rank one (a
//! mechanical structure with proportional damping), so the transfer matrix is
//! `G(s) = Σ_k c_k b_kᵀ / (s² + 2ζ_kω_k s + ω_k²)`.
//!
//! **Experiments** ([`run_multiaxis`]) run in closed loop with a discrete `nu × ny`
//! controller (a decentralised PID pairs actuator j with sensor j, [`decentralised_pid`]),
//! the excitation added at the actuators (`u = r − K y`), white force noise on every actuator
//! and white sensor noise. The plant is simulated by the fine-step route (sub-step ZOH of the
//! continuous model, every actuator's hold switching on the sub-step grid after its own
//! delay, every sensor averaging over its own window by the trapezoidal rule: another
//! numerical form than the exact discretisation the diagnosis uses). A loop that diverges is
//! an error.

use crate::error::{Result, TestbedError};
use crate::experiments::Noise;
use crate::fine::FineStep;
use nalgebra::{DMatrix, DVector};
use sd_ident::rng::SplitMix;
use sd_ident::Role;
use sd_model::{SampleTime, StateSpace};
use std::f64::consts::PI;
use std::fmt::Write as _;

/// One mode of the multi-axis stage (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisMode {
    /// Natural frequency (Hz; 0 for a rigid-body mode).
    pub freq_hz: f64,
    /// Damping ratio.
    pub zeta: f64,
    /// Modal force per newton of each actuator (1/kg): `b_k`.
    pub input: Vec<f64>,
    /// Displacement of each sensor per unit modal coordinate: `c_k`.
    pub output: Vec<f64>,
}

/// The multi-axis stage's truth (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct MultiAxisTruth {
    /// The modes, rigid-body modes included.
    pub modes: Vec<AxisMode>,
}

impl MultiAxisTruth {
    /// A beam-like two-actuator stage with three sensors (docs/stage.md, "multi-axis"): 20 kg,
    /// 2 kg·m² about its centre, actuators at ±0.3 m, sensors at −0.3, 0 and +0.3 m; the
    /// translation and rotation rigid-body modes, a symmetric bending mode at 653 Hz (ζ 0.01),
    /// an antisymmetric mode at 1100 Hz (ζ 0.008) and an asymmetric one at 1650 Hz (ζ 0.005)
    /// that couples the axes.
    pub fn two_axis() -> Self {
        let (m, j, arm) = (20.0, 2.0, 0.3);
        let mode = |freq_hz: f64, zeta: f64, input: &[f64], output: &[f64]| AxisMode {
            freq_hz,
            zeta,
            input: input.to_vec(),
            output: output.to_vec(),
        };
        MultiAxisTruth {
            modes: vec![
                mode(0.0, 0.0, &[1.0 / m, 1.0 / m], &[1.0, 1.0, 1.0]),
                mode(0.0, 0.0, &[-arm / j, arm / j], &[-arm, 0.0, arm]),
                mode(653.0, 0.01, &[2.0 / m, 2.0 / m], &[1.0, -0.8, 1.0]),
                mode(1100.0, 0.008, &[-0.5 / m, 0.5 / m], &[-1.0, 0.0, 1.0]),
                mode(1650.0, 0.005, &[0.3 / m, 0.18 / m], &[0.5, 1.0, -0.7]),
            ],
        }
    }

    /// Actuators.
    pub fn inputs(&self) -> usize {
        self.modes.first().map_or(0, |m| m.input.len())
    }

    /// Sensors.
    pub fn outputs(&self) -> usize {
        self.modes.first().map_or(0, |m| m.output.len())
    }

    /// Checks the parameters: at least one mode, every mode with as many input and output
    /// gains as the first, finite values, frequencies and dampings ≥ 0.
    ///
    /// # Errors
    /// The first violation, naming the mode.
    pub fn validate(&self) -> Result<()> {
        let (nu, ny) = (self.inputs(), self.outputs());
        if self.modes.is_empty() || nu == 0 || ny == 0 {
            return Err(TestbedError::Config(
                "a multi-axis stage needs at least one mode with input and output gains".into(),
            ));
        }
        for (k, m) in self.modes.iter().enumerate() {
            let finite = m.input.iter().chain(&m.output).all(|v| v.is_finite());
            if m.input.len() != nu || m.output.len() != ny {
                return Err(TestbedError::Config(format!(
                    "stage mode {}: {} input and {} output gains, the first mode has {nu} and \
                     {ny} (one per actuator and per sensor)",
                    k + 1,
                    m.input.len(),
                    m.output.len()
                )));
            }
            if !(finite && m.freq_hz.is_finite() && m.freq_hz >= 0.0 && m.zeta.is_finite())
                || m.zeta < 0.0
            {
                return Err(TestbedError::Config(format!(
                    "stage mode {}: frequency and damping must be ≥ 0 and every gain finite",
                    k + 1
                )));
            }
        }
        Ok(())
    }

    /// The continuous model (two states per mode: `q_k`, `q̇_k`).
    ///
    /// # Errors
    /// Invalid parameters.
    pub fn linear_model(&self) -> Result<StateSpace> {
        self.validate()?;
        let (nu, ny, n) = (self.inputs(), self.outputs(), 2 * self.modes.len());
        let mut a = DMatrix::zeros(n, n);
        let mut b = DMatrix::zeros(n, nu);
        let mut c = DMatrix::zeros(ny, n);
        for (k, m) in self.modes.iter().enumerate() {
            let w = 2.0 * PI * m.freq_hz;
            let i = 2 * k;
            a[(i, i + 1)] = 1.0;
            a[(i + 1, i)] = -w * w;
            a[(i + 1, i + 1)] = -2.0 * m.zeta * w;
            for (j, g) in m.input.iter().enumerate() {
                b[(i + 1, j)] = *g;
            }
            for (r, g) in m.output.iter().enumerate() {
                c[(r, i)] = *g;
            }
        }
        Ok(
            StateSpace::new(a, b, c, DMatrix::zeros(ny, nu), SampleTime::Continuous)?
                .with_name("multi-axis stage truth"),
        )
    }

    /// The rigid-body gain matrix `Σ_rigid c_k b_kᵀ` (`y ≈ G_rb F/s²` at low frequency).
    pub fn rigid_gain(&self) -> DMatrix<f64> {
        let mut g = DMatrix::zeros(self.outputs(), self.inputs());
        for m in self.modes.iter().filter(|m| m.freq_hz == 0.0) {
            g += DVector::from_column_slice(&m.output)
                * DVector::from_column_slice(&m.input).transpose();
        }
        g
    }
}

/// The non-idealities of a multi-axis experiment, as fractions of its sample period.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisNonIdealities {
    /// Per actuator: hold delay.
    pub hold_delay: Vec<f64>,
    /// Per sensor: averaging window.
    pub averaging: Vec<f64>,
    /// Relative error of the sample clock (true period = nominal·(1 + clock_error)).
    pub clock_error: f64,
    /// Quantization step of every sensor (m; 0: none).
    pub quantization: f64,
}

impl AxisNonIdealities {
    /// None on `nu` actuators and `ny` sensors.
    pub fn ideal(nu: usize, ny: usize) -> Self {
        AxisNonIdealities {
            hold_delay: vec![0.0; nu],
            averaging: vec![0.0; ny],
            clock_error: 0.0,
            quantization: 0.0,
        }
    }
}

/// A multi-axis identification experiment.
#[derive(Debug, Clone)]
pub struct AxisIdentification {
    /// Unique name.
    pub name: String,
    /// Discrete `nu × ny` controller (its ts is the nominal sample period).
    pub controller: StateSpace,
    /// One period of excitation per actuator (N; all of one length).
    pub excitation: Vec<Vec<f64>>,
    /// Periods recorded in total.
    pub periods: usize,
    /// Leading transient periods (to skip in the estimate).
    pub transient_periods: usize,
    /// Noise: `force_rms` on every actuator, `sensor_rms` on every sensor.
    pub noise: Noise,
    /// Non-idealities.
    pub nonideal: AxisNonIdealities,
    /// Role in a diagnosis.
    pub role: Role,
    /// Sub-steps per period of the fine-step simulation.
    pub fine_steps: usize,
}

/// Recorded signals of one multi-axis experiment: columns `r1…`, `u1…`, `y1…`.
#[derive(Debug, Clone)]
pub struct AxisData {
    /// Name.
    pub name: String,
    /// Nominal sample rate (Hz).
    pub rate_hz: f64,
    /// Samples per period.
    pub period: usize,
    /// Transient periods.
    pub skip_periods: usize,
    /// Excitation per actuator.
    pub r: Vec<Vec<f64>>,
    /// Commanded input per actuator.
    pub u: Vec<Vec<f64>>,
    /// Measurement per sensor.
    pub y: Vec<Vec<f64>>,
    /// Role.
    pub role: Role,
}

/// A decentralised PID (sd-hinf's PID-like weight, docs/formats.md) pairing actuator j with
/// sensor j for `j < min(nu, ny)`, each for the mass `1/G_rb[j, j]` of the rigid-body gain
/// ([`MultiAxisTruth::rigid_gain`]), with a low-pass at `lowpass_hz` when given; sensors
/// beyond the pairs are not fed back.
///
/// # Errors
/// A pair whose rigid-body gain is not positive (actuator and sensor not collocated), the
/// weight's errors.
pub fn decentralised_pid(
    truth: &MultiAxisTruth,
    bandwidth_hz: f64,
    lowpass_hz: Option<f64>,
    ts: f64,
) -> Result<StateSpace> {
    let g = truth.rigid_gain();
    let (nu, ny) = (truth.inputs(), truth.outputs());
    let mut opt = sd_hinf::weights::PidOptions::default();
    if let Some(lp) = lowpass_hz {
        opt.lowpass_ratio = lp / bandwidth_hz;
    }
    let mut k: Option<StateSpace> = None;
    for j in 0..nu.min(ny) {
        if g[(j, j)].is_nan() || g[(j, j)] <= 0.0 {
            return Err(TestbedError::Config(format!(
                "actuator {} and sensor {} are not collocated (rigid-body gain {:.3e}): no \
                 decentralised PID for the pair",
                j + 1,
                j + 1,
                g[(j, j)]
            )));
        }
        let kj = sd_hinf::weights::pid(bandwidth_hz, 1.0 / g[(j, j)], Some(ts), &opt)?;
        k = Some(match k {
            None => kj,
            Some(prev) => sd_model::append(&prev, &kj)?,
        });
    }
    let k = k.ok_or_else(|| TestbedError::Config("no actuator–sensor pair".into()))?;
    // zero columns for the sensors beyond the pairs
    let b = DMatrix::from_fn(
        k.n(),
        ny,
        |r, c| if c < k.nu() { k.b()[(r, c)] } else { 0.0 },
    );
    let d = DMatrix::from_fn(nu, ny, |r, c| if c < k.nu() { k.d()[(r, c)] } else { 0.0 });
    Ok(StateSpace::new(
        k.a().clone(),
        b,
        k.c().clone(),
        d,
        k.time(),
    )?)
}

/// A discrete controller stepped sample by sample.
struct Stepper {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    d: DMatrix<f64>,
    x: DVector<f64>,
}

impl Stepper {
    fn step(&mut self, e: &DVector<f64>) -> DVector<f64> {
        let out = &self.c * &self.x + &self.d * e;
        self.x = &self.a * &self.x + &self.b * e;
        out
    }
}

/// Runs a multi-axis identification experiment (module documentation).
///
/// # Errors
/// Invalid truth, controller, excitation or non-idealities; a diverging loop.
pub fn run_multiaxis(truth: &MultiAxisTruth, exp: &AxisIdentification) -> Result<AxisData> {
    let model = truth.linear_model()?;
    let (nu, ny) = (truth.inputs(), truth.outputs());
    let k = &exp.controller;
    let ts = k.ts().ok_or_else(|| {
        TestbedError::Config("the controller must be discrete (its ts sets the rate)".into())
    })?;
    if k.nu() != ny || k.ny() != nu {
        return Err(TestbedError::Config(format!(
            "experiment `{}`: the controller is {}x{}, the stage needs {nu}x{ny} (actuators × \
             sensors)",
            exp.name,
            k.ny(),
            k.nu()
        )));
    }
    let period = exp.excitation.first().map_or(0, Vec::len);
    if exp.excitation.len() != nu || period == 0 || exp.excitation.iter().any(|e| e.len() != period)
    {
        return Err(TestbedError::Config(format!(
            "experiment `{}`: one excitation period per actuator ({nu}), all of one length",
            exp.name
        )));
    }
    if exp.periods <= exp.transient_periods {
        return Err(TestbedError::Config(
            "periods must exceed transient_periods".into(),
        ));
    }
    let ni = &exp.nonideal;
    if !(ni.clock_error.is_finite() && ni.clock_error.abs() < 0.5 && ni.quantization >= 0.0) {
        return Err(TestbedError::Config(
            "clock_error must be a small relative error and quantization ≥ 0".into(),
        ));
    }
    let h = ts * (1.0 + ni.clock_error);
    let mut plant = FineStep::new(&model, h, exp.fine_steps, &ni.hold_delay, &ni.averaging)?;
    let mut ctl = Stepper {
        a: k.a().clone(),
        b: k.b().clone(),
        c: k.c().clone(),
        d: k.d().clone(),
        x: DVector::zeros(k.n()),
    };
    let mut rng = SplitMix::new(exp.noise.seed);
    let total = period * exp.periods;
    let mut data = AxisData {
        name: exp.name.clone(),
        rate_hz: 1.0 / ts,
        period,
        skip_periods: exp.transient_periods,
        r: vec![Vec::with_capacity(total); nu],
        u: vec![Vec::with_capacity(total); nu],
        y: vec![Vec::with_capacity(total); ny],
        role: exp.role,
    };
    let quantise = |v: f64| {
        if ni.quantization > 0.0 {
            ni.quantization * (v / ni.quantization).round()
        } else {
            v
        }
    };
    let mut force = vec![0.0; nu];
    for t in 0..total {
        let mut y = plant.measure();
        for v in y.iter_mut() {
            *v = quantise(*v) + exp.noise.sensor_rms * rng.normal();
        }
        let ku = ctl.step(&y);
        for j in 0..nu {
            let r = exp.excitation[j][t % period];
            let u = r - ku[j];
            data.r[j].push(r);
            data.u[j].push(u);
            force[j] = u + exp.noise.force_rms * rng.normal();
        }
        for (i, v) in y.iter().enumerate() {
            data.y[i].push(*v);
        }
        plant.step(&force);
    }
    diverged(&data)?;
    Ok(data)
}

/// `Err` when the last period's output rms exceeds 10⁴ times the first steady period's (or
/// anything is not finite): the loop is unstable.
fn diverged(d: &AxisData) -> Result<()> {
    let rms = |x: &[f64]| (x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt();
    for (i, y) in d.y.iter().enumerate() {
        let first = &y[d.skip_periods * d.period..(d.skip_periods + 1) * d.period];
        let last = &y[y.len() - d.period..];
        if !y.iter().all(|v| v.is_finite()) || rms(last) > 1e4 * rms(first).max(f64::MIN_POSITIVE) {
            return Err(TestbedError::Unstable(format!(
                "experiment `{}`: sensor {} diverges (closed loop unstable); lower the PID \
                 bandwidth",
                d.name,
                i + 1
            )));
        }
    }
    Ok(())
}

impl AxisData {
    /// Column names: `r1…`, `u1…`, `y1…`.
    fn columns(&self) -> (Vec<String>, Vec<String>, Vec<String>) {
        let name = |p: &str, n: usize| (1..=n).map(|i| format!("{p}{i}")).collect::<Vec<_>>();
        (
            name("r", self.r.len()),
            name("u", self.u.len()),
            name("y", self.y.len()),
        )
    }

    /// The CSV text (header `t,r1,…,u1,…,y1,…`).
    pub fn csv(&self) -> String {
        let (rn, un, yn) = self.columns();
        let n = self.u.first().map_or(0, Vec::len);
        let mut s = String::with_capacity(n * 16 * (rn.len() + un.len() + yn.len() + 1));
        let header: Vec<&str> = std::iter::once("t")
            .chain(rn.iter().chain(&un).chain(&yn).map(String::as_str))
            .collect();
        s.push_str(&header.join(","));
        s.push('\n');
        let dt = 1.0 / self.rate_hz;
        for i in 0..n {
            let _ = write!(s, "{:e}", i as f64 * dt);
            for col in self.r.iter().chain(&self.u).chain(&self.y) {
                let _ = write!(s, ",{:e}", col[i]);
            }
            s.push('\n');
        }
        s
    }

    /// The experiment as `sd-ident` reads it from this data's manifest entry and CSV.
    pub fn to_experiment(&self) -> sd_ident::Experiment {
        let (rn, un, yn) = self.columns();
        let rest = |v: &[String]| v.iter().skip(1).cloned().collect::<Vec<_>>();
        let tail = |v: &[Vec<f64>]| v.iter().skip(1).cloned().collect::<Vec<_>>();
        sd_ident::Experiment {
            spec: sd_ident::ExperimentSpec {
                name: self.name.clone(),
                file: format!("{}.csv", self.name),
                sample_rate_hz: self.rate_hz,
                period_samples: Some(self.period),
                skip_periods: self.skip_periods,
                reference: rn.first().cloned(),
                input: un[0].clone(),
                output: yn[0].clone(),
                role: self.role,
                extra: sd_ident::ExtraColumns {
                    inputs: rest(&un),
                    outputs: rest(&yn),
                    references: rest(&rn),
                },
            },
            r: self.r.first().cloned(),
            u: self.u[0].clone(),
            y: self.y[0].clone(),
            extra: sd_ident::ExtraSignals {
                u: tail(&self.u),
                y: tail(&self.y),
                r: tail(&self.r),
            },
        }
    }

    /// The `[[experiment]]` table of this experiment (lists of columns, docs/formats.md).
    pub(crate) fn manifest_table(&self) -> toml::Table {
        let (rn, un, yn) = self.columns();
        let list = |v: Vec<String>| toml::Value::Array(v.into_iter().map(Into::into).collect());
        let mut t = toml::Table::new();
        t.insert("name".into(), self.name.clone().into());
        t.insert("file".into(), format!("{}.csv", self.name).into());
        t.insert("sample_rate_hz".into(), self.rate_hz.into());
        t.insert("period_samples".into(), (self.period as i64).into());
        t.insert("skip_periods".into(), (self.skip_periods as i64).into());
        t.insert("reference".into(), list(rn));
        t.insert("input".into(), list(un));
        t.insert("output".into(), list(yn));
        if self.role == Role::Model {
            t.insert("role".into(), "model".into());
        }
        t
    }
}

/// A manifest listing multi-axis experiments.
pub fn axis_manifest(experiments: &[AxisData]) -> String {
    crate::experiments::manifest_of(experiments.iter().map(AxisData::manifest_table))
}
