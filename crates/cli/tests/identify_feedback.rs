//! `kestrel identify`'s feedback test on real data: the flight logs of
//! `../shared/data/flight` are closed-loop (no feed-through tried), the
//! DaISy steam generator of `../shared/data/daisy` is open-loop (the
//! open-loop candidates are planned); and the `--pem-steps` flag.

mod common;

use std::path::PathBuf;
use std::process::{Command, Output};

fn kestrel(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .arg("identify")
        .args(args)
        .output()
        .unwrap()
}

fn shared(file: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(file)
        .display()
        .to_string()
}

/// Every flight log long enough for the folds shows feedback at 50 Hz
/// (the motors react to the gyro), so no feed-through is tried. A tiny
/// work budget keeps the run short (the choice itself is not the point).
#[test]
fn flight_logs_are_closed_loop() {
    let dir = tempfile::tempdir().unwrap();
    for log in [
        "betaflight/btfl_002.bbl",
        "crazyflie/log10",
        "crazyflie/log15",
    ] {
        let name = log.replace('/', "-");
        let out = dir
            .path()
            .join(format!("{name}.json"))
            .display()
            .to_string();
        let o = kestrel(&[
            "--data",
            &shared(&format!("flight/{log}")),
            "--max-order",
            "1",
            "--work-budget",
            "1e3",
            "--out",
            &out,
        ]);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{log}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(text.contains("FEEDBACK (closed loop)"), "{log}: {text}");
        assert!(text.contains("feed-through D not tried"), "{log}: {text}");
        assert!(!text.contains(", D,"), "{log}: {text}");
    }
}

/// The steam generator's estimation half shows no feedback: the report
/// says so and lists the open-loop candidates (here skipped by a small
/// work budget, so the run stays short).
#[test]
fn the_steam_generator_is_open_loop() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.json").display().to_string();
    let o = kestrel(&[
        "--data",
        &shared("daisy/steam_generator.csv"),
        "--time-unit",
        "s",
        "--inputs",
        "u1,u2,u3,u4",
        "--outputs",
        "y1,y2,y3,y4",
        "--order",
        "2",
        "--estimate",
        "0:14397",
        "--validate",
        "14400:28797",
        "--work-budget",
        "1e3",
        "--out",
        &out,
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("no feedback found (open loop)"), "{text}");
    assert!(
        text.contains(
            "skipped (work budget): order 2, N4SID state-regression, D, PEM steps {1, 5}, fit criterion"
        ),
        "{text}"
    );
}

/// `--pem-steps` reaches PEM: accepted within `--pem-horizon`, refused
/// beyond it.
#[test]
fn pem_steps_flag() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("log.csv");
    common::write_synthetic_log(&csv, (2, 1, 1, 9), (600, 3), "u,y");
    let c = csv.display().to_string();
    let run = |steps: &str| {
        let out = dir
            .path()
            .join(format!("m-{steps}.json"))
            .display()
            .to_string();
        kestrel(&[
            "--data",
            &c,
            "--inputs",
            "u",
            "--outputs",
            "y",
            "--no-auto",
            "--order",
            "2",
            "--pem-horizon",
            "5",
            "--pem-steps",
            steps,
            "--criterion",
            "fit",
            "--out",
            &out,
        ])
    };
    let ok = run("1,5");
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert!(String::from_utf8_lossy(&ok.stdout).contains("model 5-step"));
    let bad = run("1,7");
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("7"));
}
