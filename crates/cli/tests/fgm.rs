//! End-to-end tests of `kestrel fgm certify|solve` on good and malformed files.

mod common;

use common::{kestrel as run, temp_dir};
use std::path::{Path, PathBuf};

fn temp_file(name: &str, text: &str) -> PathBuf {
    let p = temp_dir("cli-fgm").join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs `kestrel fgm certify --problem <problem> --eps <eps>`, expects it
/// to succeed, and returns its JSON.
fn certify(problem: &Path, eps: &str) -> serde_json::Value {
    certify_with(problem, eps, &[])
}

/// [`certify`] with more flags.
fn certify_with(problem: &Path, eps: &str, extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "fgm",
        "certify",
        "--problem",
        problem.to_str().unwrap(),
        "--eps",
        eps,
    ];
    args.extend_from_slice(extra);
    let (ok, out, err) = run(&args);
    assert!(ok, "{err}");
    serde_json::from_str(&out).unwrap()
}

/// Runs `kestrel fgm <args>`, expects it to fail, and checks that standard
/// error names the problem.
fn fails_with(args: &[&str], expected: &str) {
    let mut all = vec!["fgm"];
    all.extend_from_slice(args);
    let (ok, _, err) = run(&all);
    assert!(!ok && err.contains(expected), "{all:?}: {err}");
}

/// Two inputs, theta = [x, throttle]: rows shuffled and scaled on purpose.
/// -1 + t <= z0 <= 1 + t (rows 1 and 3), -2 <= z1 <= 2 (rows 0 and 2, scaled).
const BOX: &str = r#"{"format": "kestrel.mpqp.v1",
  "H": [[4, 1], [1, 2]], "F": [[3, -1], [0, 0]],
  "G": [[0, 2], [1, 0], [0, -1], [-3, 0]], "W": [4, 1, 2, 3],
  "E": [[0, 0], [0, 1], [0, 0], [0, -3]],
  "theta_lb": [-2, 0], "theta_ub": [2, 0.5]}"#;

#[test]
fn certify_prints_iterations_l_mu_and_preconditioner() {
    let p = temp_file("box.json", BOX);
    let v = certify(&p, "1e-6");
    assert!(v["iterations"].as_u64().unwrap() > 0);
    assert!(v["L"].as_f64().unwrap() > 0.0);
    assert!(v["mu"].as_f64().unwrap() > 0.0);
    assert_eq!(v["preconditioner"], "optimal-diagonal");
    // eps 1e5 .. 1e2 and the PWM eps (computed from diag(H^-1)).
    let table = v["eps_table"].as_array().unwrap();
    assert_eq!(table.len(), 5);
    assert_eq!(table[4]["eps"], v["pwm_1us"]["eps"]);
    assert_eq!(table[4]["iterations"], v["pwm_1us"]["iterations"]);
    assert!(
        v["pwm_1us"]["eps"].as_f64().unwrap() >= v["pwm_1us"]["eps_eigenvalue"].as_f64().unwrap()
    );
    assert!(v["delta"].as_f64().unwrap() <= 0.25 * v["delta_richter"].as_f64().unwrap() * 1.000001);
    // A looser tolerance never needs more iterations.
    let v2 = certify(&p, "1e-2");
    assert!(v2["iterations"].as_u64() <= v["iterations"].as_u64());
}

/// `--input-error E`: `input_tolerance` is the eps `E^2 / (2 max_j
/// (H^-1)_jj)` over the applied inputs, checked against the closed form of
/// BOX's `H = [[4, 1], [1, 2]]` (`H^-1 = [[2, -1], [-1, 4]] / 7`), beside the
/// unchanged one-unit `pwm_1us`, each with its row in the table.
#[test]
fn input_error_sets_the_input_tolerance() {
    let p = temp_file("box-input-error.json", BOX);
    let v = certify_with(&p, "1e-6", &["--input-error", "2"]);
    let close = |x: &serde_json::Value, want: f64| {
        let x = x.as_f64().unwrap();
        assert!((x - want).abs() <= 1e-12 * want, "{x} != {want}");
    };
    // All variables: the largest (H^-1)_jj is 4/7.
    close(&v["input_tolerance"]["eps"], 4.0 / (2.0 * 4.0 / 7.0));
    close(&v["pwm_1us"]["eps"], 1.0 / (2.0 * 4.0 / 7.0));
    assert_eq!(v["input_tolerance"]["max_input_error"], 2.0);
    assert_eq!(v["input_tolerance"]["worst_variable"], 1);
    let table = v["eps_table"].as_array().unwrap();
    assert_eq!(table.len(), 6);
    assert_eq!(table[4]["pwm_error"], 1.0);
    assert_eq!(table[5]["input_error"], 2.0);
    assert_eq!(table[5]["eps"], v["input_tolerance"]["eps"]);
    assert_eq!(table[5]["iterations"], v["input_tolerance"]["iterations"]);
    // A looser input tolerance never needs more iterations.
    assert!(table[5]["iterations"].as_u64() <= table[4]["iterations"].as_u64());
    // The first variable only: (H^-1)_00 = 2/7.
    let v = certify_with(&p, "1e-6", &["--input-error", "2", "--applied-inputs", "1"]);
    close(&v["input_tolerance"]["eps"], 4.0 / (2.0 * 2.0 / 7.0));
    for bad in ["0", "-1", "nan", "inf"] {
        fails_with(
            &[
                "certify",
                "--problem",
                p.to_str().unwrap(),
                "--eps",
                "1e-6",
                "--input-error",
                bad,
            ],
            "--input-error",
        );
    }
}

#[test]
fn help_says_what_goes_in_and_comes_out() {
    let (ok, out, err) = run(&["fgm", "certify", "--help"]);
    assert!(ok, "{err}");
    for needle in [
        "kestrel.mpqp.v1",
        "iterations",
        "eps_table",
        "pwm_1us",
        "input_tolerance",
        "--input-error",
        "--applied-inputs",
    ] {
        assert!(
            out.contains(needle),
            "certify --help lacks {needle}:\n{out}"
        );
    }
    let (ok, out, err) = run(&["fgm", "solve", "--help"]);
    assert!(ok, "{err}");
    for needle in [
        "one theta per row",
        "one row per theta",
        "--iterations",
        "box centre",
    ] {
        assert!(out.contains(needle), "solve --help lacks {needle}:\n{out}");
    }
}

#[test]
fn solve_matches_the_box_optimum() {
    let p = temp_file("box2.json", BOX);
    let t = temp_file("thetas.csv", "0.5, 0.25\n-2,0\n\n2,0.5\n");
    let (ok, out, err) = run(&[
        "fgm",
        "solve",
        "--problem",
        p.to_str().unwrap(),
        "--thetas",
        t.to_str().unwrap(),
        "--iterations",
        "200",
    ]);
    assert!(ok, "{err}");
    let rows: Vec<Vec<f64>> = out
        .lines()
        .map(|l| l.split(',').map(|s| s.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 3);
    // Independent check: projected gradient with a tiny step to convergence.
    for (row, th) in rows.iter().zip([[0.5, 0.25], [-2.0, 0.0], [2.0, 0.5]]) {
        let q = [3.0 * th[0], -th[0]];
        let (lo, hi) = ([-1.0 + th[1], -2.0], [1.0 + th[1], 2.0]);
        let mut z = [0.0f64, 0.0];
        for _ in 0..20000 {
            let g = [4.0 * z[0] + z[1] + q[0], z[0] + 2.0 * z[1] + q[1]];
            for i in 0..2 {
                z[i] = (z[i] - 0.05 * g[i]).clamp(lo[i], hi[i]);
            }
        }
        for i in 0..2 {
            assert!((row[i] - z[i]).abs() < 1e-6, "{row:?} vs {z:?}");
        }
    }
}

#[test]
fn bad_inputs_give_clear_errors() {
    let p = temp_file("box3.json", BOX);
    let ps = p.to_str().unwrap();
    fails_with(
        &["certify", "--problem", ps, "--eps", "0"],
        "eps must be a positive",
    );
    fails_with(
        &["certify", "--problem", ps, "--eps", "-1"],
        "eps must be a positive",
    );

    let coupled = temp_file(
        "coupled.json",
        &BOX.replace("[[0, 2], [1, 0]", "[[1, 2], [1, 0]"),
    );
    fails_with(
        &[
            "certify",
            "--problem",
            coupled.to_str().unwrap(),
            "--eps",
            "1",
        ],
        "constraint row 0 has 2 non-zero",
    );

    let open = temp_file(
        "open.json",
        &BOX.replace(
            r#""G": [[0, 2], [1, 0], [0, -1], [-3, 0]], "W": [4, 1, 2, 3],
  "E": [[0, 0], [0, 1], [0, 0], [0, -3]]"#,
            r#""G": [[0, 2], [1, 0], [-3, 0]], "W": [4, 1, 3],
  "E": [[0, 0], [0, 1], [0, -3]]"#,
        ),
    );
    fails_with(
        &["certify", "--problem", open.to_str().unwrap(), "--eps", "1"],
        "unbounded: variable 1 has no lower bound",
    );

    let nonconvex = temp_file(
        "nc.json",
        &BOX.replace("[[4, 1], [1, 2]]", "[[1, 3], [3, 1]]"),
    );
    fails_with(
        &[
            "certify",
            "--problem",
            nonconvex.to_str().unwrap(),
            "--eps",
            "1",
        ],
        "not convex",
    );

    let t = temp_file("bad.csv", "1,2\n1,x\n");
    fails_with(
        &[
            "solve",
            "--problem",
            ps,
            "--thetas",
            t.to_str().unwrap(),
            "--iterations",
            "5",
        ],
        "line 2, column 2",
    );
    let t = temp_file("short.csv", "1\n");
    fails_with(
        &[
            "solve",
            "--problem",
            ps,
            "--thetas",
            t.to_str().unwrap(),
            "--iterations",
            "5",
        ],
        "expected 2 numbers",
    );
}

#[test]
fn certify_exports_firmware_tables() {
    let p = temp_file("box4.json", BOX);
    let rs = temp_dir("cli-fgm").join("tables.rs");
    let (ok, out, err) = run(&[
        "fgm",
        "certify",
        "--problem",
        p.to_str().unwrap(),
        "--eps",
        "1e-4",
        "--export",
        rs.to_str().unwrap(),
        "--scalar",
        "q16",
        "--theta-step",
        "0.1,0.01",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    // The recommended start never needs more than the cold certificate, and
    // it is the warm start exactly when the warm certificate is shorter.
    let (warm, cold) = (
        v["warm"]["iterations"].as_u64().unwrap(),
        v["iterations"].as_u64().unwrap(),
    );
    assert_eq!(
        v["warm"]["recommended_iterations"].as_u64().unwrap(),
        warm.min(cold)
    );
    let start = if warm < cold { "warm" } else { "cold" };
    assert_eq!(v["warm"]["recommended_start"], start);
    // The export is named with the flag's spelling.
    assert_eq!(v["export"]["scalar"], "q16");
    assert_eq!(v["export"]["path"], rs.to_str().unwrap());
    let text = std::fs::read_to_string(&rs).unwrap();
    assert!(text.contains("pub static FGM: kestrel_fgm::FgmTables<kestrel_core::Q16, 2, 2,"));
    assert!(text.contains("Q16::from_bits("));
}

/// Issue 20, finding 8: an mp-QP without variables panicked in nalgebra
/// (exit 101); both subcommands now refuse it with a message.
#[test]
fn a_problem_without_variables_is_refused() {
    let p = temp_file(
        "empty.json",
        r#"{"format": "kestrel.mpqp.v1", "H": [], "F": [], "G": [], "W": [], "E": [],
            "theta_lb": [], "theta_ub": []}"#,
    );
    let t = temp_file("empty-thetas.csv", "\n");
    for args in [
        vec!["certify", "--problem", p.to_str().unwrap(), "--eps", "1"],
        vec![
            "solve",
            "--problem",
            p.to_str().unwrap(),
            "--thetas",
            t.to_str().unwrap(),
            "--iterations",
            "5",
        ],
    ] {
        let mut all = vec!["fgm"];
        all.extend_from_slice(&args);
        let (ok, _, err) = run(&all);
        assert!(!ok && !err.contains("panicked"), "{all:?}: {err}");
        assert!(
            err.contains("empty.json") && err.contains("no decision variables"),
            "{all:?}: {err}"
        );
    }
}

/// Issue 20, finding 11: `--eps 1e-300` printed `sublinear_bound:
/// 18446744073709551615` (a saturated cast shown as a count); the bound is
/// now null with a `bound_note`, and the certified count is the linear one.
#[test]
fn a_tiny_eps_reports_no_sublinear_bound() {
    let p = temp_file("box5.json", BOX);
    let v = certify(&p, "1e-300");
    assert!(v["sublinear_bound"].is_null(), "{v}");
    assert!(v["bound_note"].as_str().unwrap().contains("exceeds"), "{v}");
    assert_eq!(v["iterations"], v["linear_bound"]);
    assert!(v["iterations"].as_u64().unwrap() < 10_000, "{v}");
    // An ordinary eps: both bounds are counts and there is no note.
    let v = certify(&p, "1e-3");
    assert!(v["sublinear_bound"].as_u64().is_some() && v.get("bound_note").is_none());
}

/// Issue 20, finding 11: `fgm solve` accepted parameters outside the box
/// without a word (`empc eval` warns); it now warns on standard error and
/// still writes every row.
#[test]
fn solve_warns_about_parameters_outside_the_box() {
    let p = temp_file("box6.json", BOX);
    let solve = |thetas: &str, name: &str| {
        let t = temp_file(name, thetas);
        run(&[
            "fgm",
            "solve",
            "--problem",
            p.to_str().unwrap(),
            "--thetas",
            t.to_str().unwrap(),
            "--iterations",
            "50",
        ])
    };
    // The first outside row is named by its line in the file (blank lines
    // counted), not its row index.
    let (ok, out, err) = solve("0,0.25\n\n3,0.25\n1,-0.5\n", "outside.csv");
    assert!(ok, "{err}");
    assert_eq!(out.lines().count(), 3);
    assert!(
        err.contains("warning: 2 of 3 parameters lie outside")
            && err.contains("outside.csv line 3, entry 1 = 3.0 not in [-2.0, 2.0]"),
        "{err}"
    );
    let (ok, out, err) = solve("0,0.25\n2,0.5\n", "inside.csv");
    assert!(ok && out.lines().count() == 2, "{err}");
    assert!(!err.contains("warning"), "{err}");
}

/// An eps below the rounding of the cost (delta x 2^-52) is certified (the
/// count holds in exact arithmetic) with a note that no floating-point
/// solve reaches it; just above that floor, no note.
#[test]
fn an_eps_below_f64_rounding_is_noted() {
    let p = temp_file("box-tiny-eps.json", BOX);
    let args = |eps: &str| {
        vec![
            "fgm".to_string(),
            "certify".into(),
            "--problem".into(),
            p.to_str().unwrap().into(),
            "--eps".into(),
            eps.into(),
        ]
    };
    let run_eps = |eps: &str| {
        let a = args(eps);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        run(&a)
    };
    let (ok, out, err) = run_eps("1e-300");
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let delta = v["delta"].as_f64().unwrap();
    assert!(
        err.contains("note: --eps 1e-300 is below f64's rounding")
            && err.contains(&format!("{} iterations", v["iterations"])),
        "{err}"
    );
    let (ok, _, err) = run_eps(&format!("{:e}", 2.0 * delta * f64::EPSILON));
    assert!(ok && !err.contains("note"), "{err}");
    let (ok, _, err) = run_eps("1e-6");
    assert!(ok && !err.contains("note"), "{err}");
}
