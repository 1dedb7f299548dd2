//! `sdctl bode` (issue #43 item 3): a model and its measured FRF in one SVG with the unit on the
//! magnitude axis and unwrapped phase; `--csv` writes the plotted numbers; bad input exits 2.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::Command;

fn sdctl(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(args)
        .output()
        .unwrap()
}

/// A fresh folder for one test's files.
fn scratch(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A lightly damped mode behind a sampled double integrator (phase from −180° down through
/// −360°: an unwrapped curve keeps falling).
const MODEL: &str =
    r#"{"type":"tf","ts":0.001,"num":[0.0, 1e-6, 1e-6],"den":[1.0, -2.9, 2.85, -0.95]}"#;

#[test]
fn a_model_and_its_frf_in_one_figure() {
    let d = scratch("sdctl-bode");
    let p = |n: &str| d.join(n).to_string_lossy().into_owned();
    std::fs::write(p("m.json"), MODEL).unwrap();
    let o = sdctl(&[
        "freqresp",
        &p("m.json"),
        "--grid",
        "0.5:450:400:log",
        "-o",
        &p("frd.json"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = sdctl(&[
        "bode",
        &p("m.json"),
        &p("frd.json"),
        "--unit",
        "m/N",
        "--csv",
        &p("b.csv"),
        "-o",
        &p("b.svg"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let svg = std::fs::read_to_string(p("b.svg")).unwrap();
    assert!(
        svg.contains("dB re 1 m/N") && svg.contains("(measured)"),
        "labels"
    );
    // no temporary file left beside the figure
    let left: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("partial"))
        .collect();
    assert!(left.is_empty());
    // the CSV: per curve, the phase is continuous (no jump above 180°) and the measured
    // curve equals the model at the FRF's lines
    let csv = std::fs::read_to_string(p("b.csv")).unwrap();
    let mut rows: std::collections::BTreeMap<String, Vec<(f64, f64, f64)>> = Default::default();
    for line in csv.lines().skip(1) {
        let v: Vec<&str> = line.split(',').collect();
        let x: Vec<f64> = v[1..].iter().map(|t| t.parse().unwrap()).collect();
        rows.entry(v[0].to_string())
            .or_default()
            .push((x[0], x[1], x[2]));
    }
    assert_eq!(rows.len(), 2, "{:?}", rows.keys());
    for (name, r) in &rows {
        assert!(
            r.windows(2).all(|w| (w[1].2 - w[0].2).abs() < 180.0),
            "{name}: phase jumps"
        );
        // the unwrapped phase passes below −360° (a wrapped one never would)
        assert!(
            r.iter().any(|x| x.2 < -360.0),
            "{name}: phase not unwrapped"
        );
    }
    let model = &rows["m"];
    let measured = &rows["frd (measured)"];
    for (f, db, ph) in measured {
        // the model's grid differs: compare at the nearest model point only where it is close
        let near = model
            .iter()
            .min_by(|a, b| (a.0 - f).abs().total_cmp(&(b.0 - f).abs()))
            .unwrap();
        if (near.0 / f - 1.0).abs() < 1e-9 {
            assert!((near.1 - db).abs() < 1e-9 && (near.2 - ph).abs() < 1e-7);
        }
    }
}

#[test]
fn bad_input_is_named() {
    let d = scratch("sdctl-bode-bad");
    let p = |n: &str| d.join(n).to_string_lossy().into_owned();
    std::fs::write(p("m.json"), MODEL).unwrap();
    let o = sdctl(&["bode", &p("m.json"), "-o", &p("x.svg")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--grid"));
    std::fs::write(
        p("mimo.json"),
        r#"{"type":"ss","ts":0.001,"a":[[0.5]],"b":[[1,1]],"c":[[1],[2]],"d":[[0,0],[0,0]]}"#,
    )
    .unwrap();
    let o = sdctl(&[
        "bode",
        &p("mimo.json"),
        "--grid",
        "1:100:10",
        "-o",
        &p("x.svg"),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--entry"));
    let o = sdctl(&[
        "bode",
        &p("mimo.json"),
        "--grid",
        "1:100:10",
        "--entry",
        "2,1",
        "-o",
        &p("x.svg"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = sdctl(&[
        "bode",
        &p("mimo.json"),
        "--grid",
        "1:100:10",
        "--entry",
        "3,1",
        "-o",
        &p("x.svg"),
    ]);
    assert_eq!(o.status.code(), Some(2));
}

/// `sdctl analyze --loop-svg`: the loop gain's Bode figure with both margins marked at the
/// frequencies the summary reports; a MIMO plant is refused with exit 2.
#[test]
fn the_loop_figure_marks_the_margins() {
    let d = scratch("sdctl-loop");
    let p = |n: &str| d.join(n).to_string_lossy().into_owned();
    // 1/(20 s²) sampled at 1 kHz (ZOH)
    let h = 1e-3f64;
    std::fs::write(
        p("plant.json"),
        format!(
            r#"{{"type":"ss","ts":{h},"a":[[1,{h}],[0,1]],"b":[[{}],[{}]],"c":[[1,0]],"d":[[0]]}}"#,
            h * h / 40.0,
            h / 20.0
        ),
    )
    .unwrap();
    #[rustfmt::skip]
    let o = sdctl(&["weight", "pid", "--bandwidth-hz", "10", "--mass", "20", "--ts", "0.001", "-o", &p("k.json")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    #[rustfmt::skip]
    let o = sdctl(&["analyze", "--plant", &p("plant.json"), "--controller", &p("k.json"), "--loop-svg", &p("loop.svg"), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let svg = std::fs::read_to_string(p("loop.svg")).unwrap();
    let pm = format!(
        "PM {:.1}° @ {:.2} Hz",
        v["phase_margin_deg"].as_f64().unwrap(),
        v["phase_margin_hz"].as_f64().unwrap()
    );
    assert!(svg.contains(&pm), "{pm} not in the figure");
    let gm = format!(
        "GM {:.1} dB @ {:.2} Hz",
        v["gain_margin_db"].as_f64().unwrap(),
        v["gain_margin_hz"].as_f64().unwrap()
    );
    assert!(svg.contains(&gm), "{gm} not in the figure");
    std::fs::write(
        p("mimo.json"),
        r#"{"type":"ss","ts":0.001,"a":[[0.5]],"b":[[1,1]],"c":[[1],[2]],"d":[[0,0],[0,0]]}"#,
    )
    .unwrap();
    std::fs::write(
        p("k2.json"),
        r#"{"type":"ss","ts":0.001,"a":[[0.1]],"b":[[1,0]],"c":[[0.01],[0.01]],"d":[[0,0],[0,0]]}"#,
    )
    .unwrap();
    #[rustfmt::skip]
    let o = sdctl(&["analyze", "--plant", &p("mimo.json"), "--controller", &p("k2.json"), "--loop-svg", &p("l2.svg")]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// A measured FRD with variances: `sdctl bode` draws its ±2σ band and a third panel with the
/// per-line SNR; `freqresp --csv` and `frf --csv` write f, dB, unwrapped phase (and σ, SNR).
#[test]
fn measured_variance_band_snr_panel_and_csv() {
    let d = scratch("sdctl-bode-snr");
    let p = |n: &str| d.join(n).to_string_lossy().into_owned();
    std::fs::write(p("m.json"), MODEL).unwrap();
    // an FRD with σ = 1 % of |G| on every line: SNR 40 dB
    let frd = r#"{"type":"frd","ts":0.001,"freq_hz":[1.0,2.0,5.0,10.0,20.0,50.0],
        "re":[[[1.0]],[[0.8]],[[0.5]],[[0.1]],[[-0.2]],[[-0.1]]],
        "im":[[[0.0]],[[-0.4]],[[-0.6]],[[-0.5]],[[-0.2]],[[0.05]]],
        "var":[[[1e-4]],[[8e-5]],[[6.1e-5]],[[2.6e-5]],[[8e-6]],[[1.25e-6]]]}"#;
    std::fs::write(p("f.json"), frd).unwrap();
    let o = sdctl(&[
        "bode",
        &p("m.json"),
        &p("f.json"),
        "--unit",
        "m/N",
        "-o",
        &p("b.svg"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let svg = std::fs::read_to_string(p("b.svg")).unwrap();
    assert!(
        svg.contains("SNR |Ĝ|/σ [dB]") && svg.contains("f ±2σ"),
        "panel and band"
    );
    // freqresp --csv: the model's magnitude and unwrapped phase
    let o = sdctl(&[
        "freqresp",
        &p("m.json"),
        "--grid",
        "1:400:50:log",
        "--csv",
        &p("r.csv"),
        "-o",
        &p("r.json"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(p("r.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(
        csv.lines().next().unwrap(),
        "output,input,freq_hz,magnitude_db,phase_deg,sigma,snr_db"
    );
    assert_eq!(rows.len(), 50);
    let ph: Vec<f64> = rows.iter().map(|r| r[4].parse().unwrap()).collect();
    assert!(ph.windows(2).all(|w| (w[1] - w[0]).abs() < 180.0));
    assert!(rows.iter().all(|r| r[5].is_empty() && r[6].is_empty()));
}
