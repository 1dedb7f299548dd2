//! `sdctl analyze --plant-frd`: a controller on a measured plant (issue #40 item 5), against
//! `sdctl analyze --plant` on the model the FRF was computed from, the slow loop on a fast FRF
//! (`--downsample`), and the refusals.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::process::{Command, Output};

fn sdctl(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(args: &[&str]) -> String {
    let o = sdctl(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap()
}

/// A 20 kg rigid body with a 653 Hz mode (ζ = 0.01), `y = x₁ + x₃`.
const STAGE: &str = r#"{"type":"ss","ts":null,
 "a":[[0,1,0,0],[0,0,0,0],[0,0,0,1],[0,0,-16833936.0,-82.05]],
 "b":[[0],[0.05],[0],[0.1]],"c":[[1,0,1,0]],"d":[[0]]}"#;

#[test]
fn measured_loop_matches_the_model_and_folds_a_fast_frf() {
    let d = std::env::temp_dir().join(format!("sdctl-frd-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = |n: &str| d.join(n).to_string_lossy().into_owned();
    std::fs::write(p("c.json"), STAGE).unwrap();
    ok(&["c2d", &p("c.json"), "--ts", "0.001", "-o", &p("p1.json")]);
    ok(&["c2d", &p("c.json"), "--ts", "0.0002", "-o", &p("p5.json")]);
    ok(&[
        "freqresp",
        &p("p1.json"),
        "--grid",
        "0.5:499.5:999",
        "-o",
        &p("f1.json"),
    ]);
    ok(&[
        "freqresp",
        &p("p5.json"),
        "--grid",
        "0.5:2500:5000",
        "-o",
        &p("f5.json"),
    ]);
    #[rustfmt::skip]
    ok(&["weight", "pid", "--bandwidth-hz", "30", "--mass", "20", "--ts", "0.001", "-o", &p("k.json")]);
    let json = |s: String| -> serde_json::Value { serde_json::from_str(&s).unwrap() };
    let model = json(ok(&[
        "analyze",
        "--plant",
        &p("p1.json"),
        "--controller",
        &p("k.json"),
        "--json",
    ]));
    #[rustfmt::skip]
    let lines = json(ok(&["analyze", "--plant-frd", &p("f1.json"), "--controller", &p("k.json"), "--json", "--s-out", &p("s.json"), "--loop-svg", &p("l.svg")]));
    #[rustfmt::skip]
    let folded = json(ok(&["analyze", "--plant-frd", &p("f5.json"), "--downsample", "5", "--controller", &p("k.json"), "--json"]));
    for v in [&lines, &folded] {
        assert_eq!(v["nyquist"]["verdict"], "counted", "{v}");
        assert_eq!(v["nyquist"]["stable"], true);
        assert_eq!(v["plant_integrators"], 2);
        for (key, tol) in [("phase_margin_deg", 0.05), ("gain_margin_db", 0.05)] {
            let (a, b) = (v[key].as_f64().unwrap(), model[key].as_f64().unwrap());
            assert!(
                (a - b).abs() < tol,
                "{key}: {a} on the lines, {b} from the model"
            );
        }
    }
    assert_eq!(folded["downsampled"]["factor"], 5);
    let s = std::fs::read_to_string(p("s.json")).unwrap();
    assert!(s.contains("\"freq_hz\""));
    assert!(std::fs::read_to_string(p("l.svg")).unwrap().contains("PM "));
    // the text report names the verdict and where the margins are read
    let text = ok(&[
        "analyze",
        "--plant-frd",
        &p("f1.json"),
        "--controller",
        &p("k.json"),
    ]);
    assert!(
        text.contains("closed loop stable by the Nyquist test on the lines"),
        "{text}"
    );
    assert!(text.contains("interpolated between lines"), "{text}");

    // refusals: exit 2 with one line naming the problem
    let refused = |args: &[&str], needle: &str| {
        let o = sdctl(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    };
    #[rustfmt::skip]
    refused(&["analyze", "--plant-frd", &p("f5.json"), "--controller", &p("k.json")], "--downsample");
    #[rustfmt::skip]
    refused(&["analyze", "--plant", &p("p1.json"), "--controller", &p("k.json"), "--downsample", "5"], "--plant-frd");
    #[rustfmt::skip]
    refused(&["analyze", "--plant-frd", &p("f1.json"), "--controller", &p("k.json"), "--uncertainty", &p("s.json")], "need a plant model");
    #[rustfmt::skip]
    refused(&["analyze", "--plant-frd", &p("f1.json"), "--downsample", "3", "--controller", &p("k.json")], "line spacing");
    ok(&[
        "freqresp",
        &p("c.json"),
        "--grid",
        "1:1000:100",
        "-o",
        &p("fc.json"),
    ]);
    #[rustfmt::skip]
    refused(&["analyze", "--plant-frd", &p("fc.json"), "--downsample", "5", "--controller", &p("k.json")], "continuous");
}
