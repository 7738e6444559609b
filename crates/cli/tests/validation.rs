//! Flags that must not be silently ignored, and messages that name what
//! the user typed (issue 20, findings 6, 7 and 12).

mod common;

use common::{MODEL, kestrel, temp_dir};
use std::path::{Path, PathBuf};

/// The thesis problem (4 variables) in `dir`.
fn thesis_problem(dir: &Path) -> PathBuf {
    common::thesis_problem_of(MODEL, &dir.join("thesis.json"))
}

/// A flight log of `seconds` from the simulator (simulated once per
/// `dir`); with `millis` the `t` column is rewritten in milliseconds.
fn flight_log(dir: &Path, seconds: &str, millis: bool) -> PathBuf {
    let p = dir.join(format!("log-{seconds}.csv"));
    let (ok, _, err) = if p.exists() {
        (true, String::new(), String::new())
    } else {
        kestrel(&[
            "simulate",
            "--experiment",
            "decoupled",
            "--seconds",
            seconds,
            "--out",
            p.to_str().unwrap(),
        ])
    };
    assert!(ok, "{err}");
    if !millis {
        return p;
    }
    let text = std::fs::read_to_string(&p).unwrap();
    let mut lines = text.lines();
    let mut out = format!("{}\n", lines.next().unwrap());
    for line in lines {
        let (t, rest) = line.split_once(',').unwrap();
        let ms = t.parse::<f64>().unwrap() * 1000.0;
        out.push_str(&format!("{ms},{rest}\n"));
    }
    let q = dir.join(format!("log-{seconds}-ms.csv"));
    std::fs::write(&q, out).unwrap();
    q
}

/// The built-in model with a feed-through `D` of `scale`.
fn feedthrough_model(dir: &Path, scale: f64) -> PathBuf {
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(MODEL).unwrap()).unwrap();
    let d: Vec<Vec<f64>> = (0..3)
        .map(|i| {
            (0..4)
                .map(|j| scale * (((i + j) % 3) as f64 - 1.0))
                .collect()
        })
        .collect();
    m["D"] = serde_json::json!(d);
    let p = dir.join(format!("feedthrough-{scale}.json"));
    std::fs::write(&p, m.to_string()).unwrap();
    p
}

fn fails_with(args: &[&str], wanted: &[&str], unwanted: &[&str]) -> String {
    let (ok, _, err) = kestrel(args);
    assert!(!ok, "{args:?} succeeded: {err}");
    for w in wanted {
        assert!(err.contains(w), "{args:?}: {w:?} missing in {err}");
    }
    for u in unwanted {
        assert!(!err.contains(u), "{args:?}: {u:?} in {err}");
    }
    err
}

#[test]
fn an_error_chain_prints_each_cause_once() {
    let err = fails_with(
        &["c2d", "--model", "/nonexistent/m.json", "--ts", "0.02"],
        &["/nonexistent/m.json", "No such file"],
        &[],
    );
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
    assert_eq!(err.matches("/nonexistent/m.json").count(), 1, "{err}");
}

#[test]
fn c2d_blames_the_ts_flag_not_the_file() {
    let dir = temp_dir("validation-c2d");
    let m = dir.join("di.json");
    std::fs::write(
        &m,
        r#"{"format": "kestrel.ss.v1", "ts": 0, "A": [[0, 1], [0, 0]], "B": [[0], [1]],
            "C": [[1, 0]], "D": [[0]], "inputs": ["force"], "outputs": ["position"]}"#,
    )
    .unwrap();
    for ts in ["0", "-0.02"] {
        fails_with(
            &["c2d", "--model", m.to_str().unwrap(), "--ts", ts],
            &["--ts"],
            &["key \"ts\""],
        );
    }
}

#[test]
fn empc_max_nodes_holds_for_every_tree_method() {
    let dir = temp_dir("validation-empc");
    let p = thesis_problem(&dir);
    let p = p.to_str().unwrap();
    for method in ["auto", "lp", "sampled"] {
        fails_with(
            &[
                "empc",
                "solve",
                "--problem",
                p,
                "--no-regions",
                "--tree-method",
                method,
                "--max-nodes",
                "10",
            ],
            &["--max-nodes"],
            &[],
        );
    }
    fails_with(
        &["empc", "solve", "--problem", p, "--max-nodes", "0"],
        &["--max-nodes"],
        &[],
    );
    // A generous cap still solves.
    let (ok, out, err) = kestrel(&["empc", "solve", "--problem", p, "--max-nodes", "100000"]);
    assert!(ok && out.contains("kestrel.empc.v1"), "{err}");
    // --first-move 0 names the flag, not the library's `Outputs::First`.
    fails_with(
        &["empc", "solve", "--problem", p, "--first-move", "0"],
        &["--first-move 0", "between 1 and 4"],
        &["Outputs::"],
    );
}

#[test]
fn fgm_certify_refuses_applied_inputs_out_of_range_and_negative_steps() {
    let dir = temp_dir("validation-fgm");
    let p = thesis_problem(&dir);
    let p = p.to_str().unwrap();
    for k in ["0", "99"] {
        fails_with(
            &[
                "fgm",
                "certify",
                "--problem",
                p,
                "--eps",
                "1e3",
                "--applied-inputs",
                k,
            ],
            &["--applied-inputs", "1 to 4"],
            &[],
        );
    }
    let (ok, out, err) = kestrel(&[
        "fgm",
        "certify",
        "--problem",
        p,
        "--eps",
        "1e3",
        "--applied-inputs",
        "4",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["pwm_1us"]["applied_inputs"], 4, "{v}");
    fails_with(
        &[
            "fgm",
            "certify",
            "--problem",
            p,
            "--eps",
            "1e3",
            "--theta-step=-1,1,1,1,1,1,1,1,1",
        ],
        &["--theta-step", ">= 0"],
        &["non-finite"],
    );
}

#[test]
fn closed_loop_refuses_the_fgm_flags_for_other_controllers() {
    for (controller, flag, value) in [
        ("qp", "--start", "warm"),
        ("qp", "--iterations", "3"),
        ("pid", "--iterations", "3"),
        ("pid", "--start", "shifted"),
        ("empc", "--iterations", "3"),
    ] {
        fails_with(
            &["closed-loop", "--controller", controller, flag, value],
            &[flag, &format!("--controller {controller}")],
            &[],
        );
    }
}

#[test]
fn closed_loop_summary_uses_the_flag_names_and_rise_time_from_the_step() {
    let (ok, _, err) = kestrel(&["closed-loop", "--controller", "pid"]);
    assert!(ok, "{err}");
    assert!(err.contains("pid: rise time"), "{err}");
    assert!(!err.contains("Pid:") && !err.contains("NaN"), "{err}");
}

#[test]
fn a_diverging_closed_loop_is_an_error_and_writes_nothing() {
    let dir = temp_dir("validation-diverge");
    let model = feedthrough_model(&dir, 0.05);
    let out = dir.join("trace.csv");
    let err = fails_with(
        &[
            "closed-loop",
            "--controller",
            "pid",
            "--plant",
            "linear",
            "--model",
            model.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &["diverged", "rad/s"],
        &["overshoot"],
    );
    assert!(!out.exists(), "{err}");
}

#[test]
fn identify_names_the_flags_and_the_likely_cause() {
    let dir = temp_dir("validation-identify");
    let log = flight_log(&dir, "20", false);
    let log = log.to_str().unwrap();
    let io = ["--inputs", "pwm1,pwm2,pwm3,servo", "--outputs", "p,q,r"];
    let with = |extra: &[&'static str], data: &str| -> Vec<String> {
        let mut v: Vec<String> = ["identify", "--data", data]
            .iter()
            .map(|s| s.to_string())
            .collect();
        v.extend(io.iter().chain(extra).map(|s| s.to_string()));
        v
    };
    let run = |args: Vec<String>, wanted: &[&str], unwanted: &[&str]| {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        fails_with(&a, wanted, unwanted)
    };
    // A cut-off below the log's lowest frequency: the flag, not "pwm1 is constant".
    run(
        with(&["--lowpass", "1e-9"], log),
        &["--lowpass", "lowest frequency"],
        &["is constant"],
    );
    // The horizon against the order the user asked for, not an unexplained 10.
    run(
        with(&["--order", "4", "--horizon", "1"], log),
        &["--horizon 1", "--order 4"],
        &["invalid argument"],
    );
    // A millisecond time column: refused as read, with the flag to state it.
    let ms = flight_log(&dir, "20", true);
    let ms = ms.to_str().unwrap();
    run(
        with(&["--estimate", "2:20"], ms),
        &["milliseconds", "--time-unit ms"],
        &["is constant"],
    );
    // Stated as seconds anyway: the later messages still say so.
    run(
        with(&["--estimate", "2:20", "--time-unit", "s"], ms),
        &["is constant", "milliseconds"],
        &[],
    );
    run(
        with(&["--lowpass", "30", "--time-unit", "s"], ms),
        &["--lowpass", "milliseconds"],
        &[],
    );
}

#[test]
fn mpc_of_a_four_input_plant_gets_no_pwm_window_or_throttle_unless_asked() {
    let dir = temp_dir("validation-plant");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(MODEL).unwrap()).unwrap();
    m["inputs"] = serde_json::json!(["valve1", "valve2", "heater", "fan"]);
    let plant = dir.join("plant.json");
    std::fs::write(&plant, m.to_string()).unwrap();
    let plant = plant.to_str().unwrap();
    let base = ["mpc", "--model", plant, "--horizon", "2"];
    // No silent PWM bounds: the bounds are asked for.
    fails_with(&base, &["--u-min", "--tricopter", "valve1"], &[]);
    // Generic bounds: no throttle parameter, the given bounds.
    let bounds = [&base[..], &["--u-min=-1,-1,-1,-1", "--u-max", "1,1,1,1"]].concat();
    let (ok, out, err) = kestrel(&bounds);
    assert!(ok, "{err}");
    let p: serde_json::Value = serde_json::from_str(&out).unwrap();
    let nx = m["A"].as_array().unwrap().len();
    assert_eq!(p["theta_lb"].as_array().unwrap().len(), nx + 3, "{p}");
    assert_eq!(p["W"][0], 1.0);
    // A throttle flag on a problem without a throttle is refused.
    fails_with(
        &[&bounds[..], &["--throttle-min", "1100"]].concat(),
        &["--throttle-min"],
        &[],
    );
    // --tricopter asks for the thesis window and throttle explicitly.
    let (ok, out, err) = kestrel(&[&base[..], &["--tricopter"]].concat());
    assert!(ok, "{err}");
    let p: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(p["theta_lb"].as_array().unwrap().len(), nx + 4, "{p}");
    assert_eq!(p["theta_ub"][nx + 3], 2000.0);
}
