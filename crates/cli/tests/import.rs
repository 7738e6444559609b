//! End-to-end tests of `kestrel import` on the real flight logs of
//! `../shared/data/flight` and on damaged copies.

use std::path::PathBuf;
use std::process::Command;

fn kestrel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
}

fn flight(file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/flight")
        .join(file)
}

#[test]
fn a_crazyflie_log_to_csv_that_identify_reads() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("log16.csv");
    let run = kestrel()
        .arg("import")
        .arg(flight("crazyflie/log16"))
        .args(["--rate", "50", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(
        stderr.contains("output p        = fixedFrequency.gyro.x [rad/s]"),
        "{stderr}"
    );
    assert!(stderr.contains("2 experiment(s), 594 rows"), "{stderr}");
    let csv = std::fs::read_to_string(&out).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("t,m1,m2,m3,m4,p,q,r,experiment"));
    assert_eq!(lines.count(), 594);
    // An existing file is replaced only with --force.
    let again = kestrel()
        .arg("import")
        .arg(flight("crazyflie/log16"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    // The CSV is identification data as it is.
    let data = kestrel_sysid::IoData::read_csv(
        &out,
        &kestrel_sysid::CsvColumns::new(&["m1", "m2", "m3", "m4"], &["p", "q", "r"]),
    )
    .unwrap();
    assert_eq!(data.experiments().len(), 2);
    assert!((data.ts() - 0.02).abs() < 1e-9);
}

#[test]
fn selected_signals_the_whole_log_to_stdout() {
    let run = kestrel()
        .arg("import")
        .arg(flight("betaflight/btfl_002.bbl"))
        .args(["--rate", "10", "--segment", "all"])
        .args([
            "--inputs",
            "thr=rcCommand[3]",
            "--outputs",
            "roll=gyroADC[0]",
        ])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let csv = String::from_utf8_lossy(&run.stdout);
    assert!(csv.starts_with("t,thr,roll\n"), "{}", &csv[..40]);
    // 133.8 s of log at 10 Hz.
    assert_eq!(csv.lines().count(), 1 + 1338);
}

#[test]
fn list_shows_the_fields_to_pick() {
    let run = kestrel()
        .arg("import")
        .arg(flight("betaflight/btfl_002.bbl"))
        .arg("--list")
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(
        text.contains("Firmware revision: Betaflight 4.2.8"),
        "{text}"
    );
    assert!(text.contains("topic main: 66640 samples"), "{text}");
    assert!(text.contains("main.gyroADC[0] [rad/s]"), "{text}");
    assert!(
        text.contains("main.motor[3] [raw, range 158..2047]"),
        "{text}"
    );
}

#[test]
fn damaged_and_foreign_files_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(flight("crazyflie/log10")).unwrap();
    let cut = dir.path().join("cut");
    std::fs::write(&cut, &bytes[..1_000_003]).unwrap();
    let run = kestrel().arg("import").arg(&cut).output().unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        stderr.contains("truncated at byte offset 999979"),
        "{stderr}"
    );
    assert!(stderr.contains("--salvage"), "{stderr}");
    let salvaged = kestrel()
        .arg("import")
        .arg(&cut)
        .arg("--salvage")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&salvaged.stderr);
    assert!(salvaged.status.success(), "{stderr}");
    assert!(stderr.contains("warning: byte offset 999979"), "{stderr}");
    let foreign = dir.path().join("notes.txt");
    std::fs::write(&foreign, "t,u,y\n0,1,2\n").unwrap();
    let run = kestrel().arg("import").arg(&foreign).output().unwrap();
    assert!(String::from_utf8_lossy(&run.stderr).contains("not a flight log"));
    let run = kestrel()
        .arg("import")
        .arg(flight("crazyflie/log10"))
        .args(["--outputs", "gyro.w"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("signal \"gyro.w\": no such field") && stderr.contains("gyro.z"),
        "{stderr}"
    );
}
