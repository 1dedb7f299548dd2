//! `sdctl predict`.

use crate::io::CliError;

/// Arguments of `sdctl predict`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// A folder `sdctl diagnose` wrote (its `predictor.json` is read).
    pub(crate) diagnosis: String,
    /// Manifest of the new experiments (TOML, docs/formats.md; roles are ignored: every
    /// experiment is predicted).
    pub(crate) manifest: String,
    /// Output folder for prediction.json, report.md and the SVG figures.
    #[arg(long)]
    pub(crate) out: String,
    /// False-alarm probability of the thresholds.
    #[arg(long, default_value_t = 0.01)]
    pub(crate) alpha: f64,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        crate::io::check_out_dir(&self.out)?;
        let file = std::path::Path::new(&self.diagnosis).join("predictor.json");
        let path = file.to_string_lossy().into_owned();
        if !file.is_file() {
            return Err(CliError::input(format!(
                "{path}: not found; give a folder written by `sdctl diagnose` (this version \
                 writes predictor.json beside diagnosis.json)"
            )));
        }
        let text = crate::io::read_text(&path)?;
        let predictor = sd_diagnose::Predictor::from_json_str(&text)
            .map_err(|e| crate::io::from_diagnose(&path, e))?;
        let exps = crate::io::load_experiments(&self.manifest, |_| true)?;
        if let Some(e) = exps.iter().find(|e| e.spec.is_mimo()) {
            return Err(CliError::input(format!(
                "{}: experiment `{}` has several inputs or outputs; a diagnosis predicts SISO \
                 experiments",
                self.manifest, e.spec.name
            )));
        }
        let p = sd_diagnose::predict_experiments(&predictor, &exps, self.alpha)
            .map_err(|e| crate::io::from_diagnose(&self.manifest, e))?;
        if let Some(msg) = p.nothing_predicted() {
            return Err(CliError::input(msg));
        }
        let figs = crate::io::write_folder(&self.out, |dir| {
            sd_report::prediction::write_prediction(dir, &p, &self.diagnosis).map_err(|e| match e {
                sd_report::ReportError::Json(_) => CliError::numerical(e.to_string()),
                _ => CliError::input(e.to_string()),
            })
        })?;
        let ratios: Vec<String> = p
            .experiments
            .iter()
            .filter_map(|x| x.ratio.map(|r| format!("{} ×{r:.2}", x.name)))
            .collect();
        eprintln!(
            "[predict] {} of {} experiments predicted by the `{}` extension (plain/extended: \
             {}); report.md and {} figures in {}",
            p.predicted(),
            p.experiments.len(),
            p.extension,
            ratios.join(", "),
            figs.len(),
            self.out
        );
        Ok(())
    }
}
