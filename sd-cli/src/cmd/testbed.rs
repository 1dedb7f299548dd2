//! `sdctl testbed`.

use crate::commands::model_json;
use crate::io::{emit, from_testbed, CliError};

/// The configuration `sdctl testbed` runs without `--config`.
const DEFAULT_TESTBED: &str = r#"
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

/// Arguments of `sdctl testbed`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Configuration (TOML; format in the README). Absent: the virtual stage's defaults (docs/stage.md) with one
    /// 5 kHz and one 1 kHz identification experiment.
    #[arg(long)]
    pub(crate) config: Option<String>,
    /// Output folder (created): experiments.toml, one CSV per experiment, truth.json.
    #[arg(long)]
    pub(crate) out: String,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args { config, out } = self;
        crate::io::check_out_dir(&out)?;
        let text = match &config {
            Some(path) => crate::io::read_text(path)?,
            None => DEFAULT_TESTBED.to_string(),
        };
        let label = config.as_deref().unwrap_or("default configuration");
        let cfg = sd_testbed::parse_config(&text).map_err(|e| from_testbed(label, e))?;
        let data = sd_testbed::run_config(&cfg).map_err(|e| from_testbed(label, e))?;
        let truth = sd_testbed::truth_model(&cfg.truth).map_err(|e| from_testbed(label, e))?;
        crate::io::write_folder(&out, |dir| {
            for d in &data {
                let p = dir.join(format!("{}.csv", d.name));
                emit(&d.csv(), Some(&p.to_string_lossy()))?;
            }
            emit(
                &sd_testbed::manifest(&data),
                Some(&dir.join("experiments.toml").to_string_lossy()),
            )?;
            emit(
                &model_json(&truth)?,
                Some(&dir.join("truth.json").to_string_lossy()),
            )
        })?;
        eprintln!(
            "[testbed] {} experiments written to {out} (experiments.toml, truth.json)",
            data.len()
        );
        Ok(())
    }
}
