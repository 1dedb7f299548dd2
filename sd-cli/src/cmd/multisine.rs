//! `sdctl multisine`.

use crate::io::{emit, from_ident, CliError};

/// Which lines a multisine excites.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub(crate) enum LinesArg {
    /// Every line in the band.
    Full,
    /// Odd lines, one random detection line left out per group of three (nonlinear
    /// distortion shows at the non-excited lines).
    RandomOdd,
}

/// Arguments of `sdctl multisine`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Sample rate (Hz).
    #[arg(long)]
    pub(crate) fs: f64,
    /// Samples per period.
    #[arg(long)]
    pub(crate) period: usize,
    /// Lowest excited frequency (Hz).
    #[arg(long)]
    pub(crate) f_min: f64,
    /// Highest excited frequency (Hz), below fs/2.
    #[arg(long)]
    pub(crate) f_max: f64,
    /// Line set.
    #[arg(long, value_enum, default_value = "full")]
    pub(crate) lines: LinesArg,
    /// Seed of the random phases (and of the detection lines).
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Rms of one period of each input.
    #[arg(long, default_value_t = 1.0)]
    pub(crate) rms: f64,
    /// Periods in each file, the transient ones included.
    #[arg(long, default_value_t = 8)]
    pub(crate) periods: usize,
    /// Leading periods the manifest marks as transient (`skip_periods`).
    #[arg(long, default_value_t = 1)]
    pub(crate) skip: usize,
    /// Inputs: with more than one, orthogonal multisines, one experiment per input (in
    /// experiment e input j is the design with every line turned by 2π·j·e/inputs).
    #[arg(long, default_value_t = 1)]
    pub(crate) inputs: usize,
    /// Output column names for the manifest (the measured outputs the user adds to each CSV),
    /// comma-separated.
    #[arg(long, default_value = "y", value_delimiter = ',')]
    pub(crate) outputs: Vec<String>,
    /// Output folder (created): `exp_1.csv`… with the input columns `u1`…, and `experiments.toml`.
    #[arg(long)]
    pub(crate) out: String,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        crate::io::check_out_dir(&self.out)?;
        if self.periods <= self.skip {
            return Err(CliError::input(format!(
                "--periods {} must exceed --skip {}: at least one steady period",
                self.periods, self.skip
            )));
        }
        if self.outputs.iter().any(|o| o.is_empty()) || self.outputs.is_empty() {
            return Err(CliError::input("--outputs needs non-empty column names"));
        }
        let spec = sd_ident::MultisineSpec {
            fs: self.fs,
            period: self.period,
            f_min: self.f_min,
            f_max: self.f_max,
            lines: match self.lines {
                LinesArg::Full => sd_ident::Lines::Full,
                LinesArg::RandomOdd => sd_ident::Lines::RandomOdd {
                    group: 3,
                    seed: self.seed,
                },
            },
            phases: sd_ident::Phases::Random { seed: self.seed },
            rms: self.rms,
            fold_rate_hz: None,
        };
        let ms = sd_ident::design(&spec).map_err(|e| from_ident("multisine", e))?;
        let sets =
            sd_ident::orthogonal(&ms, self.inputs).map_err(|e| from_ident("multisine", e))?;
        let names: Vec<String> = if self.inputs == 1 {
            vec!["u".into()]
        } else {
            (1..=self.inputs).map(|j| format!("u{j}")).collect()
        };
        if let Some(c) = names.iter().find(|n| self.outputs.contains(n)) {
            return Err(CliError::input(format!(
                "--outputs names the input column `{c}`: choose other names"
            )));
        }
        let mut files = Vec::new();
        for (e, set) in sets.iter().enumerate() {
            let long: Vec<Vec<f64>> = set
                .iter()
                .map(|x| {
                    x.iter()
                        .copied()
                        .cycle()
                        .take(x.len() * self.periods)
                        .collect()
                })
                .collect();
            let cols: Vec<(&str, &[f64])> = names
                .iter()
                .map(String::as_str)
                .zip(long.iter().map(Vec::as_slice))
                .collect();
            let mut buf = Vec::new();
            sd_ident::write_csv(&mut buf, &cols).map_err(|e| from_ident("multisine", e))?;
            let text = String::from_utf8(buf).map_err(|e| CliError::numerical(e.to_string()))?;
            files.push((format!("exp_{}.csv", e + 1), text));
        }
        files.push(("experiments.toml".into(), self.manifest(&names, sets.len())));
        crate::io::write_folder(&self.out, |dir| {
            for (name, text) in &files {
                emit(text.trim_end(), Some(&dir.join(name).to_string_lossy()))?;
            }
            Ok(())
        })?;
        eprintln!(
            "[multisine] {} excited lines, crest factor {:.2}; {} experiment(s) of {} inputs \
             written to {} (add the measured {} columns to each CSV)",
            ms.excited.len(),
            ms.crest_factor,
            sets.len(),
            self.inputs,
            self.out,
            self.outputs.join(", ")
        );
        Ok(())
    }

    /// The manifest of the experiments (docs/formats.md).
    fn manifest(&self, names: &[String], n: usize) -> String {
        let list = |v: &[String]| {
            if v.len() == 1 {
                format!("\"{}\"", v[0])
            } else {
                format!(
                    "[{}]",
                    v.iter()
                        .map(|x| format!("\"{x}\""))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        };
        (1..=n)
            .map(|e| {
                format!(
                    "[[experiment]]\nname = \"exp_{e}\"\nfile = \"exp_{e}.csv\"\nsample_rate_hz = {}\n\
                     period_samples = {}\nskip_periods = {}\ninput = {}\noutput = {}\n",
                    self.fs,
                    self.period,
                    self.skip,
                    list(names),
                    list(&self.outputs)
                )
            })
            .collect::<Vec<_>>()
            .join("\n")
    }
}
