//! End-to-end tests of what the commands do to files they did not create
//! (nothing) and what a failed command leaves behind (nothing new).

mod common;

use common::kestrel as run;
use std::path::Path;
use std::time::{Duration, Instant};

/// The `.kestrel-report` manifest of a report that holds `files`.
fn manifest(files: &[&str]) -> String {
    let mut s = "kestrel pipeline report\n".to_string();
    for f in files {
        s.push_str(f);
        s.push('\n');
    }
    s
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Runs `kestrel pipeline --quick --out <out> <extra>`, expects a refusal
/// that names `expected` and comes before the work starts.
fn refused(out: &Path, extra: &[&str], expected: &str) {
    let mut args = vec!["pipeline", "--quick", "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let t = Instant::now();
    let (ok, _, err) = run(&args);
    assert!(!ok, "{args:?} succeeded");
    assert!(err.contains(expected), "{args:?}: {err}");
    assert!(
        t.elapsed() < Duration::from_secs(5),
        "{args:?}: refused only after {:?}",
        t.elapsed()
    );
}

#[test]
fn pipeline_keeps_user_files_and_replaces_a_report_only_with_force() {
    let base = tempfile::tempdir().unwrap();
    let base = base.path();

    // A directory of the user's: refused, keep.txt untouched.
    let proj = base.join("proj");
    std::fs::create_dir(&proj).unwrap();
    std::fs::write(proj.join("keep.txt"), "keep\n").unwrap();
    refused(&proj, &[], "not a kestrel report");
    refused(&proj, &["--force"], "not a kestrel report");
    assert_eq!(names(&proj), ["keep.txt"]);
    assert_eq!(
        std::fs::read_to_string(proj.join("keep.txt")).unwrap(),
        "keep\n"
    );

    // An existing file: refused, untouched, not renamed.
    let notes = base.join("notes.txt");
    std::fs::write(&notes, "my notes\n").unwrap();
    refused(&notes, &[], "not a directory");
    refused(&notes, &["--force"], "not a directory");
    assert_eq!(std::fs::read_to_string(&notes).unwrap(), "my notes\n");

    // An empty directory is accepted (the run then fails on the flight
    // logs, after the check of --out): it stays, empty.
    let empty = base.join("empty");
    std::fs::create_dir(&empty).unwrap();
    let missing = base.join("no-such-logs");
    let (ok, _, err) = run(&[
        "pipeline",
        "--quick",
        "--out",
        empty.to_str().unwrap(),
        "--flights",
        missing.to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("no-such-logs"), "{err}");
    assert!(names(&empty).is_empty());

    // A previous report: refused without --force.
    let prev = base.join("prev");
    std::fs::create_dir_all(prev.join("tables")).unwrap();
    std::fs::write(prev.join("report.md"), "# old\n").unwrap();
    std::fs::write(prev.join("tables/old.csv"), "a\n1\n").unwrap();
    std::fs::write(
        prev.join(".kestrel-report"),
        manifest(&["report.md", "tables/old.csv"]),
    )
    .unwrap();
    refused(&prev, &[], "--force");
    // With --force but a file the report did not write: refused.
    std::fs::write(prev.join("tables/mine.txt"), "mine\n").unwrap();
    refused(&prev, &["--force"], "tables/mine.txt");
    std::fs::remove_file(prev.join("tables/mine.txt")).unwrap();
    // With --force and a failure on the way: the previous report stays.
    let (ok, _, _) = run(&[
        "pipeline",
        "--quick",
        "--force",
        "--out",
        prev.to_str().unwrap(),
        "--flights",
        missing.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert_eq!(
        std::fs::read_to_string(prev.join("report.md")).unwrap(),
        "# old\n"
    );
    assert_eq!(names(base), ["empty", "notes.txt", "prev", "proj"]);

    // With --force: replaced, no debris beside it.
    let (ok, _, err) = run(&[
        "pipeline",
        "--quick",
        "--force",
        "--out",
        prev.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(!prev.join("tables/old.csv").exists());
    let md = std::fs::read_to_string(prev.join("report.md")).unwrap();
    assert!(md.starts_with("# kestrel pipeline report"), "{md}");
    // The new report lists its files, the marker included nowhere else.
    let listed = std::fs::read_to_string(prev.join(".kestrel-report")).unwrap();
    assert!(listed.starts_with("kestrel pipeline report\n"));
    for f in ["report.md", "summary.json", "tables/timings.csv"] {
        assert!(listed.lines().any(|l| l == f), "{f} not listed: {listed}");
    }
    assert_eq!(names(base), ["empty", "notes.txt", "prev", "proj"]);
    // Now a report of its own making: still refused without --force.
    refused(&prev, &[], "--force");
    assert!(prev.join("summary.json").is_file());
}

#[test]
fn simulate_failure_leaves_no_log() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("o.csv");
    let (ok, _, err) = run(&[
        "simulate",
        "--experiment",
        "hover",
        "--seconds",
        "6",
        "--out",
        csv.to_str().unwrap(),
        "--rate-model",
        "/proc/x",
    ]);
    assert!(!ok, "succeeded");
    assert!(err.contains("/proc/x"), "{err}");
    assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));
    // An existing log is left as it was.
    std::fs::write(&csv, "old\n").unwrap();
    let (ok, _, _) = run(&[
        "simulate",
        "--experiment",
        "hover",
        "--seconds",
        "6",
        "--out",
        csv.to_str().unwrap(),
        "--rate-model",
        "/proc/x",
        "--force",
    ]);
    assert!(!ok);
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "old\n");
    assert_eq!(names(dir.path()), ["o.csv"]);
}

#[test]
fn fgm_certify_failure_leaves_no_export() {
    let dir = tempfile::tempdir().unwrap();
    let problem = dir.path().join("box.json");
    std::fs::write(
        &problem,
        r#"{"format": "kestrel.mpqp.v1",
  "H": [[4, 1], [1, 2]], "F": [[3, -1], [0, 0]],
  "G": [[1, 0], [-1, 0], [0, 1], [0, -1]], "W": [1, 1, 2, 2],
  "E": [[0, 0], [0, 0], [0, 0], [0, 0]],
  "theta_lb": [-2, 0], "theta_ub": [2, 0.5]}"#,
    )
    .unwrap();
    let export = dir.path().join("e.rs");
    let certify = |out: &str| {
        run(&[
            "fgm",
            "certify",
            "--problem",
            problem.to_str().unwrap(),
            "--eps",
            "1e-3",
            "--export",
            export.to_str().unwrap(),
            "--out",
            out,
        ])
    };
    let (ok, _, err) = certify("/proc/x");
    assert!(!ok, "succeeded");
    assert!(err.contains("/proc/x"), "{err}");
    assert_eq!(names(dir.path()), ["box.json"]);
    // Both written when both can be.
    let out = dir.path().join("cert.json");
    let (ok, _, err) = certify(out.to_str().unwrap());
    assert!(ok, "{err}");
    assert_eq!(names(dir.path()), ["box.json", "cert.json", "e.rs"]);
}

/// An output file that exists already is refused by every command before
/// its work starts, with the file as it was, and replaced with `--force`;
/// the mistake it guards against: `--out` naming the input data.
#[test]
fn existing_outputs_are_refused_without_force() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = |name: &str| d.join(name).display().to_string();
    let log = path("log.csv");
    let (ok, _, err) = run(&[
        "simulate",
        "--experiment",
        "decoupled",
        "--seconds",
        "20",
        "--out",
        &log,
    ]);
    assert!(ok, "{err}");
    let data = std::fs::read_to_string(&log).unwrap();
    let refused = |args: &[&str], file: &str| {
        let t = Instant::now();
        let (ok, _, err) = run(args);
        assert!(!ok, "{args:?} succeeded");
        assert!(
            err.contains(&format!("{file} exists; give --force to replace it")),
            "{args:?}: {err}"
        );
        assert!(
            t.elapsed() < Duration::from_secs(5),
            "{args:?}: {:?}",
            t.elapsed()
        );
    };
    let identify = [
        "identify",
        "--data",
        &log,
        "--inputs",
        "pwm1,pwm2,pwm3,servo",
        "--outputs",
        "p,q,r",
        "--no-auto",
        "--order",
        "3",
        "--out",
        &log,
    ];
    refused(&identify, &log);
    assert_eq!(std::fs::read_to_string(&log).unwrap(), data);

    let mine = path("mine.json");
    let model = common::MODEL;
    let commands: [&[&str]; 5] = [
        &[
            "simulate",
            "--experiment",
            "hover",
            "--seconds",
            "2",
            "--out",
            &mine,
        ],
        &[
            "simulate",
            "--experiment",
            "hover",
            "--seconds",
            "2",
            "--rate-model",
            &mine,
        ],
        &[
            "kalman", "--model", model, "--q", "1", "--r", "1", "--out", &mine,
        ],
        &["mpc", "--model", model, "--horizon", "2", "--out", &mine],
        &["import", "/nonexistent.bbl", "--out", &mine],
    ];
    for args in commands {
        std::fs::write(&mine, "mine\n").unwrap();
        refused(args, &mine);
        assert_eq!(
            std::fs::read_to_string(&mine).unwrap(),
            "mine\n",
            "{args:?}"
        );
    }
    // With --force the file is replaced.
    let mut forced = commands[2].to_vec();
    forced.push("--force");
    let (ok, _, err) = run(&forced);
    assert!(ok, "{err}");
    assert!(
        std::fs::read_to_string(&mine)
            .unwrap()
            .contains("kestrel.kalman.v1")
    );
    assert_eq!(names(d), ["log.csv", "mine.json"]);
    // One file for two outputs: refused, even with --force.
    let twice = path("twice.json");
    let (ok, _, err) = run(&[
        "simulate",
        "--experiment",
        "hover",
        "--seconds",
        "2",
        "--out",
        &twice,
        "--rate-model",
        &twice,
        "--force",
    ]);
    assert!(!ok && err.contains("name the same file"), "{err}");
    assert_eq!(names(d), ["log.csv", "mine.json"]);
}
