//! Issue 20 finding 9: sizes that used to hang, exhaust memory or run for
//! hours unannounced are refused (or announced) before the work starts,
//! with what they would cost and how to go on. Each command runs with a
//! deadline, so a guard that is missing fails the test instead of hanging it.

mod common;
use common::{MODEL, kestrel, kestrel_within, temp_dir};
use std::path::{Path, PathBuf};

/// A refusal within `seconds`: its standard error.
fn refused(seconds: u64, args: &[&str]) -> String {
    let Some((ok, _, err)) = kestrel_within(seconds, args) else {
        panic!("kestrel {} still ran after {seconds} s", args.join(" "));
    };
    assert!(!ok, "kestrel {} succeeded: {err}", args.join(" "));
    err
}

#[test]
fn mpc_refuses_a_horizon_too_large_to_condense() {
    for n in ["2000", "100000"] {
        let err = refused(30, &["mpc", "--model", MODEL, "--horizon", n]);
        assert!(err.contains("too large to condense"), "{err}");
        assert!(
            err.contains("decision variables") && err.contains("GB"),
            "{err}"
        );
        assert!(err.contains("--blocks"), "{err}");
    }
    // A long horizon in a few blocks, the larger problem and 50 steps pass.
    for args in [
        &["--horizon", "2000", "--blocks", "1,1,2,1996"][..],
        &["--horizon", "10", "--blocks", "1,1,2,6"],
        &["--horizon", "50"],
    ] {
        let mut all = vec!["mpc", "--model", MODEL];
        all.extend_from_slice(args);
        let Some((ok, out, err)) = kestrel_within(60, &all) else {
            panic!("{args:?} still ran after 60 s");
        };
        assert!(ok && out.contains("kestrel.mpqp.v1"), "{args:?}: {err}");
    }
}

#[test]
fn closed_loop_refuses_a_horizon_too_large_to_condense() {
    let err = refused(
        30,
        &["closed-loop", "--controller", "qp", "--horizon", "100000"],
    );
    assert!(err.contains("too large to condense"), "{err}");
    assert!(err.contains("--blocks"), "{err}");
}

/// A 60 s flight: 3,000 samples at 50 Hz.
fn flight(dir: &Path) -> PathBuf {
    let log = dir.join("coupled-60.csv");
    let (ok, _, err) = kestrel(&[
        "simulate",
        "--experiment",
        "coupled",
        "--seconds",
        "60",
        "--out",
        log.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    log
}

#[test]
fn identify_refuses_an_order_or_a_pem_horizon_beyond_its_limits() {
    let dir = temp_dir("guards-identify");
    let log = flight(&dir);
    let log = log.to_str().unwrap();
    let base = [
        "identify",
        "--data",
        log,
        "--inputs",
        "pwm1,pwm2,pwm3,servo",
        "--outputs",
        "p,q,r",
    ];
    let out = dir.join("m.json");
    let with = |extra: &[&str]| {
        let mut a = base.to_vec();
        a.extend_from_slice(extra);
        a.extend_from_slice(&["--out", out.to_str().unwrap()]);
        a.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    };
    let a = with(&["--order", "500"]);
    let err = refused(30, &a.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        err.contains("order 500") && err.contains("parameters"),
        "{err}"
    );
    assert!(err.contains("--order"), "{err}");
    let a = with(&["--order", "3", "--pem-horizon", "5000"]);
    let err = refused(30, &a.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(err.contains("horizon 5000") && err.contains("GB"), "{err}");
    assert!(err.contains("--pem-horizon"), "{err}");
    assert!(!out.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn simulate_refuses_a_step_too_fine_and_a_flight_too_long() {
    let err = refused(30, &["simulate", "--experiment", "hover", "--dt", "1e-9"]);
    assert!(err.contains("RK4 steps") && err.contains("hours"), "{err}");
    assert!(err.contains("--dt"), "{err}");
    let err = refused(
        30,
        &["simulate", "--experiment", "hover", "--seconds", "1e6"],
    );
    assert!(err.contains("GB") && err.contains("--seconds"), "{err}");
}

/// The thesis problem (4 variables) in `dir`.
fn thesis_problem(dir: &Path) -> PathBuf {
    common::thesis_problem_of(MODEL, &dir.join("thesis.json"))
}

#[test]
fn fgm_refuses_a_billion_iterations() {
    let dir = temp_dir("guards-fgm");
    let problem = thesis_problem(&dir);
    let thetas = dir.join("thetas.csv");
    std::fs::write(&thetas, "0,0,0,0,0,0,0,0,1500\n").unwrap();
    let err = refused(
        30,
        &[
            "fgm",
            "solve",
            "--problem",
            problem.to_str().unwrap(),
            "--thetas",
            thetas.to_str().unwrap(),
            "--iterations",
            "1000000000",
        ],
    );
    assert!(
        err.contains("at most 1000000") && err.contains("GB"),
        "{err}"
    );
    assert!(err.contains("fgm certify"), "{err}");
    let err = refused(
        30,
        &[
            "closed-loop",
            "--controller",
            "fgm",
            "--iterations",
            "1000000000",
        ],
    );
    assert!(err.contains("at most 1000000"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A parameter file whose rows, results and output text would take more
/// than 2 GB is refused before it is parsed (and one larger than that
/// before it is read), by every command that reads one, naming the file
/// and how to go on.
#[test]
fn parameter_files_beyond_the_memory_budget_are_refused() {
    let dir = temp_dir("guards-thetas");
    // min 1/2 |z|^2 + t (z0 + z1), |z| <= 1: one parameter, two variables.
    let problem = dir.join("p.json");
    std::fs::write(
        &problem,
        r#"{"format": "kestrel.mpqp.v1", "H": [[1, 0], [0, 1]], "F": [[1, 1]],
        "G": [[1, 0], [-1, 0], [0, 1], [0, -1]], "W": [1, 1, 1, 1],
        "E": [[0], [0], [0], [0]], "theta_lb": [-1], "theta_ub": [1]}"#,
    )
    .unwrap();
    // Twelve million one-number rows (24 MB of text): about 2.1 GB with fgm
    // solve's two results per row, 2.5 GB with qp solve's three.
    let many = dir.join("many.csv");
    std::fs::write(&many, "1\n".repeat(12_000_000)).unwrap();
    // A file of 3 GB (sparse: no disk taken), refused from its size.
    let huge = dir.join("huge.csv");
    std::fs::File::create(&huge)
        .unwrap()
        .set_len(3_000_000_000)
        .unwrap();
    for (file, what) in [
        (&many, "12000000 rows of 1 parameters"),
        (&huge, "3000000000 bytes of text"),
    ] {
        for cmd in [
            &["qp", "solve"][..],
            &["fgm", "solve", "--iterations", "10"],
        ] {
            let mut args = cmd.to_vec();
            args.extend_from_slice(&[
                "--problem",
                problem.to_str().unwrap(),
                "--thetas",
                file.to_str().unwrap(),
            ]);
            let err = refused(30, &args);
            assert!(
                err.contains(what)
                    && err.contains("at most 2.0 GB")
                    && err.contains("split the file"),
                "{args:?}: {err}"
            );
        }
    }
    // A hundred thousand rows pass.
    std::fs::write(&many, "0.5\n".repeat(100_000)).unwrap();
    let Some((ok, out, err)) = kestrel_within(
        60,
        &[
            "qp",
            "solve",
            "--problem",
            problem.to_str().unwrap(),
            "--thetas",
            many.to_str().unwrap(),
        ],
    ) else {
        panic!("qp solve of 100,000 rows still ran after 60 s");
    };
    assert!(ok && out.lines().count() == 100_000, "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
