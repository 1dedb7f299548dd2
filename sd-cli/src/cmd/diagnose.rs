//! `sdctl diagnose`.

use crate::io::{read_model, CliError};

/// Arguments of `sdctl diagnose`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Experiment manifest (TOML, docs/formats.md).
    pub(crate) manifest: String,
    /// A given model (model JSON; discrete at the model experiment's rate, or continuous).
    /// Absent: fitted to the model experiment.
    #[arg(long)]
    pub(crate) model: Option<String>,
    /// Output folder for diagnosis.json, report.md and the SVG figures.
    #[arg(long)]
    pub(crate) out: String,
    /// False-alarm probability of the verdict (a consistent model is called a discrepancy
    /// this often).
    #[arg(long, default_value_t = 0.01)]
    pub(crate) alpha: f64,
    /// Highest model order tried when the model is fitted (the scan stops six orders
    /// past the best held-out error).
    #[arg(long, default_value_t = 60)]
    pub(crate) max_order: usize,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            manifest,
            model,
            out,
            alpha,
            max_order,
        } = self;
        crate::io::check_out_dir(&out)?;
        let exps = crate::io::load_experiments(&manifest, |_| true)?;
        if exps.iter().any(|e| e.spec.is_mimo()) {
            if model.is_some() {
                return Err(CliError::input(
                    "--model is for SISO experiments: the MIMO diagnosis fits its common-pole \
                     model to the model set",
                ));
            }
            return run_mimo(&exps, &manifest, &out, alpha, max_order);
        }
        let opt = sd_diagnose::DiagnoseOptions {
            model: model.as_deref().map(read_model).transpose()?,
            alpha,
            max_order,
        };
        // progress for a person at a terminal; scripts get one line (or one error line)
        let start = std::time::Instant::now();
        let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
        let d = sd_diagnose::diagnose_with_progress(&exps, &opt, &mut |m| {
            if tty {
                eprintln!("[diagnose {:6.2} s] {m}", start.elapsed().as_secs_f64())
            }
        })
        .map_err(|e| crate::io::from_diagnose(&manifest, e))?;
        let figs = crate::io::write_folder(&out, |dir| {
            sd_report::diagnosis::write_all(dir, &d, &manifest).map_err(|e| match e {
                sd_report::ReportError::Json(_) => CliError::numerical(e.to_string()),
                _ => CliError::input(e.to_string()),
            })
        })?;
        let gain = match d.gain_ratio() {
            Some(r) => format!("held-out gain ×{r:.1}"),
            None => "no held-out gain".into(),
        };
        let said = sd_report::diagnosis::causes_text(&d);
        let said = if said.is_empty() {
            String::new()
        } else {
            format!(": {}", said.join("; "))
        };
        eprintln!(
            "[diagnose] {} / {}{said} ({gain}); report.md and {} figures in {out}",
            d.verdict,
            d.cause,
            figs.len()
        );
        Ok(())
    }
}

/// The MIMO diagnosis (`sd_diagnose::diagnose_mimo`) of a manifest whose experiments have
/// several inputs or outputs: diagnosis.json, model.json and report.md in `out`.
fn run_mimo(
    exps: &[sd_ident::Experiment],
    manifest: &str,
    out: &str,
    alpha: f64,
    max_order: usize,
) -> Result<(), CliError> {
    let opt = sd_diagnose::MimoDiagnoseOptions {
        alpha,
        order: None,
        max_order,
    };
    let start = std::time::Instant::now();
    let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let d = sd_diagnose::diagnose_mimo(exps, &opt, &mut |m| {
        if tty {
            eprintln!("[diagnose {:6.2} s] {m}", start.elapsed().as_secs_f64())
        }
    })
    .map_err(|e| crate::io::from_diagnose(manifest, e))?;
    crate::io::write_folder(out, |dir| {
        sd_report::mimo::write_mimo(dir, &d, manifest).map_err(|e| match e {
            sd_report::ReportError::Json(_) => CliError::numerical(e.to_string()),
            _ => CliError::input(e.to_string()),
        })
    })?;
    let said = sd_report::mimo::mimo_causes_text(&d);
    let gain = match &d.gain {
        Some(g) if g.held_out => format!("held-out gain ×{:.1}", g.ratio),
        Some(g) => format!("gain ×{:.1} (not held out)", g.ratio),
        None => "no gain".into(),
    };
    eprintln!(
        "[diagnose] MIMO {}x{}: {}{} ({gain}); report.md in {out}",
        d.shape.0,
        d.shape.1,
        d.verdict,
        if said.is_empty() {
            String::new()
        } else {
            format!(": {}", said.join("; "))
        }
    );
    Ok(())
}
