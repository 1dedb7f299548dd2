//! The MIMO diagnosis as a person reads it: `diagnosis.json`, `model.json` and `report.md`
//! (per channel its rate-tied parameter, per entry its agreement at the slower rates, the gain
//! and what to do next).

use crate::{ReportError, Result};
use sd_diagnose::{ChannelKind, MimoDiagnosis, Verdict};
use std::fmt::Write as _;
use std::path::Path;

/// A channel's name as the report prints it (1-based; a clock by its set's experiments).
fn channel_name(d: &MimoDiagnosis, kind: ChannelKind, c: usize) -> String {
    match kind {
        ChannelKind::Actuator => format!("actuator {}", c + 1),
        ChannelKind::Sensor => format!("sensor {}", c + 1),
        ChannelKind::Clock => d.validation.get(c).map_or_else(
            || format!("clock of slower set {}", c + 1),
            |(names, f)| format!("clock of {} (F = {f})", names.join(", ")),
        ),
    }
}

/// A channel's parameter with its standard error, in the report's units.
fn parameter_text(kind: ChannelKind, v: f64, std: f64) -> String {
    match kind {
        ChannelKind::Clock => format!("{:+.4} % ± {:.4} % of the period", 100.0 * v, 100.0 * std),
        _ => format!("{v:.4} ± {std:.4} of the sample period"),
    }
}

/// One line per named cause.
pub fn mimo_causes_text(d: &MimoDiagnosis) -> Vec<String> {
    d.channels
        .iter()
        .filter(|c| c.named)
        .map(|c| {
            let what = match c.kind {
                ChannelKind::Actuator => "hold delay",
                ChannelKind::Sensor => "averaging window",
                ChannelKind::Clock => "error",
            };
            format!(
                "{} {what} {}",
                channel_name(d, c.kind, c.channel),
                parameter_text(c.kind, c.fraction, c.fraction_std)
            )
        })
        .collect()
}

/// `report.md` of a MIMO diagnosis.
pub fn mimo_report(d: &MimoDiagnosis, title: &str) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Diagnosis (MIMO): {title}\n");
    let causes = mimo_causes_text(d);
    let _ = writeln!(
        md,
        "**Verdict: {}**{}\n",
        d.verdict,
        if causes.is_empty() {
            String::new()
        } else {
            format!(" — {}", causes.join("; "))
        }
    );
    let _ = writeln!(
        md,
        "Plant {}×{} (outputs × inputs). Model: one set of poles for every entry, order {}, {} \
         states, fitted to {} (cost {:.0} over {} entry lines; about one per line for a fit \
         within the noise). Slower sets: {}.\n",
        d.shape.0,
        d.shape.1,
        d.order,
        d.states,
        d.model_experiments.join(", "),
        d.fit_cost,
        d.fit_lines,
        d.validation
            .iter()
            .map(|(n, f)| format!("{} (F = {f})", n.join(", ")))
            .collect::<Vec<_>>()
            .join("; ")
    );
    md.push_str(
        "## Channels\n\nEach actuator's hold delay acts on its column, each sensor's averaging \
         window on its row, each slower set's clock error (true period = nominal·(1 + e)) on \
         every entry of that set. Statistic: the mean score over the channel's entries' lines at \
         the slower rates it acts on (1 at the noise level), without and with the parameter.\n\n\
         | channel | parameter | named | without | with | threshold |\n\
         |---|---|---|---|---|---|\n",
    );
    for c in &d.channels {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} | {:.2} | {:.2} |",
            channel_name(d, c.kind, c.channel),
            parameter_text(c.kind, c.fraction, c.fraction_std),
            if c.named { "yes" } else { "no" },
            c.before.value,
            c.after.value,
            c.before.threshold
        );
    }
    md.push_str(
        "\n## Entries\n\nThe model's simulation at the slower rates (Lemma 6) and the extended \
         model's, per entry.\n\n| output | input | model | extended | threshold |\n\
         |---|---|---|---|---|\n",
    );
    for e in &d.entries {
        let _ = writeln!(
            md,
            "| {} | {} | {:.2} | {:.2} | {:.2} |",
            e.output + 1,
            e.input + 1,
            e.plain.value,
            e.extended.value,
            e.plain.threshold
        );
    }
    if let Some(g) = &d.gain {
        let _ = writeln!(
            md,
            "\n## Gain\n\nThe model's statistic over the extension's on {}: ×{:.1}{}.",
            g.measured_on.join(", "),
            g.ratio,
            if g.held_out {
                " (each slower set held out of the parameters' fit in turn; a set with a named \
                 clock error judged on its later periods, its clock fitted on the earlier ones)"
            } else {
                " (measured on the data the parameters were fitted on: with one slower set \
                 nothing is held out)"
            }
        );
    }
    md.push_str("\n## What to do next\n\n");
    md.push_str(&match (d.verdict, causes.is_empty()) {
        (Verdict::Consistent, _) => "The model predicts every entry at every slower rate within \
            the noise: design on it (`sdctl downsample`, `sdctl loopshape`)."
            .to_string(),
        (Verdict::Discrepancy, false) => "Model the named channels' timing in the plant at the \
            controller's rate (a hold that switches the named fraction of the period late on \
            that actuator's input, or the averaging window on that sensor's output), or fix the \
            actuator's or sensor's timing in the hardware; a named clock error means that set's \
            sample clock is off (check the timer's crystal or divider: its period, not the \
            plant, differs); the entries above show what the extension leaves."
            .to_string(),
        (Verdict::Discrepancy, true) => "The slower rates disagree and no channel's delay or \
            averaging explains it: look at the entries with the largest statistic (a mode the \
            fast data do not see, drift, or nonlinearity; the single-channel `sdctl diagnose` on \
            a SISO experiment set says more)."
            .to_string(),
    });
    md.push('\n');
    md
}

/// `entry_<output>_<input>.svg` per entry (1-based): Bode plot of the measured FRF at the
/// slowest rate with the model's simulation and the extended model's; the file names.
fn entry_figures(dir: &Path, d: &MimoDiagnosis) -> Result<Vec<String>> {
    use crate::plot::{bode_plot, Curve};
    use plotters::style::RGBColor;
    let db = |x: &[num_complex::Complex64]| -> Vec<f64> {
        x.iter().map(|v| 20.0 * v.norm().log10()).collect()
    };
    let deg = |x: &[num_complex::Complex64]| -> Vec<f64> {
        x.iter().map(|v| v.arg().to_degrees()).collect()
    };
    let mut names = Vec::new();
    for c in &d.curves {
        let (Some(&lo), Some(&hi)) = (c.freq_hz.first(), c.freq_hz.last()) else {
            continue;
        };
        let name = format!("entry_{}_{}.svg", c.output + 1, c.input + 1);
        let (dm, dp, de) = (db(&c.measured), db(&c.model), db(&c.extended));
        let (pm, pp, pe) = (deg(&c.measured), deg(&c.model), deg(&c.extended));
        let curves = [
            Curve {
                label: "measured",
                freq_hz: &c.freq_hz,
                db: &dm,
                color: RGBColor(0, 0, 0),
            },
            Curve {
                label: "model (Lemma 6)",
                freq_hz: &c.freq_hz,
                db: &dp,
                color: RGBColor(200, 30, 30),
            },
            Curve {
                label: "extended model",
                freq_hz: &c.freq_hz,
                db: &de,
                color: RGBColor(20, 110, 200),
            },
        ];
        let title = format!(
            "output {} / input {} at 1/{} of the model rate [m/N]",
            c.output + 1,
            c.input + 1,
            c.factor
        );
        let path = dir.join(&name).to_string_lossy().into_owned();
        bode_plot(
            &path,
            &title,
            &curves,
            &[Some(&pm), Some(&pp), Some(&pe)],
            lo,
            hi,
            &[],
        )?;
        names.push(name);
    }
    Ok(names)
}

/// Writes `diagnosis.json` (with `"kind": "mimo"`), `model.json`, `report.md` and one Bode
/// figure per entry at the slowest rate (`entry_<output>_<input>.svg`) into `dir`.
///
/// # Errors
/// A file that cannot be written; the model cannot be serialised.
pub fn write_mimo(dir: &Path, d: &MimoDiagnosis, title: &str) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|source| ReportError::Io {
        path: dir.display().to_string(),
        source,
    })?;
    let js =
        serde_json::to_string_pretty(&d.to_json()).map_err(|e| ReportError::Json(e.to_string()))?;
    crate::write_atomic(&dir.join("diagnosis.json"), &js)?;
    let model =
        sd_model::model_to_json_string(&d.model).map_err(|e| ReportError::Json(e.to_string()))?;
    crate::write_atomic(&dir.join("model.json"), &model)?;
    let figures = entry_figures(dir, d)?;
    let mut md = mimo_report(d, title);
    if !figures.is_empty() {
        md.push_str(
            "\n## Figures\n\nEach entry at the slowest rate: measured, the model's \
            simulation and the extended model's (magnitude in dB of m/N, phase in degrees).\n\n",
        );
        for f in &figures {
            md.push_str(&format!("- [{f}]({f})\n"));
        }
    }
    crate::write_atomic(&dir.join("report.md"), &md)
}
