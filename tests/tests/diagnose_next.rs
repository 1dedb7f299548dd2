//! Issue #42 items 1, 2 and 4: the experiment that decides. A rate-tied case (a hold delay, an
//! averaging sampler, both, or the 0.6-period delay that a delay and a delay-plus-averaging
//! pair explain alike) diagnosed on its model experiment and one slower experiment; where the
//! answer is `unexplained` with a proposal (`Diagnosis::next_experiment`), the proposed
//! experiment is run on the testbed (`sd_tests::diagcases::proposed`: the fine-step route,
//! another numerical form than the hypotheses' predictions, its own noise and phases, the same
//! hidden effect) and the case diagnosed again with it. Required: the proposal turns
//! `unexplained` into the right cause in ≥ 90 % of the cases and never into a wrong one.
//!
//! Seeds (the small-effect population, [`small`]): development (looked at while building and
//! tuning the noise model and the search) `0..60`: `NEXT_SEEDS=0..60 cargo test --release -p
//! sd-tests --test diagnose_next development -- --ignored --nocapture`; `3500..3560` was
//! reported at 82b7fd0 and re-run at e4fe7b2, then looked at case by case (seeds 3500 and
//! 3517) while fixing: spent (development now); `4200..4260` was reported once before the
//! pair rule took its present form (seed 4200 then looked at: spent), `4300..4360` at 6047e07
//! (before a pair's causes were tested against zero; seed 4338 looked at: spent), `4400..4460`
//! at a019881 (before a pair not told from zero could leave its single cause undetermined;
//! seeds 4424 and 4433 looked at: spent), `4500..4560` at b2eca7b (before the realized share
//! of the predicted separation, `REALIZED_SHARE`, measured on `0..60`), `4600..4660` at
//! a8b0201 (then run as development for a change that did not help and was not kept: a
//! contest of a delay against a window joined by their pair), `4700..4760` at a8b0201 (seed
//! 4706 then looked at: spent); fresh, never run: `4800..4860` (`cargo test --release -p
//! sd-tests --test diagnose_next reported -- --ignored --nocapture`). The clock population
//! ([`clock`]): `NEXT_CLOCK=1 NEXT_SEEDS=0..60 … development` (run once at a8b0201). The
//! default run checks one development case end to end (`the_proposal_decides_a_fixed_case`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sd_tests::diagcases::{build, per_seed, proposed, Effect, Recording};

/// The ambiguous population: small hold delays (0.03–0.2 of a period) and averaging windows
/// (0.05–0.3), alone or together, where a delay and a window lag the phase alike (about half
/// of such cases are `unexplained` on two experiments); `NEXT_LARGE` selects the larger
/// effects of `diagnose_more_data` (rarely ambiguous).
fn small() -> bool {
    std::env::var("NEXT_LARGE").is_err()
}

/// `NEXT_CLOCK` selects the second ambiguous population: small clock errors of the
/// slower experiment (0.05–0.3 %) and small hold delays (0.03–0.2), alone or together, on
/// short records (3 or 4 steady periods), where a clock error's phase drift and a delay's lag
/// can look alike at one slow rate.
fn clock() -> bool {
    std::env::var("NEXT_CLOCK").is_ok()
}

/// The hidden effect of `seed` (as `diagnose_more_data`'s: the 0.6-period delay every fourth)
/// and its recording: periodic, 3–8 steady periods, either injection, drift in 30 % (the
/// hidden-effect suite's recordings, periodic ones only).
fn effect_of(seed: u64) -> (Effect, Recording) {
    let mut r = sd_tests::gen::Rng::new(seed * 131 + 11);
    if clock() {
        let sign = sd_tests::diagcases::sign(&mut r);
        let effect = match seed % 3 {
            0 => Effect::Delay(r.range(0.03, 0.2)),
            1 => Effect::Clock(sign * r.range(5e-4, 3e-3)),
            _ => Effect::DelayClock(r.range(0.03, 0.2), sign * r.range(5e-4, 3e-3)),
        };
        let rec = Recording {
            periodic: true,
            steady: 3 + (seed / 3 % 2) as usize,
            ..sd_tests::diagcases::random_recording(&mut r, true)
        };
        return (effect, rec);
    }
    let effect = if small() {
        match seed % 3 {
            0 => Effect::Delay(r.range(0.03, 0.2)),
            1 => Effect::Averaging(r.range(0.05, 0.3)),
            _ => Effect::DelayAveraging(r.range(0.03, 0.15), r.range(0.05, 0.3)),
        }
    } else {
        match seed % 4 {
            0 => Effect::Delay(r.range(0.2, 1.2)),
            1 => Effect::Averaging(r.range(0.3, 1.0)),
            2 => Effect::DelayAveraging(r.range(0.1, 0.8), r.range(0.3, 1.0)),
            _ => Effect::Delay(0.6),
        }
    };
    let rec = Recording {
        periodic: true,
        ..sd_tests::diagcases::random_recording(&mut r, true)
    };
    (effect, rec)
}

/// One case: the effect, the answer before, and with a proposal the answer after, the
/// proposal's predicted power, and the wrong hypotheses' held-out statistics after.
#[derive(Debug)]
struct Outcome {
    effect: Effect,
    before: String,
    proposal: Option<(f64, usize, usize, f64)>,
    after: Option<String>,
    /// Time of the first diagnosis (s).
    seconds: f64,
    /// With a search for the next experiment: its time over the rest of the diagnosis's.
    added: Option<f64>,
    /// Per wrong hypothesis of `separates`: its predicted held-out excess over the noise level
    /// (`expected_held_out − 1`) and the observed one (its held-out statistic after, less the
    /// true cause's).
    excess: Vec<(f64, f64)>,
}

fn run_case(seed: u64) -> Option<Outcome> {
    let (effect, rec) = effect_of(seed);
    let case = build(seed, effect, rec)?;
    let t0 = std::time::Instant::now();
    // the search for the next experiment starts with this progress message
    let mut search_from: Option<f64> = None;
    let d = sd_diagnose::diagnose_with_progress(&case.experiments, &Default::default(), &mut |m| {
        if m.starts_with("the next experiment") && search_from.is_none() {
            search_from = Some(t0.elapsed().as_secs_f64());
        }
    })
    .unwrap();
    let first = t0.elapsed().as_secs_f64();
    let added = search_from.map(|t| (first - t) / t);
    let Some(n) = d.next_experiment.clone() else {
        return Some(Outcome {
            effect,
            before: d.cause,
            proposal: None,
            after: None,
            seconds: first,
            added,
            excess: Vec::new(),
        });
    };
    println!(
        "seed {seed} {effect:?}: {} → proposal {:.1} Hz, {} periods of {} samples ({:.1} s), \
         separates {:?}, expected {:?}, power {:.3}",
        d.cause,
        n.rate_hz,
        n.periods,
        n.period_samples,
        n.duration_s,
        n.separates,
        n.expected_statistic,
        n.power
    );
    let Some(x) = proposed(seed, effect, rec, (n.rate_hz, n.period_samples, n.periods)) else {
        println!("seed {seed}: the testbed cannot run the proposal (its loop is unstable there)");
        return Some(Outcome {
            effect,
            before: d.cause,
            proposal: Some((n.rate_hz, n.periods, n.period_samples, n.power)),
            after: Some("not run".into()),
            seconds: first,
            added,
            excess: Vec::new(),
        });
    };
    let mut exps = case.experiments.clone();
    exps.push(x);
    let d2 = sd_diagnose::diagnose(&exps, &Default::default()).unwrap();
    for rk in d2.ranking.iter().take(4) {
        println!("   after: {} held-out {:?}", rk.cause, rk.held_out);
    }
    // the named cause's parameters with their standard errors (a clock error per experiment)
    println!("   after: parameters {}", d2.parameters);
    let held = |name: &str| {
        d2.ranking
            .iter()
            .find(|r| r.cause == name)
            .and_then(|r| r.held_out)
    };
    let truth = held(effect.expected());
    let excess = n
        .expected_held_out
        .iter()
        .filter(|(h, _)| h.as_str() != effect.expected())
        .filter_map(|(h, p)| Some((p - 1.0, held(h)? - truth?)))
        .filter(|(_, o)| o.is_finite())
        .collect();
    Some(Outcome {
        effect,
        before: d.cause,
        proposal: Some((n.rate_hz, n.periods, n.period_samples, n.power)),
        after: Some(d2.cause),
        seconds: first,
        added,
        excess,
    })
}

/// `(cases, unexplained before, with a proposal, right after, unexplained after, wrong after,
/// mean predicted power, failures)`.
fn run(seeds: std::ops::Range<u64>) -> (usize, usize, usize, [usize; 3], f64, Vec<String>) {
    let out = per_seed(seeds.clone(), run_case);
    let (mut n, mut unexplained, mut proposals) = (0, 0, 0);
    let mut after = [0usize; 3];
    let mut power = 0.0;
    let mut bad = Vec::new();
    let mut ratios: Vec<f64> = Vec::new();
    let mut added: Vec<f64> = Vec::new();
    for (seed, o) in seeds.zip(&out) {
        let Some(o) = o else { continue };
        n += 1;
        added.extend(o.added);
        unexplained += usize::from(o.before == "unexplained");
        println!(
            "seed {seed} {:?}: {} -> {:?} ({:.1} s)",
            o.effect, o.before, o.after, o.seconds
        );
        let (Some(p), Some(a)) = (&o.proposal, &o.after) else {
            continue;
        };
        proposals += 1;
        power += p.3;
        for (pred, obs) in &o.excess {
            println!("seed {seed}: predicted held-out excess {pred:.4}, observed {obs:.4}");
            ratios.push(obs / pred);
        }
        let want = o.effect.expected();
        if a == "not run" {
            bad.push(format!(
                "seed {seed} {:?}: the proposal was not run",
                o.effect
            ));
            proposals -= 1;
            power -= p.3;
        } else if a == want {
            after[0] += 1;
        } else if a == "unexplained" {
            after[1] += 1;
            bad.push(format!("seed {seed} {:?}: still unexplained", o.effect));
        } else {
            after[2] += 1;
            bad.push(format!("seed {seed} {:?}: {a} (want {want})", o.effect));
        }
    }
    added.sort_by(f64::total_cmp);
    if let (Some(max), false) = (added.last(), added.is_empty()) {
        println!(
            "time the search for the next experiment adds to a diagnosis: median {:.0} %, \
             largest {:.0} % over {} searches",
            100.0 * added[added.len() / 2],
            100.0 * max,
            added.len()
        );
    }
    ratios.sort_by(f64::total_cmp);
    if !ratios.is_empty() {
        println!(
            "observed over predicted held-out excess of the wrong hypotheses: median {:.3}, \
             quartiles {:.3} / {:.3} over {}",
            ratios[ratios.len() / 2],
            ratios[ratios.len() / 4],
            ratios[3 * ratios.len() / 4],
            ratios.len()
        );
    }
    (
        n,
        unexplained,
        proposals,
        after,
        power / proposals.max(1) as f64,
        bad,
    )
}

fn report(seeds: std::ops::Range<u64>) {
    let (n, unexplained, proposals, after, power, bad) = run(seeds);
    println!(
        "{n} cases, {unexplained} unexplained, {proposals} with a proposal (mean predicted \
         power {power:.3}): after it right {}, unexplained {}, wrong {}; {bad:#?}",
        after[0], after[1], after[2]
    );
    assert_eq!(after[2], 0, "a proposal brought a wrong name: {bad:#?}");
    assert!(
        after[0] as f64 >= 0.9 * proposals as f64,
        "right after the proposal in {} of {proposals}",
        after[0]
    );
}

/// One development case end to end (seed 13: a 0.29-period averaging window that a hold delay
/// explains alike on two experiments): the proposal is made, its testbed table is a valid
/// `sdctl testbed` configuration with the case's rate, and with the proposed experiment the
/// window is named.
#[test]
fn the_proposal_decides_a_fixed_case() {
    let seed = 13;
    let (effect, rec) = effect_of(seed);
    let case = build(seed, effect, rec).unwrap();
    let d = sd_diagnose::diagnose(&case.experiments, &Default::default()).unwrap();
    assert_eq!(d.cause, "unexplained");
    let n = d.next_experiment.clone().expect("a proposal");
    assert!(n.power >= sd_diagnose::next_experiment::NEXT_POWER);
    assert_eq!(n.separates.len(), 2, "{:?}", n.separates);
    // the report folder: the proposal in Next steps and as the testbed's table
    let dir = std::env::temp_dir().join(format!("sd_next_{}", std::process::id()));
    sd_report::diagnosis::write_all(&dir, &d, "next experiment").unwrap();
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    assert!(md.contains("**The experiment that decides**"), "{md}");
    let rate = format!("at {} Hz", (n.rate_hz * 1e3).round() / 1e3);
    assert!(md.contains(&rate), "{rate} {md}");
    let written = std::fs::read_to_string(dir.join("next_experiment.toml")).unwrap();
    assert_eq!(written, n.testbed_toml());
    let json = std::fs::read_to_string(dir.join("diagnosis.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["next_experiment"]["factor"], n.factor);
    std::fs::remove_dir_all(&dir).ok();
    let toml = format!("[truth]\nmass = 20.0\n{}", n.testbed_toml());
    let cfg = sd_testbed::config::parse_config(&toml).unwrap();
    assert_eq!(cfg.identification.len(), 1);
    let ts = cfg.identification[0].controller.ts().unwrap();
    assert!((1.0 / ts - n.rate_hz).abs() < 1e-6 * n.rate_hz, "{ts}");
    assert_eq!(
        cfg.identification[0].periods,
        n.periods + n.transient_periods
    );
    // the injection point is the repeated experiment's: a reference column means reference
    let like = case
        .experiments
        .iter()
        .find(|e| e.spec.name == n.like)
        .unwrap();
    let by_reference = like.r.is_some();
    assert_eq!(
        cfg.identification[0].injection == sd_testbed::experiments::Injection::Reference,
        by_reference
    );
    assert_eq!(
        v["next_experiment"]["injection"],
        if by_reference { "reference" } else { "input" }
    );
    let x = proposed(seed, effect, rec, (n.rate_hz, n.period_samples, n.periods)).unwrap();
    let mut exps = case.experiments.clone();
    exps.push(x);
    let after = sd_diagnose::diagnose(&exps, &Default::default()).unwrap();
    assert_eq!(after.cause, effect.expected(), "{:?}", after.ranking);
}

#[test]
#[ignore]
fn development() {
    let seeds = sd_tests::env_seeds("NEXT_SEEDS", 0..60);
    assert!(
        seeds.end <= 4800 || seeds.start >= 4860,
        "development seeds must not touch the reported range"
    );
    report(seeds);
}

#[test]
#[ignore]
fn reported() {
    report(4800..4860);
}

/// Developer tool, not a check: one case's diagnosis with its progress, ranking and proposal,
/// then with the proposed experiment run its answer and ranking (`SEED=13 cargo test
/// --release -p sd-tests --test diagnose_next debug -- --ignored --nocapture`).
#[test]
#[ignore]
fn debug() {
    let seed: u64 = sd_tests::env_number("SEED", 2);
    let (effect, rec) = effect_of(seed);
    println!("{rec:?}");
    let case = build(seed, effect, rec).unwrap();
    let t0 = std::time::Instant::now();
    let d = sd_diagnose::diagnose_with_progress(&case.experiments, &Default::default(), &mut |m| {
        eprintln!("  {:.2} s > {m}", t0.elapsed().as_secs_f64())
    })
    .unwrap();
    println!("{effect:?}: {} partial {:?}", d.cause, d.partial);
    for rk in &d.ranking {
        println!("   {rk:?}");
    }
    println!("next {:#?}", d.next_experiment);
    println!("no proposal {:?}", d.no_next_experiment);
    let Some(n) = d.next_experiment else { return };
    let Some(x) = proposed(seed, effect, rec, (n.rate_hz, n.period_samples, n.periods)) else {
        println!("the testbed cannot run the proposal");
        return;
    };
    let mut exps = case.experiments.clone();
    exps.push(x);
    let d2 = sd_diagnose::diagnose(&exps, &Default::default()).unwrap();
    println!("after: {} partial {:?}", d2.cause, d2.partial);
    for rk in &d2.ranking {
        println!("   {rk:?}");
    }
    println!("after: parameters {}", d2.parameters);
}
