//! `sdctl testbed`.

use crate::io::{emit, from_testbed, CliError};

/// Arguments of `sdctl testbed`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Configuration (TOML; docs/formats.md). Absent: the virtual stage's defaults
    /// (docs/stage.md) with one 5 kHz and one 1 kHz identification experiment. A `[stage]`
    /// table instead of `[truth]` selects the multi-axis stage (several actuators and sensors).
    #[arg(long)]
    pub(crate) config: Option<String>,
    /// Output folder (created): experiments.toml, one CSV per experiment, truth.json.
    #[arg(long, required_unless_present = "print_default_config")]
    pub(crate) out: Option<String>,
    /// Print the configuration used without --config (the virtual stage's defaults written
    /// out, a starting point for your own) on stdout, and run nothing.
    #[arg(long, conflicts_with_all = ["config", "out"])]
    pub(crate) print_default_config: bool,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            config,
            out,
            print_default_config,
        } = self;
        if print_default_config {
            return emit(sd_testbed::DEFAULT_CONFIG.trim(), None);
        }
        let out = out.unwrap_or_default();
        crate::io::check_out_dir(&out)?;
        let text = match &config {
            Some(path) => crate::io::read_text(path)?,
            None => sd_testbed::DEFAULT_CONFIG.to_string(),
        };
        let label = config.as_deref().unwrap_or("default configuration");
        let (count, files) = if sd_testbed::is_multiaxis(&text) {
            // a multi-axis stage: one experiment per actuator and [[experiment]]
            let cfg = sd_testbed::parse_axis_config(&text).map_err(|e| from_testbed(label, e))?;
            let (data, files) =
                sd_testbed::run_axis_config(&cfg).map_err(|e| from_testbed(label, e))?;
            (data.len(), files)
        } else {
            let cfg = sd_testbed::parse_config(&text).map_err(|e| from_testbed(label, e))?;
            let data = sd_testbed::run_config(&cfg).map_err(|e| from_testbed(label, e))?;
            let truth = sd_testbed::truth_model(&cfg.truth).map_err(|e| from_testbed(label, e))?;
            let files =
                sd_testbed::output_files(&data, &truth).map_err(|e| from_testbed(label, e))?;
            (data.len(), files)
        };
        crate::io::write_folder(&out, |dir| {
            for (name, text) in &files {
                emit(text, Some(&dir.join(name).to_string_lossy()))?;
            }
            Ok(())
        })?;
        eprintln!("[testbed] {count} experiments written to {out} (experiments.toml, truth.json)");
        Ok(())
    }
}
