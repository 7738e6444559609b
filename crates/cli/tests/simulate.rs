//! End-to-end tests of `kestrel simulate`.

mod common;

use std::path::PathBuf;
use std::process::Command;

fn kestrel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
}

fn temp_dir() -> PathBuf {
    common::temp_dir("simulate")
}

#[test]
fn same_seed_gives_the_same_file() {
    let dir = temp_dir();
    let (a, b) = (dir.join("a.csv"), dir.join("b.csv"));
    for p in [&a, &b] {
        let out = kestrel()
            .args([
                "simulate",
                "--experiment",
                "coupled",
                "--seconds",
                "20",
                "--seed",
                "1",
                "--out",
            ])
            .arg(p)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let (ta, tb) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    assert_eq!(ta, tb);
    let text = String::from_utf8(ta).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    assert!(header.starts_with(
        "t,pwm1,pwm2,pwm3,servo,throttle,u_roll,u_pitch,u_yaw,p,q,r,ref_p,ref_q,ref_r,true_p"
    ));
    assert_eq!(lines.count(), 1000);
}

#[test]
fn ground_to_stdout_and_rate_model_file() {
    let dir = temp_dir();
    let model = dir.join("rate.json");
    let out = kestrel()
        .args([
            "simulate",
            "--experiment",
            "ground",
            "--seconds",
            "2",
            "--rate-model",
        ])
        .arg(&model)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.lines().count(), 101);
    let json = std::fs::read_to_string(&model).unwrap();
    assert!(json.contains("kestrel.ss.v1") && json.contains("\"ts\": 0.02"));
}

/// A flight too short to take off says so; one long enough, and the ground
/// experiment (which never flies), do not.
#[test]
fn a_flight_that_never_takes_off_is_noted() {
    let run = |experiment: &str, seconds: &str| {
        let out = kestrel()
            .args(["simulate", "--experiment", experiment, "--seconds", seconds])
            .output()
            .unwrap();
        assert!(out.status.success());
        let text = String::from_utf8(out.stdout).unwrap();
        let airborne = text.lines().skip(1).filter(|l| l.ends_with(",1")).count();
        let noted = String::from_utf8_lossy(&out.stderr).contains("never left the ground");
        (airborne, noted)
    };
    assert_eq!(run("hover", "5"), (0, true));
    let (airborne, noted) = run("hover", "8");
    assert!(airborne > 0 && !noted, "{airborne}");
    assert_eq!(run("ground", "5"), (0, false));
}

#[test]
fn bad_arguments_are_clear_errors() {
    let out = kestrel()
        .args(["simulate", "--experiment", "loop", "--seconds", "5"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unknown experiment") && err.contains("hover, decoupled, coupled, ground"),
        "{err}"
    );
    let out = kestrel()
        .args(["simulate", "--experiment", "hover", "--seconds", "-3"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("seconds"));
    let out = kestrel()
        .args([
            "simulate",
            "--experiment",
            "hover",
            "--seconds",
            "5",
            "--dt",
            "0.007",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("dt"));
}
