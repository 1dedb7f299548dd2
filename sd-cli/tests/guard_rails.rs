//! sdctl guard rails: a reader that goes away, a period that looks like a rate.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::Read;
use std::process::{Command, Stdio};

const DT: &str = r#"{"type":"ss","ts":0.001,"a":[[0.5]],"b":[[1]],"c":[[1]],"d":[[0]]}"#;

fn model_file(name: &str) -> String {
    let d = std::env::temp_dir().join(format!("sdctl-guard-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join("m.json");
    std::fs::write(&p, DT).unwrap();
    p.to_string_lossy().into_owned()
}

/// `sdctl freqresp … | head -c 100`: an output far larger than a pipe's buffer, the reader
/// gone after 100 bytes; sdctl ends with status 0 and no error on stderr (only freqresp's
/// usual line naming its evaluation path).
#[test]
fn a_reader_that_goes_away_is_no_error() {
    let m = model_file("pipe");
    let mut child = Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(["freqresp", &m, "--grid", "1:499:200000"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = child.stdout.take().unwrap();
    let mut first = [0u8; 100];
    out.read_exact(&mut first).unwrap();
    drop(out);
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.lines().all(|l| l.starts_with("[freqresp]")),
        "stderr: {err}"
    );
    assert_eq!(o.status.code(), Some(0));
}

/// `--ts 1000` (1 kHz meant) is a legal period of 1000 s, done, with a warning that names the
/// period it probably meant; `--ts 0.001` has none.
#[test]
fn a_period_above_a_second_is_questioned() {
    let d = std::env::temp_dir().join(format!("sdctl-guard-{}-ts", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let ct = d.join("ct.json");
    std::fs::write(
        &ct,
        r#"{"type":"ss","ts":null,"a":[[-1]],"b":[[1]],"c":[[1]],"d":[[0]]}"#,
    )
    .unwrap();
    let ct = ct.to_string_lossy().into_owned();
    let run = |ts: &str| {
        Command::new(env!("CARGO_BIN_EXE_sdctl"))
            .args(["c2d", &ct, "--ts", ts])
            .output()
            .unwrap()
    };
    let o = run("1000");
    assert!(o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("warning") && err.contains("1.000000e-3"),
        "{err}"
    );
    let o = run("0.001");
    assert!(o.status.success());
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `fit --order 600` on 200 lines: refused at once (exit 2, one line) naming the highest order
/// the lines determine; order 60 fits.
#[test]
fn an_order_the_lines_cannot_determine_is_refused() {
    let d = std::env::temp_dir().join(format!("sdctl-guard-{}-order", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let m = model_file("order");
    let frd = d.join("frd.json").to_string_lossy().into_owned();
    let o = Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(["freqresp", &m, "--grid", "1:450:200", "-o", &frd])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let fit = |order: &str| {
        Command::new(env!("CARGO_BIN_EXE_sdctl"))
            .args(["fit", &frd, "--order", order])
            .output()
            .unwrap()
    };
    let o = fit("600");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("at most 99"), "{err}");
    let o = fit("2");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    // the summary gives the cost per line (no variance here: relative weights, no noise level)
    assert!(err.contains(" per line)"), "{err}");
}

/// `testbed --print-default-config` prints the configuration the bare command runs, which
/// parses back as a testbed configuration; it needs no `--out` and refuses `--config`.
#[test]
fn the_default_testbed_configuration_is_printed() {
    let o = Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(["testbed", "--print-default-config"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let cfg = sd_testbed::parse_config(&text).unwrap();
    assert_eq!(cfg.identification.len(), 2);
    let default = sd_testbed::parse_config(sd_testbed::DEFAULT_CONFIG).unwrap();
    assert_eq!(format!("{cfg:?}"), format!("{default:?}"));
    assert!(text.contains("rate_hz = 5000.0"), "{text}");
    let o = Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(["testbed", "--print-default-config", "--config", "x.toml"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
}

/// `fit --order auto` on the default testbed's 5 kHz FRF: the order and rigid body the
/// held-out lines choose — the same as `fit --stabilization` — and the stage's physics (a
/// free mass: two rigid-body poles, and its two modes at 653 and 1650 Hz: order 6); refused,
/// naming what to give instead, with `--weighting`.
#[test]
fn order_auto_is_the_held_out_lines_choice() {
    let d = std::env::temp_dir().join(format!("sdctl-guard-{}-auto", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let run = |args: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_sdctl"))
            .args(args)
            .current_dir(&d)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        o
    };
    run(&["testbed", "--out", "data"]);
    let frd = run(&["frf", "data/experiments.toml", "--experiment", "fast"]);
    std::fs::write(d.join("frf.json"), &frd.stdout).unwrap();
    let auto = run(&[
        "fit",
        "frf.json",
        "--order",
        "auto",
        "--max-order",
        "12",
        "--json",
    ]);
    let auto: serde_json::Value = serde_json::from_slice(&auto.stdout).unwrap();
    run(&[
        "fit",
        "frf.json",
        "--stabilization",
        "--max-order",
        "12",
        "--out",
        "modal",
    ]);
    let modes: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("modal/modes.json")).unwrap())
            .unwrap();
    assert_eq!(auto["order"], modes["order"]);
    assert_eq!(auto["rigid_body"], modes["rigid_body"]);
    assert_eq!(auto["order"], 6, "{}", auto["orders"]);
    assert_eq!(auto["rigid_body"], 2);
    assert_eq!(auto["model"]["a"].as_array().unwrap().len(), 6);
    assert!(auto["cost_per_line"].as_f64().unwrap() < 1.5);
    let o = Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args([
            "fit",
            "frf.json",
            "--order",
            "auto",
            "--weighting",
            "uniform",
        ])
        .current_dir(&d)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("give a number of poles"), "{err}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// `sdctl freqresp` of a model with a pole on the grid (an integrator at 0 Hz): refused with
/// exit 2 and one line naming the frequency (issue #40 item 2), not a huge finite number.
#[test]
fn a_pole_on_the_grid_is_refused() {
    let d = std::env::temp_dir().join(format!("sdctl-guard-{}-pole", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join("int.json");
    std::fs::write(
        &p,
        r#"{"type":"ss","ts":0.001,"a":[[1,0.001],[0,1]],"b":[[0],[0.001]],"c":[[1,0]],"d":[[0]]}"#,
    )
    .unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(["freqresp", &p.to_string_lossy(), "--grid", "0:10:11"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("0 Hz is a pole of the model"), "{err}");
    // one step off the pole the same model answers
    let o = Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(["freqresp", &p.to_string_lossy(), "--grid", "1:10:10"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0));
}
