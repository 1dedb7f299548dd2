//! `sdctl analyze --plant-frd`: a controller model on a measured plant FRF
//! ([`sd_analysis::analyze_measured`]), optionally a slow controller on a fast FRF through
//! Lemma 6's fold sum ([`sd_multirate::downsample_frd`]).

use crate::cmd::analyze::{loci_figure, loop_figure, LoopMarks};
use crate::io::{emit, from_analysis, from_model, from_multirate, read_model, read_text, CliError};
use sd_analysis::{MeasuredAnalysis, MeasuredNyquist, MeasuredPlant};
use serde_json::json;

/// The options of `sdctl analyze` that only a measured plant takes.
#[derive(clap::Args, Debug)]
pub(crate) struct MeasuredArgs {
    /// With --plant-frd: the FRF is at the fast rate 1/h and the controller at T = F·h; fold
    /// the FRF to the controller's rate first (Lemma 6, no model).
    #[arg(long)]
    pub(crate) downsample: Option<usize>,
    /// With --plant-frd: the plant's poles at z = 1 / s = 0 (a rigid body: 2). Default: read
    /// from the lowest decade of lines (SISO).
    #[arg(long)]
    pub(crate) plant_integrators: Option<usize>,
    /// With --plant-frd: the plant's poles in the unstable region (default 0).
    #[arg(long, default_value_t = 0)]
    pub(crate) plant_unstable_poles: usize,
    /// With --plant-frd: write S = (I + L)⁻¹ on the lines to this FRD JSON.
    #[arg(long)]
    pub(crate) s_out: Option<String>,
    /// With --plant-frd: write T = L(I + L)⁻¹ on the lines to this FRD JSON.
    #[arg(long)]
    pub(crate) t_out: Option<String>,
}

impl MeasuredArgs {
    /// Refuses the measured-plant options beside a plant model (never silently ignored).
    pub(crate) fn refuse_without_frd(&self) -> Result<(), CliError> {
        let given = [
            ("--downsample", self.downsample.is_some()),
            ("--plant-integrators", self.plant_integrators.is_some()),
            ("--plant-unstable-poles", self.plant_unstable_poles != 0),
            ("--s-out", self.s_out.is_some()),
            ("--t-out", self.t_out.is_some()),
        ];
        match given.iter().find(|g| g.1) {
            Some((name, _)) => Err(CliError::input(format!(
                "{name} applies to a measured plant (--plant-frd); with a plant model use \
                 `sdctl downsample` and the model's own poles"
            ))),
            None => Ok(()),
        }
    }

    /// Runs the analysis on the FRD at `frd_path` with the controller at `k_path`.
    pub(crate) fn run(
        self,
        frd_path: &str,
        k_path: &str,
        (loop_svg, nyquist_svg): (Option<&str>, Option<&str>),
        json: bool,
    ) -> Result<(), CliError> {
        let mut frd = sd_model::frd_from_json_str(&read_text(frd_path)?)
            .map_err(|e| from_model(frd_path, e))?;
        let mut folded = None;
        if let Some(factor) = self.downsample {
            let d = sd_multirate::downsample_frd(&frd, factor, None)
                .map_err(|e| from_multirate(frd_path, e))?;
            if !d.missing_hz.is_empty() {
                eprintln!(
                    "[analyze] {} slow line(s) left out: a fold frequency is not a line of the \
                     fast FRF",
                    d.missing_hz.len()
                );
            }
            folded = Some(json!({"factor": factor, "lines": d.frd.len(),
                "missing_hz": d.missing_hz}));
            frd = d.frd;
        }
        let k = read_model(k_path)?;
        let plant = MeasuredPlant {
            integrators: self.plant_integrators,
            unstable_poles: self.plant_unstable_poles,
        };
        let (a, resp) = sd_analysis::analyze_measured(&frd, &k, plant)
            .map_err(|e| from_analysis("analyze --plant-frd", e))?;
        for (out, m) in [(&self.s_out, &resp.s), (&self.t_out, &resp.t)] {
            if let Some(out) = out {
                let text = sd_model::frd_to_json_string(m).map_err(|e| from_model(out, e))?;
                emit(&text, Some(out))?;
            }
        }
        figures(&a, &resp, (loop_svg, nyquist_svg))?;
        if json {
            let mut v = serde_json::to_value(&a)
                .map_err(|e| CliError::numerical(format!("summary JSON: {e}")))?;
            if let (Some(f), Some(obj)) = (folded, v.as_object_mut()) {
                obj.insert("downsampled".into(), f);
            }
            emit(&v.to_string(), None)
        } else {
            emit(&text(&a, self.downsample), None)
        }
    }
}

/// The loop-gain and Nyquist figures of a SISO measured loop.
fn figures(
    a: &MeasuredAnalysis,
    resp: &sd_analysis::MeasuredResponses,
    (loop_svg, nyquist_svg): (Option<&str>, Option<&str>),
) -> Result<(), CliError> {
    let siso = resp.l.response().first().is_some_and(|r| r.len() == 1);
    if !siso && (loop_svg.is_some() || nyquist_svg.is_some()) {
        return Err(CliError::input(
            "--loop-svg and --nyquist-svg draw a SISO measured loop",
        ));
    }
    let f = resp.l.freq_hz();
    let l: Vec<num_complex::Complex64> = resp.l.response().iter().map(|r| r[(0, 0)]).collect();
    if let Some(path) = loop_svg {
        let m = LoopMarks {
            phase_margin: (a.phase_margin_deg, a.phase_margin_hz),
            gain_margin: (a.gain_margin_db, a.gain_margin_hz),
            sensitivity_peak_db: a.sensitivity_peak_db,
        };
        loop_figure((f, &l, "L = PK on the measured lines"), m, a.band_hz, path)?;
    }
    if let Some(path) = nyquist_svg {
        let title = format!(
            "Nyquist plot of L = PK on {} measured lines, radius log10(1 + |L|)",
            a.lines
        );
        loci_figure(&[l], &["L = PK on the lines".to_string()], &title, path)?;
    }
    Ok(())
}

/// The report of a measured loop, read by people.
fn text(a: &MeasuredAnalysis, factor: Option<usize>) -> String {
    let mut t = format!(
        "measured plant: {} lines {:.4}–{:.4} Hz (spacing ≤ {:.4} Hz){}; plant integrators {} \
         ({})\n",
        a.lines,
        a.band_hz.0,
        a.band_hz.1,
        a.max_line_spacing_hz,
        factor.map_or(String::new(), |f| format!(
            ", folded from the fast FRF by Lemma 6 (F = {f})"
        )),
        a.plant_integrators,
        if a.integrators_from_lines {
            "read from the lowest lines"
        } else {
            "as stated"
        }
    );
    t += &match &a.nyquist {
        MeasuredNyquist::Counted {
            encirclements,
            open_loop_unstable,
            closed_loop_unstable,
            stable,
            loop_integrators,
            largest_step_deg,
        } => format!(
            "closed loop {} by the Nyquist test on the lines: det(I + L) encircles the origin \
             {encirclements} time(s) counterclockwise, open-loop unstable poles \
             {open_loop_unstable}, closed-loop unstable poles {closed_loop_unstable} ({} loop \
             integrator(s); largest turn between lines {largest_step_deg:.1}°)",
            if *stable { "stable" } else { "UNSTABLE" },
            loop_integrators
        ),
        MeasuredNyquist::Undetermined { reason } => {
            format!("closed-loop stability UNDETERMINED by the lines: {reason}")
        }
    };
    let hz = |v: f64| {
        if v.is_finite() {
            format!(" at {v:.3} Hz")
        } else {
            " (no crossing in the measured band)".into()
        }
    };
    t += &format!(
        "\ncrossover{} (|L| = 1 between lines)\n|S| peak {:.2} dB at {:.3} Hz (modulus margin \
         {:.4}), |T| peak {:.2} dB at {:.3} Hz: the largest over the lines; between lines it \
         can be higher",
        hz(a.crossover_hz),
        a.sensitivity_peak_db,
        a.sensitivity_peak_hz,
        a.modulus_margin,
        a.complementary_peak_db,
        a.complementary_peak_hz
    );
    if a.gain_margin_db.is_nan() {
        t += "\ngain and phase margins: MIMO loop (see the Nyquist verdict and the peaks)";
    } else {
        t += &format!(
            "\ngain margin {:.2} dB{}, phase margin {:.2} deg{} (interpolated between lines)",
            a.gain_margin_db,
            hz(a.gain_margin_hz),
            a.phase_margin_deg,
            hz(a.phase_margin_hz)
        );
    }
    t
}
