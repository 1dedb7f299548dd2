//! Project automation.
//!
//! - `cargo xtask paper [--out DIR] [--quick] [--averaging F]`: the paper's chain on the embedded
//!   virtual stage (figures, `report.md`, `report.json`; default `target/paper/`); `F` is the
//!   sensor's averaging window as a fraction of each period (default 0.6).
//! - `cargo xtask bench [--quick]`: medians of our operations and, where python-control and
//!   slycot import, of the same operations on the same inputs in python-control/scipy, with the
//!   ratio; the machine's measured peak with the fraction of it freqresp and the DARE reach,
//!   and the max RSS of whole processes (`physical`); written to `target/bench/results.json`.
//! - `cargo xtask bench --only hinfsyn [--quick]`: the H∞ synthesis entry alone (the 60-state
//!   stage's mixed-sensitivity plant, and SB10DD when slycot imports), written to
//!   `target/bench/hinfsyn.json`.

mod bench;
mod bench_hinf;
mod mixsyn_design;
mod multirate_design;
mod paper;
mod physical;
mod scaling;
mod uncertainty;

use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|i| args.get(i + 1))
        .cloned();
    let averaging = match args.iter().position(|a| a == "--averaging") {
        None => paper::DEFAULT_AVERAGING,
        Some(i) => match args.get(i + 1).and_then(|v| v.parse::<f64>().ok()) {
            Some(f) if (0.0..=1.0).contains(&f) => f,
            _ => {
                eprintln!("xtask: --averaging takes a fraction of the sample period in [0, 1]");
                return ExitCode::from(2);
            }
        },
    };
    let r = match args.first().map(String::as_str) {
        Some("paper") => paper::run(out.as_deref().unwrap_or("target/paper"), quick, averaging),
        Some("bench") => match args.iter().position(|a| a == "--only") {
            None => bench::run(quick),
            Some(i) => match args.get(i + 1).map(String::as_str) {
                Some("hinfsyn") => bench::run_hinfsyn(quick),
                _ => {
                    eprintln!("xtask: --only takes `hinfsyn` (the one entry that runs alone)");
                    return ExitCode::from(2);
                }
            },
        },
        _ => {
            eprintln!(
                "usage: cargo xtask paper [--out DIR] [--quick] [--averaging F] | cargo xtask bench [--quick] [--only hinfsyn]"
            );
            return ExitCode::from(2);
        }
    };
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: {e}");
            ExitCode::from(1)
        }
    }
}
