//! End-to-end tests of `kestrel c2d` on good and malformed files.

mod common;

use std::path::PathBuf;
use std::process::Command;

fn kestrel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
}

fn temp_file(name: &str, text: &str) -> PathBuf {
    let dir = common::temp_dir("c2d");
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const DOUBLE_INTEGRATOR: &str = r#"{"format": "kestrel.ss.v1", "ts": 0,
  "A": [[0, 1], [0, 0]], "B": [[0], [1]], "C": [[1, 0]], "D": [[0]],
  "inputs": ["force"], "outputs": ["position"]}"#;

#[test]
fn version() {
    let out = kestrel().arg("--version").output().unwrap();
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).starts_with("kestrel "));
}

#[test]
fn c2d_double_integrator_to_stdout_and_file() {
    let model = temp_file("di.json", DOUBLE_INTEGRATOR);
    let out = kestrel()
        .args(["c2d", "--model"])
        .arg(&model)
        .args(["--ts", "0.02"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["format"], "kestrel.ss.v1");
    assert_eq!(v["ts"], 0.02);
    let t = 0.02_f64;
    let close = |val: &serde_json::Value, want: f64| (val.as_f64().unwrap() - want).abs() < 1e-15;
    assert!(close(&v["A"][0][1], t));
    assert!(close(&v["A"][1][1], 1.0));
    assert!(close(&v["B"][0][0], t * t / 2.0));
    assert!(close(&v["B"][1][0], t));
    assert_eq!(v["outputs"][0], "position");

    let dest = model.with_file_name("di-d.json");
    let st = kestrel()
        .args(["c2d", "--model"])
        .arg(&model)
        .args(["--ts", "0.02", "--out"])
        .arg(&dest)
        .status()
        .unwrap();
    assert!(st.success());
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&dest).unwrap()).unwrap();
    assert_eq!(written, v);
}

fn c2d_error(name: &str, text: &str) -> String {
    let model = temp_file(name, text);
    let out = kestrel()
        .args(["c2d", "--model"])
        .arg(&model)
        .args(["--ts", "0.02"])
        .output()
        .unwrap();
    assert!(!out.status.success(), "{name} should fail");
    assert!(out.stdout.is_empty(), "nothing on stdout for {name}");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn malformed_files_fail_with_key_and_shape() {
    let missing = DOUBLE_INTEGRATOR.replace(r#""B": [[0], [1]], "#, "");
    let e = c2d_error("missing.json", &missing);
    assert!(
        e.contains("missing key \"B\"") && e.contains("2 x n matrix"),
        "{e}"
    );

    let shape = DOUBLE_INTEGRATOR.replace(r#""C": [[1, 0]]"#, r#""C": [[1, 0, 0]]"#);
    let e = c2d_error("shape.json", &shape);
    assert!(e.contains("key \"C\"") && e.contains("n x 2 matrix"), "{e}");

    let nan = DOUBLE_INTEGRATOR.replace(r#""A": [[0, 1]"#, r#""A": [[NaN, 1]"#);
    let e = c2d_error("nan.json", &nan);
    assert!(
        e.contains("key \"A[0][0]\": expected a finite number, found NaN"),
        "{e}"
    );

    let discrete = DOUBLE_INTEGRATOR.replace(r#""ts": 0"#, r#""ts": 0.01"#);
    let e = c2d_error("discrete.json", &discrete);
    assert!(e.contains("continuous-time"), "{e}");

    let e = c2d_error("notjson.json", "{ not json");
    assert!(e.contains("invalid JSON"), "{e}");
    assert!(e.contains("notjson.json"), "the file is named: {e}");
}

#[test]
fn missing_file_and_bad_ts() {
    let out = kestrel()
        .args(["c2d", "--model", "/nonexistent/m.json", "--ts", "0.02"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/m.json"));
    let model = temp_file("di2.json", DOUBLE_INTEGRATOR);
    let out = kestrel()
        .args(["c2d", "--model"])
        .arg(&model)
        .args(["--ts", "-1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    // The flag is wrong, not the file's "ts" key.
    assert!(String::from_utf8_lossy(&out.stderr).contains("--ts"));
}
