//! Fuzzing of every file reader (model JSON, FRD JSON, manifest, testbed configuration, CSV,
//! uncertainty JSON):
//! whatever the bytes, a reader returns `Ok` or an error, never panics, and never hangs.
//!
//! Inputs are valid files mutated byte-wise (insert, delete, replace with a character from a
//! dictionary of JSON/TOML/CSV tokens such as `NaN`, `1e999`, `[`, `"`, `=`, `\n`, and the
//! keys of each format), plus arbitrary byte strings. The default run tries a bounded number
//! of cases per reader (proptest, 5 readers × 400 cases + the CSV reader); the long run,
//!
//! ```text
//! FUZZ_SECONDS=600 cargo test --release -p sd-tests --test readers_fuzz long_fuzz -- --ignored --nocapture
//! ```
//!
//! mutates for the given wall time per reader with the stable seeded generator and prints the
//! number of inputs tried and the slowest one.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use proptest::prelude::*;
use sd_ident::rng::SplitMix;
use std::time::{Duration, Instant};

const MODEL: &str = r#"{"type":"ss","ts":0.001,"a":[[0.5,0.1],[0,0.2]],"b":[[1],[0]],"c":[[1,0]],"d":[[0]],"name":"p","inputs":["u"],"outputs":["y"]}"#;
const TF: &str = r#"{"type":"tf","ts":null,"num":[1,2],"den":[1,3,2]}"#;
const FRD: &str = r#"{"type":"frd","ts":0.001,"freq_hz":[1,2,3],"re":[[[1]],[[0.5]],[[0.2]]],"im":[[[0]],[[-0.1]],[[-0.2]]],"var":[[[1e-6]],[[1e-6]],[[1e-6]]]}"#;
const MANIFEST: &str = "[[experiment]]\nname = \"fast\"\nfile = \"fast.csv\"\nsample_rate_hz = 5000.0\nperiod_samples = 5000\nskip_periods = 1\nreference = \"r\"\ninput = \"u\"\noutput = \"y\"\nrole = \"model\"\n";
const CONFIG: &str = "seed = 2\n[truth]\nmass = 20.0\n[[truth.mode]]\nfreq_hz = 653.0\nzeta = 0.01\nresidue = 2.0\n[nonideal]\nhold_delay = 0.2\n[[experiment]]\nname = \"id\"\nrate_hz = 1000.0\npid_bandwidth_hz = 15.0\nperiod = 1000\nperiods = 3\nrole = \"model\"\n[[experiment]]\nkind = \"standstill\"\nname = \"ss\"\nrate_hz = 1000.0\nfactor = 5\nsamples = 5000\n";
const CSV: &str = "t,r,u,y\n0,1,2,3\n0.001,\"4\",5.5,-6e-3\n0.002,7,8,9,\n";
const UNCERTAINTY: &str = r#"{"type":"uncertainty","form":"additive","confidence":0.95,"ts":0.001,"freq_hz":[1,2,3],"nominal_re":[1,0.5,0.2],"nominal_im":[0,-0.1,-0.2],"bound":[0.1,0.2,0.3],"residual":[0.05,0.1,0.2],"sigma":[0.01,0.02,0.03]}"#;

/// Tokens the mutations insert: numbers that are not numbers, structure, and the formats' keys.
const TOKENS: &[&str] = &[
    "NaN",
    "-Infinity",
    "1e999",
    "-0",
    "0",
    "1e-320",
    "[",
    "]",
    "{",
    "}",
    "\"",
    ",",
    ":",
    "=",
    "\n",
    "[[experiment]]",
    "[truth]",
    "[[truth.mode]]",
    "ts",
    "null",
    "\"ss\"",
    "\"tf\"",
    "\"frd\"",
    "period_samples",
    "factor = 0",
    "rate_hz = 1e300",
    "periods = 99999999999",
    "samples = 0",
    "freq_hz",
    "\u{0}",
    "é",
    "\\u0000",
    "true",
    "-1",
    "9223372036854775807",
];

/// One reader: never panics; returns in well under a second for these sizes.
fn read(which: usize, text: &str) {
    let t0 = Instant::now();
    match which {
        0 => drop(sd_model::model_from_json_str(text)),
        1 => drop(sd_model::frd_from_json_str(text)),
        2 => drop(sd_ident::parse_manifest(text)),
        3 => drop(sd_testbed::parse_config(text)),
        5 => drop(sd_uncertainty::from_json_str(text)),
        _ => drop(sd_ident::read_columns(
            text.as_bytes(),
            "x.csv",
            &["r", "u", "y"],
        )),
    }
    assert!(
        t0.elapsed() < Duration::from_secs(2),
        "reader {which} took {:?} on {text:?}",
        t0.elapsed()
    );
}

fn seed_text(which: usize) -> &'static str {
    [MODEL, FRD, MANIFEST, CONFIG, CSV, UNCERTAINTY][which]
}

/// A mutation of `base`: `k` edits chosen by `rng`.
fn mutate(base: &str, rng: &mut SplitMix, k: usize) -> String {
    let mut s: Vec<char> = base.chars().collect();
    for _ in 0..k {
        let at = rng.below(s.len() + 1);
        match rng.below(3) {
            0 if !s.is_empty() => {
                let end = (at + 1 + rng.below(8)).min(s.len());
                s.drain(at.min(s.len())..end.max(at.min(s.len())));
            }
            1 if at < s.len() => s[at] = TOKENS[rng.below(TOKENS.len())].chars().next().unwrap(),
            _ => {
                let tok: Vec<char> = TOKENS[rng.below(TOKENS.len())].chars().collect();
                s.splice(at..at, tok);
            }
        }
    }
    s.into_iter().collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, .. ProptestConfig::default() })]

    /// Mutated valid files of every format.
    #[test]
    fn mutated_files_never_panic(which in 0usize..6, seed in any::<u64>(), k in 1usize..6) {
        let mut rng = SplitMix::new(seed);
        read(which, &mutate(seed_text(which), &mut rng, k));
        if which == 0 {
            read(0, &mutate(TF, &mut rng, k));
        }
    }

    /// Arbitrary text.
    #[test]
    fn arbitrary_text_never_panics(which in 0usize..6, text in ".{0,200}") {
        read(which, &text);
    }
}

/// The unmutated seeds are valid (so the mutations start from files that reach deep into each
/// reader).
#[test]
fn seeds_are_valid() {
    sd_model::model_from_json_str(MODEL).unwrap();
    sd_model::model_from_json_str(TF).unwrap();
    sd_model::frd_from_json_str(FRD).unwrap();
    sd_ident::parse_manifest(MANIFEST).unwrap();
    sd_testbed::parse_config(CONFIG).unwrap();
    sd_ident::read_columns(CSV.as_bytes(), "x.csv", &["r", "u", "y"]).unwrap();
    sd_uncertainty::from_json_str(UNCERTAINTY).unwrap();
}

/// The long run (module docs): `FUZZ_SECONDS` of mutations per reader.
#[test]
#[ignore = "long fuzz run; FUZZ_SECONDS=600 cargo test --release -p sd-tests --test readers_fuzz long_fuzz -- --ignored --nocapture"]
fn long_fuzz() {
    let secs: u64 = sd_tests::env_number("FUZZ_SECONDS", 60);
    for which in 0..6 {
        let mut rng = SplitMix::new(0xf022 + which as u64);
        let (t0, mut n, mut slowest) = (Instant::now(), 0u64, Duration::ZERO);
        while t0.elapsed() < Duration::from_secs(secs) / 6 {
            let k = 1 + rng.below(12);
            let text = mutate(seed_text(which), &mut rng, k);
            let t = Instant::now();
            read(which, &text);
            slowest = slowest.max(t.elapsed());
            n += 1;
        }
        println!(
            "reader {} ({}): {n} inputs in {:.0} s, slowest {:.2} ms",
            which,
            [
                "model JSON",
                "FRD JSON",
                "manifest",
                "testbed config",
                "CSV",
                "uncertainty JSON"
            ][which],
            t0.elapsed().as_secs_f64(),
            slowest.as_secs_f64() * 1e3
        );
    }
}
