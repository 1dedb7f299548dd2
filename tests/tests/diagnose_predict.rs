//! A diagnosis travels to new data (`sd_diagnose::predict_experiments`, `sdctl predict`): the
//! extension it found, written to `predictor.json` and read back, predicts whole experiments
//! it has never seen — a held-out excitation level (amplitude-dependent modal model), an
//! experiment at another rate (rate-tied non-idealities) — and says why where it cannot.
//!
//! The cases come from the testbed (Lawson–RK4 for the cubic stiffness, the fine-step route
//! for the delayed hold): another numerical form than the predictions. Development seeds
//! `0..8` (what the thresholds below were set on); the default run `8..10`; reported (not
//! looked at before the report) `2300..2324`:
//! `cargo test --release -p sd-tests --test diagnose_predict -- --ignored --nocapture`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_diagnose::{predict_experiments, Prediction, Predictor, SavedExtension, Unpredictable};
use sd_tests::diagcases::{
    consistent, level_case_sized, per_seed, with_another_rate, Effect, LevelEffect, Recording,
};

const PERIODIC: Recording = Recording::PERIODIC;

/// The levels the diagnosis sees (the cubic stiffness sized for the highest, 4).
const LEVELS: [f64; 3] = [1.0, 2.0, 4.0];
/// The held-out level inside their range, and one far beyond (hardening only: a softening
/// mode escapes at twelve times the force).
const HELD: f64 = 3.0;
const FAR_LEVEL: f64 = 12.0;

/// The predictor after a round trip through its file.
fn reread(p: &Predictor) -> Predictor {
    Predictor::from_json_str(&p.to_json_string().unwrap()).unwrap()
}

/// What one amplitude case gives: the diagnosis's cause, the prediction of the held-out level
/// (and of the far level for hardening).
struct AmplitudeOutcome {
    seed: u64,
    effect: LevelEffect,
    cause: String,
    prediction: Option<Prediction>,
}

fn amplitude_case(seed: u64) -> Option<AmplitudeOutcome> {
    let effect = if seed % 2 == 0 {
        LevelEffect::Hardening
    } else {
        LevelEffect::Softening
    };
    let mut levels = LEVELS.to_vec();
    levels.push(HELD);
    if effect == LevelEffect::Hardening {
        levels.push(FAR_LEVEL);
    }
    let case = level_case_sized(seed, effect, &levels, PERIODIC, 4.0)?;
    let d = sd_diagnose::diagnose(&case.experiments[..3], &Default::default()).unwrap();
    let in_memory = predict_experiments(&d.predictor, &case.experiments[3..], 0.01).unwrap();
    let prediction = matches!(d.predictor.extension, SavedExtension::Amplitude(_)).then(|| {
        let p = predict_experiments(&reread(&d.predictor), &case.experiments[3..], 0.01).unwrap();
        // the file keeps every number the prediction uses
        for (a, b) in p.experiments.iter().zip(&in_memory.experiments) {
            assert_eq!(a.extended, b.extended, "seed {seed}: {}", a.name);
            assert_eq!(a.amplitudes, b.amplitudes, "seed {seed}: {}", a.name);
        }
        p
    });
    Some(AmplitudeOutcome {
        seed,
        effect,
        cause: d.cause,
        prediction,
    })
}

/// Failures of one amplitude case: the extension found, the held-out level's mode amplitude
/// measured within 20 % of the true force ratio 3 (a mode near its linear band responds in
/// proportion to the force), its prediction in the moving mode's band at least twice as good
/// as the plain model's, and the far level refused for its amplitude.
fn amplitude_failures(o: &AmplitudeOutcome) -> Vec<String> {
    let mut bad = Vec::new();
    let Some(p) = &o.prediction else {
        return vec![format!(
            "seed {} {:?}: no amplitude extension (cause {})",
            o.seed, o.effect, o.cause
        )];
    };
    let held = &p.experiments[0];
    match (&held.reason, &held.in_band, held.amplitudes.first()) {
        (None, Some(b), Some(a)) => {
            if !(2.4..=3.6).contains(&a.relative) {
                bad.push(format!(
                    "seed {}: level 3 measured ×{:.2}",
                    o.seed, a.relative
                ));
            }
            if b.ratio < 2.0 {
                bad.push(format!(
                    "seed {}: level 3 in-band gain {:.2} ({:.2} → {:.2})",
                    o.seed, b.ratio, b.plain, b.extended
                ));
            }
        }
        _ => bad.push(format!(
            "seed {}: level 3 not predicted: {:?}",
            o.seed, held.why
        )),
    }
    if let Some(far) = p.experiments.get(1) {
        if !matches!(far.reason, Some(Unpredictable::Amplitude { .. })) {
            bad.push(format!(
                "seed {}: level 12 predicted: {:?}",
                o.seed, far.ratio
            ));
        }
    }
    bad
}

/// One rate case: the diagnosis on the fast and slow experiments, then the prediction of an
/// experiment at a third rate with the same hidden effect; `(cause, effect, prediction)`.
fn rate_case(seed: u64) -> Option<(String, Effect, Prediction)> {
    let mut r = sd_tests::gen::Rng::new(seed * 31 + 7);
    let effect = match seed % 3 {
        0 => Effect::Delay(r.range(0.2, 1.2)),
        1 => Effect::Averaging(r.range(0.3, 1.0)),
        _ => Effect::DelayAveraging(r.range(0.1, 0.8), r.range(0.3, 1.0)),
    };
    let (case, other) = with_another_rate(seed, effect, PERIODIC)?;
    let d = sd_diagnose::diagnose(&case.experiments, &Default::default()).unwrap();
    let p = predict_experiments(&reread(&d.predictor), &[other], 0.01).unwrap();
    Some((d.cause, effect, p))
}

/// Failures of a rate case: a rate-tied extension, and its prediction of the third rate at
/// least twice as good as the plain model's and within 1.5× the threshold.
fn rate_failures(seed: u64, cause: &str, p: &Prediction) -> Vec<String> {
    let x = &p.experiments[0];
    match (x.ratio, x.extended, x.threshold) {
        (Some(r), Some(e), Some(t)) if p.extension == "rate_tied" => {
            if r >= 2.0 && e <= 1.5 * t {
                Vec::new()
            } else {
                vec![format!(
                    "seed {seed} ({cause}): {} Hz plain {:.2} extended {e:.2} (threshold {t:.2})",
                    x.rate_hz,
                    x.plain.unwrap_or(f64::NAN)
                )]
            }
        }
        _ => vec![format!(
            "seed {seed}: cause {cause}, extension {}: {:?}",
            p.extension, x.why
        )],
    }
}

#[test]
fn a_held_out_level_is_predicted_from_the_saved_extension() {
    let out: Vec<_> = per_seed(8..10, amplitude_case)
        .into_iter()
        .flatten()
        .collect();
    assert_eq!(out.len(), 2);
    let bad: Vec<String> = out.iter().flat_map(amplitude_failures).collect();
    assert!(bad.is_empty(), "{bad:#?}");
}

#[test]
fn another_rate_is_predicted_and_a_wrong_rate_is_refused() {
    let (cause, _, p) = rate_case(8).unwrap();
    let bad = rate_failures(8, &cause, &p);
    assert!(bad.is_empty(), "{bad:#?}");
    // the same experiment labelled with a rate that is no whole fraction of the model's
    let (case, mut other) = with_another_rate(8, Effect::Delay(0.5), PERIODIC).unwrap();
    let d = sd_diagnose::diagnose(&case.experiments, &Default::default()).unwrap();
    other.spec.sample_rate_hz = case.rates.0 / 2.5;
    let p = predict_experiments(&d.predictor, &[other], 0.01).unwrap();
    assert_eq!(p.predicted(), 0);
    assert!(
        matches!(p.experiments[0].reason, Some(Unpredictable::Rate { .. })),
        "{:?}",
        p.experiments[0].reason
    );
    assert!(p.experiments[0]
        .why
        .as_deref()
        .unwrap()
        .contains("no whole fraction"));
}

#[test]
fn a_consistent_diagnosis_predicts_nothing_and_says_why() {
    let case = consistent(8);
    let d = sd_diagnose::diagnose(&case.experiments, &Default::default()).unwrap();
    let p = predict_experiments(&reread(&d.predictor), &case.experiments, 0.01).unwrap();
    assert_eq!(p.predicted(), 0);
    for x in &p.experiments {
        assert!(
            matches!(x.reason, Some(Unpredictable::NoExtension { .. })),
            "{:?}",
            x.reason
        );
        // the plain model is still judged
        assert!(x.plain.is_some_and(f64::is_finite));
    }
}

#[test]
fn a_damaged_predictor_file_is_refused_with_its_fault() {
    let (case, _) = with_another_rate(8, Effect::Delay(0.5), PERIODIC).unwrap();
    let d = sd_diagnose::diagnose(&case.experiments, &Default::default()).unwrap();
    let text = d.predictor.to_json_string().unwrap();
    let misspelt = text.replacen("\"hold_delay\"", "\"hold_dely\"", 1);
    let e = Predictor::from_json_str(&misspelt).unwrap_err().to_string();
    assert!(e.contains("hold_dely"), "{e}");
    let other_version = text.replacen("\"version\": 2", "\"version\": 7", 1);
    let e = Predictor::from_json_str(&other_version)
        .unwrap_err()
        .to_string();
    assert!(e.contains("version 7"), "{e}");
    // a covariance row cut short is named
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut cut = v.clone();
    cut["uncertainty"]["covariance"][0]
        .as_array_mut()
        .unwrap()
        .pop();
    let e = Predictor::from_json_str(&cut.to_string())
        .unwrap_err()
        .to_string();
    assert!(e.contains("uncertainty: the covariance"), "{e}");
    // a version-1 file (no covariance) is still read, its models taken as known
    let mut old = v;
    old["version"] = 1.into();
    old.as_object_mut().unwrap().remove("uncertainty");
    old["extension"]
        .as_object_mut()
        .unwrap()
        .remove("uncertainty");
    let p = Predictor::from_json_str(&old.to_string()).unwrap();
    assert!(p.uncertainty.is_none());
    let e = Predictor::from_json_str("{").unwrap_err().to_string();
    assert!(e.starts_with("predictor.json"), "{e}");
}

/// The reported matrix on fresh seeds: amplitude (hardening and softening alternate) and rate
/// cases (delay, averaging, both).
#[test]
#[ignore]
fn prediction_reported() {
    let seeds = 2300..2324;
    let amp: Vec<_> = per_seed(seeds.clone(), amplitude_case)
        .into_iter()
        .flatten()
        .collect();
    let mut gains = Vec::new();
    for o in &amp {
        let held = o.prediction.as_ref().map(|p| &p.experiments[0]);
        let b = held.and_then(|x| x.in_band);
        println!(
            "amplitude seed {} {:?}: cause {}, level 3 ×{:.2}, in band {:.2} → {:.2} (×{:.2}, \
             threshold {:.2}), whole band {:.2} → {:.2}",
            o.seed,
            o.effect,
            o.cause,
            held.and_then(|x| x.amplitudes.first())
                .map_or(f64::NAN, |a| a.relative),
            b.map_or(f64::NAN, |b| b.plain),
            b.map_or(f64::NAN, |b| b.extended),
            b.map_or(f64::NAN, |b| b.ratio),
            b.map_or(f64::NAN, |b| b.threshold),
            held.and_then(|x| x.plain).unwrap_or(f64::NAN),
            held.and_then(|x| x.extended).unwrap_or(f64::NAN),
        );
        if let Some(b) = b {
            gains.push(b.ratio);
        }
    }
    let amp_bad: Vec<String> = amp.iter().flat_map(amplitude_failures).collect();
    let rate: Vec<_> = per_seed(seeds, |s| rate_case(s).map(|x| (s, x)))
        .into_iter()
        .flatten()
        .collect();
    let mut rate_bad = Vec::new();
    let mut ratios = Vec::new();
    for (s, (cause, effect, p)) in &rate {
        let x = &p.experiments[0];
        println!(
            "rate seed {s} {effect:?}: cause {cause}, {} Hz plain {:.2} extended {:.2} \
             (threshold {:.2})",
            x.rate_hz,
            x.plain.unwrap_or(f64::NAN),
            x.extended.unwrap_or(f64::NAN),
            x.threshold.unwrap_or(f64::NAN)
        );
        ratios.extend(x.ratio);
        rate_bad.extend(rate_failures(*s, cause, p));
    }
    println!(
        "amplitude: {} cases, {} failing; in-band gain median {:.2}, min {:.2}",
        amp.len(),
        amp_bad.len(),
        sd_model::median(&gains),
        gains.iter().cloned().fold(f64::INFINITY, f64::min)
    );
    println!(
        "rate: {} cases, {} failing; ratio median {:.2}, min {:.2}",
        rate.len(),
        rate_bad.len(),
        sd_model::median(&ratios),
        ratios.iter().cloned().fold(f64::INFINITY, f64::min)
    );
    println!("{amp_bad:#?}\n{rate_bad:#?}");
}

/// A linear stage's model fitted at the lowest level predicts an experiment at eight times
/// the level: with the saved covariance (`predictor.json`'s `uncertainty`) its statistic is
/// calibrated, without it the model's own estimation error reads as a discrepancy.
/// (plain statistic with, without, threshold)
fn own_uncertainty_case(seed: u64) -> Option<(f64, f64, f64)> {
    let case = level_case_sized(seed, LevelEffect::Linear, &[1.0, 2.0, 8.0], PERIODIC, 8.0)?;
    let d = sd_diagnose::diagnose(&case.experiments[..2], &Default::default()).unwrap();
    let with = reread(&d.predictor);
    assert!(
        with.uncertainty.is_some(),
        "a fitted model keeps its covariance"
    );
    let without = Predictor {
        uncertainty: None,
        ..with.clone()
    };
    let a = predict_experiments(&with, &case.experiments[2..], 0.01).unwrap();
    let b = predict_experiments(&without, &case.experiments[2..], 0.01).unwrap();
    let (x, y) = (&a.experiments[0], &b.experiments[0]);
    Some((x.plain?, y.plain?, x.threshold?))
}

/// The default seeds `8..10` (`PREDICT_SEEDS=0..16` on the development seeds, where the
/// plain statistic with the covariance was below its threshold on all 16 and below the one
/// without on all 16: 0.86–0.99 against 0.92–1.11).
#[test]
fn the_models_own_uncertainty_is_counted() {
    let std::ops::Range { start: a, end: b } = sd_tests::env_seeds("PREDICT_SEEDS", 8..10);
    let mut ran = 0;
    for (s, r) in (a..b).zip(per_seed(a..b, own_uncertainty_case)) {
        let Some((with, without, threshold)) = r else {
            continue;
        };
        println!("seed {s}: plain {with:.4} with the covariance, {without:.4} without (threshold {threshold:.4})");
        assert!(with <= without + 1e-9, "seed {s}: {with} > {without}");
        assert!(with <= threshold, "seed {s}: {with} above {threshold}");
        ran += 1;
    }
    assert!(ran >= 1, "no case ran");
}
