//! End-to-end tests of `kestrel mpc` (`kestrel closed-loop`: tests/closed_loop.rs).

mod common;

use common::{kestrel, temp_dir};
use kestrel_core::formats::MpqpProblem;
use std::path::{Path, PathBuf};

fn dir(name: &str) -> PathBuf {
    temp_dir(&format!("mpc-cli-{name}"))
}

fn write(d: &Path, name: &str, text: &str) -> String {
    let p = d.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

const DOUBLE_INTEGRATOR: &str = r#"{"format": "kestrel.ss.v1", "ts": 0.1,
  "A": [[1, 0.1], [0, 1]], "B": [[0.005], [0.1]], "C": [[1, 0]], "D": [[0]]}"#;

#[test]
fn writes_tricopter_problem_with_throttle_parameter() {
    let d = dir("tri");
    let model = kestrel_tricopter::design_model().unwrap();
    let mp = write(&d, "model.json", &model.to_json_string());
    let out = d.join("problem.json").display().to_string();
    let (ok, _, err) = kestrel(&[
        "mpc",
        "--model",
        &mp,
        "--horizon",
        "10",
        "--blocks",
        "1,1,2,6",
        "--q1",
        "2000",
        "--q2",
        "0.01",
        "--terminal",
        "lq",
        "--out",
        &out,
    ]);
    assert!(ok, "{err}");
    let p = MpqpProblem::read(Path::new(&out)).unwrap();
    let nx = model.nx();
    // theta = [x; r_roll; r_pitch; r_yaw; throttle]; z = 4 blocks of 4 pulses.
    assert_eq!((p.n(), p.p(), p.m()), (16, nx + 4, 32));
    assert_eq!((p.theta_lb[nx + 3], p.theta_ub[nx + 3]), (1000.0, 2000.0));
    // (6.23): the throttle column of E is -1 on the motors' upper rows.
    assert_eq!(p.e[(0, nx + 3)], -1.0);
    assert_eq!(p.e[(3, nx + 3)], 0.0);
    assert_eq!(p.e[(16, nx + 3)], 1.0);
    // Same as the library build.
    let (q1, q2) = (
        kestrel_mpc::Weight::Scalar(2000.0),
        kestrel_mpc::Weight::Scalar(0.01),
    );
    let lib = kestrel_tricopter::tricopter_problem(
        &model,
        kestrel_tricopter::ProblemSize::Larger,
        q1,
        q2,
    )
    .unwrap()
    .to_mpqp();
    assert!((&lib.h - &p.h).amax() < 1e-9 * lib.h.amax());
    assert!((&lib.f_theta - &p.f_theta).amax() < 1e-9 * lib.f_theta.amax().max(1.0));
    // Byte for byte: the general settings behind the command build the
    // thesis's problem exactly as kestrel-tricopter does.
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text == lib.to_json_string_for_model(&model),
        "the files differ"
    );
    // The implied tricopter is said on standard error, in one line.
    assert!(
        err.contains("note:") && err.contains("--u-min") && err.lines().count() == 1,
        "{err}"
    );
}

#[test]
fn generic_model_needs_bounds_and_reads_weight_files() {
    let d = dir("gen");
    let mp = write(&d, "di.json", DOUBLE_INTEGRATOR);
    let (ok, _, err) = kestrel(&["mpc", "--model", &mp, "--horizon", "3"]);
    assert!(!ok && err.contains("give --u-min and --u-max"), "{err}");
    let q2 = write(&d, "q2.json", "[[0.5]]");
    let qn = write(&d, "qn.json", "[[3, 0], [0, 1]]");
    let (ok, text, err) = kestrel(&[
        "mpc",
        "--model",
        &mp,
        "--horizon",
        "3",
        "--q2",
        &q2,
        "--terminal",
        &qn,
        "--u-min",
        "-1",
        "--u-max",
        "1",
    ]);
    assert!(ok, "{err}");
    let p = MpqpProblem::from_json_str(&text).unwrap();
    assert_eq!((p.n(), p.p(), p.m()), (3, 3, 6)); // no throttle: theta = [x1, x2, r]
    // Bad inputs: clear messages.
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["--blocks".into(), "1,1".into()],
            "sum to 2, but the horizon is N = 3",
        ),
        (
            vec!["--q1".into(), d.join("missing.json").display().to_string()],
            "--q1: reading",
        ),
        (
            vec!["--q2".into(), write(&d, "bad.json", "[[1, 2]]")],
            "Q2: expected a 1 x 1 matrix",
        ),
        (
            vec!["--terminal".into(), write(&d, "t.json", "[[1, 2, 3]]")],
            "--terminal",
        ),
        (
            vec!["--q1".into(), "-1".into()],
            "Q1 is not positive semidefinite",
        ),
    ];
    for (extra, want) in cases {
        let mut args: Vec<String> = [
            "mpc",
            "--model",
            &mp,
            "--horizon",
            "3",
            "--u-min",
            "-1",
            "--u-max",
            "1",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        args.extend(extra);
        let refs: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        let (ok, _, err) = kestrel(&refs);
        assert!(!ok && err.contains(want), "want {want:?}, got {err}");
    }
    // Infeasible bounds.
    let (ok, _, err) = kestrel(&[
        "mpc",
        "--model",
        &mp,
        "--horizon",
        "2",
        "--u-min",
        "1",
        "--u-max",
        "-1",
    ]);
    assert!(!ok && err.contains("infeasible input bounds"), "{err}");
    // A malformed model names the file and key.
    let bad = write(
        &d,
        "badmodel.json",
        r#"{"format": "kestrel.ss.v1", "ts": 0.1, "A": [[1]]}"#,
    );
    let (ok, _, err) = kestrel(&[
        "mpc",
        "--model",
        &bad,
        "--horizon",
        "2",
        "--u-min",
        "-1",
        "--u-max",
        "1",
    ]);
    assert!(
        !ok && err.contains("badmodel.json") && err.contains("\"B\""),
        "{err}"
    );
}

#[test]
fn help_names_inputs_and_outputs() {
    let (ok, out, _) = kestrel(&["mpc", "--help"]);
    assert!(ok);
    for want in [
        "kestrel.ss.v1",
        "kestrel.mpqp.v1",
        "theta = [x; r_1..r_ny; throttle]",
    ] {
        assert!(out.contains(want), "missing {want}: {out}");
    }
}
