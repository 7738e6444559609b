//! End-to-end tests of `kestrel export` (firmware tables from design files).

use kestrel_core::formats::SsModel;
use kestrel_fgm::{BoxQp, FgmDesign, FgmSettings, eps_for_input_error};
use std::path::{Path, PathBuf};
use std::process::Command;

fn kestrel(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .args(args)
        .output()
        .expect("runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("kestrel-export-cli-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(name: &str, text: &str) -> String {
    let p = dir().join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

fn fixture() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../models/tricopter-blackbox-5.json")
        .display()
        .to_string()
}

/// `pub const NAME: usize = V;` from the generated source.
fn usize_const(src: &str, name: &str) -> usize {
    let key = format!("pub const {name}: usize = ");
    let at = src.find(&key).unwrap_or_else(|| panic!("{name} in output")) + key.len();
    src[at..].split(';').next().unwrap().parse().unwrap()
}

/// The f32 table from the generated source.
fn values_f32(src: &str) -> Vec<f64> {
    let start = src.find("pub const VALUES_F32").unwrap();
    let body = &src[start..];
    let body = &body[body.find("= [").unwrap() + 3..body.find("];").unwrap()];
    body.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect()
}

#[test]
fn tables_hold_the_model_filter_and_certified_solver() {
    let out = dir().join("generated.rs");
    let (ok, _, err) = kestrel(&[
        "export",
        "--model",
        &fixture(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let src = std::fs::read_to_string(&out).unwrap();
    let model = SsModel::read(Path::new(&fixture())).unwrap();
    let v = values_f32(&src);
    assert_eq!(v.len(), usize_const(&src, "N_VALUES"));
    let nx = usize_const(&src, "NX");
    assert_eq!(nx, model.nx());
    // The filter's A and C are the model's (the file's numbers, in f32).
    let a = usize_const(&src, "KF_A");
    let c = usize_const(&src, "KF_C");
    for i in 0..nx {
        for j in 0..nx {
            let x = model.a[(i, j)];
            assert!((v[a + i * nx + j] - x).abs() <= 1e-6 * x.abs().max(1e-30));
        }
    }
    for i in 0..3 {
        for j in 0..nx {
            let x = model.c[(i, j)];
            assert!((v[c + i * nx + j] - x).abs() <= 1e-6 * x.abs().max(1e-30));
        }
    }
    // The mixer trim is the model's u0 around the mean motor pulse (the
    // hover throttle), the servo absolute.
    let u0 = model.u0.clone().unwrap();
    let throttle = (u0[0] + u0[1] + u0[2]) / 3.0;
    let mix = usize_const(&src, "MIX_OFFSET");
    for i in 0..3 {
        assert!((v[mix + i] - (u0[i] - throttle)).abs() < 1e-3);
    }
    assert!((v[mix + 3] - u0[3]).abs() < 1e-3);
    // The certified count is kestrel-fgm's for the 1 us eps of this
    // problem, computed here from kestrel-mpc's problem directly.
    let (q1, q2) = kestrel_mpc::default_weights();
    let problem =
        kestrel_mpc::tricopter_problem(&model, kestrel_mpc::ProblemSize::Thesis, q1, q2).unwrap();
    let fgm = FgmDesign::new(
        BoxQp::from_mpqp(&problem.to_mpqp()).unwrap(),
        FgmSettings::default(),
    )
    .unwrap();
    let cert = fgm
        .certify(eps_for_input_error(fgm.preconditioning.before.mu, 1.0))
        .unwrap();
    assert_eq!(usize_const(&src, "FGM_ITERATIONS"), cert.iterations);
    assert_eq!(usize_const(&src, "FGM_LOOP_ITERATIONS"), cert.iterations);
    assert_eq!(
        (usize_const(&src, "NZ"), usize_const(&src, "NP")),
        (4, nx + 4)
    );
    // A looser accuracy needs no more iterations.
    let (ok, loose, err) = kestrel(&["export", "--model", &fixture(), "--max-input-error", "20"]);
    assert!(ok, "{err}");
    assert!(usize_const(&loose, "FGM_ITERATIONS") <= cert.iterations);
}

#[test]
fn design_files_give_the_same_tables_as_the_defaults() {
    let model = SsModel::read(Path::new(&fixture())).unwrap();
    let kalman = kestrel_mpc::sim::kalman_design(&model).unwrap();
    let (q1, q2) = kestrel_mpc::default_weights();
    let problem = kestrel_mpc::tricopter_problem(&model, kestrel_mpc::ProblemSize::Thesis, q1, q2)
        .unwrap()
        .to_mpqp();
    let kf = write("filter.json", &kalman.to_json_string());
    let pr = write("problem.json", &problem.to_json_string());
    let (ok, from_files, err) = kestrel(&[
        "export",
        "--model",
        &fixture(),
        "--kalman",
        &kf,
        "--problem",
        &pr,
    ]);
    assert!(ok, "{err}");
    let (ok, defaults, err) = kestrel(&["export", "--model", &fixture()]);
    assert!(ok, "{err}");
    // JSON round trips are exact (float_roundtrip), so the tables agree to
    // the last digit except where the SDP preconditioner is re-solved.
    let (a, b) = (values_f32(&from_files), values_f32(&defaults));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert!(
            (x - y).abs() <= 1e-5 * x.abs().max(y.abs()).max(1e-6),
            "{x} vs {y}"
        );
    }
}

#[test]
fn malformed_design_files_are_refused_with_a_reason() {
    // A model with the wrong inputs.
    let m = write(
        "two_inputs.json",
        r#"{"format": "kestrel.ss.v1", "ts": 0.02, "A": [[0.9]], "B": [[1, 1]],
            "C": [[1], [1], [1]], "D": [[0, 0], [0, 0], [0, 0]]}"#,
    );
    let (ok, _, err) = kestrel(&["export", "--model", &m]);
    assert!(!ok);
    assert!(err.contains("inputs"), "{err}");
    // A continuous-time model.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture()).unwrap()).unwrap();
    v["ts"] = serde_json::json!(0.0);
    let c = write("continuous.json", &v.to_string());
    let (ok, _, err) = kestrel(&["export", "--model", &c]);
    assert!(!ok);
    assert!(err.contains("continuous") || err.contains("ts"), "{err}");
    // A problem whose parameters are not [x; r; throttle].
    let p = write(
        "problem.json",
        r#"{"format": "kestrel.mpqp.v1", "H": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],
            "F": [[1,0,0,0]], "G": [[1,0,0,0]], "W": [1], "E": [[0]],
            "theta_lb": [-1], "theta_ub": [1]}"#,
    );
    let (ok, _, err) = kestrel(&["export", "--model", &fixture(), "--problem", &p]);
    assert!(!ok);
    assert!(err.contains("parameters"), "{err}");
    // A Kalman file of another format, a missing file, a bad accuracy.
    let (ok, _, err) = kestrel(&["export", "--model", &fixture(), "--kalman", &fixture()]);
    assert!(!ok);
    assert!(err.contains("format"), "{err}");
    let (ok, _, err) = kestrel(&["export", "--model", "/nonexistent/model.json"]);
    assert!(!ok && err.contains("nonexistent"), "{err}");
    for bad in ["0", "-1", "NaN"] {
        let (ok, _, err) = kestrel(&["export", "--model", &fixture(), "--max-input-error", bad]);
        assert!(!ok);
        assert!(err.contains("max_input_error"), "{bad}: {err}");
    }
    let (ok, _, err) = kestrel(&["export", "--model", &fixture(), "--warm-iterations", "0"]);
    assert!(!ok && err.contains("zero iterations"), "{err}");
}

#[test]
fn help_says_what_goes_in_and_out() {
    let (ok, out, _) = kestrel(&["export", "--help"]);
    assert!(ok);
    for word in [
        "kestrel.ss.v1",
        "kestrel.kalman.v1",
        "kestrel.mpqp.v1",
        "Out:",
        "--out",
    ] {
        assert!(out.contains(word), "--help lacks {word}");
    }
}
