//! The README's quick start, run verbatim: every `$ cargo sdctl …` line between the
//! `<!-- quickstart -->` and `<!-- /quickstart -->` markers, in order, in one fresh
//! directory, with `cargo sdctl` standing for this build's binary and a trailing `> FILE`
//! writing stdout there. Each command must succeed and each file it names as output must
//! exist afterwards.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;
use std::process::Command;

/// The quick start's command lines (without the `$ cargo sdctl ` prefix and comments).
fn quickstart_lines(readme: &str) -> Vec<String> {
    let start = readme
        .find("<!-- quickstart -->")
        .expect("README.md has a <!-- quickstart --> marker");
    let end = readme[start..]
        .find("<!-- /quickstart -->")
        .expect("README.md closes the quick start with <!-- /quickstart -->")
        + start;
    readme[start..end]
        .lines()
        .filter_map(|l| l.trim().strip_prefix("$ cargo sdctl "))
        .map(|l| l.split(" # ").next().unwrap_or(l).trim().to_string())
        .collect()
}

/// Runs one line in `dir`; returns the files it was to write (`-o F`, `--out D`, `> F`).
fn run(dir: &Path, line: &str) -> Vec<String> {
    let (cmd, redirect) = match line.split_once(" > ") {
        Some((c, f)) => (c.trim(), Some(f.trim())),
        None => (line, None),
    };
    let args: Vec<&str> = cmd.split_whitespace().collect();
    let t = std::time::Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(&args)
        .current_dir(dir)
        .output()
        .expect("run sdctl");
    eprintln!("{:6.2} s  sdctl {line}", t.elapsed().as_secs_f64());
    assert!(
        out.status.success(),
        "`sdctl {line}` failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut outputs = Vec::new();
    if let Some(f) = redirect {
        std::fs::write(dir.join(f), &out.stdout).unwrap();
        outputs.push(f.to_string());
    }
    for w in args.windows(2) {
        if w[0] == "-o" || w[0] == "--out" {
            outputs.push(w[1].to_string());
        }
    }
    outputs
}

#[test]
fn readme_quick_start_runs_verbatim() {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md"))
        .expect("read README.md");
    let lines = quickstart_lines(&readme);
    assert!(
        lines.len() >= 8,
        "the quick start has {} commands",
        lines.len()
    );
    let dir = std::env::temp_dir().join(format!("sdctl-quickstart-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let t = std::time::Instant::now();
    for line in &lines {
        for f in run(&dir, line) {
            assert!(dir.join(&f).exists(), "`sdctl {line}` did not write {f}");
        }
    }
    eprintln!(
        "quick start: {} commands in {:.1} s",
        lines.len(),
        t.elapsed().as_secs_f64()
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
