//! The paper chain's uncertainty step (the paper's open question): the 5 kHz fit's error bound
//! from the 5 kHz data, taken to 1 kHz through Lemma 6 (plain, and through the non-idealities
//! the diagnosis named), its coverage of what was measured and of the truth, and the robust
//! stability of Controllers 1 and 2 against it.

use sd_model::StateSpace;
use sd_uncertainty::{coverage, downsample, downsample_nonideal, from_data, Bound, Form, Robust};

/// Probability per line that the bound holds.
pub const CONFIDENCE: f64 = 0.95;
/// The aliased resonance's band at 1 kHz (Hz).
const ALIAS_BAND: (f64, f64) = (300.0, 400.0);
/// Order of the relative weight used for the margin between the lines.
const WEIGHT_ORDER: usize = 8;

fn s<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// The bounds and what they cover.
pub struct Uncertain {
    /// The fast bound's lines where the true 5 kHz plant (with its sensor) is inside.
    pub coverage_fast: f64,
    /// The measured 1 kHz FRF's lines inside the plain downsampled bound.
    pub coverage_slow: f64,
    /// … inside the bound taken through the diagnosed non-idealities (rounded to whole fast
    /// samples for the fold weights), around the extended model (`None` when the diagnosis
    /// named no rate-tied extension).
    pub coverage_slow_extended: Option<f64>,
    /// The plain downsampled bound (nominal: the fit downsampled by Lemma 6).
    pub slow: Bound,
    /// The extended one (nominal: the diagnosis's extended model at 1 kHz).
    pub slow_extended: Option<(Bound, StateSpace)>,
    /// Per controller.
    pub robust: Vec<ControllerRobust>,
    /// Controller 1's loopshaping margin `ε = 1/achieved` and the chordal distance between
    /// the shaped design model and the shaped 1 kHz measurement (the ν-gap to the measured
    /// plant when the winding condition holds).
    pub eps: f64,
    pub nu_gap: sd_uncertainty::ChordalGap,
}

/// One controller's robust stability.
pub struct ControllerRobust {
    pub name: &'static str,
    /// Against the plain bound.
    pub plain: Robust,
    /// Against the extended bound.
    pub extended: Option<Robust>,
    /// The margin the aliased band (300–400 Hz) alone leaves against the plain bound …
    pub alias_band: f64,
    /// … and against the extended one.
    pub alias_band_extended: Option<f64>,
    /// The standstill error at 5 kHz around the 5 kHz fit, bounded over every plant inside
    /// the fast bound's weight (the standstill runs' force and sensor noise, white).
    pub intersample: sd_uncertainty::RobustIntersample,
}

/// The fraction of `b`'s lines where `truth`'s response lies inside nominal ± bound (its
/// response as a measurement without variance).
fn truth_coverage(truth: &StateSpace, b: &Bound) -> Result<f64, String> {
    let p = truth.freqresp(&b.freq_hz).map_err(s)?;
    Ok(coverage(b, &p).map_err(s)?.fraction)
}

/// The fast error of `k` around `p_fast` (period `h`) bounded over the relative weight `w` of
/// the fast bound, for the standstill runs' disturbances (force 0.05 N and sensor 0.3 nm rms
/// per 5 kHz sample, white).
fn intersample(
    p_fast: &StateSpace,
    k: &StateSpace,
    w: &sd_uncertainty::Weight,
    h: f64,
) -> Result<sd_uncertainty::RobustIntersample, String> {
    let (pd, pn) = (2.0 * h * 0.05f64.powi(2), 2.0 * h * 0.3e-9f64.powi(2));
    sd_uncertainty::robust_intersample(
        p_fast,
        k,
        5,
        (&w.model, Form::Multiplicative),
        &|_| pd,
        &|_| pn,
        2000,
    )
    .map_err(s)
}

/// Robust stability of `k` with `plant` against `bound`, with a relative weight between the
/// lines.
fn robust(plant: &StateSpace, k: &StateSpace, bound: &Bound) -> Result<Robust, String> {
    let w = sd_uncertainty::overbound(&bound.with_form(Form::Multiplicative), WEIGHT_ORDER)
        .map_err(s)?;
    sd_uncertainty::robust_stability(
        plant,
        k,
        &bound.with_form(Form::Multiplicative),
        Some(&w.model),
    )
    .map_err(s)
}

/// The uncertainty step (module documentation).
pub fn uncertainty(
    truth_fast: &StateSpace,
    fast: &sd_ident::FrfEstimate,
    slow: &sd_ident::FrfEstimate,
    (p_fast, p_down): (&StateSpace, &StateSpace),
    diag: &sd_diagnose::Diagnosis,
    controllers: &[(&'static str, &StateSpace)],
    (p_design, w1, achieved): (&StateSpace, &StateSpace, f64),
) -> Result<Uncertain, String> {
    let fast_frd = fast.trusted_frd().map_err(s)?;
    let slow_frd = slow.trusted_frd().map_err(s)?;
    let b = from_data(p_fast, &fast_frd, Form::Additive, CONFIDENCE).map_err(s)?;
    let coverage_fast = truth_coverage(truth_fast, &b)?;
    let plain = downsample(&b, 5, slow_frd.freq_hz()).map_err(s)?.bound;
    let coverage_slow = coverage(&plain, &slow_frd).map_err(s)?.fraction;
    // through the named hold delay and averaging, around the extended model at 1 kHz
    let slow_extended = match (
        &diag.extended_model,
        diag.experiments
            .iter()
            .find(|x| x.factor == 5)
            .and_then(|x| x.extended_model.as_ref()),
    ) {
        (Some(em), Some(model)) => {
            // the fold weights act on fast samples: the named delay and window rounded to
            // whole fast samples (the stage's 0.6 is three of five); the nominal is the
            // extended model itself
            let whole = |x: f64| (x * 5.0).round() / 5.0;
            let ni = sd_multirate::NonIdeal {
                hold_delay: whole(em.hold_delay),
                averaging: whole(em.averaging),
            };
            let through = downsample_nonideal(&b, 5, ni, slow_frd.freq_hz())
                .map_err(s)?
                .bound;
            let nominal = model
                .freqresp(&through.freq_hz)
                .map_err(s)?
                .response()
                .iter()
                .map(|m| m[(0, 0)])
                .collect();
            Some((Bound { nominal, ..through }, model.clone()))
        }
        _ => None,
    };
    let coverage_slow_extended = slow_extended
        .as_ref()
        .map(|(bx, _)| coverage(bx, &slow_frd).map(|c| c.fraction))
        .transpose()
        .map_err(s)?;
    let band = |p: &StateSpace, k: &StateSpace, b: &Bound| -> Result<f64, String> {
        let l = sd_uncertainty::loading_per_line(p, k, b).map_err(s)?;
        Ok(1.0
            / l.iter()
                .filter(|(f, _)| (ALIAS_BAND.0..=ALIAS_BAND.1).contains(f))
                .map(|x| x.1)
                .fold(0.0, f64::max))
    };
    // the fast bound's relative weight, for the intersample bound of every controller
    let w_fast =
        sd_uncertainty::overbound(&b.with_form(Form::Multiplicative), WEIGHT_ORDER).map_err(s)?;
    let mut out = Vec::new();
    for &(name, k) in controllers {
        let plain_r = robust(p_down, k, &plain)?;
        let ext_r = slow_extended
            .as_ref()
            .map(|(bx, m)| robust(m, k, bx))
            .transpose()?;
        out.push(ControllerRobust {
            name,
            alias_band: band(p_down, k, &plain)?,
            alias_band_extended: slow_extended
                .as_ref()
                .map(|(bx, m)| band(m, k, bx))
                .transpose()?,
            plain: plain_r,
            extended: ext_r,
            intersample: intersample(p_fast, k, &w_fast, b.ts)?,
        });
    }
    let nu_gap = sd_uncertainty::chordal_gap(p_design, &slow_frd, Some(w1)).map_err(s)?;
    Ok(Uncertain {
        eps: 1.0 / achieved,
        nu_gap,
        coverage_fast,
        coverage_slow,
        coverage_slow_extended,
        slow: plain,
        slow_extended,
        robust: out,
    })
}

/// `20 log10` of nominal ± bound on `b`'s lines: (upper, lower) in dB (the lower clipped at
/// 1e-3 of the nominal's magnitude).
pub fn band_db(b: &Bound) -> (Vec<f64>, Vec<f64>) {
    b.nominal
        .iter()
        .zip(&b.additive)
        .map(|(n, a)| {
            let m = n.norm();
            (20.0 * (m + a).log10(), 20.0 * (m - a).max(1e-3 * m).log10())
        })
        .unzip()
}

/// The `report.json` entries: `uncertainty` and each controller's margins.
pub fn json(u: &Uncertain) -> (serde_json::Value, Vec<(&'static str, serde_json::Value)>) {
    let unc = serde_json::json!({
        "controller1_stability_margin_eps": u.eps,
        "nu_gap_measured": u.nu_gap,
        "confidence": CONFIDENCE,
        "coverage_fast": u.coverage_fast,
        "coverage_slow": u.coverage_slow,
        "coverage_slow_extended": u.coverage_slow_extended,
    });
    let per = u
        .robust
        .iter()
        .map(|c| {
            let (r, x) = (&c.plain, &c.extended);
            (
                c.name,
                serde_json::json!({
                    "robust_stability_margin": r.margin_lines,
                    "robust_stability_margin_alias_band": c.alias_band,
                    "robust_stability_margin_alias_band_extended": c.alias_band_extended,
                    "robust_stability_margin_weight": r.margin_weight,
                    "robust_worst_hz": r.worst_line_hz,
                    "robust_stability_margin_extended": x.as_ref().map(|x| x.margin_lines),
                    "robust_worst_hz_extended": x.as_ref().map(|x| x.worst_line_hz),
                    "intersample_slow_margin": c.intersample.slow_margin,
                    "intersample_rms_nominal": c.intersample.rms_nominal,
                    "intersample_rms_bound": c.intersample.rms_bound,
                }),
            )
        })
        .collect();
    (unc, per)
}
