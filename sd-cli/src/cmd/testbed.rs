//! `sdctl testbed`.

use crate::io::{emit, from_testbed, CliError};

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
            None => sd_testbed::DEFAULT_CONFIG.to_string(),
        };
        let label = config.as_deref().unwrap_or("default configuration");
        let cfg = sd_testbed::parse_config(&text).map_err(|e| from_testbed(label, e))?;
        let data = sd_testbed::run_config(&cfg).map_err(|e| from_testbed(label, e))?;
        let truth = sd_testbed::truth_model(&cfg.truth).map_err(|e| from_testbed(label, e))?;
        let files = sd_testbed::output_files(&data, &truth).map_err(|e| from_testbed(label, e))?;
        crate::io::write_folder(&out, |dir| {
            for (name, text) in &files {
                emit(text, Some(&dir.join(name).to_string_lossy()))?;
            }
            Ok(())
        })?;
        eprintln!(
            "[testbed] {} experiments written to {out} (experiments.toml, truth.json)",
            data.len()
        );
        Ok(())
    }
}
