//! Command definitions and their implementations.

use crate::io::{
    emit, from_analysis, from_hinf, from_ident, from_model, from_multirate, from_testbed,
    read_model, CliError,
};
use clap::{Parser, Subcommand, ValueEnum};
use sd_model::{c2d, d2c_with_aliases, Discretization, StateSpace};
use serde_json::json;

/// Sampled-data control design on files: models (JSON), FRDs (JSON), experiments (TOML + CSV).
#[derive(Parser, Debug)]
#[command(name = "sdctl", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Method {
    Zoh,
    Foh,
    Tustin,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Conn {
    Series,
    Parallel,
    Feedback,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Discretise a continuous model (exact ZOH by default).
    C2d {
        /// Model JSON file ("-" for stdin).
        model: String,
        /// Sampling period in seconds.
        #[arg(long, allow_negative_numbers = true)]
        ts: f64,
        #[arg(long, value_enum, default_value = "zoh")]
        method: Method,
        /// Tustin prewarp frequency in Hz.
        #[arg(long, allow_negative_numbers = true)]
        prewarp_hz: Option<f64>,
        /// ZOH that switches this fraction of the period late (0..1; adds nu states).
        #[arg(long, allow_negative_numbers = true)]
        hold_delay: Option<f64>,
        /// Sampler averaging over the last fraction of the period (0..1; adds ny states).
        #[arg(long, allow_negative_numbers = true)]
        averaging: Option<f64>,
        /// Output file (default stdout).
        #[arg(short, long)]
        output: Option<String>,
    },
    /// Lemma 6: a fast discrete model seen through a hold and sampler F times slower.
    Downsample {
        /// Discrete model JSON file ("-" for stdin).
        model: String,
        /// Rate factor F = T/h (integer >= 1).
        #[arg(long, allow_negative_numbers = true)]
        factor: i64,
        /// Slow hold switching this fraction of the slow period late (a multiple of 1/F).
        #[arg(long, allow_negative_numbers = true)]
        hold_delay: Option<f64>,
        /// Slow sampler returning the mean of the last fraction of fast samples (a multiple of 1/F).
        #[arg(long, allow_negative_numbers = true)]
        averaging: Option<f64>,
        #[arg(short, long)]
        output: Option<String>,
    },
    /// Continuous model from a discrete one (principal branch); alias candidates on stderr.
    D2c {
        model: String,
        /// Highest candidate frequency listed per mode (Hz; default 3 × the sample rate).
        #[arg(long, allow_negative_numbers = true)]
        max_hz: Option<f64>,
        #[arg(short, long)]
        output: Option<String>,
    },
    /// Where a continuous frequency appears after sampling, and what folds onto it.
    Alias {
        #[arg(long, allow_negative_numbers = true)]
        freq_hz: f64,
        #[arg(long, allow_negative_numbers = true)]
        rate_hz: f64,
        /// Highest folding frequency listed (Hz; default 5 × the rate).
        #[arg(long, allow_negative_numbers = true)]
        max_hz: Option<f64>,
        /// Also list the frequencies of a model F times faster that fold onto the alias, with
        /// the slow hold's weights |H_F|/F (Lemma 6).
        #[arg(long, allow_negative_numbers = true)]
        factor: Option<i64>,
        #[arg(long)]
        json: bool,
    },
    /// Frequency response on a grid FMIN:FMAX:N[:log] (Hz) as FRD JSON.
    Freqresp {
        model: String,
        #[arg(long)]
        grid: String,
        #[arg(short, long)]
        output: Option<String>,
    },
    /// Poles with frequency (Hz) and damping.
    Poles {
        model: String,
        #[arg(long)]
        json: bool,
    },
    /// Invariant zeros.
    Zeros {
        model: String,
        #[arg(long)]
        json: bool,
    },
    /// H2 and H∞ norms (with the H∞ peak frequency).
    Norm {
        model: String,
        #[arg(long)]
        json: bool,
    },
    /// Balanced truncation to N states (unstable/marginal poles kept); summary on stderr.
    Reduce {
        model: String,
        #[arg(long)]
        order: usize,
        #[arg(short, long)]
        output: Option<String>,
    },
    /// Interconnect two models: series (A then B), parallel, feedback (negative by default).
    Connect {
        #[arg(value_enum)]
        kind: Conn,
        a: String,
        b: String,
        /// Feedback sign: -1 (negative, default) or +1.
        #[arg(long, default_value_t = -1.0, allow_negative_numbers = true)]
        sign: f64,
        #[arg(short, long)]
        output: Option<String>,
    },
    /// McFarlane–Glover loopshaping: the controller K = W1·Ks·W2 for negative feedback u = −K y.
    Loopshape {
        /// Plant model JSON (discrete or continuous).
        plant: String,
        /// Input weight W1 (model JSON, nu×nu); identity if absent.
        #[arg(long)]
        w1: Option<String>,
        /// Output weight W2 (model JSON, ny×ny); identity if absent.
        #[arg(long)]
        w2: Option<String>,
        /// γ = factor·γ_min (> 1).
        #[arg(long, default_value_t = 1.1, allow_negative_numbers = true)]
        factor: f64,
        /// Strictly proper controller (no feedthrough; discrete plants).
        #[arg(long)]
        strictly_proper: bool,
        /// Print gamma_min, gamma, the controllers, stability and Riccati residuals as JSON.
        #[arg(long)]
        json: bool,
        #[arg(short, long)]
        output: Option<String>,
    },
    /// FRF of one experiment of a manifest (periodic: averaged over periods; otherwise LPM), FRD JSON with var.
    Frf {
        /// Experiment manifest (TOML, DESIGN §4).
        manifest: String,
        /// Name of the experiment.
        #[arg(long)]
        experiment: String,
        /// Excited-line threshold relative to the strongest line (periodic data).
        #[arg(long, allow_negative_numbers = true)]
        excited_fraction: Option<f64>,
        #[arg(short, long)]
        output: Option<String>,
    },
    /// Fit a discrete-time model of order N to a SISO FRD (progress on stderr).
    Fit {
        /// FRD JSON (discrete).
        frd: String,
        #[arg(long)]
        order: usize,
        /// Poles fixed at z = 1 (0, 1 or 2).
        #[arg(long, default_value_t = 0)]
        rigid_body: usize,
        /// No feedthrough term.
        #[arg(long)]
        strictly_proper: bool,
        #[arg(long, value_enum, default_value = "variance")]
        weighting: WeightingArg,
        #[arg(short, long)]
        output: Option<String>,
    },
    /// Closed loop of a plant and a controller (negative feedback): stability, bandwidth, |S| peak, margins.
    Analyze {
        #[arg(long)]
        plant: String,
        #[arg(long)]
        controller: String,
        #[arg(long)]
        json: bool,
    },
    /// Intersample analysis of a slow controller around a fast plant: predicted error spectra at both rates.
    Intersample {
        /// Fast discrete plant (period h).
        #[arg(long)]
        plant_fast: String,
        /// Slow discrete controller (period F·h, F an integer).
        #[arg(long)]
        controller: String,
        /// Force disturbance rms per fast sample (white).
        #[arg(long, default_value_t = 0.05, allow_negative_numbers = true)]
        force_rms: f64,
        /// Sensor disturbance rms per fast sample (white).
        #[arg(long, default_value_t = 3e-10, allow_negative_numbers = true)]
        sensor_rms: f64,
        /// Frequency points per band.
        #[arg(long, default_value_t = 2000)]
        points: usize,
        #[arg(long)]
        json: bool,
    },
    /// Run the virtual stage: writes DIR/experiments.toml, one CSV per experiment, DIR/truth.json.
    Testbed {
        /// Configuration (TOML; format in the README). Absent: DESIGN §6 defaults with one
        /// 5 kHz and one 1 kHz identification experiment.
        #[arg(long)]
        config: Option<String>,
        #[arg(long)]
        out: String,
    },
    /// What the model's simulation gets wrong on the validation experiments, its cause, the
    /// extended model and its gain on held-out data.
    Diagnose {
        /// Experiment manifest (TOML, DESIGN §4).
        manifest: String,
        /// A given model (model JSON; discrete at the model experiment's rate, or continuous).
        /// Absent: fitted to the model experiment.
        #[arg(long)]
        model: Option<String>,
        /// Output folder for diagnosis.json, report.md and the SVG figures.
        #[arg(long)]
        out: String,
        /// False-alarm probability of the verdict (a consistent model is called a discrepancy
        /// this often).
        #[arg(long, default_value_t = 0.01)]
        alpha: f64,
        /// Highest model order tried when the model is fitted (the scan stops six orders
        /// past the best held-out error).
        #[arg(long, default_value_t = 60)]
        max_order: usize,
    },
    /// Loopshaping weights as model JSON (continuous unless --ts is given).
    Weight {
        #[command(subcommand)]
        kind: WeightKind,
    },
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum WeightingArg {
    Variance,
    Relative,
    Uniform,
}

#[derive(Subcommand, Debug)]
enum WeightKind {
    /// PID-like: integrator, lead around the bandwidth, optional low-pass; |W/(m s²)| = 1 at the bandwidth.
    Pid {
        #[arg(long, allow_negative_numbers = true)]
        bandwidth_hz: f64,
        /// The plant's high-frequency mass line 1/(m s²): m in the plant's units.
        #[arg(long, allow_negative_numbers = true)]
        mass: f64,
        #[arg(long, allow_negative_numbers = true)]
        ts: Option<f64>,
        #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
        integrator_ratio: f64,
        #[arg(long, default_value_t = 3.0, allow_negative_numbers = true)]
        lead_ratio: f64,
        /// 0: no low-pass.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        lowpass_ratio: f64,
        #[arg(long, default_value_t = 0.7, allow_negative_numbers = true)]
        lowpass_zeta: f64,
        #[arg(short, long)]
        output: Option<String>,
    },
    /// Notch (s² + 2ζz ω s + ω²)/(s² + 2ζp ω s + ω²), prewarped at its frequency.
    Notch {
        #[arg(long, allow_negative_numbers = true)]
        freq_hz: f64,
        #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
        zeta_zero: f64,
        #[arg(long, default_value_t = 0.2, allow_negative_numbers = true)]
        zeta_pole: f64,
        #[arg(long, allow_negative_numbers = true)]
        ts: Option<f64>,
        #[arg(short, long)]
        output: Option<String>,
    },
    /// Second-order low-pass ω²/(s² + 2ζω s + ω²), prewarped at its corner.
    Lowpass {
        #[arg(long, allow_negative_numbers = true)]
        freq_hz: f64,
        #[arg(long, default_value_t = 0.7, allow_negative_numbers = true)]
        zeta: f64,
        #[arg(long, allow_negative_numbers = true)]
        ts: Option<f64>,
        #[arg(short, long)]
        output: Option<String>,
    },
}

fn finite_pos(v: f64, what: &str) -> Result<f64, CliError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(CliError::input(format!(
            "{what} = {v} must be finite and > 0"
        )))
    }
}

fn model_json(sys: &StateSpace) -> Result<String, CliError> {
    sd_model::model_to_json_string(sys).map_err(|e| from_model("output", e))
}

fn pole_info(p: num_complex::Complex64, ts: Option<f64>) -> (f64, f64) {
    // (frequency Hz, damping) of the equivalent continuous pole
    let s = match ts {
        None => p,
        Some(h) => p.ln() / h,
    };
    let f = s.norm() / (2.0 * std::f64::consts::PI);
    let z = if s.norm() == 0.0 {
        1.0
    } else {
        -s.re / s.norm()
    };
    (f, z)
}

/// Parses FMIN:FMAX:N[:log].
fn parse_grid(g: &str) -> Result<Vec<f64>, CliError> {
    let parts: Vec<&str> = g.split(':').collect();
    let bad = || {
        CliError::input(format!(
            "--grid {g}: expected FMIN:FMAX:N[:log], e.g. 1:500:1000:log"
        ))
    };
    if parts.len() < 3 || parts.len() > 4 {
        return Err(bad());
    }
    let fmin: f64 = parts[0].trim().parse().map_err(|_| bad())?;
    let fmax: f64 = parts[1].trim().parse().map_err(|_| bad())?;
    let n: usize = parts[2].trim().parse().map_err(|_| bad())?;
    let log = match parts.get(3).map(|s| s.trim()) {
        None | Some("lin") => false,
        Some("log") => true,
        Some(_) => return Err(bad()),
    };
    sd_model::grid(fmin, fmax, n, log).map_err(|e| from_model("--grid", e))
}

pub fn run(cli: Cli) -> Result<(), CliError> {
    match cli.cmd {
        Cmd::C2d {
            model,
            ts,
            method,
            prewarp_hz,
            hold_delay,
            averaging,
            output,
        } => {
            let sys = read_model(&model)?;
            finite_pos(ts, "--ts")?;
            if prewarp_hz.is_some() && !matches!(method, Method::Tustin) {
                return Err(CliError::input(
                    "--prewarp-hz only applies to --method tustin",
                ));
            }
            if hold_delay.is_some() || averaging.is_some() {
                if !matches!(method, Method::Zoh) {
                    return Err(CliError::input(
                        "--hold-delay and --averaging apply to --method zoh (the default)",
                    ));
                }
                let ni = sd_multirate::NonIdeal {
                    hold_delay: hold_delay.unwrap_or(0.0),
                    averaging: averaging.unwrap_or(0.0),
                };
                let d = sd_multirate::c2d_nonideal(&sys, ts, ni)
                    .map_err(|e| from_multirate(&model, e))?;
                return emit(&model_json(&d)?, output.as_deref());
            }
            let m = match method {
                Method::Zoh => Discretization::Zoh,
                Method::Foh => Discretization::Foh,
                Method::Tustin => Discretization::Tustin { prewarp_hz },
            };
            let d = c2d(&sys, ts, m).map_err(|e| from_model(&model, e))?;
            emit(&model_json(&d)?, output.as_deref())
        }
        Cmd::D2c {
            model,
            max_hz,
            output,
        } => {
            let sys = read_model(&model)?;
            let ts = sys.ts().unwrap_or(1.0);
            let max_hz = finite_pos(max_hz.unwrap_or(3.0 / ts), "--max-hz")?;
            let (c, modes) = d2c_with_aliases(&sys, max_hz).map_err(|e| from_model(&model, e))?;
            emit(&model_json(&c)?, output.as_deref())?;
            eprintln!("mode alias candidates (Hz, damping) up to {max_hz} Hz:");
            for m in modes {
                let list: Vec<String> = m
                    .candidates
                    .iter()
                    .map(|(f, z)| format!("{f:.4} (ζ={z:.4})"))
                    .collect();
                eprintln!(
                    "  z = {:.6}{:+.6}i  principal {:.4} Hz ζ={:.5}: {}",
                    m.z.re,
                    m.z.im,
                    m.freq_hz,
                    m.damping,
                    list.join(", ")
                );
            }
            Ok(())
        }
        Cmd::Alias {
            freq_hz,
            rate_hz,
            max_hz,
            factor,
            json,
        } => {
            let a = sd_model::alias(freq_hz, rate_hz).map_err(|e| from_model("alias", e))?;
            let max_hz = max_hz.unwrap_or(5.0 * rate_hz);
            let folds = sd_model::folding_frequencies(a.alias_hz, rate_hz, max_hz)
                .map_err(|e| from_model("alias", e))?;
            let fast = match factor {
                Some(f) => {
                    let f = factor_arg(f)?;
                    Some(
                        sd_multirate::fold_map(a.alias_hz, rate_hz, f)
                            .map_err(|e| from_multirate("alias", e))?,
                    )
                }
                None => None,
            };
            if json {
                let mut v = json!({
                    "freq_hz": a.freq_hz, "rate_hz": a.rate_hz, "alias_hz": a.alias_hz,
                    "fold_index": a.fold_index, "mirrored": a.mirrored,
                    "nyquist_hz": rate_hz / 2.0,
                    "folding_frequencies_hz": folds, "folding_max_hz": max_hz,
                });
                if let (Some(terms), Some(f)) = (&fast, factor) {
                    v["factor"] = json!(f);
                    v["fast_rate_hz"] = json!(rate_hz * f as f64);
                    v["fast_folds"] = terms
                        .iter()
                        .map(|t| json!({"k": t.k, "fast_hz": t.fast_hz, "weight": t.weight}))
                        .collect();
                }
                emit(&v.to_string(), None)
            } else {
                let list: Vec<String> = folds.iter().map(|f| format!("{f}")).collect();
                let mut text = format!(
                    "{} Hz sampled at {} Hz appears at {} Hz (fold index {}{}).\nContinuous frequencies up to {} Hz that appear there: {}",
                    a.freq_hz, a.rate_hz, a.alias_hz, a.fold_index, if a.mirrored { ", mirrored" } else { "" }, max_hz, list.join(", ")
                );
                if let (Some(terms), Some(f)) = (&fast, factor) {
                    let l: Vec<String> = terms
                        .iter()
                        .map(|t| format!("{} Hz (weight {:.4})", t.fast_hz, t.weight))
                        .collect();
                    text.push_str(&format!(
                        "\nAt {} Hz (F = {f}) through the slow hold, weights |H_F|/F: {}",
                        rate_hz * f as f64,
                        l.join(", ")
                    ));
                }
                emit(&text, None)
            }
        }
        Cmd::Loopshape {
            plant,
            w1,
            w2,
            factor,
            strictly_proper,
            json,
            output,
        } => {
            let p = read_model(&plant)?;
            let w1m = w1.as_deref().map(read_model).transpose()?;
            let w2m = w2.as_deref().map(read_model).transpose()?;
            let opt = sd_hinf::LoopshapeOptions {
                factor,
                strictly_proper,
            };
            let d = sd_hinf::loopshape(&p, w1m.as_ref(), w2m.as_ref(), &opt)
                .map_err(|e| from_hinf(&plant, e))?;
            if json {
                let parse = |m: &StateSpace| -> Result<serde_json::Value, CliError> {
                    serde_json::from_str(&model_json(m)?)
                        .map_err(|e| CliError::numerical(format!("model JSON: {e}")))
                };
                let v = json!({
                    "gamma_min": d.gamma_min,
                    "gamma": d.gamma,
                    "achieved": d.achieved,
                    "closed_loop_stable": d.closed_loop_stable,
                    "closed_loop_pole": d.closed_loop_pole,
                    "controller": parse(&d.controller)?,
                    "shaped_controller": parse(&d.shaped_controller)?,
                    "riccati": d.riccati.iter().map(|r| json!({"equation": r.name, "residual": r.residual, "condition": r.condition})).collect::<Vec<_>>(),
                });
                emit(&v.to_string(), output.as_deref())
            } else {
                eprintln!(
                    "γ_min {:.6}, γ {:.6}, achieved {:.6}, closed loop {}",
                    d.gamma_min,
                    d.gamma,
                    d.achieved,
                    if d.closed_loop_stable {
                        "stable"
                    } else {
                        "UNSTABLE"
                    }
                );
                emit(&model_json(&d.controller)?, output.as_deref())
            }
        }
        Cmd::Frf {
            manifest,
            experiment,
            excited_fraction,
            output,
        } => {
            let text = crate::io::read_text(&manifest)?;
            let specs = sd_ident::parse_manifest(&text).map_err(|e| from_ident(&manifest, e))?;
            let spec = specs
                .into_iter()
                .find(|s| s.name == experiment)
                .ok_or_else(|| {
                    CliError::input(format!("{manifest}: no experiment named `{experiment}`"))
                })?;
            let base = std::path::Path::new(&manifest)
                .parent()
                .map(|p| p.to_path_buf())
                .unwrap_or_default();
            let path = base.join(&spec.file);
            let file = std::fs::File::open(&path)
                .map_err(|e| CliError::input(format!("cannot open {}: {e}", path.display())))?;
            let exp = sd_ident::Experiment::from_reader(spec, std::io::BufReader::new(file))
                .map_err(|e| from_ident(&manifest, e))?;
            let fs = exp.spec.sample_rate_hz;
            let frd = match exp.spec.period_samples {
                Some(p) => {
                    let mut opt = sd_ident::PeriodicOptions::new(p, exp.spec.skip_periods);
                    if let Some(f) = excited_fraction {
                        if !(f.is_finite() && f > 0.0 && f < 1.0) {
                            return Err(CliError::input(format!(
                                "--excited-fraction {f} must be in (0, 1)"
                            )));
                        }
                        opt.excited_fraction = f;
                    }
                    sd_ident::frf_periodic(fs, exp.r.as_deref(), &exp.u, &exp.y, &opt)
                        .map_err(|e| from_ident(&experiment, e))?
                        .frd
                }
                None => {
                    let lo = sd_ident::LpmOptions::default();
                    match &exp.r {
                        Some(r) => sd_ident::lpm_closed_loop(fs, r, &exp.u, &exp.y, &lo),
                        None => {
                            let n = exp.u.len();
                            let x = nalgebra::DMatrix::from_column_slice(n, 1, &exp.u);
                            let z = nalgebra::DMatrix::from_column_slice(n, 1, &exp.y);
                            sd_ident::lpm(fs, &x, &z, &lo).map(|e| e.frd)
                        }
                    }
                    .map_err(|e| from_ident(&experiment, e))?
                }
            };
            let json = sd_model::frd_to_json_string(&frd).map_err(|e| from_model("output", e))?;
            emit(&json, output.as_deref())
        }
        Cmd::Fit {
            frd,
            order,
            rigid_body,
            strictly_proper,
            weighting,
            output,
        } => {
            let text = crate::io::read_text(&frd)?;
            let data = sd_model::frd_from_json_str(&text).map_err(|e| from_model(&frd, e))?;
            let opt = sd_ident::FitOptions {
                order,
                rigid_body,
                feedthrough: !strictly_proper,
                weighting: match weighting {
                    WeightingArg::Variance => sd_ident::Weighting::Variance,
                    WeightingArg::Relative => sd_ident::Weighting::Relative,
                    WeightingArg::Uniform => sd_ident::Weighting::Uniform,
                },
                ..Default::default()
            };
            let r = sd_ident::fit_with_progress(&data, &opt, &mut |p| {
                eprintln!(
                    "[fit] {} iteration {:>3}: cost {:.6e}",
                    p.stage, p.iteration, p.cost
                );
            })
            .map_err(|e| from_ident(&frd, e))?;
            eprintln!(
                "[fit] order {}: cost {:.6e}, median relative error {:.3} %",
                r.model.n(),
                r.cost,
                100.0 * r.median_rel_error
            );
            emit(&model_json(&r.model)?, output.as_deref())
        }
        Cmd::Analyze {
            plant,
            controller,
            json,
        } => {
            let p = read_model(&plant)?;
            let k = read_model(&controller)?;
            let cl =
                sd_analysis::ClosedLoop::new(&p, &k).map_err(|e| from_analysis("analyze", e))?;
            let s = cl.summary().map_err(|e| from_analysis("analyze", e))?;
            if json {
                let v = json!({
                    "stable": s.stable,
                    "closed_loop_radius": s.closed_loop_radius,
                    "bandwidth_hz": s.bandwidth_hz,
                    "sensitivity_peak_db": s.sensitivity_peak_db,
                    "sensitivity_peak_hz": s.sensitivity_peak_hz,
                    "gain_margin_db": s.gain_margin_db,
                    "phase_margin_deg": s.phase_margin_deg,
                    "modulus_margin": s.modulus_margin,
                });
                emit(&v.to_string(), None)
            } else {
                emit(
                    &format!(
                        "closed loop {} (spectral {} {:.6})\nbandwidth {:.3} Hz\n|S| peak {:.2} dB at {:.3} Hz (modulus margin {:.4})\ngain margin {:.2} dB, phase margin {:.2} deg",
                        if s.stable { "stable" } else { "UNSTABLE" },
                        if p.time().is_continuous() { "abscissa" } else { "radius" },
                        s.closed_loop_radius,
                        s.bandwidth_hz,
                        s.sensitivity_peak_db,
                        s.sensitivity_peak_hz,
                        s.modulus_margin,
                        s.gain_margin_db,
                        s.phase_margin_deg
                    ),
                    None,
                )
            }
        }
        Cmd::Intersample {
            plant_fast,
            controller,
            force_rms,
            sensor_rms,
            points,
            json,
        } => {
            let p = read_model(&plant_fast)?;
            let k = read_model(&controller)?;
            let (h, t) = match (p.ts(), k.ts()) {
                (Some(h), Some(t)) => (h, t),
                _ => {
                    return Err(CliError::input(
                        "intersample needs discrete plant and controller models",
                    ))
                }
            };
            let ratio = t / h;
            if !(ratio.is_finite() && ratio >= 1.0 && (ratio - ratio.round()).abs() <= 1e-9 * ratio)
            {
                return Err(CliError::input(format!(
                    "the controller period {t} s must be an integer multiple of the plant period {h} s"
                )));
            }
            for (v, what) in [(force_rms, "--force-rms"), (sensor_rms, "--sensor-rms")] {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(CliError::input(format!(
                        "{what} {v} must be finite and >= 0"
                    )));
                }
            }
            let (pd, pn) = (
                2.0 * h * force_rms * force_rms,
                2.0 * h * sensor_rms * sensor_rms,
            );
            let r =
                sd_analysis::intersample(&p, &k, ratio.round() as usize, &|_| pd, &|_| pn, points)
                    .map_err(|e| from_analysis("intersample", e))?;
            let argmax = |f: &[f64], v: &[f64]| {
                (0..v.len())
                    .max_by(|&a, &b| v[a].total_cmp(&v[b]))
                    .map(|i| f[i])
                    .unwrap_or(f64::NAN)
            };
            let (df, ds, dk) = (
                argmax(&r.fast_hz, &r.fast_psd),
                argmax(&r.slow_hz, &r.slow_psd),
                argmax(&r.slow_hz, &r.control_sensitivity),
            );
            if json {
                let v = json!({
                    "factor": ratio.round() as usize,
                    "rms_fast": r.rms_fast, "rms_slow": r.rms_slow,
                    "dominant_hz_fast": df, "dominant_hz_slow": ds,
                    "control_sensitivity_peak_hz": dk,
                    "fast_hz": r.fast_hz, "fast_psd": r.fast_psd,
                    "slow_hz": r.slow_hz, "slow_psd": r.slow_psd,
                    "control_sensitivity": r.control_sensitivity,
                });
                emit(&v.to_string(), None)
            } else {
                emit(
                    &format!(
                        "predicted error rms: fast rate {:.4e}, at the samples {:.4e}\ndominant frequency: fast {:.2} Hz, slow {:.2} Hz\n|K S| peaks at {:.2} Hz",
                        r.rms_fast, r.rms_slow, df, ds, dk
                    ),
                    None,
                )
            }
        }
        Cmd::Diagnose {
            manifest,
            model,
            out,
            alpha,
            max_order,
        } => {
            let text = crate::io::read_text(&manifest)?;
            let specs = sd_ident::parse_manifest(&text).map_err(|e| from_ident(&manifest, e))?;
            let base = std::path::Path::new(&manifest)
                .parent()
                .map(|p| p.to_path_buf())
                .unwrap_or_default();
            let mut exps = Vec::new();
            for spec in specs {
                let path = base.join(&spec.file);
                let file = std::fs::File::open(&path)
                    .map_err(|e| CliError::input(format!("cannot open {}: {e}", path.display())))?;
                exps.push(
                    sd_ident::Experiment::from_reader(spec, std::io::BufReader::new(file))
                        .map_err(|e| from_ident(&manifest, e))?,
                );
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
            .map_err(|e| match e {
                sd_diagnose::DiagnoseError::Numerical(_) => {
                    CliError::numerical(format!("{manifest}: {e}"))
                }
                _ => CliError::input(format!("{manifest}: {e}")),
            })?;
            std::fs::create_dir_all(&out)
                .map_err(|e| CliError::input(format!("cannot create {out}: {e}")))?;
            let dir = std::path::Path::new(&out);
            let js = serde_json::to_string_pretty(&d.to_json())
                .map_err(|e| CliError::numerical(format!("diagnosis JSON: {e}")))?;
            emit(&js, Some(&dir.join("diagnosis.json").to_string_lossy()))?;
            let figs = sd_report::diagnosis::write(dir, &d, &manifest)
                .map_err(|e| CliError::input(e.to_string()))?;
            let gain = match d.gain_ratio() {
                Some(r) => format!("held-out gain ×{r:.1}"),
                None => "no held-out gain".into(),
            };
            eprintln!(
                "[diagnose] {} / {} {} ({gain}); report.md and {} figures in {out}",
                d.verdict,
                d.cause,
                d.parameters,
                figs.len()
            );
            Ok(())
        }
        Cmd::Testbed { config, out } => {
            let text = match &config {
                Some(path) => crate::io::read_text(path)?,
                None => DEFAULT_TESTBED.to_string(),
            };
            let label = config.as_deref().unwrap_or("default configuration");
            let cfg = sd_testbed::parse_config(&text).map_err(|e| from_testbed(label, e))?;
            let data = sd_testbed::run_config(&cfg).map_err(|e| from_testbed(label, e))?;
            std::fs::create_dir_all(&out)
                .map_err(|e| CliError::input(format!("cannot create {out}: {e}")))?;
            let dir = std::path::Path::new(&out);
            for d in &data {
                let p = dir.join(format!("{}.csv", d.name));
                emit(&d.csv(), Some(&p.to_string_lossy()))?;
            }
            emit(
                &sd_testbed::manifest(&data),
                Some(&dir.join("experiments.toml").to_string_lossy()),
            )?;
            let truth = sd_testbed::truth_model(&cfg.truth).map_err(|e| from_testbed(label, e))?;
            emit(
                &model_json(&truth)?,
                Some(&dir.join("truth.json").to_string_lossy()),
            )?;
            eprintln!(
                "[testbed] {} experiments written to {out} (experiments.toml, truth.json)",
                data.len()
            );
            Ok(())
        }
        Cmd::Weight { kind } => {
            let (w, output) = match kind {
                WeightKind::Pid {
                    bandwidth_hz,
                    mass,
                    ts,
                    integrator_ratio,
                    lead_ratio,
                    lowpass_ratio,
                    lowpass_zeta,
                    output,
                } => {
                    let opt = sd_hinf::weights::PidOptions {
                        integrator_ratio,
                        lead_ratio,
                        lowpass_ratio,
                        lowpass_zeta,
                    };
                    (sd_hinf::weights::pid(bandwidth_hz, mass, ts, &opt), output)
                }
                WeightKind::Notch {
                    freq_hz,
                    zeta_zero,
                    zeta_pole,
                    ts,
                    output,
                } => (
                    sd_hinf::weights::notch(freq_hz, zeta_zero, zeta_pole, ts),
                    output,
                ),
                WeightKind::Lowpass {
                    freq_hz,
                    zeta,
                    ts,
                    output,
                } => (sd_hinf::weights::lowpass(freq_hz, zeta, ts), output),
            };
            let w = w.map_err(|e| from_hinf("weight", e))?;
            emit(&model_json(&w)?, output.as_deref())
        }
        Cmd::Downsample {
            model,
            factor,
            hold_delay,
            averaging,
            output,
        } => {
            let sys = read_model(&model)?;
            let f = factor_arg(factor)?;
            let ni = sd_multirate::NonIdeal {
                hold_delay: hold_delay.unwrap_or(0.0),
                averaging: averaging.unwrap_or(0.0),
            };
            let d = sd_multirate::downsample_nonideal(&sys, f, ni)
                .map_err(|e| from_multirate(&model, e))?;
            emit(&model_json(&d)?, output.as_deref())
        }
        Cmd::Freqresp {
            model,
            grid,
            output,
        } => {
            let sys = read_model(&model)?;
            let f = parse_grid(&grid)?;
            if let Some(ny) = sys.time().nyquist_hz() {
                if let Some(fm) = f.iter().cloned().reduce(f64::max) {
                    if fm > ny * (1.0 + 1e-12) {
                        return Err(CliError::input(format!("--grid {grid}: FMAX = {fm} Hz is above the model's Nyquist frequency {ny} Hz")));
                    }
                }
            }
            let frd = sys.freqresp(&f).map_err(|e| from_model(&model, e))?;
            let txt = sd_model::frd_to_json_string(&frd).map_err(|e| from_model("output", e))?;
            emit(&txt, output.as_deref())
        }
        Cmd::Poles { model, json } => roots(&model, json, true),
        Cmd::Zeros { model, json } => roots(&model, json, false),
        Cmd::Norm { model, json } => {
            let sys = read_model(&model)?;
            let hinf = sys.hinf_norm().map_err(|e| from_model(&model, e))?;
            let h2 = sys.h2_norm().ok();
            if json {
                emit(
                    &json!({"hinf": if hinf.value.is_finite() { json!(hinf.value) } else { json!("inf") },
                            "hinf_db": if hinf.value.is_finite() { json!(20.0 * hinf.value.log10()) } else { json!("inf") },
                            "peak_hz": hinf.peak_hz, "stable": hinf.stable,
                            "h2": h2.map(|v| json!(v)).unwrap_or(json!("inf"))})
                    .to_string(),
                    None,
                )
            } else {
                emit(
                    &format!(
                        "H-infinity norm {} ({:.3} dB) at {:.6} Hz{}\nH2 norm {}",
                        hinf.value,
                        20.0 * hinf.value.log10(),
                        hinf.peak_hz,
                        if hinf.stable {
                            ""
                        } else {
                            " (unstable model: L-infinity norm)"
                        },
                        h2.map(|v| v.to_string()).unwrap_or_else(|| "inf".into())
                    ),
                    None,
                )
            }
        }
        Cmd::Reduce {
            model,
            order,
            output,
        } => {
            let sys = read_model(&model)?;
            let r = sys
                .balanced_truncation(order)
                .map_err(|e| from_model(&model, e))?;
            emit(&model_json(&r.model)?, output.as_deref())?;
            eprintln!(
                "balanced truncation {} -> {} states ({} unstable/marginal kept); error bound ‖G−Gr‖∞ ≤ {:.6e}",
                sys.n(),
                r.model.n(),
                r.n_unstable,
                r.error_bound
            );
            let hs: Vec<String> = r
                .hankel_sv
                .iter()
                .take(20)
                .map(|v| format!("{v:.4e}"))
                .collect();
            eprintln!("Hankel singular values (stable part): {}", hs.join(" "));
            Ok(())
        }
        Cmd::Connect {
            kind,
            a,
            b,
            sign,
            output,
        } => {
            let ga = read_model(&a)?;
            let gb = read_model(&b)?;
            let r = match kind {
                Conn::Series => sd_model::series(&ga, &gb),
                Conn::Parallel => sd_model::parallel(&ga, &gb),
                Conn::Feedback => sd_model::feedback(&ga, &gb, sign),
            }
            .map_err(|e| from_model("connect", e))?;
            emit(&model_json(&r)?, output.as_deref())
        }
    }
}

fn roots(model: &str, json: bool, poles: bool) -> Result<(), CliError> {
    let sys = read_model(model)?;
    let r = if poles { sys.poles() } else { sys.zeros() }.map_err(|e| from_model(model, e))?;
    let ts = sys.ts();
    if json {
        let v: Vec<_> = r
            .iter()
            .map(|p| {
                let (f, z) = pole_info(*p, ts);
                json!({"re": p.re, "im": p.im, "freq_hz": f, "damping": z})
            })
            .collect();
        emit(&serde_json::Value::Array(v).to_string(), None)
    } else {
        let mut s = format!(
            "{:>24} {:>24} {:>14} {:>10}\n",
            "re", "im", "freq_hz", "damping"
        );
        for p in &r {
            let (f, z) = pole_info(*p, ts);
            s += &format!(
                "{:>24.16e} {:>24.16e} {:>14.6} {:>10.6}\n",
                p.re, p.im, f, z
            );
        }
        emit(s.trim_end(), None)
    }
}

fn factor_arg(f: i64) -> Result<usize, CliError> {
    if f < 1 || f > sd_multirate::tol::MAX_FACTOR as i64 {
        return Err(CliError::input(format!(
            "--factor {f}: the rate factor must be an integer in 1..={}",
            sd_multirate::tol::MAX_FACTOR
        )));
    }
    Ok(f as usize)
}

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
