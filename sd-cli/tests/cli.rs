//! sdctl contract tests: outputs, exit codes, one-line errors, atomic files.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::process::{Command, Output};

fn sdctl(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sdctl"))
        .args(args)
        .output()
        .expect("run sdctl")
}

/// `sdctl` that must succeed (its stderr shown when it does not).
fn sdctl_ok(args: &[&str]) -> Output {
    let o = sdctl(args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sdctl-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(dir: &std::path::Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_string_lossy().into_owned()
}

/// Exit code 2, exactly one line on stderr, no panic trace.
///
/// Every case is printed as `bad input case: <message>`, so the tally of bad-input cases is
/// `cargo test --release -p sd-cli --test cli -- --nocapture 2>&1 | grep '^bad input case:' | sort -u | wc -l`
/// (one output checked for two needles counts once).
fn assert_input_error(o: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    println!("bad input case: {}", err.trim_end());
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "one line expected: {err}"
    );
    assert!(
        !err.contains("panicked") && !err.contains("RUST_BACKTRACE"),
        "{err}"
    );
    assert!(
        err.to_lowercase().contains(&needle.to_lowercase()),
        "expected '{needle}' in: {err}"
    );
}

const CT: &str =
    r#"{"type":"ss","ts":null,"a":[[0,1],[-100,-2]],"b":[[0],[100]],"c":[[1,0]],"d":[[0]]}"#;
const DT: &str = r#"{"type":"ss","ts":0.001,"a":[[0.5]],"b":[[1]],"c":[[1]],"d":[[0]]}"#;

#[test]
fn alias_json() {
    let o = sdctl_ok(&["alias", "--freq-hz", "653", "--rate-hz", "1000", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((v["alias_hz"].as_f64().unwrap() - 347.0).abs() < 1e-9);
    assert_eq!(v["fold_index"], 1);
    let folds: Vec<f64> = serde_json::from_value(v["folding_frequencies_hz"].clone()).unwrap();
    assert!(
        folds.iter().any(|f| (f - 653.0).abs() < 1e-9)
            && folds.iter().any(|f| (f - 1347.0).abs() < 1e-9)
    );
}

#[test]
fn c2d_d2c_freqresp_poles_norm_reduce_connect() {
    let d = tmpdir("ok");
    let ct = write(&d, "ct.json", CT);
    let out = d.join("dt.json").to_string_lossy().into_owned();
    sdctl_ok(&["c2d", &ct, "--ts", "0.01", "-o", &out]);
    let dt = std::fs::read_to_string(&out).unwrap();
    assert!(dt.contains("\"ts\":0.01"));
    let o = sdctl_ok(&["d2c", &out]);
    let back = sd_model::model_from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
    assert!((back.a()[(1, 0)] + 100.0).abs() < 1e-9);
    assert!(String::from_utf8_lossy(&o.stderr).contains("candidates"));
    let o = sdctl_ok(&["freqresp", &out, "--grid", "1:50:20:log"]);
    let frd = sd_model::frd_from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
    assert_eq!(frd.len(), 20);
    // which algorithm ran is in the output (a 2-state model with distinct poles: block form)
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["eval_path"], "block_diagonal");
    assert!(String::from_utf8_lossy(&o.stderr).contains("block-diagonal"));
    for args in [
        vec!["poles", &ct, "--json"],
        vec!["zeros", &ct],
        vec!["norm", &ct, "--json"],
    ] {
        let o = sdctl(&args);
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let o = sdctl(&["norm", &ct, "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((v["hinf"].as_f64().unwrap() - 5.02519).abs() < 1e-4, "{v}");
    let o = sdctl_ok(&["reduce", &ct, "--order", "1"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("Hankel"));
    let o = sdctl_ok(&["connect", "feedback", &ct, &ct]);
    let fb = sd_model::model_from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
    assert_eq!(fb.n(), 4);
}

#[test]
fn bad_inputs_exit_2_with_one_line() {
    let d = tmpdir("bad");
    // (file, contents, what the one-line message must name); needle None = the file's path
    let bad_models: [(&str, &str, Option<&str>); 6] = [
        (
            "shape.json",
            r#"{"type":"ss","ts":null,"a":[[0,1],[0,0]],"b":[[1]],"c":[[1,0]],"d":[[0]]}"#,
            Some("\"b\""),
        ),
        (
            "ragged.json",
            r#"{"type":"ss","ts":null,"a":[[0,1],[0]],"b":[[0],[1]],"c":[[1,0]],"d":[[0]]}"#,
            Some("row 1"),
        ),
        (
            "nan.json",
            r#"{"type":"ss","ts":null,"a":[[NaN]],"b":[[1]],"c":[[1]],"d":[[0]]}"#,
            Some("NaN and infinite values are not allowed"),
        ),
        (
            "inf.json",
            r#"{"type":"ss","ts":null,"a":[[1e999]],"b":[[1]],"c":[[1]],"d":[[0]]}"#,
            None,
        ),
        (
            "ts0.json",
            r#"{"type":"ss","ts":0,"a":[[0.5]],"b":[[1]],"c":[[1]],"d":[[0]]}"#,
            Some("write `\"ts\": null` for continuous time"),
        ),
        ("junk.json", "{not json", Some("cannot read")),
    ];
    for (name, text, needle) in bad_models {
        let path = write(&d, name, text);
        assert_input_error(&sdctl(&["poles", &path]), needle.unwrap_or(&path));
    }
    let ct = write(&d, "ct.json", CT);
    assert_input_error(&sdctl(&["c2d", &ct, "--ts", "-1"]), "--ts");
    let dt = write(&d, "dt.json", DT);
    assert_input_error(&sdctl(&["c2d", &dt, "--ts", "0.01"]), "continuous-time");
    assert_input_error(
        &sdctl(&["connect", "series", &ct, &dt]),
        "sample time mismatch",
    );
    assert_input_error(&sdctl(&["freqresp", &dt, "--grid", "1:600:10"]), "nyquist");
    assert_input_error(
        &sdctl(&["freqresp", &dt, "--grid", "1:x:10"]),
        "FMIN:FMAX:N",
    );
    assert_input_error(&sdctl(&["poles", "/nonexistent/model.json"]), "cannot read");
    assert_input_error(&sdctl(&["alias", "--freq-hz", "653"]), "rate-hz");
    let neg = write(
        &d,
        "neg.json",
        r#"{"type":"ss","ts":0.01,"a":[[-0.5]],"b":[[1]],"c":[[1]],"d":[[0]]}"#,
    );
    assert_input_error(&sdctl(&["d2c", &neg]), "negative real axis");
    // no half-written output: a failing command leaves no file
    let out = d.join("never.json");
    let o = sdctl(&["c2d", &dt, "--ts", "0.01", "-o", &out.to_string_lossy()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!out.exists());
    assert_eq!(
        std::fs::read_dir(&d)
            .unwrap()
            .filter(|e| e
                .as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .contains(".tmp"))
            .count(),
        0
    );
}

/// `frf` says when the data cannot be trusted: a record without excitation is refused by
/// default (kept with a warning when asked), and low-SNR lines are left out with a warning
/// that also travels in the FRD JSON.
#[test]
fn frf_warns_about_data_it_cannot_trust() {
    let d = tmpdir("frfwarn");
    let cfg = write(
        &d,
        "c.toml",
        "[[experiment]]\nkind = \"standstill\"\nname = \"s\"\nrate_hz = 1000.0\nsamples = 40000\n\
         [[experiment]]\nname = \"a\"\nrate_hz = 1000.0\nperiod = 1000\nperiods = 4\n",
    );
    let data = d.join("data");
    assert!(sdctl(&[
        "testbed",
        "--config",
        &cfg,
        "--out",
        &data.to_string_lossy()
    ])
    .status
    .success());
    // the standstill record as it is (no period, no reference): the input is the controller's
    // reaction to the output, at the slow rate and held at the fast one
    let manifest0 = data.join("experiments.toml").to_string_lossy().into_owned();
    for e in ["s_slow", "s_fast"] {
        assert_input_error(
            &sdctl(&["frf", &manifest0, "--experiment", e]),
            "the input is the controller's reaction to the measured output",
        );
    }
    let o = sdctl_ok(&[
        "frf",
        &manifest0,
        "--experiment",
        "s_slow",
        "--keep-low-snr",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["warnings"][0]["kind"], "feedback_only");
    let both = write(
        &data,
        "still2.toml",
        "[[experiment]]\nname = \"f\"\nfile = \"s_fast.csv\"\nsample_rate_hz = 5000.0\n\
         input = \"u\"\noutput = \"y\"\nrole = \"model\"\n\
         [[experiment]]\nname = \"s\"\nfile = \"s_slow.csv\"\nsample_rate_hz = 1000.0\n\
         input = \"u\"\noutput = \"y\"\n",
    );
    let out_dir = d.join("diag").to_string_lossy().into_owned();
    assert_input_error(
        &sdctl(&["diagnose", &both, "--out", &out_dir]),
        "experiment `f`: no excitation",
    );
    // the standstill record read as periodic (a user's wrong period): no excitation
    let still = write(
        &data,
        "still.toml",
        "[[experiment]]\nname = \"still\"\nfile = \"s_slow.csv\"\nsample_rate_hz = 1000.0\n\
         period_samples = 1000\ninput = \"u\"\noutput = \"y\"\n",
    );
    assert_input_error(
        &sdctl(&["frf", &still, "--experiment", "still"]),
        "not excited",
    );
    let o = sdctl_ok(&["frf", &still, "--experiment", "still", "--keep-low-snr"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("warning: still: no excitation"), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let kinds: Vec<&str> = v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["feedback_only", "no_excitation", "low_input_snr"]);
    assert!(v["warnings"][1]["median_input_snr"].as_f64().unwrap() < 10.0);
    // the closed-loop experiment: its lowest lines are left out, and the JSON reads back
    let manifest = data.join("experiments.toml").to_string_lossy().into_owned();
    let out = d.join("a.json").to_string_lossy().into_owned();
    sdctl_ok(&["frf", &manifest, "--experiment", "a", "-o", &out]);
    let v = read_json(&out);
    let n_default = v["freq_hz"].as_array().unwrap().len();
    let o = sdctl(&["frf", &manifest, "--experiment", "a", "--keep-low-snr"]);
    let all: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let n_all = all["freq_hz"].as_array().unwrap().len();
    match v.get("warnings") {
        Some(w) => {
            assert_eq!(w[0]["kind"], "low_input_snr");
            assert_eq!(w[0]["excluded"], true);
            assert_eq!(n_all - n_default, w[0]["lines"].as_u64().unwrap() as usize);
        }
        None => assert_eq!(n_all, n_default),
    }
    sdctl_ok(&["fit", &out, "--order", "2"]);
    // fit --json: the model, the cost per line (summing to the cost) and the warnings
    let o = sdctl_ok(&["fit", &out, "--order", "4", "--rigid-body", "2", "--json"]);
    let f: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let lines = f["lines"].as_array().unwrap();
    assert_eq!(lines.len(), n_default);
    let sum: f64 = lines.iter().map(|l| l["cost"].as_f64().unwrap()).sum();
    let cost = f["cost"].as_f64().unwrap();
    assert!((sum - cost).abs() <= 1e-9 * cost, "{sum} vs {cost}");
    assert!(f["warnings"].is_array());
    assert_eq!(f["model"]["type"], "ss");
    assert!(String::from_utf8_lossy(&o.stderr).contains("largest line terms"));
    assert_input_error(
        &sdctl(&["fit", &out, "--order", "4", "--min-damping", "1.5"]),
        "min_damping",
    );
}

/// Transforms asked for what they cannot do say what to run instead.
#[test]
fn transforms_say_what_to_do_instead() {
    let d = tmpdir("transforms");
    let ct = write(&d, "ct.json", CT);
    let o = sdctl(&["downsample", &ct, "--factor", "5"]);
    assert_input_error(&o, "is continuous-time");
    assert_input_error(&o, "sdctl c2d");
    assert!(
        !String::from_utf8_lossy(&o.stderr).contains("delayed hold"),
        "no options the user did not give"
    );
    // A 653 Hz mode sampled at 1 kHz reads 347 Hz; --near-hz puts it back.
    let stage = r#"{"type":"ss","ts":null,"a":[[0,1],[-16833952.6,-41.03]],"b":[[0],[1]],"c":[[1,0]],"d":[[0]]}"#;
    let st = write(&d, "stage.json", stage);
    let slow = d.join("slow.json").to_string_lossy().into_owned();
    assert!(sdctl(&["c2d", &st, "--ts", "0.001", "-o", &slow])
        .status
        .success());
    let o = sdctl_ok(&["d2c", &slow, "--near-hz", "650"]);
    let back = model_of(&o);
    let f = sd_model::poles::natural_frequency(
        sd_model::linalg::convert::eigenvalues(back.a()).unwrap()[0],
        None,
    )
    .0;
    assert!((f - 653.0).abs() < 0.01, "{f} Hz");
    assert!(String::from_utf8_lossy(&o.stderr).contains("branch k = "));
    assert_input_error(
        &sdctl(&["d2c", &slow, "--near-hz", "nan"]),
        "finite and positive",
    );
    assert_input_error(
        &sdctl(&["d2c", &slow, "--near-hz", "653", "--near-hz", "347"]),
        "a mode has one branch",
    );
    let dt = write(&d, "dt.json", DT);
    assert_input_error(
        &sdctl(&["d2c", &dt, "--near-hz", "600"]),
        "no oscillatory mode",
    );
}

/// A typo, a missing `ts` or a non-finite number is never read silently: exit 2 with one line
/// that names the key, where it is, and the closest allowed key.
#[test]
fn typos_and_missing_keys_are_named() {
    let d = tmpdir("typos");
    let models: [(&str, &str); 6] = [
        (
            r#"{"type":"ss","Ts":0.001,"a":[[0.5]],"b":[[1]],"c":[[1]],"d":[[0]]}"#,
            "unknown key `Ts` in the file: did you mean `ts`?",
        ),
        (
            r#"{"type":"ss","dt":0.001,"a":[[0.5]],"b":[[1]],"c":[[1]],"d":[[0]]}"#,
            "unknown key `dt` in the file: did you mean `ts`?",
        ),
        (
            r#"{"type":"ss","a":[[0.5]],"b":[[1]],"c":[[1]],"d":[[0]]}"#,
            "the key `ts` is missing",
        ),
        (
            r#"{"type":"tf","ts":0.001,"num":[1],"den":[1,-0.5],"nmae":"x"}"#,
            "unknown key `nmae` in the file: did you mean `name`?",
        ),
        (
            "{\"type\":\"ss\",\"ts\":0.001,\n\"a\":[[-Infinity]],\"b\":[[1]],\"c\":[[1]],\"d\":[[0]]}",
            "line 2 column 7: NaN and infinite values are not allowed",
        ),
        (
            r#"{"type":"ss","ts":0.001,"a":[[0.5]],"b":[[1]],"c":[[1]],"d":[[0]],"input":["u"]}"#,
            "did you mean `inputs`?",
        ),
    ];
    for (i, (text, needle)) in models.iter().enumerate() {
        let path = write(&d, &format!("m{i}.json"), text);
        assert_input_error(&sdctl(&["poles", &path]), needle);
    }
    let frd = write(
        &d,
        "f.json",
        r#"{"type":"frd","ts":0.001,"freq":[1],"re":[[[1]]],"im":[[[0]]]}"#,
    );
    assert_input_error(
        &sdctl(&["fit", &frd, "--order", "2"]),
        "unknown key `freq` in the file: did you mean `freq_hz`?",
    );
    let exp =
        "name = \"a\"\nfile = \"x.csv\"\nsample_rate_hz = 1000\ninput = \"u\"\noutput = \"y\"\n";
    for (extra, needle) in [
        ("perod_samples = 1000\n", "did you mean `period_samples`?"),
        ("skip_period = 1\n", "did you mean `skip_periods`?"),
        ("rol = \"model\"\n", "did you mean `role`?"),
        ("fs = 1000\n", "did you mean `sample_rate_hz`?"),
    ] {
        let m = write(&d, "m.toml", &format!("[[experiment]]\n{exp}{extra}"));
        let o = sdctl(&["frf", &m, "--experiment", "a"]);
        assert_input_error(&o, needle);
        assert_input_error(&o, "in experiment 1 (`a`)");
    }
    let m = write(&d, "m2.toml", &format!("[[experiments]]\n{exp}"));
    assert_input_error(
        &sdctl(&["frf", &m, "--experiment", "a"]),
        "did you mean `experiment`?",
    );
    let id = "[[experiment]]\nname = \"a\"\nrate_hz = 1000.0\n";
    let out = d.join("tb").to_string_lossy().into_owned();
    for (text, needle) in [
        (
            format!("[nonideal]\nhold_dealy = 0.1\n{id}"),
            "unknown key `hold_dealy` in [nonideal]: did you mean `hold_delay`?",
        ),
        (
            format!("[nonideals]\nhold_delay = 0.1\n{id}"),
            "did you mean `nonideal`?",
        ),
        (
            format!("[[truth.mode]]\nfreq = 653.0\n{id}"),
            "did you mean `freq_hz`?",
        ),
        (format!("{id}perods = 3\n"), "did you mean `periods`?"),
        ("[truth]\nmass = 2.0\n".into(), "no [[experiment]]"),
        (
            "[[experiment]]\nkind = \"standstill\"\nname = \"s\"\nrate_hz = 1000.0\nfactor = 0\n"
                .into(),
            "`factor` must be ≥ 1",
        ),
        (
            format!("{id}injection = \"reference\"\nrms = 1.0\n"),
            "1 m rms position reference",
        ),
        (
            "[[experiment]]\nname = \"a\"\nrate_hz = 1e12\n".into(),
            "more than 80000000 samples",
        ),
        (format!("{id}periods = 100000000000\n"), "`periods`"),
        (
            "[[experiment]]\nkind = \"standstill\"\nname = \"s\"\nrate_hz = 1000.0\nsamples = 100000000000\n"
                .into(),
            "`samples` × `factor`",
        ),
    ] {
        let cfg = write(&d, "c.toml", &text);
        assert_input_error(
            &sdctl(&["testbed", "--config", &cfg, "--out", &out]),
            needle,
        );
        assert!(
            !std::path::Path::new(&out).exists(),
            "nothing written: {text}"
        );
    }
}

/// A configuration that leaves `injection` out runs the experiments exactly as `sdctl testbed`
/// without a configuration does (input injection, `rms` in N).
#[test]
fn testbed_defaults_are_the_same_with_and_without_a_config() {
    let d = tmpdir("defaults");
    let (a, b) = (d.join("a"), d.join("b"));
    sdctl_ok(&["testbed", "--out", &a.to_string_lossy()]);
    let cfg = write(
        &d,
        "c.toml",
        "[[experiment]]\nname = \"fast\"\nrate_hz = 5000.0\nrole = \"model\"\npid_bandwidth_hz = 30.0\n\
         pid_lowpass_hz = 1000.0\nperiod = 5000\nperiods = 5\nf_min = 1.0\nf_max = 2400.0\n\
         [[experiment]]\nname = \"slow\"\nrate_hz = 1000.0\npid_bandwidth_hz = 20.0\nperiod = 1000\n\
         periods = 5\nf_min = 1.0\nf_max = 499.0\n",
    );
    sdctl_ok(&["testbed", "--config", &cfg, "--out", &b.to_string_lossy()]);
    for f in ["fast.csv", "slow.csv", "experiments.toml"] {
        let (x, y) = (
            std::fs::read_to_string(a.join(f)).unwrap(),
            std::fs::read_to_string(b.join(f)).unwrap(),
        );
        assert!(
            x == y,
            "{f} differs between the default run and the config without injection"
        );
    }
}

/// The JSON a successful command printed, with each of `keys` present.
/// A JSON file the CLI wrote.
fn read_json(path: impl AsRef<std::path::Path>) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn json_with_keys(o: &Output, keys: &[&str]) -> serde_json::Value {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in keys {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    v
}

fn model_of(o: &Output) -> sd_model::StateSpace {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    sd_model::model_from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap()
}

#[test]
fn downsample_c2d_nonideal_and_alias_factor() {
    let dir = tmpdir("downsample");
    let ct = write(&dir, "ct.json", CT);
    // c2d at 1 ms, and at 0.2 ms then downsample by 5: the same model (Lemma 5 then Lemma 6)
    let slow = model_of(&sdctl(&["c2d", &ct, "--ts", "0.001"]));
    let fast_file = dir.join("fast.json").to_string_lossy().into_owned();
    sdctl_ok(&["c2d", &ct, "--ts", "0.0002", "-o", &fast_file]);
    let down = model_of(&sdctl(&["downsample", &fast_file, "--factor", "5"]));
    assert!((down.a() - slow.a()).norm() < 1e-12 * slow.a().norm());
    assert!((down.b() - slow.b()).norm() < 1e-12 * slow.b().norm());
    assert!((down.ts().unwrap() - 1e-3).abs() < 1e-15);
    // delayed hold from CT at 1 kHz equals a delay of 2 fast samples at 5 kHz
    let dct = model_of(&sdctl(&[
        "c2d",
        &ct,
        "--ts",
        "0.001",
        "--hold-delay",
        "0.4",
    ]));
    let ddt = model_of(&sdctl(&[
        "downsample",
        &fast_file,
        "--factor",
        "5",
        "--hold-delay",
        "0.4",
    ]));
    assert_eq!(dct.n(), 3);
    let f = [7.0, 100.0, 333.0];
    let (a, b) = (dct.freqresp(&f).unwrap(), ddt.freqresp(&f).unwrap());
    for i in 0..3 {
        let (x, y) = (a.response()[i][(0, 0)], b.response()[i][(0, 0)]);
        assert!((x - y).norm() < 1e-9 * y.norm());
    }
    let avg = model_of(&sdctl(&["c2d", &ct, "--ts", "0.001", "--averaging", "1"]));
    assert_eq!(avg.n(), 3);
    // alias with the fast folding list
    let o = sdctl_ok(&[
        "alias",
        "--freq-hz",
        "653",
        "--rate-hz",
        "1000",
        "--factor",
        "5",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let folds = v["fast_folds"].as_array().unwrap();
    assert_eq!(folds.len(), 5);
    assert!(folds
        .iter()
        .any(|t| (t["fast_hz"].as_f64().unwrap() - 653.0).abs() < 1e-9
            && t["weight"].as_f64().unwrap() > 0.0
            && t["weight"].as_f64().unwrap() < 1.0));
    let o = sdctl(&[
        "alias",
        "--freq-hz",
        "653",
        "--rate-hz",
        "1000",
        "--factor",
        "5",
    ]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("weights"));
    // bad input: exit 2, one line
    assert_input_error(&sdctl(&["downsample", &ct, "--factor", "5"]), "discrete");
    assert_input_error(
        &sdctl(&["downsample", &fast_file, "--factor", "0"]),
        "factor",
    );
    assert_input_error(
        &sdctl(&[
            "downsample",
            &fast_file,
            "--factor",
            "5",
            "--hold-delay",
            "0.3",
        ]),
        "multiple of 1/F",
    );
    assert_input_error(
        &sdctl(&["c2d", &ct, "--ts", "0.001", "--hold-delay", "4.5"]),
        "hold delay",
    );
    assert_input_error(
        &sdctl(&[
            "c2d",
            &ct,
            "--ts",
            "0.001",
            "--method",
            "tustin",
            "--averaging",
            "0.5",
        ]),
        "zoh",
    );
    assert_input_error(
        &sdctl(&[
            "alias",
            "--freq-hz",
            "653",
            "--rate-hz",
            "1000",
            "--factor",
            "-2",
        ]),
        "factor",
    );
}

#[test]
fn weight_and_loopshape() {
    let dir = tmpdir("loopshape");
    let ct = write(&dir, "ct.json", CT);
    let p = dir.join("p.json").to_string_lossy().into_owned();
    assert!(sdctl(&["c2d", &ct, "--ts", "0.01", "-o", &p])
        .status
        .success());
    let w = sdctl(&[
        "weight",
        "pid",
        "--bandwidth-hz",
        "2",
        "--mass",
        "0.01",
        "--ts",
        "0.01",
    ]);
    let wm = model_of(&w);
    assert_eq!(wm.ts(), Some(0.01));
    let w1 = write(&dir, "w1.json", &String::from_utf8_lossy(&w.stdout));
    // controller JSON on stdout
    let k = model_of(&sdctl(&["loopshape", &p, "--w1", &w1]));
    assert_eq!(k.ts(), Some(0.01));
    // --json object with the contract keys
    let o = sdctl(&["loopshape", &p, "--w1", &w1, "--json", "--strictly-proper"]);
    let v = json_with_keys(
        &o,
        &[
            "gamma_min",
            "gamma",
            "controller",
            "shaped_controller",
            "closed_loop_stable",
            "riccati",
        ],
    );
    assert_eq!(v["closed_loop_stable"], true);
    let g = v["gamma"].as_f64().unwrap() / v["gamma_min"].as_f64().unwrap();
    assert!((g - 1.1).abs() < 1e-12);
    let ks: sd_model::StateSpace =
        sd_model::model_from_json_str(&v["shaped_controller"].to_string()).unwrap();
    assert_eq!(ks.d().norm(), 0.0);
    for r in v["riccati"].as_array().unwrap() {
        assert!(r["residual"].as_f64().unwrap() < 1e-12);
    }
    // notch and low-pass
    assert!(
        model_of(&sdctl(&[
            "weight",
            "notch",
            "--freq-hz",
            "3",
            "--ts",
            "0.01"
        ]))
        .n() == 2
    );
    assert!(model_of(&sdctl(&["weight", "lowpass", "--freq-hz", "3"]))
        .ts()
        .is_none());
    // bad input: exit 2, one line
    assert_input_error(&sdctl(&["loopshape", &p, "--factor", "1"]), "factor");
    assert_input_error(&sdctl(&["loopshape", &p, "--w1", &ct]), "sample time");
    assert_input_error(
        &sdctl(&["weight", "notch", "--freq-hz", "70", "--ts", "0.01"]),
        "nyquist",
    );
    assert_input_error(
        &sdctl(&["weight", "pid", "--bandwidth-hz", "-3", "--mass", "1"]),
        "bandwidth",
    );
}

#[test]
fn frf_and_fit() {
    let dir = tmpdir("frf-fit");
    // a 2nd-order resonance at 100 Hz, sampled at 1 kHz, driven by a multisine (4 periods)
    let ct = write(
        &dir,
        "ct.json",
        r#"{"type":"ss","ts":null,"a":[[0,1],[-394784.176,-62.83]],"b":[[0],[394784.176]],"c":[[1,0]],"d":[[0]]}"#,
    );
    let pd = model_of(&sdctl(&["c2d", &ct, "--ts", "0.001"]));
    let ms = sd_ident::design(&sd_ident::MultisineSpec {
        fs: 1000.0,
        period: 1000,
        f_min: 1.0,
        f_max: 400.0,
        lines: sd_ident::Lines::Full,
        phases: sd_ident::Phases::Schroeder,
        rms: 1.0,
        fold_rate_hz: None,
    })
    .unwrap();
    let u = ms.repeat(4);
    let y = pd
        .simulate(&nalgebra::DMatrix::from_column_slice(u.len(), 1, &u), None)
        .unwrap()
        .y;
    let mut csv = String::from("\"time\", \"u\",y,unused,\n");
    for (i, v) in u.iter().enumerate() {
        csv.push_str(&format!("{},{v},{},,\n", i as f64 * 1e-3, y[(i, 0)]));
    }
    write(&dir, "data.csv", &csv);
    let manifest = write(
        &dir,
        "exp.toml",
        "[[experiment]]\nname = \"a\"\nfile = \"data.csv\"\nsample_rate_hz = 1000.0\nperiod_samples = 1000\nskip_periods = 1\ninput = \"u\"\noutput = \"y\"\n",
    );
    let o = sdctl_ok(&["frf", &manifest, "--experiment", "a"]);
    let frd = sd_model::frd_from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
    assert_eq!(frd.len(), 400);
    let truth = pd.freqresp(frd.freq_hz()).unwrap();
    for i in 0..frd.len() {
        let (a, b) = (frd.response()[i][(0, 0)], truth.response()[i][(0, 0)]);
        assert!((a - b).norm() < 1e-9 * b.norm());
    }
    let frd_path = write(&dir, "frd.json", &String::from_utf8_lossy(&o.stdout));
    // --csv: per line f, dB, unwrapped phase, σ and SNR, equal to the JSON's response
    let csv_path = dir.join("frf.csv").to_string_lossy().into_owned();
    sdctl_ok(&["frf", &manifest, "--experiment", "a", "--csv", &csv_path]);
    let csv = std::fs::read_to_string(&csv_path).unwrap();
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), frd.len());
    for (r, g) in rows.iter().zip(frd.response()) {
        assert!((r[3] - 20.0 * g[(0, 0)].norm().log10()).abs() < 1e-9);
    }
    assert!(rows.windows(2).all(|w| (w[1][4] - w[0][4]).abs() < 180.0));
    let o = sdctl(&[
        "fit",
        &frd_path,
        "--order",
        "2",
        "--weighting",
        "relative",
        "--strictly-proper",
    ]);
    let m = model_of(&o);
    assert_eq!(m.n(), 2);
    assert!(String::from_utf8_lossy(&o.stderr).contains("median relative error"));
    let fr = m.freqresp(&[100.0]).unwrap().response()[0][(0, 0)];
    let tr = pd.freqresp(&[100.0]).unwrap().response()[0][(0, 0)];
    assert!((fr - tr).norm() < 1e-6 * tr.norm());
    // errors: unknown experiment, bad cell, continuous FRD
    assert_input_error(
        &sdctl(&["frf", &manifest, "--experiment", "b"]),
        "no experiment named",
    );
    write(&dir, "data.csv", "u,y\n1,2\n1,x\n");
    assert_input_error(&sdctl(&["frf", &manifest, "--experiment", "a"]), "line 3");
    assert_input_error(&sdctl(&["fit", &ct, "--order", "2"]), "frd");
}

#[test]
fn analyze_and_intersample() {
    let dir = tmpdir("analyze");
    // the paper's stage at 5 kHz and 1 kHz, and a PID-like controller at 1 kHz
    let stage = r#"{"type":"ss","ts":null,"a":[[0,1,0,0],[0,0,0,0],[0,0,0,1],[0,0,-16834268.0,-82.05]],"b":[[0],[0.05],[0],[0.1]],"c":[[1,0,1,0]],"d":[[0]]}"#;
    let ct = write(&dir, "stage.json", stage);
    let p1k = dir.join("p1k.json").to_string_lossy().into_owned();
    let p5k = dir.join("p5k.json").to_string_lossy().into_owned();
    assert!(sdctl(&["c2d", &ct, "--ts", "0.001", "-o", &p1k])
        .status
        .success());
    assert!(sdctl(&["c2d", &ct, "--ts", "0.0002", "-o", &p5k])
        .status
        .success());
    let k = sdctl(&[
        "weight",
        "pid",
        "--bandwidth-hz",
        "65",
        "--mass",
        "20",
        "--ts",
        "0.001",
    ]);
    let kf = write(&dir, "k.json", &String::from_utf8_lossy(&k.stdout));
    let o = sdctl(&["analyze", "--plant", &p1k, "--controller", &kf, "--json"]);
    let v = json_with_keys(
        &o,
        &[
            "stable",
            "closed_loop_radius",
            "bandwidth_hz",
            "crossover_hz",
            "sensitivity_peak_db",
            "sensitivity_peak_hz",
            "gain_margin_db",
            "phase_margin_deg",
            "modulus_margin",
        ],
    );
    assert_eq!(v["stable"], true);
    // the PID's |L| crossover is near its 65 Hz design bandwidth; the closed-loop −3 dB
    // bandwidth of T lies above it
    let cross = v["crossover_hz"].as_f64().unwrap();
    assert!((cross - 65.0).abs() < 5.0, "crossover {cross}");
    assert!(v["bandwidth_hz"].as_f64().unwrap() > cross);
    assert!(String::from_utf8_lossy(
        &sdctl(&["analyze", "--plant", &p1k, "--controller", &kf]).stdout
    )
    .contains("|S| peak"));
    let o = sdctl(&[
        "intersample",
        "--plant-fast",
        &p5k,
        "--controller",
        &kf,
        "--json",
        "--points",
        "500",
    ]);
    let v = json_with_keys(&o, &[]);
    assert_eq!(v["factor"], 5);
    assert!(
        v["rms_fast"].as_f64().unwrap() > 0.0 && v["fast_psd"].as_array().unwrap().len() == 500
    );
    // bad input
    assert_input_error(
        &sdctl(&["analyze", "--plant", &p1k, "--controller", &ct]),
        "sample time",
    );
    assert_input_error(
        &sdctl(&["intersample", "--plant-fast", &p1k, "--controller", &p5k]),
        "multiple",
    );
    assert_input_error(
        &sdctl(&[
            "intersample",
            "--plant-fast",
            &p5k,
            "--controller",
            &kf,
            "--force-rms",
            "-1",
        ]),
        "force-rms",
    );
}

#[test]
fn testbed() {
    let dir = tmpdir("testbed");
    let out = dir.join("run").to_string_lossy().into_owned();
    let cfg = write(
        &dir,
        "stage.toml",
        "seed = 3\n[truth]\nmass = 20.0\n[[truth.mode]]\nfreq_hz = 653.0\nzeta = 0.01\nresidue = 2.0\n[nonideal]\nhold_delay = 0.2\n\
         [[experiment]]\nname = \"id\"\nrate_hz = 1000.0\npid_bandwidth_hz = 15.0\nperiod = 1000\nperiods = 3\ninjection = \"input\"\nrole = \"model\"\n\
         [[experiment]]\nkind = \"standstill\"\nname = \"ss\"\nrate_hz = 1000.0\npid_bandwidth_hz = 40.0\nfactor = 5\nsamples = 5000\n",
    );
    sdctl_ok(&["testbed", "--config", &cfg, "--out", &out]);
    for f in [
        "experiments.toml",
        "id.csv",
        "ss_fast.csv",
        "ss_slow.csv",
        "truth.json",
    ] {
        assert!(std::path::Path::new(&out).join(f).exists(), "{f}");
    }
    let manifest = std::path::Path::new(&out).join("experiments.toml");
    sdctl_ok(&["frf", &manifest.to_string_lossy(), "--experiment", "id"]);
    let truth = sd_model::read_model(
        std::fs::File::open(std::path::Path::new(&out).join("truth.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(truth.n(), 4);
    // bad configurations: exit 2, one line
    let bad = write(&dir, "bad.toml", "[truth]\nmass = -1\n");
    assert_input_error(
        &sdctl(&["testbed", "--config", &bad, "--out", &out]),
        "mass",
    );
    let bad = write(
        &dir,
        "bad2.toml",
        "[[experiment]]\nname = \"x\"\nrate_hz = 1000.0\npid_bandwidth_hz = 400.0\n",
    );
    assert_input_error(
        &sdctl(&["testbed", "--config", &bad, "--out", &out]),
        "stabilize",
    );
    let bad = write(&dir, "bad3.toml", "[[experiment\n");
    assert_input_error(
        &sdctl(&["testbed", "--config", &bad, "--out", &out]),
        "configuration",
    );
    // an output folder that is a file is refused before the simulation runs
    assert_input_error(
        &sdctl(&["testbed", "--out", &bad]),
        "is a file, not a folder",
    );
}

#[test]
fn testbed_then_diagnose() {
    let dir = tmpdir("diagnose");
    let cfg = write(
        &dir,
        "stage.toml",
        "[nonideal]\naveraging = 0.8\n\
         [[experiment]]\nname = \"fast\"\nrate_hz = 5000.0\nrole = \"model\"\npid_bandwidth_hz = 30.0\npid_lowpass_hz = 1000.0\nperiod = 10000\nperiods = 6\nf_min = 0.5\nf_max = 2499.5\ninjection = \"input\"\nrms = 2.0\n\
         [[experiment]]\nname = \"slow\"\nrate_hz = 1000.0\npid_bandwidth_hz = 20.0\nperiod = 2000\nperiods = 6\nf_min = 0.5\nf_max = 499.5\ninjection = \"input\"\nrms = 2.0\n",
    );
    let data = dir.join("data").to_string_lossy().into_owned();
    assert!(sdctl(&["testbed", "--config", &cfg, "--out", &data])
        .status
        .success());
    let out = dir.join("diag").to_string_lossy().into_owned();
    let manifest = dir
        .join("data")
        .join("experiments.toml")
        .to_string_lossy()
        .into_owned();
    sdctl_ok(&["diagnose", &manifest, "--out", &out]);
    let v: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("diag").join("diagnosis.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(v["verdict"], "discrepancy");
    assert_eq!(v["cause"], "averaging_sampler");
    assert!((v["parameters"]["window_frac"].as_f64().unwrap() - 0.8).abs() < 0.1);
    assert!(v["gain"]["ratio"].as_f64().unwrap() >= 3.0);
    assert!((v["parameters"]["window_frac"].as_f64().unwrap() - 0.8).abs() < 0.02);
    let report = std::fs::read_to_string(dir.join("diag").join("report.md")).unwrap();
    assert!(report.contains("averaging_sampler"));
    // per experiment: statistics, bands, the time-domain comparison, and the figures
    let slow = &v["experiments"][1];
    assert_eq!(slow["name"], "slow");
    assert!(slow["model_statistic"]["value"].as_f64().unwrap() > 10.0);
    assert!(slow["extended_statistic"]["value"].as_f64().unwrap() < 3.0);
    assert!(!slow["bands"].as_array().unwrap().is_empty());
    let td = &slow["time_domain"];
    assert!(td["error_rms_extended"].as_f64().unwrap() < td["error_rms_model"].as_f64().unwrap());
    for f in [
        "frf_slow.svg",
        "residual_slow.svg",
        "time_slow.svg",
        "frf_fast.svg",
    ] {
        let svg = std::fs::read_to_string(dir.join("diag").join(f)).unwrap();
        assert!(svg.starts_with("<svg") && svg.len() > 2000, "{f}");
        assert!(report.contains(f), "{f} not linked from the report");
    }
    // the models are written, and the next step's c2d of the continuous extension reproduces
    // the extended model at the slow rate
    assert!(report.contains("## Next steps"), "{report}");
    let diag = dir.join("diag");
    let model =
        sd_model::read_model(std::fs::File::open(diag.join("model.json")).unwrap()).unwrap();
    assert_eq!(model.ts(), Some(2e-4));
    let window = v["parameters"]["window_frac"].as_f64().unwrap();
    let cmd = format!(
        "sdctl c2d extended_model.json --ts 0.001000 --hold-delay 0.0000 --averaging {window:.4}"
    );
    assert!(report.contains(&cmd), "{cmd} not in the report:\n{report}");
    let p_slow = diag.join("plant_slow.json").to_string_lossy().into_owned();
    sdctl_ok(&[
        "c2d",
        &diag.join("extended_model.json").to_string_lossy(),
        "--ts",
        "0.001",
        "--averaging",
        &window.to_string(),
        "-o",
        &p_slow,
    ]);
    let via_c2d = sd_model::read_model(std::fs::File::open(&p_slow).unwrap()).unwrap();
    let written =
        sd_model::read_model(std::fs::File::open(diag.join("extended_model_slow.json")).unwrap())
            .unwrap();
    let f: Vec<f64> = (1..50).map(|k| k as f64 * 9.7).collect();
    let (a, b) = (via_c2d.freqresp(&f).unwrap(), written.freqresp(&f).unwrap());
    for (x, y) in a.response().iter().zip(b.response()) {
        let (x, y) = (x[(0, 0)], y[(0, 0)]);
        assert!((x - y).norm() <= 1e-6 * y.norm(), "{x} vs {y}");
    }
    // the testbed's truth (continuous) as the given model: same cause, same window
    let truth = dir
        .join("data")
        .join("truth.json")
        .to_string_lossy()
        .into_owned();
    // into an existing folder holding a file of the user's: the file stays, nothing staged
    // is left behind
    let out2 = dir.join("diag_given").to_string_lossy().into_owned();
    std::fs::create_dir_all(&out2).unwrap();
    write(std::path::Path::new(&out2), "keep.txt", "mine");
    sdctl_ok(&["diagnose", &manifest, "--model", &truth, "--out", &out2]);
    let staged = |d: &std::path::Path| {
        std::fs::read_dir(d)
            .unwrap()
            .filter(|e| {
                let n = e.as_ref().unwrap().file_name();
                let n = n.to_string_lossy();
                n.contains(".partial") || n.contains(".tmp")
            })
            .count()
    };
    assert_eq!(
        std::fs::read_to_string(dir.join("diag_given").join("keep.txt")).unwrap(),
        "mine"
    );
    assert_eq!(
        staged(&dir) + staged(&dir.join("diag_given")) + staged(&diag),
        0
    );
    // a folder that cannot be made (its parent is a file): exit 2 naming it, nothing left
    let under_file = dir
        .join("stage.toml")
        .join("diag")
        .to_string_lossy()
        .into_owned();
    assert_input_error(
        &sdctl(&["diagnose", &manifest, "--out", &under_file]),
        "cannot write",
    );
    assert_eq!(staged(&dir), 0);
    let g: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("diag_given").join("diagnosis.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(g["model"]["source"], "given");
    assert_eq!(g["cause"], "averaging_sampler");
    assert!((g["parameters"]["window_frac"].as_f64().unwrap() - 0.8).abs() < 0.02);
    // a given model that is not a model, or not SISO at the right rate: exit 2
    let junk = write(&dir, "junk.json", "{\"A\": 1}");
    let o = sdctl(&["diagnose", &manifest, "--model", &junk, "--out", &out]);
    assert_eq!(o.status.code(), Some(2));
    let wrong_rate = write(
        &dir,
        "wrong_rate.json",
        r#"{"type":"ss","ts":0.01,"a":[[0.5]],"b":[[1.0]],"c":[[2.0]],"d":[[0.0]]}"#,
    );
    assert_input_error(
        &sdctl(&["diagnose", &manifest, "--model", &wrong_rate, "--out", &out]),
        "model experiment",
    );
    // a manifest with one experiment cannot be diagnosed: exit 2
    let one = write(&dir, "one.toml", "[[experiment]]\nname = \"fast\"\nfile = \"data/fast.csv\"\nsample_rate_hz = 5000.0\nperiod_samples = 10000\ninput = \"u\"\noutput = \"y\"\n");
    assert_input_error(&sdctl(&["diagnose", &one, "--out", &out]), "validation");
}

/// `uncertainty`, `downsample --uncertainty` and `coverage`: a bound from the fast data, taken
/// to the slow rate, covers the slow measurement; a bound is refused for another model, and
/// bad arguments exit 2 with one line.
#[test]
fn uncertainty_travels_to_the_slow_rate() {
    let d = tmpdir("uncertainty");
    let data = d.join("data").to_string_lossy().into_owned();
    assert!(sdctl(&["testbed", "--out", &data]).status.success());
    let manifest = d
        .join("data")
        .join("experiments.toml")
        .to_string_lossy()
        .into_owned();
    let p = |n: &str| d.join(n).to_string_lossy().into_owned();
    for e in ["fast", "slow"] {
        sdctl_ok(&[
            "frf",
            &manifest,
            "--experiment",
            e,
            "-o",
            &p(&format!("{e}.json")),
        ]);
    }
    sdctl_ok(&[
        "fit",
        &p("fast.json"),
        "--order",
        "4",
        "--rigid-body",
        "2",
        "--strictly-proper",
        "-o",
        &p("m.json"),
    ]);
    sdctl_ok(&[
        "uncertainty",
        &p("m.json"),
        &p("fast.json"),
        "--weight-order",
        "6",
        "-o",
        &p("u.json"),
    ]);
    let u = read_json(p("u.json"));
    assert_eq!(u["type"], "uncertainty");
    assert!(u["weight"]["median_ratio"].as_f64().unwrap() >= 1.0);
    // 99 % on all lines at once: per line 1 − 0.01/K, a wider bound everywhere
    sdctl_ok(&[
        "uncertainty",
        &p("m.json"),
        &p("fast.json"),
        "--confidence",
        "0.99",
        "--simultaneous",
        "-o",
        &p("u_all.json"),
    ]);
    let all = read_json(p("u_all.json"));
    let k = all["freq_hz"].as_array().unwrap().len() as f64;
    let c = all["confidence"].as_f64().unwrap();
    assert!((c - (1.0 - 0.01 / k)).abs() < 1e-12, "{c} for {k} lines");
    let wider = |x: &serde_json::Value, y: &serde_json::Value| {
        let (a, b) = (
            x["bound"].as_array().unwrap(),
            y["bound"].as_array().unwrap(),
        );
        a.iter()
            .zip(b)
            .all(|(a, b)| a.as_f64().unwrap() >= b.as_f64().unwrap())
    };
    assert!(wider(&all, &u));
    sdctl_ok(&[
        "downsample",
        &p("m.json"),
        "--factor",
        "5",
        "--uncertainty",
        &p("u.json"),
        "--uncertainty-out",
        &p("us.json"),
        "-o",
        &p("ms.json"),
    ]);
    // through an averaging sampler: the bound's nominal is the slow model's response
    sdctl_ok(&[
        "downsample",
        &p("m.json"),
        "--factor",
        "5",
        "--averaging",
        "0.8",
        "--uncertainty",
        &p("u.json"),
        "--uncertainty-out",
        &p("ua.json"),
        "-o",
        &p("ma.json"),
    ]);
    let ua = read_json(p("ua.json"));
    let ma = sd_model::read_model(std::fs::File::open(p("ma.json")).unwrap()).unwrap();
    let fz: Vec<f64> = serde_json::from_value(ua["freq_hz"].clone()).unwrap();
    let resp = ma.freqresp(&fz).unwrap();
    for (i, r) in resp.response().iter().enumerate() {
        let n = sd_model::Complex64::new(
            ua["nominal_re"][i].as_f64().unwrap(),
            ua["nominal_im"][i].as_f64().unwrap(),
        );
        assert!(
            (r[(0, 0)] - n).norm() <= 1e-8 * n.norm(),
            "{} vs {n}",
            r[(0, 0)]
        );
    }
    let o = sdctl_ok(&["coverage", &p("us.json"), &p("slow.json"), "--json"]);
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(c["lines"].as_u64().unwrap() > 200);
    assert!(c["fraction"].as_f64().unwrap() >= 0.93, "{c}");
    // robust stability at 1 kHz against the downsampled bound: a low-bandwidth PID is robustly
    // stable, a high-gain one (×25) is not, and the plant inside the bound that it does not
    // stabilise is written and is unstable in the loop
    let ts = "0.001";
    sdctl_ok(&[
        "weight",
        "pid",
        "--bandwidth-hz",
        "10",
        "--mass",
        "20",
        "--ts",
        ts,
        "-o",
        &p("k.json"),
    ]);
    let o = sdctl_ok(&[
        "analyze",
        "--plant",
        &p("ms.json"),
        "--controller",
        &p("k.json"),
        "--uncertainty",
        &p("us.json"),
        "--weight-order",
        "8",
        "--json",
    ]);
    let a: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let r = &a["robust"];
    assert!(r["margin_lines"].as_f64().unwrap() > 1.0, "{a}");
    assert!(r["margin_weight"].as_f64().unwrap() > 0.0, "{a}");
    assert!(r["destabilising"].is_null(), "{a}");
    let text = sdctl_ok(&[
        "analyze",
        "--plant",
        &p("ms.json"),
        "--controller",
        &p("k.json"),
        "--uncertainty",
        &p("us.json"),
    ]);
    let text = String::from_utf8_lossy(&text.stdout).into_owned();
    assert!(text.contains("robustly stable"), "{text}");
    let k = sd_model::read_model(std::fs::File::open(p("k.json")).unwrap()).unwrap();
    let hot = sd_model::series(
        &k,
        &sd_model::StateSpace::gain(nalgebra::DMatrix::from_element(1, 1, 25.0), k.time()).unwrap(),
    )
    .unwrap();
    std::fs::write(p("hot.json"), sd_model::model_to_json_string(&hot).unwrap()).unwrap();
    let o = sdctl_ok(&[
        "analyze",
        "--plant",
        &p("ms.json"),
        "--controller",
        &p("hot.json"),
        "--uncertainty",
        &p("us.json"),
        "--destabilising-out",
        &p("bad_plant.json"),
        "--json",
    ]);
    let a: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(a["stable"].as_bool().unwrap(), "{a}");
    {
        assert!(a["robust"]["margin_lines"].as_f64().unwrap() < 1.0, "{a}");
        let d = &a["robust"]["destabilising"];
        assert!(
            d["max_ratio_to_bound"].as_f64().unwrap() <= 1.0 + 1e-9,
            "{a}"
        );
        let o = sdctl_ok(&[
            "analyze",
            "--plant",
            &p("bad_plant.json"),
            "--controller",
            &p("hot.json"),
            "--json",
        ]);
        let b: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(b["stable"], false, "{b}");
    }
    // the model carries its bound: `uncertainty --embed`, then `downsample` takes it along and
    // `analyze` and `coverage` read it from the model file
    sdctl_ok(&[
        "uncertainty",
        &p("m.json"),
        &p("fast.json"),
        "--embed",
        &p("mu.json"),
        "-o",
        &p("u2.json"),
    ]);
    sdctl_ok(&[
        "downsample",
        &p("mu.json"),
        "--factor",
        "5",
        "-o",
        &p("msu.json"),
    ]);
    let msu = read_json(p("msu.json"));
    assert_eq!(msu["uncertainty"]["ts"].as_f64(), Some(0.001), "{msu}");
    let o = sdctl_ok(&[
        "analyze",
        "--plant",
        &p("msu.json"),
        "--controller",
        &p("k.json"),
        "--json",
    ]);
    let a: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(a["robust"]["margin_lines"].as_f64().unwrap() > 1.0, "{a}");
    let o = sdctl_ok(&["coverage", &p("msu.json"), &p("slow.json"), "--json"]);
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(c["fraction"].as_f64().unwrap() >= 0.93, "{c}");
    // a typo inside the carried bound is named
    let typo = std::fs::read_to_string(p("msu.json"))
        .unwrap()
        .replace("\"confidence\"", "\"confidense\"");
    let t = write(&d, "typo_carried.json", &typo);
    assert_input_error(
        &sdctl(&["coverage", &t, &p("slow.json")]),
        "did you mean `confidence`",
    );
    assert_input_error(
        &sdctl(&[
            "analyze",
            "--plant",
            &p("ms.json"),
            "--controller",
            &p("k.json"),
            "--weight-order",
            "8",
        ]),
        "need --uncertainty",
    );
    // the fast bound against the slow loop: another sample time
    assert_input_error(
        &sdctl(&[
            "analyze",
            "--plant",
            &p("ms.json"),
            "--controller",
            &p("k.json"),
            "--uncertainty",
            &p("u.json"),
        ]),
        "sample time",
    );
    // a measurement the bound misses (the slow FRF scaled by 1.5): the text says what to do
    let mut scaled = read_json(p("slow.json"));
    for key in ["re", "im"] {
        for line in scaled[key].as_array_mut().unwrap() {
            let v = line[0][0].as_f64().unwrap();
            line[0][0] = serde_json::json!(1.5 * v);
        }
    }
    let sc = write(&d, "scaled.json", &scaled.to_string());
    let o = sdctl_ok(&["coverage", &p("us.json"), &sc]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(text.contains("sdctl diagnose"), "{text}");
    let o = sdctl_ok(&["coverage", &p("us.json"), &p("slow.json")]);
    assert!(!String::from_utf8_lossy(&o.stdout).contains("sdctl diagnose"));
    // another model's bound, a confidence that is not a probability, a missing partner option
    sdctl_ok(&[
        "fit",
        &p("fast.json"),
        "--order",
        "6",
        "--rigid-body",
        "2",
        "--strictly-proper",
        "-o",
        &p("m6.json"),
    ]);
    assert_input_error(
        &sdctl(&[
            "downsample",
            &p("m6.json"),
            "--factor",
            "5",
            "--uncertainty",
            &p("u.json"),
            "--uncertainty-out",
            &p("x.json"),
        ]),
        "belongs to another model",
    );
    assert_input_error(
        &sdctl(&[
            "uncertainty",
            &p("m.json"),
            &p("fast.json"),
            "--confidence",
            "1.5",
        ]),
        "must be a probability",
    );
    assert_input_error(
        &sdctl(&["uncertainty", &p("m.json"), &p("slow.json")]),
        "differ",
    );
    let o = sdctl(&[
        "downsample",
        &p("m.json"),
        "--factor",
        "5",
        "--uncertainty",
        &p("u.json"),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let typo = std::fs::read_to_string(p("us.json"))
        .unwrap()
        .replace("\"confidence\"", "\"confidance\"");
    let t = write(&d, "typo.json", &typo);
    assert_input_error(
        &sdctl(&["coverage", &t, &p("slow.json")]),
        "did you mean `confidence`",
    );
}

/// `sdctl intersample --uncertainty`: the fast error of the 1 kHz loop around the 5 kHz model
/// bounded over every plant inside the fast bound's weight (a bound at least the nominal
/// density at every frequency, the slow margin above 1 for a low-bandwidth PID); a high-gain
/// controller gets no bound and the text says why; a file without a weight and no
/// `--weight-order`, or a downsampled (slow) bound, exit 2 naming the problem.
#[test]
fn intersample_under_uncertainty() {
    let d = tmpdir("intersample_unc");
    let data = d.join("data").to_string_lossy().into_owned();
    assert!(sdctl(&["testbed", "--out", &data]).status.success());
    let manifest = d.join("data").join("experiments.toml");
    let manifest = manifest.to_string_lossy().into_owned();
    let p = |n: &str| d.join(n).to_string_lossy().into_owned();
    sdctl_ok(&[
        "frf",
        &manifest,
        "--experiment",
        "fast",
        "-o",
        &p("fast.json"),
    ]);
    #[rustfmt::skip]
    sdctl_ok(&["fit", &p("fast.json"), "--order", "4", "--rigid-body", "2", "--strictly-proper", "-o", &p("m.json")]);
    sdctl_ok(&[
        "uncertainty",
        &p("m.json"),
        &p("fast.json"),
        "-o",
        &p("u0.json"),
    ]);
    #[rustfmt::skip]
    sdctl_ok(&["uncertainty", &p("m.json"), &p("fast.json"), "--form", "multiplicative", "--weight-order", "8", "-o", &p("u.json")]);
    #[rustfmt::skip]
    sdctl_ok(&["weight", "pid", "--bandwidth-hz", "10", "--mass", "20", "--ts", "0.001", "-o", &p("k.json")]);
    let m = p("m.json");
    let run = |k: &str, u: &str, json: bool| {
        let mut args = vec![
            "intersample",
            "--plant-fast",
            &m,
            "--controller",
            k,
            "--uncertainty",
            u,
            "--points",
            "300",
        ];
        if json {
            args.push("--json");
        }
        sdctl(&args)
    };
    let o = run(&p("k.json"), &p("u.json"), true);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let r = &v["robust"];
    assert!(r["slow_margin"].as_f64().unwrap() > 1.0, "{r}");
    let (nom, bound) = (
        r["nominal_psd"].as_array().unwrap(),
        r["bound_psd"].as_array().unwrap(),
    );
    assert_eq!(nom.len(), 300);
    assert!(nom
        .iter()
        .zip(bound)
        .all(|(a, b)| b.as_f64().unwrap() >= a.as_f64().unwrap()));
    assert!(r["rms_bound"].as_f64().unwrap() >= r["rms_nominal"].as_f64().unwrap());
    // the nominal density is the plain intersample command's
    let rms = v["rms_fast"].as_f64().unwrap();
    assert!(
        (r["rms_nominal"].as_f64().unwrap() / rms - 1.0).abs() < 0.02,
        "{v}"
    );
    let text = String::from_utf8_lossy(&run(&p("k.json"), &p("u.json"), false).stdout).into_owned();
    assert!(
        text.contains("at most") && text.contains("margin"),
        "{text}"
    );
    // ×25: not robustly stable against the weight, no bound
    let k = sd_model::read_model(std::fs::File::open(p("k.json")).unwrap()).unwrap();
    let g = sd_model::StateSpace::gain(nalgebra::DMatrix::from_element(1, 1, 25.0), k.time());
    let hot = sd_model::series(&k, &g.unwrap()).unwrap();
    std::fs::write(p("hot.json"), sd_model::model_to_json_string(&hot).unwrap()).unwrap();
    let o = run(&p("hot.json"), &p("u.json"), true);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["robust"]["slow_margin"].as_f64().unwrap() < 1.0, "{v}");
    assert!(v["robust"]["rms_bound"].is_null());
    let text =
        String::from_utf8_lossy(&run(&p("hot.json"), &p("u.json"), false).stdout).into_owned();
    assert!(text.contains("no intersample bound"), "{text}");
    assert_input_error(&run(&p("k.json"), &p("u0.json"), false), "--weight-order");
    #[rustfmt::skip]
    sdctl_ok(&["downsample", &p("m.json"), "--factor", "5", "--uncertainty", &p("u.json"), "--uncertainty-out", &p("us.json"), "-o", &p("ms.json")]);
    let o = sdctl(&[
        "intersample",
        "--plant-fast",
        &p("m.json"),
        "--controller",
        &p("k.json"),
        "--uncertainty",
        &p("us.json"),
        "--weight-order",
        "6",
    ]);
    assert_input_error(&o, "fast plant's period");
    // #40 item 6: the margin on the bound's lines that intersample prints beside the weight's
    // is the one `analyze --uncertainty` reports on the downsampled bound (one loop, one fit)
    for k in [p("k.json"), p("hot.json")] {
        let o = run(&k, &p("u.json"), true);
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let lines = &v["robust_lines"];
        #[rustfmt::skip]
        let o = sdctl_ok(&["analyze", "--plant", &p("ms.json"), "--controller", &k, "--uncertainty", &p("us.json"), "--json"]);
        let a: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let (mi, ma) = (
            lines["margin"].as_f64().unwrap(),
            a["robust"]["margin_lines"].as_f64().unwrap(),
        );
        assert!(
            (mi / ma - 1.0).abs() < 1e-6,
            "intersample {mi} vs analyze {ma}: {lines}"
        );
        println!(
            "{k}: slow margin with the weight {:.3}, on the lines {mi:.3} (analyze {ma:.3}), \
             weight over the lines' bound up to {:.2}",
            v["robust"]["slow_margin"].as_f64().unwrap_or(f64::NAN),
            lines["weight_over_bound"].as_f64().unwrap_or(f64::NAN)
        );
        // the weight overbounds the lines: its downsampled bound is at least theirs
        assert!(
            lines["weight_over_bound"].as_f64().unwrap() >= 0.99,
            "{lines}"
        );
        let text = String::from_utf8_lossy(&run(&k, &p("u.json"), false).stdout).into_owned();
        assert!(
            text.contains("on the bound's") && text.contains("slow lines"),
            "{text}"
        );
    }
}

/// `sdctl fit` of a 2×2 FRD: one set of poles for the four entries; two rank-one pairs are
/// realised in four states; a rank above min(ny, nu) is bad input.
#[test]
fn fit_mimo_common_poles() {
    let d = tmpdir("fit_mimo");
    // two lightly damped pairs (0.98 e^{±j0.3}, 0.95 e^{±j1.1}) with rank-one residues
    let (r1, i1) = (0.98 * 0.3f64.cos(), 0.98 * 0.3f64.sin());
    let (r2, i2) = (0.95 * 1.1f64.cos(), 0.95 * 1.1f64.sin());
    let model = format!(
        r#"{{"type":"ss","ts":0.001,"a":[[{r1},{i1},0,0],[{n1},{r1},0,0],[0,0,{r2},{i2}],[0,0,{n2},{r2}]],
        "b":[[1,0.5],[0.2,-0.3],[0.4,1],[-0.6,0.1]],"c":[[1,0.3,0.5,-0.2],[-0.4,1,0.8,0.6]],"d":[[0.01,0],[0,0.02]]}}"#,
        n1 = -i1,
        n2 = -i2
    );
    let m = write(&d, "m.json", &model);
    let frd = d.join("g.json").to_string_lossy().into_owned();
    sdctl_ok(&["freqresp", &m, "--grid", "1:450:200", "-o", &frd]);
    let o = sdctl_ok(&["fit", &frd, "--order", "4", "--json"]);
    let f: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(f["states"], 4, "{f}");
    assert_eq!(
        f["model"]["b"].as_array().unwrap()[0]
            .as_array()
            .unwrap()
            .len(),
        2
    );
    let modes = f["modes"].as_array().unwrap();
    assert_eq!(modes.len(), 2);
    assert!(modes.iter().all(|m| m["rank"] == 1), "{modes:?}");
    // noise-free data: the relative error is at round-off
    assert!(f["median_rel_error"].as_f64().unwrap() < 1e-8, "{f}");
    assert!(String::from_utf8_lossy(&o.stderr).contains("2x2, order 4 (poles common"));
    assert_input_error(
        &sdctl(&["fit", &frd, "--order", "4", "--rank", "3"]),
        "rank 3",
    );
    assert_input_error(
        &sdctl(&["fit", &frd, "--order", "4", "--rank", "two"]),
        "not a rank",
    );
}

/// The MIMO chain from the command line: `sdctl multisine --inputs 2` (orthogonal multisines
/// and their manifest), the user's measured outputs added to each CSV (here a 2×2 model's
/// simulated response with seeded noise), `sdctl frf` of both experiments (2×2, with the
/// covariance), `sdctl fit` in common; and the bad manifests and sets of the issue.
#[test]
fn mimo_chain_multisine_frf_fit() {
    let d = tmpdir("mimo_chain");
    let out = d.join("ms").to_string_lossy().into_owned();
    let o = sdctl(&[
        "multisine",
        "--fs",
        "1000",
        "--period",
        "500",
        "--f-min",
        "2",
        "--f-max",
        "400",
        "--inputs",
        "2",
        "--outputs",
        "y1,y2",
        "--periods",
        "6",
        "--out",
        &out,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let manifest = std::fs::read_to_string(d.join("ms/experiments.toml")).unwrap();
    assert!(manifest.contains("input = [\"u1\", \"u2\"]"), "{manifest}");
    assert!(manifest.contains("output = [\"y1\", \"y2\"]"), "{manifest}");
    // the plant: two lightly damped pairs, rank-one residues, 1 kHz
    let (r1, i1) = (0.98 * 0.3f64.cos(), 0.98 * 0.3f64.sin());
    let (r2, i2) = (0.95 * 1.1f64.cos(), 0.95 * 1.1f64.sin());
    let a = nalgebra::DMatrix::from_row_slice(
        4,
        4,
        &[
            r1, i1, 0.0, 0.0, -i1, r1, 0.0, 0.0, 0.0, 0.0, r2, i2, 0.0, 0.0, -i2, r2,
        ],
    );
    let b = nalgebra::DMatrix::from_row_slice(4, 2, &[1.0, 0.5, 0.2, -0.3, 0.4, 1.0, -0.6, 0.1]);
    let c = nalgebra::DMatrix::from_row_slice(2, 4, &[1.0, 0.3, 0.5, -0.2, -0.4, 1.0, 0.8, 0.6]);
    let plant = sd_model::StateSpace::new(
        a,
        b,
        c,
        nalgebra::DMatrix::zeros(2, 2),
        sd_model::SampleTime::discrete(1e-3).unwrap(),
    )
    .unwrap();
    let mut seed = 7u64;
    let mut noise = || {
        // a small deterministic pseudo-noise (splitmix), uniform in ±1e-4
        seed = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = seed;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2e-4
    };
    for e in ["exp_1", "exp_2"] {
        let path = d.join(format!("ms/{e}.csv"));
        let text = std::fs::read_to_string(&path).unwrap();
        let rows: Vec<Vec<f64>> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect();
        let u = nalgebra::DMatrix::from_fn(rows.len(), 2, |t, j| rows[t][j]);
        let y = plant.simulate(&u, None).unwrap().y;
        let mut csv = String::from("u1,u2,y1,y2\n");
        for t in 0..rows.len() {
            csv.push_str(&format!(
                "{:e},{:e},{:e},{:e}\n",
                u[(t, 0)],
                u[(t, 1)],
                y[(t, 0)] + noise(),
                y[(t, 1)] + noise()
            ));
        }
        std::fs::write(&path, csv).unwrap();
    }
    let m = d.join("ms/experiments.toml").to_string_lossy().into_owned();
    let frd = d.join("g.json").to_string_lossy().into_owned();
    sdctl_ok(&[
        "frf",
        &m,
        "--experiment",
        "exp_1",
        "--experiment",
        "exp_2",
        "--covariance",
        "-o",
        &frd,
    ]);
    let g = read_json(&frd);
    let n = g["freq_hz"].as_array().unwrap().len();
    assert_eq!(g["re"][0].as_array().unwrap().len(), 2);
    assert_eq!(g["re"][0][0].as_array().unwrap().len(), 2);
    assert_eq!(g["covariance"]["re"].as_array().unwrap().len(), n);
    assert_eq!(g["covariance"]["re"][0].as_array().unwrap().len(), 4);
    let o = sdctl_ok(&["fit", &frd, "--order", "4", "--strictly-proper", "--json"]);
    let f: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(f["states"], 4, "{f}");
    assert!(f["median_rel_error"].as_f64().unwrap() < 0.01, "{f}");
    // one experiment cannot tell two inputs apart
    assert_input_error(
        &sdctl(&["frf", &m, "--experiment", "exp_1", "--covariance"]),
        "1 experiment(s) for 2 inputs",
    );
    // a column named twice; references not one per input
    let bad = |name: &str, extra: &str| {
        write(
            &d,
            name,
            &format!("[[experiment]]\nname = \"a\"\nfile = \"ms/exp_1.csv\"\nsample_rate_hz = 1000\nperiod_samples = 500\n{extra}"),
        )
    };
    let twice = bad("twice.toml", "input = [\"u1\", \"u1\"]\noutput = \"y1\"\n");
    assert_input_error(&sdctl(&["frf", &twice, "--experiment", "a"]), "`u1` twice");
    let refs = bad(
        "refs.toml",
        "input = [\"u1\", \"u2\"]\noutput = \"y1\"\nreference = [\"y2\"]\n",
    );
    assert_input_error(
        &sdctl(&["frf", &refs, "--experiment", "a"]),
        "lists of different lengths",
    );
}

/// A 2×2 loop end to end: diagonal weights by `connect append`, `loopshape` of the coupled
/// double integrator, `analyze` with loop-at-a-time and disk margins per channel and the
/// singular-value figure.
#[test]
fn mimo_loopshape_and_analyze() {
    let d = tmpdir("mimo_ls");
    let pc = write(
        &d,
        "pc.json",
        r#"{"type":"ss","ts":null,"a":[[0,1,0,0],[0,0,0,0],[0,0,0,1],[0,0,0,0]],"b":[[0,0],[0.05,0.01],[0,0],[0.005,0.04]],"c":[[1,0,0,0],[0,0,1,0]],"d":[[0,0],[0,0]]}"#,
    );
    let p = |n: &str| d.join(n).to_string_lossy().into_owned();
    sdctl_ok(&["c2d", &pc, "--ts", "0.001", "-o", &p("p.json")]);
    sdctl_ok(&[
        "weight",
        "pid",
        "--bandwidth-hz",
        "30",
        "--mass",
        "20",
        "--ts",
        "0.001",
        "-o",
        &p("w.json"),
    ]);
    sdctl_ok(&[
        "connect",
        "append",
        &p("w.json"),
        &p("w.json"),
        "-o",
        &p("w2.json"),
    ]);
    sdctl_ok(&[
        "loopshape",
        &p("p.json"),
        "--w1",
        &p("w2.json"),
        "-o",
        &p("k.json"),
    ]);
    let o = sdctl_ok(&[
        "analyze",
        "--plant",
        &p("p.json"),
        "--controller",
        &p("k.json"),
        "--json",
        "--sigma-svg",
        &p("sigma.svg"),
        "--nyquist-svg",
        &p("loci.svg"),
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["stable"], true);
    // the generalised Nyquist criterion agrees: no open-loop pole outside (the integrators lie
    // on the boundary), no encirclement
    let n = &v["nyquist"];
    assert_eq!(n["stable"], true, "{n}");
    assert_eq!(n["agrees"], true, "{n}");
    assert_eq!(n["encirclements"], 0, "{n}");
    assert_eq!(n["open_loop_unstable"], 0, "{n}");
    let loci = std::fs::read_to_string(p("loci.svg")).unwrap();
    assert!(loci.contains("locus 2") && loci.contains("critical point"));
    let ch = v["loop_at_a_time"]["channels"].as_array().unwrap();
    assert_eq!(ch.len(), 4, "{v}");
    for c in ch {
        let (gm, pm, dm) = (
            c["gain_margin_db"].as_f64().unwrap(),
            c["phase_margin_deg"].as_f64().unwrap(),
            c["disk_margin"].as_f64().unwrap(),
        );
        assert!(gm > 6.0 && pm > 30.0 && dm > 0.5, "{c}");
    }
    let sim = v["loop_at_a_time"]["simultaneous_input_disk_margin"]
        .as_f64()
        .unwrap();
    assert!(ch
        .iter()
        .all(|c| sim <= c["disk_margin"].as_f64().unwrap() + 1e-9));
    let svg = std::fs::read_to_string(p("sigma.svg")).unwrap();
    assert!(
        svg.contains("σ_max(KS)") && svg.starts_with("<svg"),
        "{}",
        &svg[..100.min(svg.len())]
    );
    let t = sdctl_ok(&[
        "analyze",
        "--plant",
        &p("p.json"),
        "--controller",
        &p("k.json"),
    ]);
    assert!(String::from_utf8_lossy(&t.stdout).contains("input 2 (loop at a time)"));
    assert!(String::from_utf8_lossy(&t.stdout).contains("generalised Nyquist"));
    // positive feedback through a static gain: unstable by both counts
    let bad = write(
        &d,
        "kbad.json",
        r#"{"type":"ss","ts":0.001,"a":[],"b":[],"c":[],"d":[[-50,0],[0,-50]]}"#,
    );
    let o = sdctl_ok(&[
        "analyze",
        "--plant",
        &p("p.json"),
        "--controller",
        &bad,
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let n = &v["nyquist"];
    assert_eq!(v["stable"], false);
    assert_eq!(n["stable"], false, "{n}");
    assert_eq!(n["agrees"], true, "{n}");
    assert!(n["closed_loop_unstable"].as_i64().unwrap() >= 1, "{n}");
}

/// The multi-axis stage from a configuration: `testbed` with a `[stage]` table writes one
/// experiment per actuator (manifest with lists of columns), `frf` combines them into the
/// 3×2 FRF, `fit` finds the two-axis stage's coupled modes; a per-actuator list of the wrong
/// length, a misspelled key and a mode with the wrong number of gains exit 2 naming them.
#[test]
fn multiaxis_testbed_frf_fit() {
    let d = tmpdir("multiaxis");
    let cfg = write(
        &d,
        "axes.toml",
        "seed = 5\n[stage]\n[nonideal]\nhold_delay = [0.0, 0.2]\n[[experiment]]\nname = \
         \"fast\"\nrate_hz = 5000.0\nrole = \"model\"\nperiod = 2500\nperiods = 4\nf_max = \
         2400.0\n",
    );
    let out = d.join("run").to_string_lossy().into_owned();
    sdctl_ok(&["testbed", "--config", &cfg, "--out", &out]);
    let m = format!("{out}/experiments.toml");
    let manifest = std::fs::read_to_string(&m).unwrap();
    assert!(
        manifest.contains("fast_2") && manifest.contains("\"y3\""),
        "{manifest}"
    );
    let frd = d.join("g.json").to_string_lossy().into_owned();
    sdctl_ok(&[
        "frf",
        &m,
        "--experiment",
        "fast_1",
        "--experiment",
        "fast_2",
        "-o",
        &frd,
    ]);
    let fit_with = |extra: &[&str]| {
        let mut args = vec!["fit", frd.as_str(), "--order", "8", "--rigid-body", "2"];
        args.extend_from_slice(extra);
        sdctl(&args)
    };
    let o = fit_with(&["--strictly-proper", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let f: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let freqs: Vec<f64> = f["modes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["freq_hz"].as_f64().unwrap())
        .collect();
    for truth in [653.0, 1100.0, 1650.0] {
        assert!(
            freqs.iter().any(|x| (x / truth - 1.0).abs() < 3e-3),
            "{truth} Hz not among {freqs:?}"
        );
    }
    assert_eq!(f["input_delay"], serde_json::json!([0, 0]));
    let fit_delay = |v: &str| fit_with(&["--input-delay", v]);
    assert_input_error(&fit_delay("-1,0,2"), "3 input delays given for 2 inputs");
    assert_input_error(&fit_delay("aut0"), "is not an input delay");
    let bad = |name: &str, text: &str, needle: &str| {
        let p = write(&d, name, text);
        let o = d.join(format!("{name}.out")).to_string_lossy().into_owned();
        assert_input_error(&sdctl(&["testbed", "--config", &p, "--out", &o]), needle);
    };
    let exp = "[[experiment]]\nname = \"a\"\nrate_hz = 1000.0\nperiod = 500\nperiods = 2\n";
    bad(
        "len.toml",
        &format!("[stage]\n[nonideal]\nhold_delay = [0.0, 0.1, 0.2]\n{exp}"),
        "list of 2 numbers (one per actuator)",
    );
    bad(
        "typo.toml",
        &format!("[stage]\n[nonideal]\nhold_dealy = 0.1\n{exp}"),
        "hold_delay",
    );
    bad(
        "gains.toml",
        &format!(
            "[stage]\n[[stage.mode]]\nfreq_hz = 0.0\nzeta = 0.0\ninput = [0.05, 0.05]\noutput = \
             [1.0, 1.0]\n[[stage.mode]]\nfreq_hz = 500.0\ninput = [0.1]\noutput = [1.0, 1.0]\n{exp}"
        ),
        "stage mode 2: 1 input and 2 output gains",
    );
}

/// `diagnose` on a multi-axis manifest: the MIMO diagnosis names the actuator whose hold is
/// late (0.3 of each period on actuator 2 at 5 kHz, 2.5 kHz and 1 kHz), writes
/// diagnosis.json (`kind = "mimo"`), model.json and report.md, and refuses `--model`.
#[test]
fn multiaxis_diagnose_names_the_actuator() {
    let d = tmpdir("multiaxis_diag");
    let exp = |name: &str, rate: f64, period: usize, fmax: f64, role: &str| {
        format!(
            "[[experiment]]\nname = \"{name}\"\nrate_hz = {rate}\nrole = \"{role}\"\nperiod = \
             {period}\nperiods = 4\nf_max = {fmax}\n"
        )
    };
    let cfg = write(
        &d,
        "axes.toml",
        &format!(
            "seed = 7\n[stage]\n[nonideal]\nhold_delay = [0.0, 0.3]\n{}{}{}",
            exp("fast", 5000.0, 2500, 2400.0, "model"),
            exp("mid", 2500.0, 1250, 1200.0, "validation"),
            exp("slow", 1000.0, 500, 499.0, "validation")
        ),
    );
    let data = d.join("data").to_string_lossy().into_owned();
    sdctl_ok(&["testbed", "--config", &cfg, "--out", &data]);
    let m = format!("{data}/experiments.toml");
    let out = d.join("diag").to_string_lossy().into_owned();
    let o = sdctl_ok(&["diagnose", &m, "--out", &out]);
    let line = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(line.contains("actuator 2 hold delay"), "{line}");
    let v = read_json(format!("{out}/diagnosis.json"));
    assert_eq!(v["kind"], "mimo");
    assert_eq!(v["verdict"], "discrepancy");
    let named: Vec<&serde_json::Value> = v["channels"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["named"] == true)
        .collect();
    assert_eq!(named.len(), 1, "{v}");
    assert_eq!(named[0]["kind"], "actuator");
    assert_eq!(named[0]["channel"], 1);
    assert!(v["gain"]["held_out"] == true && v["gain"]["ratio"].as_f64().unwrap() > 3.0);
    let report = std::fs::read_to_string(format!("{out}/report.md")).unwrap();
    assert!(report.contains("| actuator 2 |") && report.contains("What to do next"));
    // one Bode figure per entry at the slowest rate, linked from the report
    let fig = std::fs::read_to_string(format!("{out}/entry_3_2.svg")).unwrap();
    assert!(fig.starts_with("<svg") && fig.contains("extended model"));
    assert!(report.contains("(entry_3_2.svg)"));
    assert!(std::path::Path::new(&format!("{out}/model.json")).exists());
    let model = format!("{out}/model.json");
    let out2 = d.join("diag2").to_string_lossy().into_owned();
    assert_input_error(
        &sdctl(&["diagnose", &m, "--model", &model, "--out", &out2]),
        "--model is for SISO experiments",
    );
}

#[test]
fn diagnose_then_predict_another_rate() {
    let dir = tmpdir("predict");
    let exp = |name: &str, rate: f64, role: &str| {
        format!(
            "[[experiment]]\nname = \"{name}\"\nrate_hz = {rate:.1}\nrole = \"{role}\"\n\
             pid_bandwidth_hz = 25.0\nperiod = {p}\nperiods = 5\nf_min = 1.0\nf_max = {fmax:.1}\n\
             injection = \"input\"\n",
            p = rate as usize,
            fmax = rate / 2.0 - 1.0
        )
    };
    let head = "[nonideal]\nhold_delay = 0.4\n";
    let cfg = write(
        &dir,
        "stage.toml",
        &format!(
            "{head}{}{}",
            exp("fast", 5000.0, "model"),
            exp("slow", 1000.0, "validation")
        ),
    );
    let cfg_new = write(
        &dir,
        "new.toml",
        &format!(
            "seed = 3\n{head}{}{}",
            exp("mid", 2500.0, "model"),
            exp("odd", 1500.0, "model")
        ),
    );
    let path = |p: &str| dir.join(p).to_string_lossy().into_owned();
    sdctl_ok(&["testbed", "--config", &cfg, "--out", &path("data")]);
    sdctl_ok(&["testbed", "--config", &cfg_new, "--out", &path("new")]);
    sdctl_ok(&[
        "diagnose",
        &path("data/experiments.toml"),
        "--out",
        &path("diag"),
    ]);
    sdctl_ok(&[
        "predict",
        &path("diag"),
        &path("new/experiments.toml"),
        "--out",
        &path("pred"),
    ]);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("pred/prediction.json")).unwrap())
            .unwrap();
    assert_eq!(v["extension"], "rate_tied");
    let (mid, odd) = (&v["experiments"][0], &v["experiments"][1]);
    assert_eq!(mid["name"], "mid");
    assert!(mid["why"].is_null());
    // the delay fitted at 5 kHz and 1 kHz predicts 2.5 kHz: the plain model misses it, the
    // extension is near the noise
    assert!(mid["ratio"].as_f64().unwrap() > 2.0, "{mid}");
    assert!(mid["extended"].as_f64().unwrap() < 1.5 * mid["threshold"].as_f64().unwrap());
    assert_eq!(odd["reason"]["code"], "rate");
    assert!(odd["why"].as_str().unwrap().contains("no whole fraction"));
    let report = std::fs::read_to_string(dir.join("pred/report.md")).unwrap();
    assert!(
        report.contains("frf_mid.svg") && report.contains("| mid | 2500 |"),
        "{report}"
    );
    // nothing to predict: exit 2 with the reason; a folder without predictor.json: exit 2
    let cfg_odd = write(
        &dir,
        "odd.toml",
        &format!("{head}{}", exp("odd", 1500.0, "model")),
    );
    sdctl_ok(&["testbed", "--config", &cfg_odd, "--out", &path("odd")]);
    assert_input_error(
        &sdctl(&[
            "predict",
            &path("diag"),
            &path("odd/experiments.toml"),
            "--out",
            &path("p1"),
        ]),
        "no experiment can be predicted: `odd`: its rate 1500 Hz is no whole fraction",
    );
    assert_input_error(
        &sdctl(&[
            "predict",
            &path("data"),
            &path("new/experiments.toml"),
            "--out",
            &path("p2"),
        ]),
        "predictor.json: not found",
    );
}

/// `sdctl c2d --method matched | impulse`: poles mapped by `e^{pT}`, the DC gain kept; a
/// feedthrough refused by the impulse-invariant map and a MIMO model by the matched one
/// (exit 2, one line).
#[test]
fn c2d_matched_and_impulse() {
    let d = tmpdir("mapped");
    let ct = write(&d, "ct.json", CT);
    let m = model_of(&sdctl(&["c2d", &ct, "--ts", "0.01", "--method", "matched"]));
    let g = sd_model::model_from_json_str(CT).unwrap();
    let one = num_complex::Complex64::new(1.0, 0.0);
    let (dc, dcd) = (
        g.eval_direct(num_complex::Complex64::new(0.0, 0.0))
            .unwrap()[(0, 0)],
        m.eval_direct(one).unwrap()[(0, 0)],
    );
    assert!((dc - dcd).norm() < 1e-10, "{dc} vs {dcd}");
    let i = model_of(&sdctl(&["c2d", &ct, "--ts", "0.01", "--method", "impulse"]));
    assert_eq!(i.n(), 2);
    let with_d = write(
        &d,
        "with_d.json",
        r#"{"type":"ss","ts":null,"a":[[-1]],"b":[[1]],"c":[[1]],"d":[[2]]}"#,
    );
    assert_input_error(
        &sdctl(&["c2d", &with_d, "--ts", "0.01", "--method", "impulse"]),
        "strictly proper",
    );
    let mimo = write(
        &d,
        "mimo.json",
        r#"{"type":"ss","ts":null,"a":[[-1]],"b":[[1,1]],"c":[[1],[1]],"d":[[0,0],[0,0]]}"#,
    );
    assert_input_error(
        &sdctl(&["c2d", &mimo, "--ts", "0.01", "--method", "matched"]),
        "SISO",
    );
}
