//! The testbed configuration file (`sdctl testbed --config STAGE.toml`), documented in
//! docs/formats.md. Every table and key but at least one `[[experiment]]` (with its `name` and `rate_hz`)
//! is optional; missing ones take the virtual stage's defaults (docs/stage.md). A key that is not
//! listed below is an error naming the closest allowed key, so a typo never changes a result
//! silently; `factor = 0` and a position reference above 1 cm rms are errors too.
//!
//! ```toml
//! seed = 1                         # default seed of every experiment's noise
//! [truth]
//! mass = 20.0                      # kg
//! amplifier_hz = 4000.0            # optional amplifier pole
//! viscous = 0.0                    # N·s/m
//! coulomb = 0.0                    # N (smoothed by tanh(v / coulomb_velocity))
//! coulomb_velocity = 1e-6          # m/s
//! [[truth.mode]]                   # default: 653 Hz (ζ 0.01, r 2) and 1650 Hz (ζ 0.005, r 0.3)
//! freq_hz = 653.0
//! zeta = 0.01
//! residue = 2.0
//! cubic = 0.0                      # cubic stiffness κ (1/m²)
//! [nonideal]                       # tied to each experiment's own sample period
//! hold_delay = 0.0                 # fraction of the period
//! averaging = 0.0                  # fraction of the period
//! clock_error = 0.0                # true period = nominal·(1 + clock_error)
//! quantization = 0.0               # sensor step (m)
//! [[experiment]]
//! kind = "identification"          # or "standstill"
//! name = "fast"
//! rate_hz = 5000.0                 # controller rate
//! role = "model"                   # identification only; default "validation"
//! pid_bandwidth_hz = 30.0          # PID-like controller (integrator, lead) for the mass
//! pid_lowpass_hz = 1000.0          # optional second-order low-pass in the controller
//! notch_hz = 653.0                 # optional notch in the controller (ζ 0.02 / 0.3)
//! period = 10000                   # samples per multisine period
//! periods = 6                      # periods recorded
//! transient_periods = 1
//! f_min = 1.0                      # excited band (Hz)
//! f_max = 2400.0
//! rms = 1.0                        # excitation rms: N (input), m (reference, ≤ 0.01)
//! multisine = "random"             # "random", "schroeder" or "random-odd"
//! injection = "input"              # force at the plant input (default) or "reference"
//! force_noise = 0.05               # rms per sample (N)
//! sensor_noise = 3e-10             # rms per sample (m)
//! sensor_drift = 0.0               # random-walk sensor offset, rms step per sample (m)
//! factor = 5                       # standstill: plant simulated at factor·rate_hz
//! samples = 70000                  # standstill: fast samples
//! ```

use crate::error::{Result, TestbedError};
use crate::experiments::{
    run_identification, run_standstill, ExperimentData, Identification, Injection, Noise,
    Standstill,
};
use crate::sim::NonIdealities;
use crate::truth::{ModeSpec, Truth};
use sd_ident::{Lines, Multisine, MultisineSpec, Phases, Role};
use sd_model::connect::series;
use sd_model::StateSpace;

/// A parsed configuration.
#[derive(Debug, Clone)]
pub struct TestbedConfig {
    /// The truth.
    pub truth: Truth,
    /// Non-idealities.
    pub nonideal: NonIdealities,
    /// Identification experiments.
    pub identification: Vec<Identification>,
    /// Standstill experiments.
    pub standstill: Vec<Standstill>,
}

pub(crate) fn err(m: String) -> TestbedError {
    TestbedError::Config(m)
}

const TOP_KEYS: &[&str] = &["seed", "truth", "nonideal", "experiment"];
const TRUTH_KEYS: &[&str] = &[
    "mass",
    "amplifier_hz",
    "viscous",
    "coulomb",
    "coulomb_velocity",
    "mode",
];
const MODE_KEYS: &[&str] = &["freq_hz", "zeta", "residue", "cubic"];
/// The keys of `[nonideal]` (the multi-axis configuration's too, where each may be a list).
pub(crate) const NONIDEAL_KEYS: &[&str] =
    &["hold_delay", "averaging", "clock_error", "quantization"];
/// The keys of an `[[experiment]]` table (both kinds; the module docs say which applies).
const EXPERIMENT_KEYS: &[&str] = &[
    "kind",
    "name",
    "rate_hz",
    "role",
    "seed",
    "pid_bandwidth_hz",
    "pid_lowpass_hz",
    "notch_hz",
    "period",
    "periods",
    "transient_periods",
    "f_min",
    "f_max",
    "rms",
    "multisine",
    "injection",
    "force_noise",
    "sensor_noise",
    "sensor_drift",
    "factor",
    "samples",
];
/// Plural or manifest spellings users type for config keys.
const ALIASES: &[(&str, &str)] = &[
    ("nonideals", "nonideal"),
    ("non_ideal", "nonideal"),
    ("modes", "mode"),
    ("experiments", "experiment"),
    ("sample_rate_hz", "rate_hz"),
    ("period_samples", "period"),
];
/// The most samples one experiment may simulate (per signal: 8·10⁷ f64 = 640 MB), so that a typo
/// in `period`, `periods`, `samples`, `factor` or `rate_hz` is an error instead of an
/// allocation that fails.
pub const MAX_SAMPLES: usize = 80_000_000;

/// `Err` naming the experiment and the keys when `count` samples exceed [`MAX_SAMPLES`].
pub(crate) fn within_budget(name: &str, count: Option<usize>, keys: &str) -> Result<()> {
    match count {
        Some(c) if c <= MAX_SAMPLES => Ok(()),
        _ => Err(err(format!(
            "experiment `{name}`: {keys} ask for more than {MAX_SAMPLES} samples; shorten the \
             experiment"
        ))),
    }
}

/// A position reference above this rms (m) is not a precision-stage experiment.
const MAX_REFERENCE_RMS_M: f64 = 1e-2;

/// Every key of `t` is one of `allowed` (else an error naming the key, the place and the
/// closest allowed key).
pub(crate) fn keys(t: &toml::Table, allowed: &[&str], place: &str) -> Result<()> {
    sd_model::keys::check_keys(t.keys().map(String::as_str), allowed, ALIASES, place).map_err(err)
}

/// A TOML number (float or integer) as `f64`.
pub(crate) fn as_number(v: &toml::Value) -> Option<f64> {
    v.as_float().or_else(|| v.as_integer().map(|i| i as f64))
}

pub(crate) fn num(t: &toml::Table, key: &str, default: f64) -> Result<f64> {
    match t.get(key) {
        None => Ok(default),
        Some(v) => as_number(v).ok_or_else(|| err(format!("`{key}` must be a number"))),
    }
}

pub(crate) fn opt_num(t: &toml::Table, key: &str) -> Result<Option<f64>> {
    match t.get(key) {
        None => Ok(None),
        Some(_) => num(t, key, 0.0).map(Some),
    }
}

pub(crate) fn int(t: &toml::Table, key: &str, default: usize) -> Result<usize> {
    match t.get(key) {
        None => Ok(default),
        Some(v) => match v.as_integer() {
            Some(i) if i >= 0 => Ok(i as usize),
            _ => Err(err(format!("`{key}` must be a non-negative integer"))),
        },
    }
}

pub(crate) fn text<'a>(t: &'a toml::Table, key: &str, default: &'a str) -> Result<&'a str> {
    match t.get(key) {
        None => Ok(default),
        Some(v) => v
            .as_str()
            .ok_or_else(|| err(format!("`{key}` must be a string"))),
    }
}

/// PID-like controller (sd-hinf weight) with optional low-pass and notch, at period `ts`.
fn controller(t: &toml::Table, mass: f64, ts: f64) -> Result<StateSpace> {
    let bw = num(t, "pid_bandwidth_hz", 30.0)?;
    let mut opt = sd_hinf::weights::PidOptions::default();
    if let Some(lp) = opt_num(t, "pid_lowpass_hz")? {
        opt.lowpass_ratio = lp / bw;
    }
    let mut k = sd_hinf::weights::pid(bw, mass, Some(ts), &opt)?;
    if let Some(f) = opt_num(t, "notch_hz")? {
        k = series(&k, &sd_hinf::weights::notch(f, 0.02, 0.3, Some(ts))?)?;
    }
    Ok(k)
}

/// The configuration `sdctl testbed` runs without `--config` (and `sdtoolkit.testbed()` without
/// a config): closed-loop identification of the default stage at 5 kHz (the model experiment)
/// and 1 kHz, five periods of one second each, input injection.
pub const DEFAULT_CONFIG: &str = r#"
[[experiment]]
kind = "identification"
name = "fast"
rate_hz = 5000.0
role = "model"
pid_bandwidth_hz = 30.0
pid_lowpass_hz = 1000.0
period = 5000
periods = 5
transient_periods = 1
f_min = 1.0
f_max = 2400.0
injection = "input"

[[experiment]]
kind = "identification"
name = "slow"
rate_hz = 1000.0
pid_bandwidth_hz = 20.0
period = 1000
periods = 5
transient_periods = 1
f_min = 1.0
f_max = 499.0
injection = "input"
"#;

/// Parses a configuration (module documentation).
///
/// # Errors
/// TOML syntax, wrong types, invalid values (with the experiment and key named).
pub fn parse_config(source: &str) -> Result<TestbedConfig> {
    let doc: toml::Table = source
        .parse()
        .map_err(|e: toml::de::Error| err(e.to_string().replace('\n', " ")))?;
    keys(&doc, TOP_KEYS, "the configuration's top level")?;
    let empty = toml::Table::new();
    let seed = int(&doc, "seed", 1)? as u64;
    let truth = parse_truth(table(&doc, "truth", &empty)?)?;
    let nonideal = parse_nonideal(table(&doc, "nonideal", &empty)?)?;
    let mut identification = Vec::new();
    let mut standstill = Vec::new();
    let exps = match doc.get("experiment") {
        Some(v) => v
            .as_array()
            .ok_or_else(|| err("[[experiment]] must be an array".into()))?
            .clone(),
        None => Vec::new(),
    };
    if exps.is_empty() {
        return Err(err(
            "the configuration has no [[experiment]] table, so nothing would be written: add an \
             identification or standstill experiment (the keys are in docs/formats.md)"
                .into(),
        ));
    }
    for (i, e) in exps.iter().enumerate() {
        let e = e
            .as_table()
            .ok_or_else(|| err(format!("experiment {} is not a table", i + 1)))?;
        match parse_experiment(i, e, seed, &truth, nonideal)? {
            Parsed::Identification(x) => identification.push(x),
            Parsed::Standstill(x) => standstill.push(x),
        }
    }
    Ok(TestbedConfig {
        truth,
        nonideal,
        identification,
        standstill,
    })
}

/// The table `key` of `doc` (`empty` when absent).
pub(crate) fn table<'a>(
    doc: &'a toml::Table,
    key: &str,
    empty: &'a toml::Table,
) -> Result<&'a toml::Table> {
    match doc.get(key) {
        Some(v) => v
            .as_table()
            .ok_or_else(|| err(format!("[{key}] must be a table"))),
        None => Ok(empty),
    }
}

/// `[truth]` with its `[[truth.mode]]` tables.
fn parse_truth(tt: &toml::Table) -> Result<Truth> {
    keys(tt, TRUTH_KEYS, "[truth]")?;
    let mut truth = Truth {
        mass: num(tt, "mass", 20.0)?,
        amplifier_hz: opt_num(tt, "amplifier_hz")?,
        viscous: num(tt, "viscous", 0.0)?,
        coulomb: num(tt, "coulomb", 0.0)?,
        coulomb_velocity: num(tt, "coulomb_velocity", 1e-6)?,
        ..Truth::default()
    };
    if let Some(modes) = tt.get("mode") {
        let arr = modes
            .as_array()
            .ok_or_else(|| err("[[truth.mode]] must be an array of tables".into()))?;
        truth.modes = arr
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let m = m
                    .as_table()
                    .ok_or_else(|| err(format!("truth.mode {} is not a table", i + 1)))?;
                keys(m, MODE_KEYS, &format!("[[truth.mode]] {}", i + 1))?;
                Ok(ModeSpec {
                    freq_hz: num(m, "freq_hz", f64::NAN)?,
                    zeta: num(m, "zeta", 0.01)?,
                    residue: num(m, "residue", 1.0)?,
                    cubic: num(m, "cubic", 0.0)?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
    }
    truth.validate()?;
    Ok(truth)
}

/// `[nonideal]`.
fn parse_nonideal(nt: &toml::Table) -> Result<NonIdealities> {
    keys(nt, NONIDEAL_KEYS, "[nonideal]")?;
    Ok(NonIdealities {
        hold_delay: num(nt, "hold_delay", 0.0)?,
        averaging: num(nt, "averaging", 0.0)?,
        clock_error: num(nt, "clock_error", 0.0)?,
        quantization: num(nt, "quantization", 0.0)?,
    })
}

/// One parsed `[[experiment]]`.
enum Parsed {
    Identification(Identification),
    Standstill(Standstill),
}

/// The `i`-th `[[experiment]]` table.
fn parse_experiment(
    i: usize,
    e: &toml::Table,
    seed: u64,
    truth: &Truth,
    nonideal: NonIdealities,
) -> Result<Parsed> {
    let ctx = |m: TestbedError| err(format!("experiment {}: {m}", i + 1));
    let name = text(e, "name", "")?.to_string();
    keys(
        e,
        EXPERIMENT_KEYS,
        &format!("experiment {} (`{name}`)", i + 1),
    )?;
    if name.is_empty() {
        return Err(err(format!("experiment {} needs a `name`", i + 1)));
    }
    let rate = num(e, "rate_hz", f64::NAN)?;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(err(format!("experiment `{name}`: `rate_hz` must be > 0")));
    }
    let noise = Noise {
        force_rms: num(e, "force_noise", 0.05)?,
        sensor_rms: num(e, "sensor_noise", 3e-10)?,
        sensor_drift: num(e, "sensor_drift", 0.0)?,
        seed: int(e, "seed", seed as usize)? as u64,
    };
    let k = controller(e, truth.mass, 1.0 / rate).map_err(ctx)?;
    match text(e, "kind", "identification")? {
        "identification" => {
            let injection = choice(
                e,
                &name,
                "injection",
                "input",
                &[
                    ("reference", Injection::Reference),
                    ("input", Injection::Input),
                ],
            )?;
            let excitation =
                parse_excitation(e, &name, rate, noise.seed, injection).map_err(|x| match x {
                    TestbedError::Config(_) => x,
                    other => ctx(other),
                })?;
            let (periods, transient_periods) =
                (int(e, "periods", 6)?, int(e, "transient_periods", 1)?);
            let total = periods
                .checked_add(transient_periods)
                .and_then(|p| p.checked_mul(excitation.signal.len()));
            within_budget(&name, total, "`period` × (`periods` + `transient_periods`)")?;
            Ok(Parsed::Identification(Identification {
                controller: k,
                excitation,
                periods,
                transient_periods,
                injection,
                role: choice(
                    e,
                    &name,
                    "role",
                    "validation",
                    &[("model", Role::Model), ("validation", Role::Validation)],
                )?,
                name,
                noise,
                nonideal,
                substeps: None,
                fine_steps: None,
            }))
        }
        "standstill" => {
            let factor = int(e, "factor", 5)?;
            let samples = int(e, "samples", 70_000)?;
            within_budget(&name, samples.checked_mul(factor), "`samples` × `factor`")?;
            if factor == 0 {
                return Err(err(format!(
                    "experiment `{name}`: `factor` must be ≥ 1 (the plant is simulated at \
                     factor × rate_hz)"
                )));
            }
            Ok(Parsed::Standstill(Standstill {
                name,
                controller: k,
                factor,
                samples,
                noise,
                nonideal,
            }))
        }
        other => Err(err(format!("experiment `{name}`: unknown kind `{other}`"))),
    }
}

/// The string key `key` of experiment `name` as one of `options` (`default` when absent).
pub(crate) fn choice<T: Copy>(
    e: &toml::Table,
    name: &str,
    key: &str,
    default: &str,
    options: &[(&str, T)],
) -> Result<T> {
    let v = text(e, key, default)?;
    options
        .iter()
        .find(|(k, _)| *k == v)
        .map(|(_, t)| *t)
        .ok_or_else(|| err(format!("experiment `{name}`: unknown {key} `{v}`")))
}

/// An identification experiment's multisine (`period`, `multisine`, `f_min`, `f_max`, `rms`; a
/// reference-injection `rms` is a position and is checked against [`MAX_REFERENCE_RMS_M`]).
pub(crate) fn parse_excitation(
    e: &toml::Table,
    name: &str,
    rate: f64,
    seed: u64,
    injection: Injection,
) -> Result<Multisine> {
    let rms = num(e, "rms", 1.0)?;
    if injection == Injection::Reference && rms > MAX_REFERENCE_RMS_M {
        return Err(err(format!(
            "experiment `{name}`: `rms = {rms}` with injection = \"reference\" is a {rms} m rms \
             position reference; give it in metres (a precision stage moves µm to mm, e.g. \
             rms = 1e-5) or set injection = \"input\" for a force in N"
        )));
    }
    let period = int(
        e,
        "period",
        (rate.min(MAX_SAMPLES as f64 + 1.0) as usize).max(16),
    )?;
    within_budget(
        name,
        Some(period),
        "`period` (default: one second at `rate_hz`)",
    )?;
    let kind = text(e, "multisine", "random")?;
    let lines = match kind {
        "random" | "schroeder" => Lines::Full,
        "random-odd" => Lines::RandomOdd {
            group: 3,
            seed: seed ^ 0x5eed,
        },
        other => {
            return Err(err(format!(
                "experiment `{name}`: unknown multisine `{other}`"
            )))
        }
    };
    let phases = match kind {
        "schroeder" => Phases::Schroeder,
        _ => Phases::Random {
            seed: seed.wrapping_add(7),
        },
    };
    sd_ident::design(&MultisineSpec {
        fs: rate,
        period,
        f_min: num(e, "f_min", rate / period as f64)?,
        f_max: num(e, "f_max", 0.45 * rate)?,
        lines,
        phases,
        rms,
        fold_rate_hz: None,
    })
    .map_err(Into::into)
}

/// Runs every experiment of a configuration, in order (identification, then standstill).
///
/// # Errors
/// As the experiments.
pub fn run_config(cfg: &TestbedConfig) -> Result<Vec<ExperimentData>> {
    let mut out = Vec::new();
    for e in &cfg.identification {
        out.push(run_identification(&cfg.truth, e)?);
    }
    for s in &cfg.standstill {
        let (f, sl) = run_standstill(&cfg.truth, s)?;
        out.push(f);
        out.push(sl);
    }
    Ok(out)
}
