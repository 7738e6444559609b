//! End-to-end tests of `kestrel closed-loop`: every controller on the
//! nonlinear plant, the explicit and fast-gradient laws against the QP law.

mod common;

use common::{kestrel, temp_dir};
use std::path::PathBuf;

fn dir(name: &str) -> PathBuf {
    temp_dir(&format!("cl-cli-{name}"))
}

/// Runs `closed-loop` with `args` and returns the trace's rows.
fn fly(d: &std::path::Path, name: &str, args: &[&str]) -> Vec<Vec<String>> {
    let out = d.join(format!("{name}.csv")).display().to_string();
    let mut all = vec!["closed-loop"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--out", &out]);
    let (ok, _, err) = kestrel(&all);
    assert!(ok, "{name}: {err}");
    assert!(err.contains("rise time"), "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t,r_p,r_q,r_r,throttle,p,q,r,p_meas,q_meas,r_meas,p_est,q_est,r_est,pwm1,pwm2,pwm3,servo,saturated,J"
    );
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    assert_eq!(rows.len(), 200); // 4 s at 50 Hz
    rows
}

fn num(rows: &[Vec<String>], i: usize, col: usize) -> f64 {
    rows[i][col].parse().unwrap()
}

/// Largest difference of the pulses (columns 14..18) between two traces.
fn max_pwm_diff(a: &[Vec<String>], b: &[Vec<String>]) -> f64 {
    (0..a.len())
        .flat_map(|i| (14..18).map(move |c| (i, c)))
        .map(|(i, c)| (num(a, i, c) - num(b, i, c)).abs())
        .fold(0.0, f64::max)
}

#[test]
fn qp_and_pid_track_the_step_with_pwms_and_cost() {
    let d = dir("basic");
    for (ctl, plant) in [("qp", "nonlinear"), ("qp", "linear"), ("pid", "nonlinear")] {
        let rows = fly(
            &d,
            &format!("{ctl}-{plant}"),
            &["--controller", ctl, "--plant", plant, "--noise"],
        );
        // J is there for the MPC and empty for the PI.
        assert_eq!(rows[10][19].is_empty(), ctl == "pid");
        // Pulses inside the ESC and servo ranges.
        for i in 0..rows.len() {
            for c in 14..17 {
                assert!((1000.0..=2000.0).contains(&num(&rows, i, c)));
            }
            assert!((1200.0..=1800.0).contains(&num(&rows, i, 17)));
        }
        // Ends near the step reference [1, -1, 0.5].
        for (k, want) in [(5, 1.0), (6, -1.0), (7, 0.5)] {
            let v = num(&rows, 199, k);
            assert!((v - want).abs() < 0.2, "{ctl}: column {k} = {v}");
        }
    }
}

#[test]
fn explicit_law_equals_the_qp_law_on_the_same_run() {
    let d = dir("empc");
    let qp = fly(&d, "qp", &["--controller", "qp"]);
    let ex = fly(&d, "empc", &["--controller", "empc"]);
    let dp = max_pwm_diff(&qp, &ex);
    assert!(dp < 1e-3, "max pulse difference {dp} us");
    for i in 0..qp.len() {
        let (a, b) = (num(&qp, i, 19), num(&ex, i, 19));
        assert!(
            (a - b).abs() <= 1e-6 * a.abs().max(1.0),
            "row {i}: J {a} vs {b}"
        );
    }
}

/// The exact online solver flies the QP law: the pulses and the cost of
/// the clarabel run, cold and warm, on the larger problem (general
/// saturation over 16 variables); `--start shifted` is fgm's alone.
#[test]
fn active_set_law_equals_the_qp_law_cold_and_warm() {
    let d = dir("active-set");
    let qp = fly(&d, "qp", &["--controller", "qp", "--size", "larger"]);
    for start in ["cold", "warm"] {
        let name = format!("as-{start}");
        let args = [
            "--controller",
            "active-set",
            "--size",
            "larger",
            "--start",
            start,
        ];
        let ours = fly(&d, &name, &args);
        // Equal to the trace's printed digits (pulses to 1e-4 us, J to 7
        // significant digits): at most one unit in the last place.
        let dp = max_pwm_diff(&qp, &ours);
        assert!(dp <= 1.5e-4, "{start}: max pulse difference {dp} us");
        for i in 0..qp.len() {
            let (a, b) = (num(&qp, i, 19), num(&ours, i, 19));
            assert!(
                (a - b).abs() <= 1.5e-6 * a.abs().max(1.0),
                "{start} row {i}: J {a} vs {b}"
            );
        }
    }
    // The bounds are active in the run: the servo reaches 1500 - 300 us.
    assert!((0..qp.len()).any(|i| num(&qp, i, 17) <= 1200.0 + 1e-9));
    let (ok, _, err) = kestrel(&[
        "closed-loop",
        "--controller",
        "active-set",
        "--start",
        "shifted",
    ]);
    assert!(
        !ok && err.contains("--start shifted applies to --controller fgm only"),
        "{err}"
    );
}

#[test]
fn fast_gradient_approaches_the_qp_law_with_iterations() {
    let d = dir("fgm");
    let qp = fly(&d, "qp", &["--controller", "qp"]);
    let few = fly(&d, "fgm2", &["--controller", "fgm", "--iterations", "2"]);
    let many = fly(
        &d,
        "fgm200",
        &["--controller", "fgm", "--iterations", "200"],
    );
    let warm = fly(
        &d,
        "fgm5w",
        &[
            "--controller",
            "fgm",
            "--iterations",
            "5",
            "--start",
            "warm",
        ],
    );
    let (d_few, d_many) = (max_pwm_diff(&qp, &few), max_pwm_diff(&qp, &many));
    assert!(d_many < 1e-2, "{d_many}");
    assert!(d_few > 10.0 * d_many, "{d_few} vs {d_many}");
    // The warm-started run still tracks: near [1, -1, 0.5] at the end.
    for (k, want) in [(5, 1.0), (6, -1.0), (7, 0.5)] {
        assert!((num(&warm, 199, k) - want).abs() < 0.2);
    }
}

#[test]
fn model_file_offset_free_and_bad_input() {
    let d = dir("model");
    // The identified model from a file flies like the built-in default.
    let model = d.join("model.json");
    std::fs::write(&model, kestrel_tricopter::IDENTIFIED_MODEL_JSON).unwrap();
    let m = model.display().to_string();
    let a = fly(&d, "file", &["--controller", "qp", "--model", &m]);
    let b = fly(&d, "builtin", &["--controller", "qp"]);
    assert!(max_pwm_diff(&a, &b) < 1e-9);
    // Offset-free: closer to the reference over the last second.
    let of = fly(&d, "of", &["--controller", "qp", "--offset-free"]);
    let tail_err = |rows: &[Vec<String>]| {
        (150..200)
            .map(|i| {
                (1..4)
                    .map(|k| (num(rows, i, k) - num(rows, i, k + 4)).abs())
                    .sum::<f64>()
            })
            .sum::<f64>()
    };
    assert!(
        tail_err(&of) < tail_err(&b),
        "{} vs {}",
        tail_err(&of),
        tail_err(&b)
    );
    // Wrong model shape, bad options: clear errors.
    let bad = d.join("bad.json");
    std::fs::write(
        &bad,
        r#"{"format": "kestrel.ss.v1", "ts": 0.02, "A": [[0.9]], "B": [[0.1]], "C": [[1]], "D": [[0]]}"#,
    )
    .unwrap();
    let (ok, _, err) = kestrel(&[
        "closed-loop",
        "--controller",
        "qp",
        "--model",
        &bad.display().to_string(),
    ]);
    assert!(
        !ok && err.contains("4 pulse inputs and 3 rate outputs") && err.contains("kestrel mpc"),
        "{err}"
    );
    // The refusal comes first: no note on reading its channels as motors.
    assert!(!err.contains("note:"), "{err}");
    let (ok, _, err) = kestrel(&["closed-loop", "--controller", "fgm", "--iterations", "0"]);
    assert!(!ok && err.contains("--iterations"), "{err}");
    let (ok, _, err) = kestrel(&["closed-loop", "--controller", "pid", "--offset-free"]);
    assert!(!ok && err.contains("offset-free"), "{err}");
    // MPC design flags are not silently ignored by the PI controller.
    for flag in [
        ["--horizon", "3"],
        ["--blocks", "1,1"],
        ["--q1", "5"],
        ["--q2", "1"],
    ] {
        let (ok, _, err) = kestrel(&["closed-loop", "--controller", "pid", flag[0], flag[1]]);
        assert!(
            !ok && err.contains(flag[0]) && err.contains("not to pid"),
            "{err}"
        );
    }
    // A model whose inputs are not the tricopter's flies with a note.
    let mut named: serde_json::Value =
        serde_json::from_str(kestrel_tricopter::IDENTIFIED_MODEL_JSON).unwrap();
    named["inputs"] = serde_json::json!(["m1", "m2", "m3", "m4"]);
    let quad = d.join("quad.json");
    std::fs::write(&quad, named.to_string()).unwrap();
    let out = d.join("quad.csv");
    let (ok, _, err) = kestrel(&[
        "closed-loop",
        "--controller",
        "qp",
        "--model",
        &quad.display().to_string(),
        "--out",
        &out.display().to_string(),
    ]);
    assert!(ok, "{err}");
    assert!(
        err.contains("note:") && err.contains("m1, m2, m3, m4") && err.contains("closed loop"),
        "{err}"
    );
    let (ok, _, err) = kestrel(&["closed-loop", "--controller", "qp", "--model", &m]);
    assert!(ok && !err.contains("note:"), "{err}");
}

#[test]
fn help_names_inputs_and_outputs() {
    let (ok, out, _) = kestrel(&["closed-loop", "--help"]);
    assert!(ok);
    for want in [
        "kestrel.ss.v1",
        "tricopter-blackbox-5.json",
        "pwm1, pwm2, pwm3, servo",
        "J (the MPC cost",
        "--iterations",
    ] {
        assert!(out.contains(want), "missing {want}: {out}");
    }
}
