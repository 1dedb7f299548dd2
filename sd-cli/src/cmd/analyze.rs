//! `sdctl analyze`.

use crate::cmd::uncertainty::{from_unc, read_bound_and_weight};
use crate::io::{atomic_svg, emit, from_analysis, read_model, read_text, CliError};
use serde_json::json;

/// Arguments of `sdctl analyze`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Plant model JSON (same sample time as the controller).
    #[arg(
        long,
        required_unless_present = "plant_frd",
        conflicts_with = "plant_frd"
    )]
    pub(crate) plant: Option<String>,
    /// A *measured* plant instead of a model: FRD JSON (from `sdctl frf`). The loop is
    /// analysed on its lines: L, S, T, margins between lines, the Nyquist test.
    #[arg(long)]
    pub(crate) plant_frd: Option<String>,
    #[command(flatten)]
    pub(crate) measured: crate::cmd::analyze_measured::MeasuredArgs,
    /// Controller model JSON (negative feedback u = −K y).
    #[arg(long)]
    pub(crate) controller: String,
    /// Uncertainty JSON at the loop's sample time (from `sdctl uncertainty` or `sdctl
    /// downsample --uncertainty`, or a model carrying one): robust stability against it
    /// (margin > 1: robustly stable). A plant file that carries its bound is used by default.
    #[arg(long)]
    pub(crate) uncertainty: Option<String>,
    /// Fit an overbounding weight of this order for the margin between the lines when the
    /// uncertainty file has none.
    #[arg(long)]
    pub(crate) weight_order: Option<usize>,
    /// Write the destabilising plant inside the bound (when there is one) to this model JSON.
    #[arg(long)]
    pub(crate) destabilising_out: Option<String>,
    /// Write the singular values of S, T and KS against frequency (largest and smallest, dB)
    /// to this SVG file.
    #[arg(long)]
    pub(crate) sigma_svg: Option<String>,
    /// Write the characteristic loci (eigenvalues of L = PK along the frequency axis, on a
    /// compressed radius log10(1 + |λ|)) with the critical point −1 to this SVG file.
    #[arg(long)]
    pub(crate) nyquist_svg: Option<String>,
    /// Write the loop gain L = PK (SISO) as a Bode figure with the gain and phase margins
    /// marked where they occur to this SVG file (also spelt --bode-svg).
    #[arg(long, visible_alias = "bode-svg")]
    pub(crate) loop_svg: Option<String>,
    #[arg(help = crate::commands::JSON_HELP, long)]
    pub(crate) json: bool,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            plant,
            plant_frd,
            measured,
            controller,
            uncertainty,
            weight_order,
            destabilising_out,
            sigma_svg,
            nyquist_svg,
            loop_svg,
            json,
        } = self;
        let plant = match (plant, plant_frd) {
            (_, Some(frd)) => {
                if uncertainty.is_some() || sigma_svg.is_some() || destabilising_out.is_some() {
                    return Err(CliError::input(
                        "--plant-frd takes --loop-svg, --nyquist-svg, --s-out, --t-out and \
                         --json; --uncertainty, --sigma-svg and --destabilising-out need a plant \
                         model (--plant)",
                    ));
                }
                let figures = (loop_svg.as_deref(), nyquist_svg.as_deref());
                return measured.run(&frd, &controller, figures, json);
            }
            (Some(p), None) => p,
            (None, None) => return Err(CliError::input("give --plant MODEL or --plant-frd FRD")),
        };
        measured.refuse_without_frd()?;
        let p = read_model(&plant)?;
        let k = read_model(&controller)?;
        let cl = sd_analysis::ClosedLoop::new(&p, &k).map_err(|e| from_analysis("analyze", e))?;
        let s = cl.summary().map_err(|e| from_analysis("analyze", e))?;
        // loop-at-a-time and disk margins of every channel (a stable loop only)
        let lat = if s.stable {
            Some(sd_analysis::mimo_margins(&cl).map_err(|e| from_analysis("analyze", e))?)
        } else {
            None
        };
        // the generalised Nyquist criterion, an independent check of the eigenvalues' verdict
        let nyq = sd_analysis::generalized_nyquist(&cl).map_err(|e| from_analysis("analyze", e))?;
        if let Some(path) = &sigma_svg {
            sigma_plot(&cl, &p, path)?;
        }
        if let Some(path) = &nyquist_svg {
            loci_plot(&cl, &p, path)?;
        }
        if let Some(path) = &loop_svg {
            loop_plot((&p, &k), &s, path)?;
        }
        // a plant file that carries its bound is judged against it unless another is given
        let uncertainty = uncertainty.or_else(|| {
            let carried = read_text(&plant).is_ok_and(|t| sd_uncertainty::carries(&t));
            if carried {
                eprintln!("[analyze] {plant} carries its uncertainty: robust stability against it");
            }
            carried.then(|| plant.clone())
        });
        if uncertainty.is_none() && (weight_order.is_some() || destabilising_out.is_some()) {
            return Err(CliError::input(
                "--weight-order and --destabilising-out need --uncertainty (or a plant file \
                 that carries its bound)",
            ));
        }
        let robust = uncertainty
            .as_deref()
            .map(|u| robust(&p, &k, u, weight_order, destabilising_out.as_deref()))
            .transpose()?;
        if json {
            let mut v = serde_json::to_value(&s)
                .map_err(|e| CliError::numerical(format!("summary JSON: {e}")))?;
            if let (Some(r), Some(obj)) = (&robust, v.as_object_mut()) {
                obj.insert("robust".into(), json!(r));
            }
            if let (Some(m), Some(obj)) = (&lat, v.as_object_mut()) {
                obj.insert("loop_at_a_time".into(), json!(m));
            }
            if let Some(obj) = v.as_object_mut() {
                obj.insert("nyquist".into(), json!(nyq));
            }
            emit(&v.to_string(), None)
        } else {
            let mut extra = robust
                .as_ref()
                .map_or(String::new(), |r| format!("\n{}", robust_text(r)));
            extra.push_str(&nyquist_text(&nyq, p.time().is_continuous()));
            if let Some(m) = &lat {
                extra.push_str(&channels_text(m));
            }
            emit(
            &(format!(
                "closed loop {} (spectral {} {:.6})\ncrossover {:.3} Hz (|L| = 1), closed-loop bandwidth {:.3} Hz (|T| −3 dB)\n|S| peak {:.2} dB at {:.3} Hz (modulus margin {:.4})\ngain margin {}, phase margin {}",
                if s.stable { "stable" } else { "UNSTABLE" },
                if p.time().is_continuous() { "abscissa" } else { "radius" },
                s.closed_loop_radius,
                s.crossover_hz,
                s.bandwidth_hz,
                s.sensitivity_peak_db,
                s.sensitivity_peak_hz,
                s.modulus_margin,
                margin_text(s.gain_margin_db, s.gain_margin_hz, "dB"),
                margin_text(s.phase_margin_deg, s.phase_margin_hz, "deg"),
            ) + &extra),
            None,
        )
        }
    }
}

/// Robust stability against the uncertainty file `path` (its weight, or one fitted of
/// `weight_order`), writing the destabilising plant to `out` when there is one.
fn robust(
    p: &sd_model::StateSpace,
    k: &sd_model::StateSpace,
    path: &str,
    weight_order: Option<usize>,
    out: Option<&str>,
) -> Result<sd_uncertainty::Robust, CliError> {
    let (bound, weight) = read_bound_and_weight(path, weight_order)?;
    let r = sd_uncertainty::robust_stability(p, k, &bound, weight.as_ref())
        .map_err(|e| from_unc(path, e))?;
    if let Some(out) = out {
        match &r.destabilising {
            Some(d) => {
                let text = sd_model::model_to_json_string(&d.plant)
                    .map_err(|e| crate::io::from_model("--destabilising-out", e))?;
                emit(&text, Some(out))?;
            }
            None => eprintln!(
                "[analyze] no destabilising plant inside the bound: nothing written to {out}"
            ),
        }
    }
    Ok(r)
}

/// The robust-stability lines of the text output.
fn robust_text(r: &sd_uncertainty::Robust) -> String {
    let form = match r.form {
        sd_uncertainty::Form::Additive => "additive (|W K S| < 1)",
        sd_uncertainty::Form::Multiplicative => "multiplicative (|W T| < 1)",
    };
    let verdict = |m: f64| {
        if m > 1.0 {
            "robustly stable"
        } else {
            "NOT robustly stable"
        }
    };
    let mut t = if r.nominal_stable {
        format!(
            "robust stability, {form}: margin {:.3} on the bound's lines (worst at {:.2} Hz): {}",
            r.margin_lines,
            r.worst_line_hz,
            verdict(r.margin_lines)
        )
    } else {
        "robust stability: the nominal loop is unstable (margin 0)".to_string()
    };
    if let (Some(m), Some(f)) = (r.margin_weight, r.weight_peak_hz) {
        t += &format!(
            "\nwith the overbounding weight (between the lines too): margin {m:.3} (peak at \
             {f:.2} Hz): {}",
            verdict(m)
        );
    }
    if r.nominal_stable {
        t += &format!(
            "\nworst-case |S| over the bound: {:.2} dB at {:.2} Hz",
            r.worst_sensitivity_db, r.worst_sensitivity_hz
        );
    }
    if let Some(d) = &r.destabilising {
        t += &format!(
            "\na plant inside the bound that this controller does not stabilise: |Δ| = {:.3e} \
             at {:.2} Hz (bound {:.3e}; at most {:.3} of the bound on every line), closed-loop \
             radius {:.6}; reduce {} near {:.0} Hz (less gain there, or more phase margin)",
            d.magnitude,
            d.freq_hz,
            d.bound_at,
            d.max_ratio_to_bound,
            d.closed_loop_radius,
            match r.form {
                sd_uncertainty::Form::Additive => "|K S|",
                sd_uncertainty::Form::Multiplicative => "|T|",
            },
            d.freq_hz
        );
    }
    t
}

/// The generalised Nyquist criterion as one line (and a warning when it disagrees with the
/// closed loop's eigenvalues).
fn nyquist_text(n: &sd_analysis::Nyquist, continuous: bool) -> String {
    let region = if continuous {
        "in the right half-plane"
    } else {
        "outside the unit circle"
    };
    let mut t = format!(
        "\ngeneralised Nyquist: det(I + L) encircles the origin {} time(s) counterclockwise; \
         open-loop poles {region}: {}; closed-loop poles {region}: {} (eigenvalues: {})",
        n.encirclements,
        n.open_loop_unstable,
        n.closed_loop_unstable,
        n.closed_loop_unstable_eigenvalues
    );
    if !n.agrees {
        t.push_str(
            "\nWARNING: the criterion and the closed-loop eigenvalues disagree: a pole near the \
             stability boundary or an ill-conditioned realisation; check the loop's poles",
        );
    }
    t
}

/// A margin with where it is read: `6.02 dB at 12.345 Hz`, or `inf dB (no crossing)`.
fn margin_text(value: f64, at_hz: f64, unit: &str) -> String {
    if at_hz.is_finite() {
        format!("{value:.2} {unit} at {at_hz:.3} Hz")
    } else {
        format!("{value:.2} {unit} (no crossing)")
    }
}

/// The loop-at-a-time margins as text, one line per channel.
fn channels_text(m: &sd_analysis::MimoMargins) -> String {
    let mut out = String::new();
    for c in &m.channels {
        out.push_str(&format!(
            "\n{} {} (loop at a time): gain margin {:.2} dB, phase margin {:.2} deg; disk margin \
             {:.3} (gain ±{:.2} dB, phase ±{:.2} deg)",
            match c.side {
                sd_analysis::Side::Input => "input",
                sd_analysis::Side::Output => "output",
            },
            c.channel + 1,
            c.gain_margin_db,
            c.phase_margin_deg,
            c.disk_margin,
            c.disk_gain_margin_db,
            c.disk_phase_margin_deg
        ));
    }
    out.push_str(&format!(
        "\nsimultaneous disk margin, unstructured (every channel at once, coupled; a lower \
         bound): inputs {:.3}, outputs {:.3}",
        m.simultaneous_input_disk_margin, m.simultaneous_output_disk_margin
    ));
    for (side, s) in [
        ("input", &m.structured_input_disk_margin),
        ("output", &m.structured_output_disk_margin),
    ] {
        if let Some(s) = s {
            out.push_str(&format!(
                "\nsimultaneous disk margin, structured (μ: each {side} channel on its own, all \
                 {side}s at once): {:.3} (at most {:.3}) at {:.3} Hz: gain ±{:.2} dB, phase ±{:.2} deg",
                s.margin, s.margin_upper, s.freq_hz, s.gain_margin_db, s.phase_margin_deg
            ));
        }
    }
    out
}

/// The analysis grid (Hz): up to Nyquist for a discrete loop.
fn analysis_grid(p: &sd_model::StateSpace, n: usize) -> Result<(Vec<f64>, f64, f64), CliError> {
    let (lo, hi) = match p.time() {
        sd_model::SampleTime::Discrete { ts } => (1e-3 * 0.5 / ts, 0.4999 / ts),
        sd_model::SampleTime::Continuous => (1e-2, 1e4),
    };
    let f = sd_model::grid(lo, hi, n, true).map_err(|e| crate::io::from_model("analyze", e))?;
    Ok((f, lo, hi))
}

/// The characteristic loci on a compressed radius `log10(1 + |λ|)` (phase kept), with the
/// critical point −1 and the unit circle, as an SVG written atomically.
fn loci_plot(
    cl: &sd_analysis::ClosedLoop,
    p: &sd_model::StateSpace,
    path: &str,
) -> Result<(), CliError> {
    let (f, _, _) = analysis_grid(p, 2000)?;
    let loci = sd_analysis::characteristic_loci(cl, &f).map_err(|e| from_analysis("analyze", e))?;
    let title = format!(
        "characteristic loci of L = PK ({}x{} loop), radius log10(1 + |λ|)",
        p.ny(),
        p.ny()
    );
    let names: Vec<String> = (0..loci.len())
        .map(|i| format!("locus {}", i + 1))
        .collect();
    loci_figure(&loci, &names, &title, path)
}

/// Loci in the complex plane on a compressed radius `log10(1 + |λ|)` (phase kept), each with
/// its mirror image (negative frequencies), the unit circle and the critical point −1, as an
/// SVG written atomically.
pub(crate) fn loci_figure(
    loci: &[Vec<num_complex::Complex64>],
    names: &[String],
    title: &str,
    path: &str,
) -> Result<(), CliError> {
    let squash = |z: &num_complex::Complex64| {
        let r = z.norm();
        if r > 0.0 {
            *z * ((1.0 + r).log10() / r)
        } else {
            *z
        }
    };
    // each locus and its mirror image (negative frequencies)
    let mut xy: Vec<(Vec<f64>, Vec<f64>)> = Vec::new();
    for l in loci {
        let pts: Vec<num_complex::Complex64> = l.iter().map(squash).collect();
        xy.push((
            pts.iter().map(|z| z.re).collect(),
            pts.iter().map(|z| z.im).collect(),
        ));
        xy.push((
            pts.iter().map(|z| z.re).collect(),
            pts.iter().map(|z| -z.im).collect(),
        ));
    }
    let unit: Vec<num_complex::Complex64> = (0..=360)
        .map(|d| {
            squash(&num_complex::Complex64::from_polar(
                1.0,
                f64::from(d).to_radians(),
            ))
        })
        .collect();
    let (ux, uy): (Vec<f64>, Vec<f64>) = unit.iter().map(|z| (z.re, z.im)).unzip();
    // the critical point's cross, 2 % of the figure's extent
    let extent = xy
        .iter()
        .flat_map(|(x, y)| x.iter().chain(y))
        .filter(|v| v.is_finite())
        .fold(1.0f64, |m, v| m.max(v.abs()));
    let (c, e) = (2f64.log10(), 0.02 * extent);
    let (cx, cy) = (vec![-c - e, -c + e, -c, -c, -c], vec![0.0, 0.0, 0.0, e, -e]);
    use sd_report::plot::{Line, RGBColor};
    let palette = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
    ];
    let mut lines: Vec<Line<'_>> = xy
        .iter()
        .enumerate()
        .map(|(i, (x, y))| Line {
            label: if i % 2 == 0 { &names[i / 2] } else { "" },
            x,
            y,
            color: palette[(i / 2) % palette.len()],
        })
        .collect();
    lines.push(Line {
        label: "|λ| = 1",
        x: &ux,
        y: &uy,
        color: RGBColor(170, 170, 170),
    });
    lines.push(Line {
        label: "critical point −1",
        x: &cx,
        y: &cy,
        color: RGBColor(0, 0, 0),
    });
    atomic_svg(path, |tmp| {
        sd_report::plot::plane_plot(
            tmp,
            title,
            "real part (compressed)",
            "imaginary part (compressed)",
            &lines,
        )
    })
}

/// σ_max and σ_min of S, T and KS against frequency (dB) as an SVG, written atomically.
fn sigma_plot(
    cl: &sd_analysis::ClosedLoop,
    p: &sd_model::StateSpace,
    path: &str,
) -> Result<(), CliError> {
    let (f, lo, hi) = analysis_grid(p, 600)?;
    let sv = sd_analysis::singular_values(cl, &f).map_err(|e| from_analysis("analyze", e))?;
    let db = |m: &[Vec<f64>], last: bool| -> Vec<f64> {
        m.iter()
            .map(|v| {
                let x = if last { v.last() } else { v.first() };
                20.0 * x.copied().unwrap_or(f64::NAN).max(1e-300).log10()
            })
            .collect()
    };
    let (s_hi, s_lo, t_hi, ks_hi) = (
        db(&sv.s, false),
        db(&sv.s, true),
        db(&sv.t, false),
        db(&sv.ks, false),
    );
    use sd_report::plot::{Curve, RGBColor};
    let curves = [
        Curve {
            label: "σ_max(S)",
            freq_hz: &f,
            db: &s_hi,
            color: RGBColor(31, 119, 180),
        },
        Curve {
            label: "σ_min(S)",
            freq_hz: &f,
            db: &s_lo,
            color: RGBColor(158, 202, 225),
        },
        Curve {
            label: "σ_max(T)",
            freq_hz: &f,
            db: &t_hi,
            color: RGBColor(214, 39, 40),
        },
        Curve {
            label: "σ_max(KS)",
            freq_hz: &f,
            db: &ks_hi,
            color: RGBColor(44, 160, 44),
        },
    ];
    let title = format!(
        "singular values of the closed loop ({}x{} plant)",
        p.ny(),
        p.nu()
    );
    atomic_svg(path, |tmp| {
        sd_report::plot::magnitude_plot(tmp, &title, &curves, lo, hi, &[])
    })
}

/// The loop gain `L = PK` of a SISO loop as a Bode figure, with the gain and phase margins
/// marked at their frequencies (the summary's), written atomically.
fn loop_plot(
    (p, k): (&sd_model::StateSpace, &sd_model::StateSpace),
    s: &sd_analysis::Summary,
    path: &str,
) -> Result<(), CliError> {
    if (p.ny(), p.nu()) != (1, 1) {
        return Err(CliError::input(format!(
            "--loop-svg draws a SISO loop; the plant is {}x{} (use --sigma-svg or --nyquist-svg)",
            p.ny(),
            p.nu()
        )));
    }
    let (f, lo, hi) = analysis_grid(p, 2000)?;
    let ev = |m: &sd_model::StateSpace| {
        sd_model::FreqRespEvaluator::new(m)
            .map(|e| e.eval_many_flat(&f))
            .map_err(|e| crate::io::from_model("analyze", e))
    };
    let l: Vec<num_complex::Complex64> = ev(p)?.iter().zip(ev(k)?).map(|(a, b)| a * b).collect();
    let m = LoopMarks {
        phase_margin: (s.phase_margin_deg, s.phase_margin_hz),
        gain_margin: (s.gain_margin_db, s.gain_margin_hz),
        sensitivity_peak_db: s.sensitivity_peak_db,
    };
    loop_figure((&f, &l, "L = PK"), m, (lo, hi), path)
}

/// The margins a loop-gain figure marks: `(value, Hz)` each, and the |S| peak for the title.
pub(crate) struct LoopMarks {
    pub(crate) phase_margin: (f64, f64),
    pub(crate) gain_margin: (f64, f64),
    pub(crate) sensitivity_peak_db: f64,
}

/// The loop gain `l` at `f` (Hz) as a Bode figure over `band`, the margins marked where they
/// occur, written atomically to `path`.
pub(crate) fn loop_figure(
    (f, l, label): (&[f64], &[num_complex::Complex64], &str),
    m: LoopMarks,
    band: (f64, f64),
    path: &str,
) -> Result<(), CliError> {
    let db: Vec<f64> = l.iter().map(|g| 20.0 * g.norm().log10()).collect();
    let ph =
        sd_report::plot::unwrap_deg(&l.iter().map(|g| g.arg().to_degrees()).collect::<Vec<_>>());
    let mut marks: Vec<(f64, String)> = Vec::new();
    let (pm, pm_hz) = m.phase_margin;
    if pm_hz.is_finite() && pm_hz > 0.0 {
        marks.push((pm_hz, format!("PM {pm:.1}° @ {pm_hz:.2} Hz")));
    }
    let (gm, gm_hz) = m.gain_margin;
    if gm_hz.is_finite() && gm_hz > 0.0 {
        marks.push((gm_hz, format!("GM {gm:.1} dB @ {gm_hz:.2} Hz")));
    }
    let mark_refs: Vec<(f64, &str)> = marks.iter().map(|(f, t)| (*f, t.as_str())).collect();
    use sd_report::plot::{Curve, RGBColor};
    let curves = [Curve {
        label,
        freq_hz: f,
        db: &db,
        color: RGBColor(31, 119, 180),
    }];
    let title = format!(
        "loop gain: phase margin {pm:.1}°, gain margin {gm:.1} dB, |S| peak {:.1} dB",
        m.sensitivity_peak_db
    );
    atomic_svg(path, |tmp| {
        sd_report::plot::bode_plot_in(tmp, &title, &curves, &[Some(&ph)], band, &mark_refs, "")
    })
}
