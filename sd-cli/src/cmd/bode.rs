//! `sdctl bode`: a Bode plot (SVG) of models and measured FRFs together, magnitude in dB re 1
//! of the plant's unit and unwrapped phase, the measurements drawn on top; `--csv` writes the
//! plotted numbers.

use crate::commands::parse_grid;
use crate::io::{atomic_svg, from_model, read_text, CliError};
use num_complex::Complex64 as C;
use sd_report::plot::{bode_snr_plot_in, unwrap_deg, Curve, RGBColor};

/// Arguments of `sdctl bode`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Model JSON files (ss/tf) and FRD JSON files (`sdctl frf`, `sdctl freqresp`), in any
    /// order: the models are drawn first, the measurements on top.
    #[arg(required = true)]
    pub(crate) inputs: Vec<String>,
    /// Frequencies for the models `FMIN:FMAX:N[:log]` (Hz); default: the FRDs' band on 2000
    /// logarithmic points (needed when no FRD is given).
    #[arg(long)]
    pub(crate) grid: Option<String>,
    /// The entry `OUT,IN` (1-based) of a MIMO model or FRD; SISO needs none.
    #[arg(long, value_parser = parse_entry)]
    pub(crate) entry: Option<(usize, usize)>,
    /// The plant's unit, written on the magnitude axis as `dB re 1 UNIT` (e.g. `m/N`).
    #[arg(long)]
    pub(crate) unit: Option<String>,
    /// The figure's title.
    #[arg(long, default_value = "Bode plot")]
    pub(crate) title: String,
    /// Also write the plotted numbers: `curve,freq_hz,magnitude_db,phase_deg` (phase unwrapped).
    #[arg(long)]
    pub(crate) csv: Option<String>,
    /// The SVG file.
    #[arg(short, long)]
    pub(crate) output: String,
}

fn parse_entry(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("--entry {s}: expected OUT,IN (1-based), e.g. 1,2");
    let (o, i) = s.split_once(',').ok_or_else(bad)?;
    let (o, i): (usize, usize) = (
        o.trim().parse().map_err(|_| bad())?,
        i.trim().parse().map_err(|_| bad())?,
    );
    if o == 0 || i == 0 {
        return Err(bad());
    }
    Ok((o - 1, i - 1))
}

/// One curve's name, frequencies and complex response (the chosen entry).
struct Series {
    name: String,
    freq_hz: Vec<f64>,
    response: Vec<C>,
    measured: bool,
    /// σ of each measured line (`√var`), when the FRD carries variances.
    sigma: Option<Vec<f64>>,
}

/// The entry of a `ny×nu` response that `entry` names, or the error saying what to give.
fn pick(
    path: &str,
    (ny, nu): (usize, usize),
    entry: Option<(usize, usize)>,
) -> Result<(usize, usize), CliError> {
    match entry {
        None if ny == 1 && nu == 1 => Ok((0, 0)),
        None => Err(CliError::input(format!(
            "{path} is {ny}x{nu}: give --entry OUT,IN (1-based) to plot one entry"
        ))),
        Some((o, i)) if o < ny && i < nu => Ok((o, i)),
        Some((o, i)) => Err(CliError::input(format!(
            "--entry {},{}: {path} is {ny}x{nu}",
            o + 1,
            i + 1
        ))),
    }
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let mut models = Vec::new();
        let mut measured = Vec::new();
        for path in &self.inputs {
            let text = read_text(path)?;
            let kind = serde_json::from_str::<serde_json::Value>(&text)
                .ok()
                .and_then(|v| v.get("type").and_then(|t| t.as_str()).map(str::to_owned));
            if kind.as_deref() == Some("frd") {
                let frd = sd_model::frd_from_json_str(&text).map_err(|e| from_model(path, e))?;
                let (o, i) = pick(path, frd.shape(), self.entry)?;
                measured.push(Series {
                    name: name_of(path),
                    freq_hz: frd.freq_hz().to_vec(),
                    response: frd.response().iter().map(|g| g[(o, i)]).collect(),
                    measured: true,
                    sigma: frd
                        .variance()
                        .map(|v| v.iter().map(|m| m[(o, i)].sqrt()).collect()),
                });
            } else {
                let sys = sd_model::read_model(text.as_bytes()).map_err(|e| from_model(path, e))?;
                models.push((path.clone(), sys));
            }
        }
        let grid = self.model_grid(&measured)?;
        let mut series = Vec::new();
        for (path, sys) in &models {
            let (o, i) = pick(path, (sys.ny(), sys.nu()), self.entry)?;
            let f: Vec<f64> = match sys.time().nyquist_hz() {
                Some(ny) => grid.iter().copied().filter(|f| *f <= ny).collect(),
                None => grid.clone(),
            };
            // an entry at a pole is infinite: left out of the curve (a gap), not drawn huge
            let frd = sd_model::FreqRespEvaluator::new(sys).map_err(|e| from_model(path, e))?;
            let mut flat = frd.eval_many_flat(&f);
            frd.mark_poles(&f, &mut flat);
            let (ny, nu) = (sys.ny(), sys.nu());
            series.push(Series {
                name: name_of(path),
                response: (0..f.len())
                    .map(|k| flat[k * ny * nu + i * ny + o])
                    .collect(),
                freq_hz: f,
                measured: false,
                sigma: None,
            });
        }
        series.extend(measured);
        self.draw(&series)
    }

    /// The models' frequencies: `--grid`, else the FRDs' band on 2000 log points.
    fn model_grid(&self, measured: &[Series]) -> Result<Vec<f64>, CliError> {
        if let Some(g) = &self.grid {
            return parse_grid(g);
        }
        let (lo, hi) = band(measured);
        if !(lo.is_finite() && hi > lo) {
            return Err(CliError::input(
                "no FRD with a positive band among the inputs: give --grid FMIN:FMAX:N[:log] for the models",
            ));
        }
        sd_model::grid(lo, hi, 2000, true).map_err(|e| from_model("--grid", e))
    }

    /// The figure (written through a temporary file, then renamed) and the CSV.
    fn draw(&self, series: &[Series]) -> Result<(), CliError> {
        const COLORS: [RGBColor; 6] = [
            RGBColor(31, 119, 180),
            RGBColor(214, 39, 40),
            RGBColor(44, 160, 44),
            RGBColor(148, 103, 189),
            RGBColor(255, 127, 14),
            RGBColor(23, 190, 207),
        ];
        let db: Vec<Vec<f64>> = series
            .iter()
            .map(|s| s.response.iter().map(|g| 20.0 * g.norm().log10()).collect())
            .collect();
        let ph: Vec<Vec<f64>> = series
            .iter()
            .map(|s| {
                let p: Vec<f64> = s
                    .response
                    .iter()
                    .map(|g| {
                        if g.is_finite() {
                            g.arg().to_degrees()
                        } else {
                            f64::NAN
                        }
                    })
                    .collect();
                unwrap_deg(&p)
            })
            .collect();
        let labels: Vec<String> = series
            .iter()
            .map(|s| format!("{}{}", s.name, if s.measured { " (measured)" } else { "" }))
            .collect();
        let curves: Vec<Curve<'_>> = series
            .iter()
            .enumerate()
            .map(|(k, s)| Curve {
                label: &labels[k],
                freq_hz: &s.freq_hz,
                db: &db[k],
                color: if s.measured {
                    RGBColor(0, 0, 0)
                } else {
                    COLORS[k % COLORS.len()]
                },
            })
            .collect();
        let mut phases: Vec<Option<&[f64]>> = ph.iter().map(|p| Some(p.as_slice())).collect();
        // a measured FRD with variances: its ±2σ band (two unlabelled edges, drawn first) and
        // its per-line SNR |G|/σ in a third panel
        let (bands, snr) = sigma_parts(series, &db);
        let band_labels: Vec<String> = series
            .iter()
            .filter(|s| s.sigma.is_some())
            .flat_map(|s| [format!("{} ±2σ", s.name), String::new()])
            .collect();
        let mut all: Vec<Curve<'_>> = bands
            .iter()
            .zip(&band_labels)
            .map(|((f, d), l)| Curve {
                label: l,
                freq_hz: f,
                db: d,
                color: RGBColor(170, 170, 170),
            })
            .collect();
        phases.splice(0..0, bands.iter().map(|_| None));
        all.extend(curves);
        let snr_curves: Vec<Curve<'_>> = snr
            .iter()
            .map(|(f, d)| Curve {
                label: "",
                freq_hz: f,
                db: d,
                color: RGBColor(0, 0, 0),
            })
            .collect();
        let (fmin, fmax) = band(series);
        if !(fmin.is_finite() && fmax > fmin) {
            return Err(CliError::input("nothing to plot: no positive frequency"));
        }
        atomic_svg(&self.output, |tmp| {
            bode_snr_plot_in(
                tmp,
                &self.title,
                (&all, &phases),
                &snr_curves,
                (fmin, fmax),
                &[],
                self.unit.as_deref().unwrap_or(""),
            )
        })?;
        if let Some(csv) = &self.csv {
            let mut text = String::from("curve,freq_hz,magnitude_db,phase_deg\n");
            for (k, s) in series.iter().enumerate() {
                for (j, f) in s.freq_hz.iter().enumerate() {
                    text += &format!("{},{f},{},{}\n", labels[k], db[k][j], ph[k][j]);
                }
            }
            sd_report::write_atomic(std::path::Path::new(csv), &text)
                .map_err(|e| CliError::input(format!("{csv}: {e}")))?;
        }
        eprintln!("[bode] {} curves → {}", series.len(), self.output);
        Ok(())
    }
}

/// A curve's name: the file's stem.
fn name_of(path: &str) -> String {
    std::path::Path::new(path)
        .file_stem()
        .map_or_else(|| path.to_string(), |s| s.to_string_lossy().into_owned())
}

/// The lowest and highest positive frequency of the curves (`(∞, 0)` when there is none).
fn band(series: &[Series]) -> (f64, f64) {
    series
        .iter()
        .flat_map(|s| s.freq_hz.iter().copied())
        .filter(|f| *f > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), f| {
            (lo.min(f), hi.max(f))
        })
}

/// The ±2σ band edges (dB: `20·log10(|G| ± 2σ)`, the lower edge left out where it would be
/// ≤ 0) and the per-line SNR `20·log10(|G|/σ)` of every measured series with variances.
#[allow(clippy::type_complexity)]
fn sigma_parts(
    series: &[Series],
    db: &[Vec<f64>],
) -> (Vec<(Vec<f64>, Vec<f64>)>, Vec<(Vec<f64>, Vec<f64>)>) {
    let (mut bands, mut snr) = (Vec::new(), Vec::new());
    for (s, d) in series.iter().zip(db) {
        let Some(sig) = &s.sigma else { continue };
        let mag: Vec<f64> = s.response.iter().map(|g| g.norm()).collect();
        let up: Vec<f64> = mag
            .iter()
            .zip(sig)
            .map(|(m, e)| 20.0 * (m + 2.0 * e).log10())
            .collect();
        let lo: Vec<f64> = mag
            .iter()
            .zip(sig)
            .map(|(m, e)| {
                if m > &(2.0 * e) {
                    20.0 * (m - 2.0 * e).log10()
                } else {
                    f64::NAN
                }
            })
            .collect();
        bands.push((s.freq_hz.clone(), up));
        bands.push((s.freq_hz.clone(), lo));
        let r: Vec<f64> = d
            .iter()
            .zip(sig)
            .map(|(db, e)| {
                if *e > 0.0 {
                    db - 20.0 * e.log10()
                } else {
                    f64::NAN
                }
            })
            .collect();
        snr.push((s.freq_hz.clone(), r));
    }
    (bands, snr)
}
