//! The multi-axis stage's configuration (`sdctl testbed --config` with a `[stage]` table
//! instead of `[truth]`), documented in docs/formats.md. As for the single-axis stage every
//! key is checked (a typo is an error naming the closest allowed key) and every table but
//! one `[[experiment]]` is optional.
//!
//! ```toml
//! seed = 1
//! [stage]                          # default modes: MultiAxisTruth::two_axis (docs/stage.md)
//! [[stage.mode]]                   # one per mode, rigid-body modes with freq_hz = 0
//! freq_hz = 653.0
//! zeta = 0.01
//! input = [0.1, 0.1]               # modal force per newton of each actuator (1/kg)
//! output = [1.0, -0.8, 1.0]        # displacement of each sensor per modal coordinate
//! [nonideal]                       # a number applies to every channel, a list to each
//! hold_delay = [0.0, 0.3]          # per actuator, fraction of the period
//! averaging = 0.0                  # per sensor, fraction of the period
//! clock_error = 0.0
//! quantization = 0.0
//! [[experiment]]                   # one experiment per actuator: `<name>_1`, `<name>_2`, …
//! name = "fast"
//! rate_hz = 5000.0
//! role = "model"                   # of every experiment of the set
//! excite = "orthogonal"            # orthogonal multisines, or "each": one actuator at a time
//! pid_bandwidth_hz = 20.0          # decentralised PID (actuator j with sensor j)
//! pid_lowpass_hz = 1000.0
//! period = 5000
//! periods = 6
//! transient_periods = 1
//! f_min = 1.0
//! f_max = 2400.0
//! rms = 1.0                        # N per actuator
//! multisine = "random"             # "random", "schroeder" or "random-odd"
//! force_noise = 0.02               # N rms per sample on every actuator
//! sensor_noise = 1e-10             # m rms per sample on every sensor
//! fine_steps = 16                  # sub-steps per period of the fine-step simulation
//! ```

use crate::config::{
    as_number, choice, err, int, keys, num, opt_num, parse_excitation, table, text, within_budget,
};
use crate::error::Result;
use crate::experiments::{Injection, Noise};
use crate::multiaxis::{
    axis_manifest, decentralised_pid, run_multiaxis, AxisData, AxisIdentification, AxisMode,
    AxisNonIdealities, MultiAxisTruth,
};
use sd_ident::Role;

const TOP_KEYS: &[&str] = &["seed", "stage", "nonideal", "experiment"];
const STAGE_KEYS: &[&str] = &["mode"];
const MODE_KEYS: &[&str] = &["freq_hz", "zeta", "input", "output"];
use crate::config::NONIDEAL_KEYS;
const EXPERIMENT_KEYS: &[&str] = &[
    "kind",
    "name",
    "rate_hz",
    "role",
    "seed",
    "excite",
    "pid_bandwidth_hz",
    "pid_lowpass_hz",
    "period",
    "periods",
    "transient_periods",
    "f_min",
    "f_max",
    "rms",
    "multisine",
    "force_noise",
    "sensor_noise",
    "fine_steps",
];

/// A parsed multi-axis configuration.
#[derive(Debug, Clone)]
pub struct AxisConfig {
    /// The stage.
    pub truth: MultiAxisTruth,
    /// The experiments, one per actuator and `[[experiment]]`.
    pub experiments: Vec<AxisIdentification>,
}

/// Files to write: (file name, text).
pub type Files = Vec<(String, String)>;

/// Whether a configuration describes a multi-axis stage (it has a `[stage]` table).
pub fn is_multiaxis(source: &str) -> bool {
    source
        .parse::<toml::Table>()
        .is_ok_and(|d| d.contains_key("stage"))
}

/// A list of numbers, or one number for every one of `n` channels.
fn per_channel(t: &toml::Table, key: &str, n: usize, what: &str) -> Result<Vec<f64>> {
    match t.get(key) {
        None => Ok(vec![0.0; n]),
        Some(toml::Value::Array(a)) => {
            let v: Option<Vec<f64>> = a.iter().map(as_number).collect();
            match v {
                Some(v) if v.len() == n => Ok(v),
                _ => Err(err(format!(
                    "`{key}` must be a number or a list of {n} numbers (one per {what})"
                ))),
            }
        }
        Some(_) => Ok(vec![num(t, key, 0.0)?; n]),
    }
}

/// A list of numbers of any length (a mode's gains).
fn gains(t: &toml::Table, key: &str, place: &str) -> Result<Vec<f64>> {
    let bad = || err(format!("{place}: `{key}` must be a list of numbers"));
    let a = t.get(key).and_then(|v| v.as_array()).ok_or_else(bad)?;
    a.iter()
        .map(as_number)
        .collect::<Option<Vec<f64>>>()
        .ok_or_else(bad)
}

/// `[stage]` with its `[[stage.mode]]` tables (default: the two-axis stage).
fn parse_stage(st: &toml::Table) -> Result<MultiAxisTruth> {
    keys(st, STAGE_KEYS, "[stage]")?;
    let Some(modes) = st.get("mode") else {
        return Ok(MultiAxisTruth::two_axis());
    };
    let arr = modes
        .as_array()
        .ok_or_else(|| err("[[stage.mode]] must be an array of tables".into()))?;
    let modes = arr
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let place = format!("[[stage.mode]] {}", i + 1);
            let m = m
                .as_table()
                .ok_or_else(|| err(format!("{place} is not a table")))?;
            keys(m, MODE_KEYS, &place)?;
            Ok(AxisMode {
                freq_hz: num(m, "freq_hz", f64::NAN)?,
                zeta: num(m, "zeta", 0.01)?,
                input: gains(m, "input", &place)?,
                output: gains(m, "output", &place)?,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let truth = MultiAxisTruth { modes };
    truth.validate()?;
    Ok(truth)
}

/// Parses a multi-axis configuration (module documentation).
///
/// # Errors
/// TOML syntax, unknown keys, wrong types or list lengths, invalid values, a standstill
/// experiment (single-axis only).
pub fn parse_axis_config(source: &str) -> Result<AxisConfig> {
    let doc: toml::Table = source
        .parse()
        .map_err(|e: toml::de::Error| err(e.to_string().replace('\n', " ")))?;
    keys(&doc, TOP_KEYS, "the configuration's top level")?;
    let empty = toml::Table::new();
    let seed = int(&doc, "seed", 1)? as u64;
    let truth = parse_stage(table(&doc, "stage", &empty)?)?;
    let (nu, ny) = (truth.inputs(), truth.outputs());
    let nt = table(&doc, "nonideal", &empty)?;
    keys(nt, NONIDEAL_KEYS, "[nonideal]")?;
    let nonideal = AxisNonIdealities {
        hold_delay: per_channel(nt, "hold_delay", nu, "actuator")?,
        averaging: per_channel(nt, "averaging", ny, "sensor")?,
        clock_error: num(nt, "clock_error", 0.0)?,
        quantization: num(nt, "quantization", 0.0)?,
    };
    let exps = doc
        .get("experiment")
        .and_then(|v| v.as_array())
        .filter(|a| !a.is_empty())
        .ok_or_else(|| {
            err("the configuration has no [[experiment]] table: add one (docs/formats.md)".into())
        })?;
    let mut experiments = Vec::new();
    for (i, e) in exps.iter().enumerate() {
        let e = e
            .as_table()
            .ok_or_else(|| err(format!("experiment {} is not a table", i + 1)))?;
        experiments.extend(parse_axis_experiment(i, e, seed, &truth, &nonideal)?);
    }
    Ok(AxisConfig { truth, experiments })
}

/// The `i`-th `[[experiment]]`: one experiment per actuator.
fn parse_axis_experiment(
    i: usize,
    e: &toml::Table,
    seed: u64,
    truth: &MultiAxisTruth,
    nonideal: &AxisNonIdealities,
) -> Result<Vec<AxisIdentification>> {
    let name = text(e, "name", "")?.to_string();
    keys(
        e,
        EXPERIMENT_KEYS,
        &format!("experiment {} (`{name}`)", i + 1),
    )?;
    if name.is_empty() {
        return Err(err(format!("experiment {} needs a `name`", i + 1)));
    }
    if text(e, "kind", "identification")? != "identification" {
        return Err(err(format!(
            "experiment `{name}`: a multi-axis stage runs identification experiments only"
        )));
    }
    let rate = num(e, "rate_hz", f64::NAN)?;
    if !(rate.is_finite() && rate > 0.0) {
        return Err(err(format!("experiment `{name}`: `rate_hz` must be > 0")));
    }
    let seed = int(e, "seed", seed as usize)? as u64;
    let ms = parse_excitation(e, &name, rate, seed, Injection::Input)?;
    let nu = truth.inputs();
    let set: Vec<Vec<Vec<f64>>> = match text(e, "excite", "orthogonal")? {
        "orthogonal" => sd_ident::orthogonal(&ms, nu)?,
        "each" => (0..nu)
            .map(|x| {
                (0..nu)
                    .map(|j| {
                        if j == x {
                            ms.signal.clone()
                        } else {
                            vec![0.0; ms.signal.len()]
                        }
                    })
                    .collect()
            })
            .collect(),
        other => {
            return Err(err(format!(
                "experiment `{name}`: unknown excite `{other}` (\"orthogonal\" or \"each\")"
            )))
        }
    };
    let (periods, transient_periods) = (int(e, "periods", 6)?, int(e, "transient_periods", 1)?);
    let fine_steps = int(e, "fine_steps", 16)?;
    let total = periods
        .checked_add(transient_periods)
        .and_then(|p| p.checked_mul(ms.signal.len()))
        .and_then(|s| s.checked_mul(fine_steps.max(1)));
    within_budget(
        &name,
        total,
        "`period` × (`periods` + `transient_periods`) × `fine_steps`",
    )?;
    let (force_rms, sensor_rms) = (num(e, "force_noise", 0.02)?, num(e, "sensor_noise", 1e-10)?);
    if !(force_rms.is_finite() && force_rms >= 0.0 && sensor_rms.is_finite() && sensor_rms >= 0.0) {
        return Err(err(format!(
            "experiment `{name}`: `force_noise` and `sensor_noise` must be ≥ 0"
        )));
    }
    let role = choice(
        e,
        &name,
        "role",
        "validation",
        &[("model", Role::Model), ("validation", Role::Validation)],
    )?;
    let controller = decentralised_pid(
        truth,
        num(e, "pid_bandwidth_hz", 20.0)?,
        opt_num(e, "pid_lowpass_hz")?,
        1.0 / rate,
    )
    .map_err(|x| err(format!("experiment `{name}`: {x}")))?;
    Ok(set
        .into_iter()
        .enumerate()
        .map(|(x, excitation)| AxisIdentification {
            name: format!("{name}_{}", x + 1),
            controller: controller.clone(),
            excitation,
            periods,
            transient_periods,
            noise: Noise {
                force_rms,
                sensor_rms,
                sensor_drift: 0.0,
                seed: seed.wrapping_mul(31).wrapping_add(x as u64),
            },
            nonideal: nonideal.clone(),
            role,
            fine_steps,
        })
        .collect())
}

/// Runs every experiment of a multi-axis configuration; returns the data and the files
/// `sdctl testbed` writes (each `<name>.csv`, `experiments.toml` with lists of columns, the
/// continuous `truth.json`).
///
/// # Errors
/// As the experiments; the truth cannot be written as JSON.
pub fn run_axis_config(cfg: &AxisConfig) -> Result<(Vec<AxisData>, Files)> {
    let data = cfg
        .experiments
        .iter()
        .map(|x| run_multiaxis(&cfg.truth, x))
        .collect::<Result<Vec<_>>>()?;
    let mut files: Files = data
        .iter()
        .map(|d| (format!("{}.csv", d.name), d.csv()))
        .collect();
    files.push(("experiments.toml".into(), axis_manifest(&data)));
    files.push((
        "truth.json".into(),
        sd_model::model_to_json_string(&cfg.truth.linear_model()?)?,
    ));
    Ok((data, files))
}
