//! The diagnosis as a person reads it: `report.md` and SVG figures.
//!
//! Figures per experiment: `frf_<name>.svg` (measured FRF against the model's simulation and
//! the extended model's, with the noise level), `residual_<name>.svg` (|measured − simulated|
//! before and after the extension against the noise level σ), and for periodic experiments
//! `time_<name>.svg` (one averaged steady period: the measured output and the errors of both
//! simulations).

use crate::plot::{bode_plot, line_plot, magnitude_plot, Curve, Line};
use crate::{ReportError, Result};
use num_complex::Complex64 as C;
use plotters::style::RGBColor;
use sd_diagnose::{
    Cause, CornerTrend, DampingTrend, Diagnosis, DriftCheck, DriftSign, ExperimentReport,
    Extension, FreqTrend, PoleKind,
};
use std::fmt::Write as _;
use std::path::Path;

mod causes;
mod data;
mod figures;
mod tracks;
use causes::*;
pub use causes::{cause_text, causes_text};
use data::{bla_section, own_excess, own_fit_sentence, pieces_section};
use figures::*;
pub(crate) use figures::{db, deg, magnitude_figure, MEASURED, MODEL};
use tracks::{tracks_figure, tracks_section};

/// A file-name-safe version of an experiment name.
pub(crate) fn slug(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// What the extension is, in words.
pub fn describe(h: &Extension) -> String {
    match h {
        Extension::None => "none".into(),
        Extension::RateTied(p) => {
            let mut parts = Vec::new();
            if p.hold_delay > 0.0 {
                parts.push(format!(
                    "hold switching {:.3} of each sample period late",
                    p.hold_delay
                ));
            }
            if p.averaging > 0.0 {
                parts.push(format!(
                    "sensor averaging over {:.3} of each sample period",
                    p.averaging
                ));
            }
            if !p.clock_error.is_empty() {
                let e: Vec<String> = p
                    .clock_error
                    .iter()
                    .map(|e| format!("{:+.3} %", 100.0 * e))
                    .collect();
                parts.push(format!("sample clock off by {}", e.join(", ")));
            }
            if parts.is_empty() {
                "the plain continuous modal model".into()
            } else {
                parts.join("; ")
            }
        }
        Extension::FastFrf => {
            "the measured fast FRF in place of the model (model-free Lemma 6)".into()
        }
        Extension::PerLevel => "one best linear approximation per excitation level".into(),
        Extension::Amplitude(modes) => {
            let m: Vec<String> = modes
                .iter()
                .map(|m| {
                    format!(
                        "the {:.1} Hz mode's {}",
                        m.linear_freq_hz,
                        match (m.frequency_moves, m.damping_moves) {
                            (true, true) => "frequency and damping",
                            (true, false) => "frequency",
                            _ => "damping",
                        }
                    )
                })
                .collect();
            format!(
                "the modal model with amplitude-dependent modes: {}, as trends in the mode's \
                 output amplitude",
                m.join("; ")
            )
        }
    }
}

/// Writes `report.md` and the figures of a diagnosis into `dir` (which must exist); returns
/// the figure file names.
///
/// # Errors
/// A figure or the report cannot be written.
pub fn write(dir: &Path, d: &Diagnosis, title: &str) -> Result<Vec<String>> {
    let ext_label = match d.extension {
        Extension::RateTied(_) => "extended model",
        Extension::FastFrf => "model-free Lemma 6",
        _ => "extended",
    };
    let mut figs = Vec::new();
    for x in &d.experiments {
        figs.extend(figures(dir, x, ext_label)?);
    }
    figs.extend(amplitude_figures(dir, d)?);
    figs.extend(tracks_figure(dir, d)?);
    let md = markdown(d, title, &figs);
    crate::write_atomic(&dir.join("report.md"), &md)?;
    Ok(figs)
}

/// Everything a diagnosis writes, for `sdctl diagnose` and `cargo xtask paper` alike:
/// `diagnosis.json` (its fields in docs/diagnosis.md), the model files, `predictor.json` (what
/// `sdctl predict` reads, docs/formats.md), `next_experiment.toml` where the diagnosis proposes
/// one (an `sdctl testbed` experiment table), `report.md` and the
/// figures, into `dir` (created when missing); returns the figure file names. Each file is
/// written atomically; `sdctl diagnose` stages the whole folder so that a run is published as
/// a whole.
///
/// # Errors
/// The folder, a figure or a file cannot be written.
pub fn write_all(dir: &Path, d: &Diagnosis, title: &str) -> Result<Vec<String>> {
    std::fs::create_dir_all(dir).map_err(|source| ReportError::Io {
        path: dir.display().to_string(),
        source,
    })?;
    let js =
        serde_json::to_string_pretty(&d.to_json()).map_err(|e| ReportError::Json(e.to_string()))?;
    crate::write_atomic(&dir.join("diagnosis.json"), &js)?;
    for (file, model) in model_files(d) {
        let text =
            sd_model::model_to_json_string(model).map_err(|e| ReportError::Json(e.to_string()))?;
        crate::write_atomic(&dir.join(&file), &text)?;
    }
    let predictor = d
        .predictor
        .to_json_string()
        .map_err(|e| ReportError::Json(e.to_string()))?;
    crate::write_atomic(&dir.join("predictor.json"), &predictor)?;
    if let Some(n) = &d.next_experiment {
        crate::write_atomic(&dir.join("next_experiment.toml"), &n.testbed_toml())?;
    }
    write(dir, d, title)
}

/// The model files a diagnosis writes: `model.json` (the model judged), `extended_model.json`
/// (the rate-tied extension as a continuous model) and `extended_model_<experiment>.json` (the
/// extended model at each experiment's rate, where the extension is a model).
pub fn model_files(d: &Diagnosis) -> Vec<(String, &sd_model::StateSpace)> {
    let mut out = vec![("model.json".to_string(), &d.model)];
    if let Some(x) = &d.extended_model {
        out.push(("extended_model.json".into(), &x.continuous));
    }
    for x in &d.experiments {
        if let Some(m) = &x.extended_model {
            out.push((format!("extended_model_{}.json", file_safe(&x.name)), m));
        }
    }
    out
}

/// An experiment name as part of a file name (anything but letters, digits, `-`, `_` and `.`
/// becomes `_`).
fn file_safe(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The slowest experiment (largest rate factor), where a controller would run.
fn slowest(d: &Diagnosis) -> Option<&ExperimentReport> {
    d.experiments.iter().max_by_key(|x| x.factor)
}

/// "What to do next": the files written and the commands that use them, from the verdict and
/// the named causes.
fn next_steps(md: &mut String, d: &Diagnosis) {
    let _ = writeln!(md, "\n## Next steps\n");
    let files: Vec<String> = model_files(d)
        .iter()
        .map(|(f, _)| format!("`{f}`"))
        .collect();
    let _ = writeln!(
        md,
        "Model files written beside this report: {}.\n",
        files.join(", ")
    );
    let slow = slowest(d);
    let (ts, factor) = slow
        .map(|x| (1.0 / x.rate_hz, x.factor))
        .unwrap_or((d.model.ts().unwrap_or(0.0), 1));
    let names: Vec<&str> = d.causes.iter().map(Cause::name).collect();
    if d.verdict == sd_diagnose::Verdict::Consistent {
        let _ = writeln!(
            md,
            "- The model reproduces every experiment within the noise: design on it. \
             `sdctl downsample model.json --factor {factor} -o plant_slow.json` gives the plant at \
             {:.6} s (Lemma 6); then `sdctl analyze --plant plant_slow.json --controller \
             controller.json` checks a controller on it.",
            ts
        );
        return;
    }
    if let Some(x) = &d.extended_model {
        let _ = writeln!(
            md,
            "- Design on the extended model: `sdctl c2d extended_model.json --ts {ts:.6} \
             --hold-delay {:.4} --averaging {:.4} -o plant_slow.json` discretises it with the named \
             hold and sampler at the controller's period; then \
             `sdctl analyze --plant plant_slow.json --controller controller.json` checks a \
             controller on it.",
            x.hold_delay, x.averaging
        );
    }
    if let Some(n) = &d.next_experiment {
        next_experiment_step(md, n);
    }
    if let Some(sd_diagnose::next_experiment::NoProposal::NothingSeparates {
        best_power,
        most_periods,
        slowest_factor,
    }) = &d.no_next_experiment
    {
        let _ = writeln!(
            md,
            "- The explanations in the ranking that fit alike cannot be told apart by another \
             rate either: no repeat of a slower experiment at 1/2 to 1/{slowest_factor} of the \
             model experiment's rate with up to {most_periods} steady periods separates them \
             with probability 0.9 (the best reached {best_power:.2}): they act alike at every \
             rate searched. The timing of the hold and the sampler in the hardware, or a \
             repeat of the model experiment, decides instead."
        );
    }
    for name in names {
        let step = match name {
            "clock_error" => {
                "- A sample clock runs off its nominal period: check the time base \
                 of the named experiments' data acquisition; the extended models \
                 `extended_model_<experiment>.json` include the measured error."
            }
            "fast_model_error" => {
                "- The experiments agree with each other but the model misses \
                 them: fit a higher order (`sdctl diagnose ... --max-order N` with N above the \
                 model's order, or `sdctl fit frd.json --order N`) or pass a better model with \
                 `--model`."
            }
            "nonlinearity" => {
                "- The dynamics depend on the excitation level: design at the level \
                 of operation (`extended_model_<experiment>.json` is the model at each measured \
                 level) and check the controller on the models of the other levels."
            }
            "drift" => {
                "- The plant changed with time between the experiments: repeat the model \
                 experiment after the others and fit the model on data taken in the state the \
                 controller will meet."
            }
            // the proposed experiment's bullet above says what to do
            "unexplained" if d.next_experiment.is_some() || d.no_next_experiment.is_some() => {
                continue
            }
            "unexplained" => {
                "- No cataloged cause explains the excess (see the best partial \
                 explanation above): check that the rates are exact integer ratios, the timing \
                 of hold and sampler, and the sensor chain; a repeat of the model experiment \
                 separates drift from a rate effect."
            }
            _ => continue,
        };
        let _ = writeln!(md, "{step}");
    }
}

/// The "Next steps" bullet of a proposed experiment ([`sd_diagnose::NextExperiment`]).
fn next_experiment_step(md: &mut String, n: &sd_diagnose::NextExperiment) {
    // rates and band edges to the millihertz, without trailing zeros
    let hz = |v: f64| format!("{}", (v * 1e3).round() / 1e3);
    let expected: Vec<String> = n
        .expected_statistic
        .iter()
        .map(|(h, v)| format!("{h} would read {v:.2}"))
        .collect();
    let others = if n.alternatives_hz.is_empty() {
        String::new()
    } else {
        let rates: Vec<String> = n.alternatives_hz.iter().map(|f| hz(*f)).collect();
        format!(" Other rates that would also do: {} Hz.", rates.join(", "))
    };
    let _ = writeln!(
        md,
        "- **The experiment that decides** between {}: repeat `{}` at {} Hz (the model \
         experiment's rate / {}), {} steady periods of {} samples after {} transient ({:.1} s), \
         band {}–{} Hz, excitation rms {:.4e} {} as in `{}` (level {:.2} of the model \
         experiment's), injected {}. If one were true, the other would show the \
         statistic (1 = noise level): {}; the diagnosis with it separates them with probability \
         {:.3} (predicted from the fitted hypotheses and the noise of `{}`). \
         `next_experiment.toml` is its `[[experiment]]` table for `sdctl testbed`; on the \
         stage, add the record to the manifest and run `sdctl diagnose` again.{}",
        n.separates.join(" and "),
        n.like,
        hz(n.rate_hz),
        n.factor,
        n.periods,
        n.period_samples,
        n.transient_periods,
        n.duration_s,
        hz(n.band_hz[0]),
        hz(n.band_hz[1]),
        n.rms,
        match n.injection {
            sd_diagnose::Injection::Input => "N",
            sd_diagnose::Injection::Reference => "m",
        },
        n.like,
        n.level,
        match n.injection {
            sd_diagnose::Injection::Input => "as a force at the plant input",
            sd_diagnose::Injection::Reference => "in the position reference",
        },
        expected.join(", "),
        n.power,
        n.like,
        others
    );
}

/// A table cell: the number (3 decimals, or 3 significant digits in scientific notation), or
/// "–" when there is none or it is not finite.
fn cell(v: Option<f64>, sci: bool) -> String {
    match v.filter(|e| e.is_finite()) {
        Some(e) if sci => format!("{e:.3e}"),
        Some(e) => format!("{e:.3}"),
        None => "–".into(),
    }
}

/// The hypotheses, the evidence and the held-out gain of `report.md`.
fn hypotheses_section(md: &mut String, d: &Diagnosis) {
    let _ = writeln!(
        md,
        "\n## Hypotheses\n\nFitted on the training data (earlier periods), ranked by the penalised criterion \
         (score sum + ½ ln K per parameter), judged on the held-out data.\n\n| hypothesis | \
         parameters | statistic (training) | criterion | statistic (held out) |\n|---|---|---|---|---|"
    );
    for r in &d.ranking {
        let _ = writeln!(
            md,
            "| {} | {} | {:.3} | {:.1} | {} |",
            r.cause,
            r.n_params,
            r.cost,
            r.criterion,
            cell(r.held_out, false)
        );
    }
    if let Some(p) = &d.partial {
        match &d.next_experiment {
            Some(n) => {
                let _ = writeln!(
                    md,
                    "\nBest partial explanation: {} (held-out statistic {}), not named: {} \
                     explain the data alike (see Next steps for the experiment that separates \
                     them).",
                    p.cause,
                    cell(p.held_out, false),
                    n.separates.join(" and ")
                );
            }
            None => {
                let _ = writeln!(
                    md,
                    "\nBest partial explanation (not named: {}): {}.",
                    d.gain.why.as_deref().map_or_else(
                        || format!(
                            "its held-out statistic {} is above the threshold",
                            cell(p.held_out, false)
                        ),
                        str::to_string
                    ),
                    p.cause
                );
            }
        }
    }
    let _ = writeln!(
        md,
        "\nExtension: {}.\n\n## Evidence\n\n| test | statistic | threshold | passed |\n|---|---|---|---|",
        describe(&d.extension)
    );
    for e in &d.evidence {
        let _ = writeln!(
            md,
            "| {} | {:.3} | {:.3} | {} |",
            e.test,
            e.statistic,
            e.threshold,
            if e.passed { "yes" } else { "**no**" }
        );
    }
    let failed: Vec<&sd_diagnose::Evidence> = d.evidence.iter().filter(|e| !e.passed).collect();
    if !failed.is_empty() {
        let _ = writeln!(
            md,
            "\nWhy the failed rows failed, beside the verdict `{}`:\n",
            d.verdict
        );
        for e in failed {
            let _ = writeln!(md, "- *{}*: {}.", e.test, explain_failed(d, e));
        }
    }
    let g = &d.gain;
    let _ = match (g.before, g.after, g.ratio) {
        (Some(b), Some(a), Some(r)) => writeln!(
            md,
            "\n## Gain on held-out data\n\nStatistic {b:.3} before (plain modal model) and {a:.3} \
             after the extension: ratio {r:.1} (held out: {}).",
            g.held_out.join(", ")
        ),
        _ => writeln!(
            md,
            "\n## Gain on held-out data\n\nNot measured: {}.",
            g.why.as_deref().unwrap_or("no held-out data")
        ),
    };
    held_out_levels(md, d);
}

/// Per held-out experiment (levels left out in turn): the linear model's statistic, the
/// extension's, their ratio, and the experiment's own fit in the extension's model class (the
/// floor a prediction can approach).
fn held_out_levels(md: &mut String, d: &Diagnosis) {
    let rows: Vec<(&str, sd_diagnose::HeldOut)> = d
        .experiments
        .iter()
        .filter_map(|x| x.held_out.map(|h| (x.name.as_str(), h)))
        .collect();
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "\nEach experiment left out in turn (statistics on its lines in the moving modes' bands; \
         1 is the noise):\n\n| experiment | linear model | extension | ratio | own fit (floor) | \
         |---|---|---|---|---|---|"
    );
    for (name, h) in rows {
        let _ = writeln!(
            md,
            "| {name} | {:.3} | {:.3} | {:.1} | {} | {} |",
            h.before,
            h.after,
            h.ratio,
            cell(Some(h.floor), false),
            if h.extrapolated {
                "extrapolated: beyond the fitted amplitudes"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(
        md,
        "\nAn extension statistic near the floor means the prediction from the other experiments \
         does as well as a fit to this experiment's own data in the same model class; well above \
         it, the trend between the levels is what misses (more levels, or a level nearer this \
         one, would help)."
    );
}

/// The modes that move with amplitude: per mode its trend and every level's fit, with the
/// frequency and damping the model fitted without that level predicted for it.
fn moving_modes_section(md: &mut String, d: &Diagnosis) {
    for c in &d.causes {
        let Cause::Nonlinearity { modes, .. } = c else {
            continue;
        };
        if modes.is_empty() {
            continue;
        }
        let _ = writeln!(md, "## Modes (and poles) that move with amplitude\n");
        let _ = writeln!(
            md,
            "Amplitude: rms of the measured output in the mode's band (f ± max(3ζ, 2 %) f), \
             relative to the model experiment's (ρ). Trend: value = at ρ = 1 + slope·(ρ^k − \
             1).\n"
        );
        for m in modes {
            if m.pole == PoleKind::Real {
                corner_rows(md, m);
                continue;
            }
            let _ = writeln!(
                md,
                "**Mode at {:.2} Hz (ζ = {:.4} linear).** Frequency {}: {:.2} ± {:.2} Hz + \
                 ({:.3} ± {:.3}) Hz·(ρ^{} − 1); damping {}: {:.4} + ({:.2e} ± {:.1e})·(ρ^{} − 1).\n",
                m.linear_freq_hz,
                m.linear_damping,
                if m.frequency_moves { "moves" } else { "does not move beyond its errors" },
                m.frequency.at_reference,
                m.frequency.at_reference_std,
                m.frequency.slope,
                m.frequency.slope_std,
                m.frequency.exponent,
                if m.damping_moves { "moves" } else { "does not move beyond its errors" },
                m.damping.at_reference,
                m.damping.slope,
                m.damping.slope_std,
                m.damping.exponent
            );
            points_table(md, m);
        }
    }
}

/// A friction-damped rigid body's corner: its trend and every level's point.
fn corner_rows(md: &mut String, m: &sd_diagnose::MovingMode) {
    let _ = writeln!(
        md,
        "**Damped rigid body, corner at {:.2} Hz linear** (the pole −2πf of `1/(s(s + a))`: \
         friction's equivalent damping over the mass). Corner {}: {:.2} ± {:.2} Hz + ({:.3} ± \
         {:.3}) Hz·(ρ^{} − 1).\n",
        m.linear_freq_hz,
        if m.frequency_moves {
            "moves"
        } else {
            "does not move beyond its errors"
        },
        m.frequency.at_reference,
        m.frequency.at_reference_std,
        m.frequency.slope,
        m.frequency.slope_std,
        m.frequency.exponent
    );
    points_table(md, m);
}

/// Every level's point of a moving pole: frequency and damping of a mode, the corner of a
/// real pole, with what the model fitted without that level predicted.
fn points_table(md: &mut String, m: &sd_diagnose::MovingMode) {
    let real = m.pole == PoleKind::Real;
    let _ = writeln!(
        md,
        "{}",
        if real {
            "| experiment | ρ | corner [Hz] | predicted without it [Hz] |\n|---|---|---|---|"
        } else {
            "| experiment | ρ | frequency [Hz] | damping | predicted without it [Hz, ζ] |\n|---|---|---|---|---|"
        }
    );
    for p in &m.points {
        let damping = if real {
            String::new()
        } else {
            format!(" {:.4} ± {:.4} |", p.damping, p.damping_std)
        };
        let predicted = p.held_out_prediction.map_or("–".to_string(), |(f, z)| {
            if real {
                format!("{f:.2}")
            } else {
                format!("{f:.2}, {z:.4}")
            }
        });
        let _ = writeln!(
            md,
            "| {} | {:.2} | {:.2} ± {:.2} |{damping} {predicted} |",
            p.experiment, p.relative_amplitude, p.freq_hz, p.freq_hz_std,
        );
    }
    let _ = writeln!(md);
}

/// The text of `report.md`.
pub fn markdown(d: &Diagnosis, title: &str, figures: &[String]) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# Diagnosis of {title}\n");
    let named = causes_text(d);
    let _ = writeln!(
        md,
        "**Verdict: {}. Cause: {}.**{}\n",
        d.verdict,
        d.cause,
        if named.is_empty() {
            String::new()
        } else {
            format!(" {}.", named.join("; "))
        }
    );
    let _ = writeln!(
        md,
        "The model: {} ({} states at {:.6} s).\n",
        d.model_source(),
        d.model.n(),
        d.model.ts().unwrap_or(0.0)
    );
    own_fit_sentence(&mut md, d);
    bla_section(&mut md, d);
    pieces_section(&mut md, d);
    tracks_section(&mut md, d);
    moving_modes_section(&mut md, d);
    let _ = writeln!(md, "## What the model's simulation gets wrong\n");
    let _ = writeln!(
        md,
        "Statistic: mean calibrated score per line (|P_meas − P_sim|²/variance, corrected for \
         the degrees of freedom of the estimated variances); 1 is the noise level; a \
         discrepancy is above the threshold at false-alarm probability {} (per test: shared \
         by the verdict's tests).\n",
        d.alpha
    );
    let _ = writeln!(
        md,
        "| experiment | rate [Hz] | F | level | lines | threshold | model-free Lemma 6 | model | extended |\n|---|---|---|---|---|---|---|---|---|"
    );
    for x in &d.experiments {
        let _ = writeln!(
            md,
            "| {} ({:?}) | {} | {} | {:.2} | {} | {:.3} | {} | {:.3} | {} |",
            x.name,
            x.role,
            x.rate_hz,
            x.factor,
            x.relative_level,
            x.model_stat.lines,
            x.model_stat.threshold,
            cell(x.model_free.map(|m| m.value), false),
            x.model_stat.value,
            cell(x.extended_stat.map(|m| m.value), false)
        );
    }
    for x in &d.experiments {
        if x.bands.is_empty() {
            continue;
        }
        let _ = writeln!(
            md,
            "\n**{}**: bands where the model misses beyond 3σ (largest share of the statistic first)\n\n| band [Hz] | worst line [Hz] | measured/simulated [dB] | phase [°] | comes from [Hz] | share |\n|---|---|---|---|---|---|",
            x.name
        );
        for b in &x.bands {
            let _ = writeln!(
                md,
                "| {:.1}–{:.1} | {:.1} | {:+.2} | {:+.1} | {:.1} | {:.0} % |",
                b.f_lo,
                b.f_hi,
                b.worst_hz,
                b.worst_db,
                b.worst_deg,
                b.from_fast_hz,
                100.0 * b.share
            );
        }
    }
    let tds: Vec<&ExperimentReport> = d
        .experiments
        .iter()
        .filter(|x| x.time_domain.is_some())
        .collect();
    if !tds.is_empty() {
        let _ = writeln!(
            md,
            "\n## Time domain (measured input through the model, one averaged steady period)\n\nAll bins where the input is measured, then only the bands above (where a discrepancy of the\nfrequency domain shows in time without the low-frequency input noise around it).\n\n| experiment | output rms | noise rms | error rms, model | error rms, extended | in the bands: noise | model | extended |\n|---|---|---|---|---|---|---|---|"
        );
        for x in tds {
            if let Some(t) = &x.time_domain {
                let opt = |v: Option<f64>| cell(v, true);
                let _ = writeln!(
                    md,
                    "| {} | {:.3e} | {} | {:.3e} | {} | {} | {} | {} |",
                    x.name,
                    t.output_rms,
                    opt(t.noise_rms),
                    t.error_rms_model,
                    opt(t.error_rms_extended),
                    opt(t.in_bands.map(|b| b.noise_rms)),
                    opt(t.in_bands.map(|b| b.error_rms_model)),
                    opt(t.in_bands.and_then(|b| b.error_rms_extended)),
                );
            }
        }
    }
    hypotheses_section(&mut md, d);
    next_steps(&mut md, d);
    if !figures.is_empty() {
        let _ = writeln!(md, "\n## Figures\n");
        for f in figures {
            let _ = writeln!(md, "![{f}]({f})");
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_read_with_their_uncertainty() {
        // the standard error sets the digits: two significant ones
        assert_eq!(pm(0.80071, Some(1.2e-4), 1.0, 3), "0.80071 ± 0.00012");
        assert_eq!(pm(0.3, Some(0.04), 1.0, 3), "0.300 ± 0.040");
        assert_eq!(pm(-0.002, Some(0.0005), 100.0, 3), "-0.200 ± 0.050");
        // no sign on a value that rounds to zero
        assert_eq!(pm(-1e-9, None, 1.0, 3), "0.000");
        assert_eq!(fixed(-0.0, 2), "0.00");
        assert_eq!(fixed(-0.5, 1), "-0.5");
    }
}
