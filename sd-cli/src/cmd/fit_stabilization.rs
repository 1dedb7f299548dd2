//! `sdctl fit --stabilization`: the physical modal model of a SISO FRD
//! ([`sd_ident::physical_fit`]) with its mode table, order scan and stabilisation chart.

use crate::commands::model_json;
use crate::io::{from_ident, write_folder, CliError};
use sd_ident::{PhysicalFit, PoleClass, StabilizationOptions};

/// Runs the stabilisation fit of `data` (read from `name`) and writes `out/model.json`,
/// `out/modes.json` and `out/stabilization.svg`; the mode table on stderr.
pub(crate) fn run(
    name: &str,
    data: &sd_model::Frd,
    opt: &StabilizationOptions,
    out: &str,
) -> Result<(), CliError> {
    crate::io::check_out_dir(out)?;
    let r = sd_ident::physical_fit(data, opt, &mut |s| eprintln!("[fit] {s}"))
        .map_err(|e| from_ident(name, e))?;
    eprint!("{}", mode_table(&r));
    for w in &r.fit.warnings {
        eprintln!("sdctl: warning: {name}: {w}");
    }
    let (delayed, phase_err) = r
        .model_with_delay(data.freq_hz())
        .map_err(|e| from_ident(name, e))?;
    if r.delay_samples != 0.0 {
        eprintln!(
            "[fit] input delay {:.3} samples ({:.1} µs; the data tell apart no delay in \
             [{:.3}, {:.3}]): model.json holds the model with it (whole samples exact{}); \
             modes.json's modes are of the model without it",
            r.delay_samples,
            1e6 * r.delay_samples * data.time().ts().unwrap_or(0.0),
            r.delay_interval.0,
            r.delay_interval.1,
            if phase_err > 0.0 {
                format!(
                    ", the fraction by Thiran's allpass: worst phase error {phase_err:.3}° over \
                     the lines"
                )
            } else {
                String::new()
            }
        );
    }
    let model = model_json(&delayed)?;
    let modes = modes_json(&r, phase_err)?;
    write_folder(out, |dir| {
        let write = |file: &str, text: &str| {
            sd_report::write_atomic_parts(&dir.join(file), &[text.as_bytes(), b"\n"])
                .map_err(|e| CliError::input(e.to_string()))
        };
        write("model.json", &model)?;
        write("modes.json", &modes)?;
        chart(&dir.join("stabilization.svg"), data, &r, name)
    })
}

/// The mode table people read: one row per mode.
pub(crate) fn mode_table(r: &PhysicalFit) -> String {
    let mut s = format!(
        "[fit] physical model: order {} ({} rigid-body pole(s)), input delay {:.3} samples, cost \
         {:.2} per line (1 = the FRD's variance), line spacing {:.3} Hz\n\
         {:>10} {:>10} {:>9} {:>7} {:>7} {:>8} {:>10}  kind\n",
        r.order,
        r.rigid_body,
        r.delay_samples,
        r.cost_per_line,
        r.line_spacing_hz,
        "freq [Hz]",
        "damping",
        "share %",
        "stable",
        "f-only",
        "in band",
        "2ζf/Δf"
    );
    for m in &r.modes {
        s += &format!(
            "{:>10.3} {:>10.5} {:>9.2} {:>7} {:>7} {:>8} {:>10}  {:?}{}\n",
            m.freq_hz,
            m.damping,
            100.0 * m.share,
            m.stable_orders,
            m.frequency_orders,
            if m.in_band { "yes" } else { "no" },
            m.resolution.map_or("-".into(), |x| format!("{x:.2}")),
            m.kind,
            if m.ripple {
                " (ripple: at the bandwidth floor in a broader mode's band, no peak of its own)"
            } else {
                ""
            }
        );
    }
    s
}

/// `modes.json`: the choice, the modes, every order's costs and the diagram
/// ([`sd_ident::PhysicalFitSummary`]; each warning with its `message`).
fn modes_json(r: &PhysicalFit, delay_phase_error_deg: f64) -> Result<String, CliError> {
    let mut v = serde_json::to_value(r.summary(delay_phase_error_deg))
        .map_err(|e| CliError::numerical(format!("modes JSON: {e}")))?;
    v["warnings"] = crate::io::warnings_json(&r.fit.warnings);
    serde_json::to_string_pretty(&v).map_err(|e| CliError::numerical(format!("modes JSON: {e}")))
}

/// The stabilisation chart over the FRF's magnitude.
fn chart(
    path: &std::path::Path,
    data: &sd_model::Frd,
    r: &PhysicalFit,
    name: &str,
) -> Result<(), CliError> {
    use sd_report::stabilization::{stabilization_chart, Mark, StabilizationChart};
    let db: Vec<f64> = data
        .response()
        .iter()
        .map(|m| 20.0 * m[(0, 0)].norm().max(f64::MIN_POSITIVE).log10())
        .collect();
    let poles: Vec<(f64, usize, Mark)> = r
        .diagram
        .iter()
        .map(|p| {
            let mark = match p.class {
                PoleClass::Stable => Mark::Stable,
                PoleClass::Frequency => Mark::Frequency,
                PoleClass::New => Mark::New,
            };
            (p.freq_hz, p.order, mark)
        })
        .collect();
    let title = format!(
        "stabilisation diagram of {name} (rigid body: {})",
        r.rigid_body
    );
    stabilization_chart(
        &path.to_string_lossy(),
        &StabilizationChart {
            title: &title,
            freq_hz: data.freq_hz(),
            db: (&db, "dB re 1 output unit per input unit"),
            poles: &poles,
            chosen: r.order,
        },
    )
    .map_err(|e| CliError::numerical(e.to_string()))
}
