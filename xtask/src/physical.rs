//! The physical yardsticks of `cargo xtask bench`: this machine's floating-point peak
//! (measured with faer's blocked, SIMD matrix product in the same run), the flops of the
//! freqresp and DARE algorithms with the fraction of that peak they reach, and the peak
//! memory (max RSS) of whole `sdctl` and `cargo xtask paper` processes.

use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;
use std::time::Instant;

/// Side of the square products that measure the peak.
const PEAK_N: usize = 768;

/// Flops per second of `threads` simultaneous `PEAK_N`-square faer products (`Par::Seq` each,
/// `2n³` flops per product), best of five rounds.
fn matmul_rate(threads: usize) -> f64 {
    let n = PEAK_N;
    let one = || {
        let a = faer::Mat::<f64>::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
        let b = faer::Mat::<f64>::from_fn(n, n, |i, j| ((i * 5 + j) % 13) as f64 - 6.0);
        let mut c = faer::Mat::<f64>::zeros(n, n);
        faer::linalg::matmul::matmul(
            c.as_mut(),
            faer::Accum::Replace,
            a.as_ref(),
            b.as_ref(),
            1.0,
            faer::Par::Seq,
        );
        c[(0, 0)]
    };
    let mut best = 0.0f64;
    for _ in 0..5 {
        let t0 = Instant::now();
        std::thread::scope(|s| {
            let hs: Vec<_> = (0..threads).map(|_| s.spawn(one)).collect();
            for h in hs {
                let _ = h.join();
            }
        });
        let t = t0.elapsed().as_secs_f64();
        best = best.max(threads as f64 * 2.0 * (n as f64).powi(3) / t);
    }
    best
}

/// The machine's measured peak: one core and every core (`available_parallelism`).
pub(crate) fn peak() -> Value {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    eprintln!("[bench] the machine's peak: faer matmul {PEAK_N}² on 1 and {cores} cores...");
    let one = matmul_rate(1);
    let all = matmul_rate(cores);
    json!({"name": "machine_peak", "method": format!("faer matmul {PEAK_N}x{PEAK_N} (Par::Seq per thread, best of 5)"),
        "cores": cores, "one_core_gflops": one / 1e9, "all_cores_gflops": all / 1e9})
}

/// Flops of one evaluation of the block-diagonal form per point (`sd_model`'s pole sum,
/// `pole_sum.rs`): per conjugate pair of simple poles the shared denominator (the offsets, the
/// product `d₁d₂`, its squared modulus and one division: 12) and per entry the numerator, the
/// quotient and the sum (16); per simple pole summed alone the reciprocal (6) and per entry a
/// complex multiply-add (10); per cluster of size m and input the back substitution (8 flops
/// per multiply-add, m(m−1)/2 of them, and m reciprocals of ~11) and the output product
/// (8·m·ny); the point itself (a sin_cos, counted 20).
pub(crate) fn freqresp_flops_per_point(
    block_sizes: &[usize],
    (pairs, singles): (usize, usize),
    ny: usize,
    nu: usize,
) -> f64 {
    let entries = (ny * nu) as f64;
    let clusters: f64 = block_sizes
        .iter()
        .filter(|&&b| b > 1)
        .map(|&m| {
            let m = m as f64;
            nu as f64 * (8.0 * m * (m - 1.0) / 2.0 + 11.0 * m + 8.0 * m * ny as f64)
        })
        .sum();
    20.0 + pairs as f64 * (12.0 + 16.0 * entries)
        + singles as f64 * (6.0 + 10.0 * entries)
        + clusters
}

/// Flops of one structured-doubling step on an n-state DARE (`sd_hinf::riccati`'s SDA):
/// `G_k H_k` (2n³), the LU of `I + G_k H_k` (⅔n³), its solve for 2n right-hand sides (4n³),
/// three general products (6n³) and the lower triangles of the symmetric `H⁺`, `G⁺` (2n³):
/// 44/3·n³.
pub(crate) fn dare_flops_per_step(n: usize) -> f64 {
    44.0 / 3.0 * (n as f64).powi(3)
}

/// GNU time, which reports a child's max RSS (`ru_maxrss`) without unsafe code here.
const GNU_TIME: &str = "/usr/bin/time";

/// Wall time and max RSS (KiB) of one process, through GNU time (`apt install time`).
pub(crate) fn measure(program: &Path, args: &[String], dir: &Path) -> Result<(f64, u64), String> {
    let report = dir.join("rss_time.txt");
    let t0 = Instant::now();
    let st = Command::new(GNU_TIME)
        .arg("-f")
        .arg("%M")
        .arg("-o")
        .arg(&report)
        .arg(program)
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .map_err(|e| format!("{GNU_TIME}: {e} (apt install time)"))?;
    let secs = t0.elapsed().as_secs_f64();
    if !st.success() {
        return Err(format!("{} {args:?} failed ({st})", program.display()));
    }
    let text = std::fs::read_to_string(&report).map_err(|e| e.to_string())?;
    let kb = text
        .lines()
        .last()
        .and_then(|l| l.trim().parse::<u64>().ok())
        .ok_or_else(|| format!("{GNU_TIME} reported no max RSS: {text}"))?;
    Ok((secs, kb))
}

/// Max RSS of `sdctl fit` (order 60 on the bench's 2500-line FRD), `sdctl testbed` and
/// `sdctl diagnose` (the default virtual-stage identification and its diagnosis) and
/// `cargo xtask paper --quick` (this binary, the paper's whole chain).
pub(crate) fn memory(sdctl: &Path, dir: &Path) -> Result<Value, String> {
    eprintln!("[bench] peak memory of sdctl fit / testbed / diagnose and xtask paper...");
    let s = |p: &Path| p.to_string_lossy().into_owned();
    let (fit_path, tb, dg, paper) = (
        dir.join("fit60_frd.json"),
        dir.join("rss_testbed"),
        dir.join("rss_diagnose"),
        dir.join("rss_paper"),
    );
    let _ = std::fs::remove_dir_all(&tb);
    let _ = std::fs::remove_dir_all(&dg);
    let mut rows = Vec::new();
    let mut run = |name: &str, program: &Path, args: &[String]| -> Result<(), String> {
        let (t, kb) = measure(program, args, dir)?;
        rows.push(json!({"command": name, "seconds": t, "max_rss_mib": kb as f64 / 1024.0}));
        Ok(())
    };
    let a = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    run(
        "sdctl fit --order 60 (2500 lines)",
        sdctl,
        &a(&[
            "fit",
            &s(&fit_path),
            "--order",
            "60",
            "-o",
            &s(&dir.join("rss_fit.json")),
        ]),
    )?;
    run(
        "sdctl testbed (default: 5 kHz and 1 kHz identification)",
        sdctl,
        &a(&["testbed", "--out", &s(&tb)]),
    )?;
    run(
        "sdctl diagnose (the testbed's experiments)",
        sdctl,
        &a(&[
            "diagnose",
            &s(&tb.join("experiments.toml")),
            "--out",
            &s(&dg),
        ]),
    )?;
    let me = std::env::current_exe().map_err(|e| e.to_string())?;
    run(
        "cargo xtask paper --quick (the xtask binary)",
        &me,
        &a(&["paper", "--quick", "--out", &s(&paper)]),
    )?;
    Ok(json!({"name": "peak_memory", "processes": rows}))
}
