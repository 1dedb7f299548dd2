//! The paper run's `report.json` and `report.md`, each sentence from this run's numbers.

use super::*;
/// Everything the report states.
pub(super) struct Results<'a> {
    /// Where 653 Hz appears at 1 kHz (Hz).
    pub(super) alias_hz: f64,
    pub(super) quick: bool,
    pub(super) periods: usize,
    pub(super) averaging: f64,
    pub(super) fitted: &'a Fitted,
    pub(super) pk: &'a Peaks,
    pub(super) c: &'a Controllers,
    pub(super) stand: &'a [Run],
    pub(super) with_sensor: &'a serde_json::Map<String, serde_json::Value>,
    pub(super) diag: &'a sd_diagnose::Diagnosis,
    pub(super) unc: &'a crate::uncertainty::Uncertain,
    pub(super) figures: Vec<String>,
}

/// `report.json`.
pub(super) fn report_json(r: &Results<'_>) -> Result<serde_json::Value, String> {
    let standstill_json: serde_json::Map<String, serde_json::Value> = r
        .stand
        .iter()
        .map(|x| (x.name.to_string(), standstill_summary(x)))
        .collect();
    let d = r.diag;
    let mut report = json!({
        "resonance_hz": 653.0,
        "alias_peak_hz": r.pk.measured.0,
        "alias_map_hz": r.alias_hz,
        "injected_nonideality": {"averaging_fraction": r.averaging},
        "fit": {"order": r.fitted.p_fast.n(), "median_rel_error": r.fitted.median_rel_error, "cost_per_order": r.fitted.table},
        "downsample": {"model_peak_hz": r.pk.model.0, "model_peak_db": r.pk.model.1, "measured_peak_hz": r.pk.measured.0, "measured_peak_db": r.pk.measured.1},
        "design": {"model_order": r.fitted.p_design.n(), "gamma_min": r.c.gamma_min, "gamma": r.c.gamma},
        "standstill": standstill_json,
        "standstill_with_averaging_sensor": r.with_sensor,
        "figures": r.figures,
        "diagnosis": {"verdict": d.verdict, "cause": d.cause, "parameters": d.parameters,
                      "gain_ratio": d.gain_ratio(), "gain_before": d.gain.before, "gain_after": d.gain.after,
                      "held_out": d.gain.held_out, "partial": d.partial},
    });
    for (name, v) in &r.c.summary {
        report[*name] = v.clone();
    }
    let (unc, per) = crate::uncertainty::json(r.unc);
    report["uncertainty"] = unc;
    for (name, v) in per {
        if let (Some(obj), Some(add)) = (report[name].as_object_mut(), v.as_object()) {
            obj.extend(add.clone());
        }
    }
    Ok(report)
}

/// A number of a JSON object (NaN when absent).
pub(super) fn num(v: &serde_json::Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or(f64::NAN)
}

/// The table of `report.md`.
pub(super) fn report_table(md: &mut String, r: &Results<'_>) -> Result<(), String> {
    let (mpk_f, mpk_db) = r.pk.measured;
    let (dpk_f, dpk_db) = r.pk.model;
    let _ = writeln!(md, "| quantity | value |\n|---|---|");
    let _ = writeln!(
        md,
        "| 653 Hz sampled at 1 kHz appears at | {:.3} Hz |",
        r.alias_hz
    );
    let _ = writeln!(
        md,
        "| measured 1 kHz FRF peak (250–450 Hz) | {mpk_f:.2} Hz, {mpk_db:.2} dB |"
    );
    let costs: Vec<String> = r
        .fitted
        .table
        .iter()
        .map(|(n, c)| format!("{c:.1} at order {n}"))
        .collect();
    let _ = writeln!(
        md,
        "| fit at 5 kHz | order {} (weighted cost {}), median relative error {:.2} % |",
        r.fitted.p_fast.n(),
        costs.join(", "),
        100.0 * r.fitted.median_rel_error
    );
    let _ = writeln!(md, "| fit downsampled to 1 kHz (Lemma 6), peak | {dpk_f:.2} Hz, {dpk_db:.2} dB — {:.2} dB from the measurement |", dpk_db - mpk_db);
    let stable = |v: &serde_json::Value| {
        if v["stable"].as_bool().unwrap_or(false) {
            "stable"
        } else {
            "UNSTABLE"
        }
    };
    for (name, v) in &r.c.summary {
        let _ = writeln!(md, "| {name} with the design model | crossover {:.1} Hz, closed-loop bandwidth {:.1} Hz, \\|S\\| peak {:.1} dB at {:.1} Hz, \\|S(347 Hz)\\| {:.1} dB, {} |",
            num(v, "crossover_hz"), num(v, "bandwidth_hz"), num(v, "sensitivity_peak_db"), num(v, "sensitivity_peak_hz"), num(v, "sensitivity_at_alias_db"), stable(v));
        if v.get("fast_rate_norm").is_some() {
            let _ = writeln!(md, "| {name}, multirate criterion (worst-case standstill error in nm per unit of the experiment's disturbances) | {:.2} at every 5 kHz sample, {:.2} at the 1 kHz samples |",
                num(v, "fast_rate_norm"), num(v, "slow_rate_norm"));
        }
        let t = &v["true_plant"];
        let _ = writeln!(md, "| {name} on the true 1 kHz plant | \\|S\\| peak {:.1} dB at {:.1} Hz, \\|S(347 Hz)\\| {:.1} dB, {} |",
            num(t, "sensitivity_peak_db"), num(t, "sensitivity_peak_hz"), num(t, "sensitivity_at_alias_db"), stable(t));
    }
    let u = r.unc;
    let _ = writeln!(md, "| 5 kHz fit's error bound ({:.0} % per line), downsampled to 1 kHz | covers the true 5 kHz plant on {:.1} % of the 5 kHz lines; the measured 1 kHz FRF on {:.1} % of its lines{} |",
        100.0 * crate::uncertainty::CONFIDENCE, 100.0 * u.coverage_fast, 100.0 * u.coverage_slow,
        u.coverage_slow_extended.map_or(String::new(), |c| format!(", {:.1} % when taken through the diagnosed non-idealities around the extended model", 100.0 * c)));
    for c in &u.robust {
        let (name, plain, ext) = (c.name, &c.plain, &c.extended);
        let alias = (c.alias_band, c.alias_band_extended);
        let _ = writeln!(md, "| {name}, robust stability margin (1/max b·\\|T\\| over the 1 kHz lines; > 1 robustly stable) | {:.3} against the plain bound (worst at {:.1} Hz){}; the aliased band 300–400 Hz alone: {:.1}{} |",
            plain.margin_lines, plain.worst_line_hz,
            ext.as_ref().map_or(String::new(), |x| format!("; {:.3} against the extended bound (worst at {:.1} Hz)", x.margin_lines, x.worst_line_hz)),
            alias.0, alias.1.map_or(String::new(), |a| format!(" (extended: {a:.1})")));
    }
    for x in r.stand {
        let _ = writeln!(md, "| standstill, {} | rms {:.3e} m at 5 kHz (dominant {:.1} Hz; {:.3e} m above 500 Hz), {:.3e} m at 1 kHz (dominant {:.1} Hz) |", x.name, x.wf.rms(), x.wf.dominant_hz(), x.wf.band_power(500.0, 2500.0).sqrt(), x.ws.rms(), x.ws.dominant_hz());
        let w = &r.with_sensor[x.name];
        let _ = writeln!(md, "| standstill, {}, averaging sensor in the loop | rms {:.3e} m at 5 kHz (dominant {:.1} Hz), {:.3e} m at 1 kHz (dominant {:.1} Hz) |", x.name, num(w, "rms_fast"), num(w, "dominant_hz_fast"), num(w, "rms_slow"), num(w, "dominant_hz_slow"));
    }
    Ok(())
}

/// "What it shows": each sentence from this run's numbers.
pub(super) fn what_it_shows(md: &mut String, r: &Results<'_>) {
    let (mpk_f, mpk_db) = r.pk.measured;
    let (dpk_f, dpk_db) = r.pk.model;
    let _ = writeln!(md, "\n## What it shows\n");
    let _ = write!(md, "The 653 Hz mode appears at {mpk_f:.1} Hz in the 1 kHz data. The 5 kHz fit, downsampled exactly (Lemma 6), puts the aliased peak at {dpk_f:.1} Hz, {:.1} dB {} the measurement. ",
        (dpk_db - mpk_db).abs(), if dpk_db >= mpk_db { "above" } else { "below" });
    let cause = r.diag.cause.to_string();
    if r.averaging > 0.0 {
        let _ = write!(md, "The stage's sensor averages over {} of each rate's own period, an effect tied to the sample rate that Lemma 6 alone cannot carry over; the diagnosis names `{cause}`. ", r.averaging);
    } else {
        let _ = write!(md, "The stage carries no rate-tied non-ideality in this run; the diagnosis names `{cause}`. ");
    }
    let v = |i: usize, k: &str| r.c.summary.get(i).map_or(f64::NAN, |(_, v)| num(v, k));
    let _ = write!(md, "Controller 2 (PID alone) has its |S| peak of {:.1} dB at {:.1} Hz; Controller 1, designed by loopshaping on the downsampled model, has |S(347 Hz)| = {:.1} dB against Controller 2's {:.1} dB. ",
        v(1, "sensitivity_peak_db"), v(1, "sensitivity_peak_hz"), v(0, "sensitivity_at_alias_db"), v(1, "sensitivity_at_alias_db"));
    if let Some((_, m)) = r.c.summary.iter().find(|(n, _)| *n == "controller_mixsyn") {
        let _ = write!(md, "The mixed-sensitivity controller (W₁ on S, W₂ on KS, an input force disturbance; γ = {:.4}, a {}-state generalized plant, synthesized in {:.2} s) crosses over at {:.1} Hz with |S| peaking at {:.1} dB at {:.1} Hz and |S(347 Hz)| = {:.1} dB; it is {} on the true 1 kHz plant. ",
            num(m, "gamma"), num(m, "generalized_plant_states"), num(m, "synthesis_seconds"), num(m, "crossover_hz"), num(m, "sensitivity_peak_db"), num(m, "sensitivity_peak_hz"), num(m, "sensitivity_at_alias_db"),
            if m["true_plant"]["stable"].as_bool().unwrap_or(false) { "stable" } else { "UNSTABLE" });
    }
    multirate_sentence(md, r);
    if let [c1, c2, ..] = r.stand {
        let _ = write!(md, "At standstill (the controller sampling the position ideally, as in the paper's Fig. 6), Controller 2's error is dominated by {:.1} Hz at 1 kHz and {:.1} Hz between the samples (rms {:.2e} m at 5 kHz, against {:.2e} m with Controller 1). ",
            c2.ws.dominant_hz(), c2.wf.dominant_hz(), c2.wf.rms(), c1.wf.rms());
        if let Some(w) = r.with_sensor.get(c2.name) {
            let _ = write!(md, "With the identification's averaging sensor in the standstill loop, Controller 2's error is dominated by {:.1} Hz at 5 kHz (rms {:.2e} m).", num(w, "dominant_hz_fast"), num(w, "rms_fast"));
        }
    }
    let _ = writeln!(md);
}

/// `report.md`.
pub(super) fn report_md(r: &Results<'_>) -> Result<String, String> {
    let mut md = String::new();
    let _ = writeln!(md, "# Aliasing of resonance phenomena in sampled-data feedback (Oomen, van de Wal, Bosgra, ACC 2007), on the virtual stage\n");
    let _ = writeln!(md, "Virtual stage (docs/stage.md): m = 20 kg, rigid body, 653 Hz (ζ 0.01, r 2) and 1.65 kHz (ζ 0.005, r 0.3) modes, force noise 0.05 N and sensor noise 0.3 nm per 5 kHz sample. Hidden rate-tied non-ideality: the sensor averages over the last {} of each sample period. Runs: {} periods per identification experiment{}.\n", r.averaging, r.periods, if r.quick { " (quick)" } else { "" });
    report_table(&mut md, r)?;
    for f in r.figures.iter().filter(|f| !f.starts_with("diagnosis/")) {
        let _ = writeln!(md, "\n![{f}]({f})");
    }
    what_it_shows(&mut md, r);
    let d = r.diag;
    let _ = writeln!(md, "\n## Diagnosis (beyond the paper)\n\nThe fit's Lemma 6 simulation was compared with the 1 kHz FRF, and the 1 kHz FRF with the model-free Lemma 6 prediction from the 5 kHz FRF (every fold frequency is a measured line); the rate-tied causes were fitted on a continuous modal model built from the fit's poles (full report in `diagnosis/report.md`): verdict **{}**, cause **{}**, parameters `{}`. {}", d.verdict, d.cause, d.parameters,
        match (d.gain.before, d.gain.after, d.gain_ratio()) {
            (Some(b), Some(a), Some(g)) => format!("On held-out periods ({}) the discrepancy statistic (1 = noise level) goes from {b:.1} for the plain modal model to {a:.2} with the extension: a gain of ×{g:.0}.", d.gain.held_out.join(", ")),
            _ => format!("The gain could not be measured on held-out data: {}.", d.gain.why.as_deref().unwrap_or("no held-out data")),
        });
    uncertainty_md(&mut md, r.unc, r.stand);
    Ok(md)
}

/// The "Uncertainty" section of `report.md`, from this run's numbers.
pub(super) fn uncertainty_md(md: &mut String, u: &crate::uncertainty::Uncertain, stand: &[Run]) {
    let _ = write!(md, "\n## Uncertainty (beyond the paper)\n\nThe fit's error bound from the 5 kHz data ({:.0} % per line: residual + κσ) covers the true 5 kHz plant on {:.1} % of the lines. Taken to 1 kHz through Lemma 6 (each slow line sums its five fold frequencies weighted by the hold), it covers the measured 1 kHz FRF on {:.1} % of the lines",
        100.0 * crate::uncertainty::CONFIDENCE, 100.0 * u.coverage_fast, 100.0 * u.coverage_slow);
    match u.coverage_slow_extended {
        Some(c) => {
            let _ = write!(md, "; taken through the non-idealities the diagnosis named, around its extended model, on {:.1} %: the downsampled model's miss is the rate-tied effect, not model error the 5 kHz data could have shown. ", 100.0 * c);
        }
        None => {
            let _ = write!(md, ". ");
        }
    }
    let _ = write!(md, "Controller 1's loopshaping margin is ε = 1/achieved = {:.3}; the chordal distance between the shaped design model and the shaped 1 kHz measurement is {:.3} (at {:.1} Hz): {} ",
        u.eps, u.nu_gap.max, u.nu_gap.at_hz,
        if u.nu_gap.max < u.eps { "below ε, so the design's margin covers the measured plant (Vinnicombe's ν-gap condition, with the winding condition assumed)." } else { "at or above ε: the design's margin alone does not cover the measured plant." });
    if let [c1, c2, ..] = u.robust.as_slice() {
        let (n1, r1, a1) = (c1.name, &c1.plain, c1.alias_band);
        let (n2, r2, a2) = (c2.name, &c2.plain, c2.alias_band);
        let _ = writeln!(md, "Robust stability against the plain bound (multiplicative, 1/max b·|T|; > 1 robustly stable): {n1} {:.2} (limited at {:.1} Hz), {n2} {:.2} (at {:.1} Hz); the aliased band (300–400 Hz) alone leaves {n1} {:.1} and {n2} {:.1}, {:.1}× {} for the loopshaping controller (Controller 1).",
            r1.margin_lines, r1.worst_line_hz, r2.margin_lines, r2.worst_line_hz, a1, a2,
            if a1 >= a2 { a1 / a2 } else { a2 / a1 }, if a1 >= a2 { "more" } else { "less" });
    }
    for c in &u.robust {
        let r = &c.intersample;
        let measured = stand.iter().find(|x| x.name == c.name).map(|x| x.wf.rms());
        let _ = match r.rms_bound {
            Some(b) => writeln!(md, "\nIntersample under uncertainty, {}: the 5 kHz standstill error around the 5 kHz fit has rms {:.3e} m; over every plant inside the fast bound's weight it is at most {:.3e} m ({:.1}× the nominal; the slow loop tolerates {:.2}× the weight). The virtual stage's standstill run (ideal sampling) measured {}.",
                c.name, r.rms_nominal, b, b / r.rms_nominal, r.slow_margin,
                measured.map_or("nothing".to_string(), |m| format!("{m:.3e} m, {} the bound", if m <= b { "inside" } else { "above" }))),
            None => writeln!(md, "\nIntersample under uncertainty, {}: nominal rms {:.3e} m; no bound, since the slow loop tolerates only {:.2}× the fast weight (a plant inside it may destabilise the loop).",
                c.name, r.rms_nominal, r.slow_margin),
        };
    }
}

/// "What it shows" on the multirate design against the single-rate design of the same
/// problem and Controller 1, from this run's numbers.
fn multirate_sentence(md: &mut String, r: &Results<'_>) {
    let find = |n: &str| r.c.summary.iter().find(|(k, _)| *k == n).map(|(_, v)| v);
    let run = |n: &str| r.stand.iter().find(|x| x.name == n);
    let (Some(m), Some(sr), Some(mr), Some(srr), Some(c1)) = (
        find("controller_multirate"),
        find(SINGLE_SAME),
        run("controller_multirate"),
        run(SINGLE_SAME),
        run("controller1"),
    ) else {
        return;
    };
    let above = |x: &Run| x.wf.band_power(500.0, 2500.0).sqrt();
    let change = |a: f64, b: f64| 100.0 * (a / b - 1.0);
    let _ = write!(md, "The multirate H∞ controller (designed for the standstill error at every 5 kHz sample on the 5 kHz fit reduced to {} states, the error at the sample instants weighted {:.2}× — the least factor of the grid at which its rms at the samples predicted on that model, {:.3e} m, is no larger than the single-rate design's {:.3e} m — γ = {:.2}, synthesized in {:.2} s) and the single-rate design of the same problem with the same weights: on the factor-1 worst-case criterion {:.2} against {:.2} at every 5 kHz sample and {:.2} against {:.2} at the 1 kHz samples. ",
        num(m, "fast_model_order"), num(m, "at_samples"), num(m, "predicted_rms_at_samples_m"), num(sr, "predicted_rms_at_samples_m"), num(m, "gamma"), num(m, "synthesis_seconds"), num(m, "fast_rate_norm"), num(sr, "fast_rate_norm"), num(m, "slow_rate_norm"), num(sr, "slow_rate_norm"));
    let (at_m, at_s) = (mr.rms_phases(true), srr.rms_phases(true));
    let (bt_m, bt_s) = (mr.rms_phases(false), srr.rms_phases(false));
    let _ = write!(md, "At standstill on the true stage its error at the 5 kHz instants between the samples has rms {bt_m:.3e} m against {bt_s:.3e} m ({:+.0} %) and Controller 1's {:.3e} m (above 500 Hz: {:.3e} m against {:.3e} m, {:+.0} %); at the samples {at_m:.3e} m against {at_s:.3e} m ({:+.0} %) and Controller 1's {:.3e} m: {}. ",
        change(bt_m, bt_s), c1.rms_phases(false), above(mr), above(srr), change(above(mr), above(srr)), change(at_m, at_s), c1.rms_phases(true),
        match (at_m <= at_s, bt_m < bt_s) {
            (true, true) => "no worse at the samples and better between them",
            (true, false) => "no worse at the samples, but not better between them",
            (false, _) => "the single-rate design stays better at the samples on the true stage",
        });
}
