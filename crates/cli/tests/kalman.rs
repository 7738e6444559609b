//! End-to-end tests of `kestrel kalman` on good and malformed input.

mod common;

use kestrel_kalman::{KalmanDesign, dlqe};
use nalgebra::{DMatrix, dmatrix};
use std::path::PathBuf;
use std::process::{Command, Output};

fn kestrel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
}

fn temp_file(name: &str, text: &str) -> PathBuf {
    let dir = common::temp_dir("kalman");
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Position/velocity model at 50 Hz with an operating point.
const MODEL: &str = r#"{"format": "kestrel.ss.v1", "ts": 0.02,
  "A": [[1, 0.02], [0, 1]], "B": [[0.0002], [0.02]], "C": [[1, 0]], "D": [[0]],
  "u0": [0.5], "y0": [2.0]}"#;

fn run(args: &[&str], model: &PathBuf) -> Output {
    kestrel()
        .arg("kalman")
        .arg("--model")
        .arg(model)
        .args(args)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn numbers_mean_multiples_of_the_identity() {
    let model = temp_file("m1.json", MODEL);
    let out_path = model.with_file_name("filter1.json");
    let out = run(
        &[
            "--q",
            "1e-3",
            "--r",
            "0.01",
            "--out",
            out_path.to_str().unwrap(),
        ],
        &model,
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&out_path).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["format"], "kestrel.kalman.v1");
    // The folded step's cost: 2 nx ny + nx^2 + nx nu = 4 + 4 + 2 (D = 0).
    assert_eq!(v["multiply_adds"], 2 * 2 + 2 * 2 + 2);
    assert!(
        stderr(&out).contains("10 multiply-adds"),
        "{}",
        stderr(&out)
    );
    let d = KalmanDesign::from_json_str(&text).unwrap();
    // Independent: the library's dlqe on the same matrices.
    let a = dmatrix![1.0, 0.02; 0.0, 1.0];
    let c = dmatrix![1.0, 0.0];
    let f = dlqe(
        &a,
        &DMatrix::identity(2, 2),
        &c,
        &(DMatrix::identity(2, 2) * 1e-3),
        &dmatrix![0.01],
        None,
    )
    .unwrap();
    assert!((&d.filter.m - &f.m).amax() < 1e-14);
    assert!((&d.filter.l - &a * &f.m).amax() < 1e-14);
    assert!((&d.filter.p - &f.p).amax() < 1e-14 * f.p.amax());
    // P solves (5.15c) with the gain (5.15d).
    let s = &c * &d.filter.p * c.transpose() + dmatrix![0.01];
    let rhs = &a * &d.filter.p * a.transpose()
        - &a * &d.filter.p
            * c.transpose()
            * s.try_inverse().unwrap()
            * &c
            * &d.filter.p
            * a.transpose()
        + DMatrix::identity(2, 2) * 1e-3;
    assert!((&rhs - &d.filter.p).amax() < 1e-12 * d.filter.p.amax());
    assert_eq!(d.u0[0], 0.5);
    assert_eq!(d.y0[0], 2.0);
}

#[test]
fn matrix_files_g_and_bias() {
    let model = temp_file("m2.json", MODEL);
    let g = temp_file("g.json", "[[0], [1]]");
    let q = temp_file("q.json", r#"{"Q": [[0.5]]}"#);
    let r = temp_file("r.json", "[[0.02]]");
    let out = run(
        &[
            "--q",
            q.to_str().unwrap(),
            "--r",
            r.to_str().unwrap(),
            "--g",
            g.to_str().unwrap(),
            "--bias",
            "-0.25",
        ],
        &model,
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let d = KalmanDesign::from_json_str(&String::from_utf8_lossy(&out.stdout)).unwrap();
    let f = dlqe(
        &dmatrix![1.0, 0.02; 0.0, 1.0],
        &dmatrix![0.0; 1.0],
        &dmatrix![1.0, 0.0],
        &dmatrix![0.5],
        &dmatrix![0.02],
        None,
    )
    .unwrap();
    assert!((&d.filter.m - &f.m).amax() < 1e-14);
    assert_eq!(d.g, dmatrix![0.0; 1.0]);
    assert_eq!(d.bias[0], -0.25);
}

#[test]
fn rejects_bad_input() {
    let model = temp_file("m3.json", MODEL);
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["--q".into(), "-1".into(), "--r".into(), "1".into()],
            ">= 0",
        ),
        (
            vec!["--q".into(), "1".into(), "--r".into(), "nan".into()],
            "finite",
        ),
        (
            vec![
                "--q".into(),
                "nosuchfile.json".into(),
                "--r".into(),
                "1".into(),
            ],
            "neither a number nor",
        ),
        (
            vec![
                "--q".into(),
                temp_file("q3.json", "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]")
                    .to_string_lossy()
                    .into(),
                "--r".into(),
                "1".into(),
            ],
            "2 x 2",
        ),
        (
            vec![
                "--q".into(),
                temp_file("qnan.json", "[[1, NaN], [0, 1]]")
                    .to_string_lossy()
                    .into(),
                "--r".into(),
                "1".into(),
            ],
            "Q[0][1]",
        ),
        (
            vec![
                "--q".into(),
                temp_file("qasym.json", "[[1, 0.5], [0, 1]]")
                    .to_string_lossy()
                    .into(),
                "--r".into(),
                "1".into(),
            ],
            "symmetric",
        ),
        (
            vec!["--q".into(), "1".into(), "--r".into(), "0".into()],
            "positive definite",
        ),
        (
            vec![
                "--q".into(),
                "1".into(),
                "--r".into(),
                "1".into(),
                "--bias".into(),
                "1,2".into(),
            ],
            "--bias",
        ),
    ];
    for (args, want) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = run(&args, &model);
        assert!(!out.status.success(), "{args:?} should fail");
        let err = stderr(&out);
        assert!(err.contains(want), "{args:?}: {err}");
    }
    // Continuous-time model, malformed model, undetectable model.
    let cont = temp_file("cont.json", &MODEL.replace("\"ts\": 0.02", "\"ts\": 0"));
    let out = run(&["--q", "1", "--r", "1"], &cont);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("kestrel c2d"), "{}", stderr(&out));
    let bad = temp_file(
        "bad.json",
        &MODEL.replace("\"C\": [[1, 0]]", "\"C\": [[1, 0, 0]]"),
    );
    let out = run(&["--q", "1", "--r", "1"], &bad);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("\"C\""), "{}", stderr(&out));
    let blind = temp_file(
        "blind.json",
        &MODEL.replace("\"C\": [[1, 0]]", "\"C\": [[0, 1]]"),
    );
    let out = run(&["--q", "1", "--r", "1"], &blind);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("not detectable"), "{}", stderr(&out));
}

/// `--innovations`: the identified model's own gain `K` becomes the
/// filter's predictor gain (`A - K C` stable: eigenvalues of modulus
/// sqrt(0.54) here), with `M = 0` and `P = 0`, for any `--r`; an unstable
/// predictor, a model without `K` and `--q` beside it are refused.
#[test]
fn innovations_use_the_models_gain() {
    let with_k = |k: &str| MODEL.replace("\"D\": [[0]],", &format!("\"D\": [[0]], \"K\": {k},"));
    let model = temp_file("m_innov.json", &with_k("[[0.5], [2.0]]"));
    for r in [None, Some("0.01")] {
        let mut args = vec!["--innovations"];
        args.extend(r.map(|r| ["--r", r]).into_iter().flatten());
        let o = run(&args, &model);
        assert!(o.status.success(), "{}", stderr(&o));
        let d = KalmanDesign::from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
        assert!(
            (&d.filter.l - dmatrix![0.5; 2.0]).amax() < 1e-12,
            "{}",
            d.filter.l
        );
        assert!(d.filter.m.amax() < 1e-12 && d.filter.p.amax() < 1e-12);
    }
    let o = run(&["--innovations", "--out", "/dev/null"], &model);
    assert!(stderr(&o).contains("own predictor"), "{}", stderr(&o));
    // A - K C = [1.5, 0.02; 0.5, 1] is unstable.
    let bad = temp_file("m_innov_bad.json", &with_k("[[-0.5], [-0.5]]"));
    let o = run(&["--innovations"], &bad);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("A - K C is not stable") && err.contains("1.5193"),
        "{err}"
    );
    let plain = temp_file("m_innov_none.json", MODEL);
    let o = run(&["--innovations"], &plain);
    assert!(!o.status.success() && stderr(&o).contains("no innovation gain K"));
    let o = run(&["--innovations", "--q", "1"], &model);
    assert!(!o.status.success() && stderr(&o).contains("cannot be used with"));
    let o = run(&["--r", "1"], &model);
    assert!(!o.status.success() && stderr(&o).contains("--q"));
}

#[test]
fn help_says_what_goes_in_and_comes_out() {
    let out = kestrel().args(["kalman", "--help"]).output().unwrap();
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "--model",
        "kestrel.ss.v1",
        "kestrel.kalman.v1",
        "measurement-update gain",
        "predictor gain",
        "one-step prediction",
        "multiply_adds",
        "--innovations",
    ] {
        assert!(help.contains(needle), "--help lacks {needle:?}:\n{help}");
    }
}
