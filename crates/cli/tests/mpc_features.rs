//! End-to-end tests of the general MPC flags of `kestrel mpc` (input-move
//! weight and bounds, output and state bounds hard or soft, reference
//! preview, input target, terminal cost `none`, terminal set, parameter
//! dependent input bounds) on a plant that is not a rotorcraft: a double
//! integrator whose input is named `force`. The tricopter problems are in
//! tests/mpc.rs.

mod common;

use common::{MODEL, kestrel, temp_dir};
use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_mpc::{
    Bounds, InputTarget, MpcProblem, MpcSettings, Parameter, SoftPenalty, Terminal, TerminalSet,
    Weight,
};
use nalgebra::{DMatrix, dmatrix, dvector};
use std::path::{Path, PathBuf};

/// A 2-state double integrator (position, velocity), ts = 0.1, input
/// "force", one output "position".
const DOUBLE_INTEGRATOR: &str = r#"{"format": "kestrel.ss.v1", "ts": 0.1,
  "A": [[1, 0.1], [0, 1]], "B": [[0.005], [0.1]], "C": [[1, 0]], "D": [[0]],
  "inputs": ["force"], "outputs": ["position"]}"#;

/// The same plant measuring both states (outputs "position", "velocity").
const TWO_OUTPUTS: &str = r#"{"format": "kestrel.ss.v1", "ts": 0.1,
  "A": [[1, 0.1], [0, 1]], "B": [[0.005], [0.1]], "C": [[1, 0], [0, 1]], "D": [[0], [0]],
  "inputs": ["force"], "outputs": ["position", "velocity"]}"#;

struct Plant {
    dir: PathBuf,
    model: String,
}

impl Plant {
    fn new(name: &str, text: &str) -> Plant {
        let dir = temp_dir(&format!("mpc-features-{name}"));
        let model = write(&dir, "model.json", text);
        Plant { dir, model }
    }

    fn file(&self, name: &str, text: &str) -> String {
        write(&self.dir, name, text)
    }

    /// `kestrel mpc --model <plant> --horizon N --u-min -1 --u-max 1 <extra>`
    /// (without the input bounds when `extra` gives them).
    fn run(&self, horizon: usize, extra: &[&str]) -> (bool, String, String) {
        let h = horizon.to_string();
        let mut args = vec!["mpc", "--model", &self.model, "--horizon", &h];
        if !extra.contains(&"--u-min") {
            args.extend_from_slice(&["--u-min", "-1", "--u-max", "1"]);
        }
        args.extend_from_slice(extra);
        kestrel(&args)
    }

    /// The problem written for `extra`, failing the test on an error.
    fn problem(&self, horizon: usize, extra: &[&str]) -> (MpqpProblem, String) {
        let (ok, text, err) = self.run(horizon, extra);
        assert!(ok, "{extra:?}: {err}");
        (MpqpProblem::from_json_str(&text).unwrap(), text)
    }

    /// The error of `extra`, checked to contain every one of `want`.
    fn refuses(&self, horizon: usize, extra: &[&str], want: &[&str]) {
        let (ok, _, err) = self.run(horizon, extra);
        assert!(!ok, "{extra:?} was accepted");
        for w in want {
            assert!(err.contains(w), "{extra:?}: want {w:?} in {err}");
        }
    }

    fn ss(&self) -> SsModel {
        SsModel::read(Path::new(&self.model)).unwrap()
    }
}

fn write(d: &Path, name: &str, text: &str) -> String {
    let p = d.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

/// The input bounds every run of [`Plant::run`] gives.
fn unit_input_bounds() -> Option<Bounds> {
    Some(Bounds::new(dvector![-1.0], dvector![1.0]))
}

#[test]
fn general_problem_has_the_documented_theta_and_no_throttle() {
    let plant = Plant::new("layout", DOUBLE_INTEGRATOR);
    let n = 5;
    // Plain: theta = [x1, x2, r], z = 5 moves, 10 input rows.
    let (p, _) = plant.problem(n, &[]);
    assert_eq!((p.n(), p.p(), p.m()), (5, 3, 10));
    // Everything at once: theta = [x (2); u_prev (1); r_1..r_3 (3); u_target (1)],
    // z = 5 moves + 1 output slack; rows: input 2 x 5, move 2 x 5,
    // output 2 x 5 (steps 1..5), slack >= 0.
    let (p, _) = plant.problem(
        n,
        &[
            "--du-weight",
            "0.1",
            "--du-max",
            "0.2",
            "--y-min",
            "-0.5",
            "--y-max",
            "0.5",
            "--soft",
            "--preview",
            "3",
            "--u-target",
            "param",
        ],
    );
    assert_eq!((p.n(), p.p(), p.m()), (6, 7, 31));
    // No throttle (1000-2000 us) or other entry beyond the documented ones:
    // the box is the state box (10), the input bounds (1) for u_prev and
    // u_target, the reference box (3).
    let ub: Vec<f64> = p.theta_ub.iter().copied().collect();
    assert_eq!(ub, [10.0, 10.0, 1.0, 3.0, 3.0, 3.0, 1.0]);
    // A move weight alone also puts u_prev in theta; a state bound adds
    // rows but no parameter.
    let (p, _) = plant.problem(n, &["--du-weight", "1", "--state-max", ",2"]);
    assert_eq!((p.n(), p.p(), p.m()), (5, 4, 15));
    // Without a finite input bound, u_prev's box is --u-param-max.
    let (p, _) = plant.problem(
        n,
        &[
            "--du-weight",
            "1",
            "--u-min",
            "-inf",
            "--u-max",
            "",
            "--u-param-max",
            "4",
        ],
    );
    assert_eq!((p.theta_lb[2], p.theta_ub[2]), (-4.0, 4.0));
    // A parameter moving the input bounds is the last entry of theta.
    let shift = plant.file("shift.json", "[[-0.5]]");
    let (p, _) = plant.problem(n, &["--param", "load=0:1", "--u-shift", &shift]);
    assert_eq!((p.p(), p.theta_lb[3], p.theta_ub[3]), (4, 0.0, 1.0));
    assert_eq!((p.e[(0, 3)], p.e[(5, 3)]), (-0.5, 0.5));
}

#[test]
fn the_cli_writes_what_mpc_problem_build_gives() {
    let plant = Plant::new("roundtrip", TWO_OUTPUTS);
    let model = plant.ss();
    let set = plant.file("set.json", r#"{"a": [[1, 0], [-1, 0]], "b": [0.5, 0.5]}"#);
    let shift = plant.file("shift.json", "[[0.25, -0.5]]");
    let soft = SoftPenalty {
        quadratic: 50.0,
        linear: 300.0,
    };
    let cases: Vec<(Vec<&str>, MpcSettings)> = vec![
        (
            vec!["--du-weight", "0.3", "--du-max", "0.2", "--du-min=-0.1"],
            MpcSettings {
                du_weight: Some(Weight::Scalar(0.3)),
                du_bounds: Some(Bounds::new(dvector![-0.1], dvector![0.2])),
                ..MpcSettings::default()
            },
        ),
        (
            vec![
                "--y-min",
                "-1,",
                "--y-max",
                "1,0.5",
                "--soft",
                "y",
                "--soft-weight",
                "50",
                "--soft-linear",
                "300",
                "--state-max",
                ",0.8",
            ],
            MpcSettings {
                output_bounds: Some(
                    Bounds::new(dvector![-1.0, f64::NEG_INFINITY], dvector![1.0, 0.5])
                        .with_soft(soft),
                ),
                state_bounds: Some(Bounds::new(
                    dvector![f64::NEG_INFINITY, f64::NEG_INFINITY],
                    dvector![f64::INFINITY, 0.8],
                )),
                ..MpcSettings::default()
            },
        ),
        (
            vec!["--state-min", "-2,-1", "--state-max", "2,1", "--soft"],
            MpcSettings {
                state_bounds: Some(
                    Bounds::new(dvector![-2.0, -1.0], dvector![2.0, 1.0])
                        .with_soft(SoftPenalty::default()),
                ),
                ..MpcSettings::default()
            },
        ),
        (
            vec!["--preview", "4", "--terminal", "none", "--u-target", "0.25"],
            MpcSettings {
                preview: 4,
                terminal: Terminal::None,
                input_target: InputTarget::Fixed(dvector![0.25]),
                ..MpcSettings::default()
            },
        ),
        (
            vec![
                "--u-target",
                "param",
                "--terminal-set",
                &set,
                "--blocks",
                "1,3",
                "--terminal",
                "q1",
            ],
            MpcSettings {
                input_target: InputTarget::Parameter,
                terminal_set: Some(TerminalSet {
                    a: dmatrix![1.0, 0.0; -1.0, 0.0],
                    b: dvector![0.5, 0.5],
                }),
                blocking: Some(kestrel_mpc::Blocking::new(vec![1, 3]).unwrap()),
                terminal: Terminal::StageWeight,
                ..MpcSettings::default()
            },
        ),
        (
            vec![
                "--param",
                "load=0:1",
                "--param",
                "wind=-1:1",
                "--u-shift",
                &shift,
                "--du-max",
                "0.5",
                "--soft",
                "du",
            ],
            MpcSettings {
                parameters: vec![
                    Parameter::new("load", 0.0, 1.0),
                    Parameter::new("wind", -1.0, 1.0),
                ],
                du_bounds: Some(
                    Bounds::new(dvector![-0.5], dvector![0.5]).with_soft(SoftPenalty::default()),
                ),
                ..MpcSettings::default()
            },
        ),
    ];
    for (i, (extra, settings)) in cases.into_iter().enumerate() {
        let mut settings = MpcSettings {
            horizon: 4,
            input_bounds: unit_input_bounds(),
            ..settings
        };
        if !settings.parameters.is_empty() {
            let b = settings.input_bounds.take().unwrap();
            settings.input_bounds = Some(b.shifted(DMatrix::from_row_slice(1, 2, &[0.25, -0.5])));
        }
        let (_, text) = plant.problem(4, &extra);
        let lib = MpcProblem::build(&model, &settings)
            .unwrap_or_else(|e| panic!("case {i} {extra:?}: {e}"))
            .to_mpqp()
            .to_json_string_for_model(&model);
        assert!(
            text == lib,
            "case {i} {extra:?}: the CLI's file differs from the library's"
        );
    }
}

#[test]
fn bad_settings_name_the_flag() {
    let plant = Plant::new("errors", TWO_OUTPUTS);
    let no_rows = plant.file("set.json", r#"{"a": [[1, 0, 0]], "b": [1]}"#);
    let wide = plant.file("shift.json", "[[1, 2]]");
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (vec!["--du-max", "-1"], vec!["--du-max", "below zero"]),
        (
            vec!["--du-max", "1", "--du-min", "0.5"],
            vec!["--du-min", "above zero"],
        ),
        (
            vec!["--y-max", "1,1", "--soft", "--soft-weight", "0"],
            vec!["--soft-weight 0", "above zero"],
        ),
        (
            vec!["--y-max", "1,1", "--soft", "--soft-linear", "-1"],
            vec!["--soft-linear -1"],
        ),
        (
            vec!["--preview", "20"],
            vec!["--preview 20", "--horizon 10"],
        ),
        (vec!["--preview", "0"], vec!["--preview 0"]),
        (vec!["--u-param-max", "0"], vec!["--u-param-max"]),
        (
            vec!["--y-min", "-1,-1,-1"],
            vec![
                "--y-min",
                "expected 2",
                "2 outputs: position, velocity",
                "found 3",
            ],
        ),
        (
            vec!["--y-max", "1"],
            vec!["--y-max", "expected 2", "found 1"],
        ),
        (
            vec!["--y-min", "0,2", "--y-max", "1,1"],
            vec!["--y-min above --y-max", "output 2 (velocity)"],
        ),
        (
            vec!["--y-min", "inf,0"],
            vec!["--y-min", "entry 1", "is inf"],
        ),
        (
            vec!["--state-max", "1,2,3"],
            vec!["--state-max", "expected 2"],
        ),
        (
            vec!["--state-min", "1,x"],
            vec!["--state-min", "not a number"],
        ),
        (vec!["--soft", "y"], vec!["--soft y", "no such bounds"]),
        (vec!["--soft", "u"], vec!["--soft u", "unknown"]),
        (vec!["--soft-weight", "5"], vec!["--soft"]),
        (
            vec!["--u-target", "1,2"],
            vec!["--u-target", "expected `param` or 1"],
        ),
        (
            vec!["--du-weight", "-1"],
            vec!["--du-weight: du_weight is not positive semidefinite"],
        ),
        (
            vec!["--terminal-set", &no_rows],
            vec!["--terminal-set", "\"a\""],
        ),
        (
            vec!["--param", "load=2:1", "--u-shift", &wide],
            vec!["--param load=2:1"],
        ),
        (
            vec!["--param", "load=0:1", "--u-shift", &wide],
            vec!["--u-shift", "1 x 1"],
        ),
        (vec!["--param", "load=0:1"], vec!["--u-shift"]),
    ];
    for (extra, want) in cases {
        plant.refuses(10, &extra, &want);
    }
    plant.refuses(0, &[], &["--horizon 0", "at least one step"]);
    let (ok, _, err) = kestrel(&[
        "mpc",
        "--model",
        &plant.model,
        "--horizon",
        "3",
        "--u-min",
        "1",
        "--u-max",
        "-1",
    ]);
    assert!(
        !ok && err.contains("infeasible input bounds: --u-min above --u-max for input 1 (force)"),
        "{err}"
    );
}

#[test]
fn tricopter_only_when_asked_or_named_and_then_said() {
    // A 4-input plant with other names: no PWM window, no throttle.
    let d = temp_dir("mpc-features-names");
    let mut model = SsModel::read(Path::new(MODEL)).unwrap();
    let (ok, _, err) = kestrel(&["mpc", "--model", MODEL, "--horizon", "2", "--blocks", "2"]);
    assert!(ok, "{err}");
    assert!(
        err.contains("note:") && err.contains("pwm1, pwm2, pwm3, servo") && err.contains("--u-min"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    let (ok, _, err) = kestrel(&[
        "mpc",
        "--model",
        MODEL,
        "--horizon",
        "2",
        "--blocks",
        "2",
        "--tricopter",
    ]);
    assert!(ok && !err.contains("note:"), "{err}");
    model.inputs = Some(
        ["valve1", "valve2", "heater", "fan"]
            .map(String::from)
            .to_vec(),
    );
    let mp = write(&d, "process.json", &model.to_json_string());
    let (ok, text, err) = kestrel(&[
        "mpc",
        "--model",
        &mp,
        "--horizon",
        "2",
        "--u-min",
        "-1,-1,-1,-1",
        "--u-max",
        "1,1,1,1",
    ]);
    assert!(ok && !err.contains("note:"), "{err}");
    let p = MpqpProblem::from_json_str(&text).unwrap();
    assert_eq!(p.p(), model.nx() + model.ny());
    assert!(p.theta_ub.iter().all(|v| *v <= 10.0), "{}", p.theta_ub);
    let (ok, _, err) = kestrel(&["mpc", "--model", &mp, "--horizon", "2"]);
    assert!(!ok && err.contains("valve1, valve2, heater, fan"), "{err}");
}

#[test]
fn help_lists_the_theta_layout_and_an_example_per_feature() {
    let (ok, out, _) = kestrel(&["mpc", "--help"]);
    assert!(ok);
    for want in [
        "u_prev",
        "r_1..r_P",
        "u_target",
        "--du-weight 0.1 --du-max 0.2",
        "--soft",
        "--preview 5",
        "--terminal none",
        "--u-target 0.2",
        "--terminal-set set.json",
        "--param load=0:1 --u-shift shift.json",
        "--state-min ,-2",
    ] {
        assert!(out.contains(want), "missing {want}: {out}");
    }
}

#[test]
fn help_examples_run() {
    // The double-integrator examples of the after-help text, as written.
    let plant = Plant::new("examples", DOUBLE_INTEGRATOR);
    let set = plant.file("set.json", r#"{"a": [[1, 0], [-1, 0]], "b": [0.1, 0.1]}"#);
    let shift = plant.file("shift.json", "[[-0.5]]");
    for extra in [
        vec!["--du-weight", "0.1", "--du-max", "0.2"],
        vec![
            "--y-min",
            "-0.5",
            "--y-max",
            "0.5",
            "--soft",
            "--soft-weight",
            "1e3",
            "--soft-linear",
            "1e4",
        ],
        vec!["--state-min", ",-2", "--state-max", ",2"],
        vec!["--preview", "5"],
        vec!["--terminal", "none"],
        vec!["--u-target", "0.2"],
        vec!["--u-target", "param"],
        vec!["--terminal-set", &set],
        vec!["--param", "load=0:1", "--u-shift", &shift],
    ] {
        let (p, _) = plant.problem(10, &extra);
        assert!(p.n() >= 10, "{extra:?}");
    }
    // A move bound alone puts u_prev in theta: [x1, x2, u_prev, r].
    let (p, _) = plant.problem(10, &["--du-max", "0.2"]);
    assert_eq!(p.p(), 4);
}
