//! `kestrel identify --data LOG` on a real flight log: the same
//! identification as on the CSV `kestrel import` writes of it, and the
//! flags that belong to one kind of file refused on the other.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn kestrel(args: &[&str], files: &[&Path]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_kestrel"));
    c.args(args);
    for f in files {
        c.arg(f);
    }
    c.output().unwrap()
}

fn flight(file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/flight")
        .join(file)
}

/// The numbers of the fit table's rows (label, then one value per output
/// and the mean).
fn fit_rows(stdout: &str) -> Vec<(String, Vec<f64>)> {
    stdout
        .lines()
        .filter(|l| l.contains("step") || l.contains("simulation"))
        .filter_map(|l| {
            let words: Vec<&str> = l.split_whitespace().collect();
            let nums: Vec<f64> = words.iter().filter_map(|w| w.parse().ok()).collect();
            (nums.len() == 4).then(|| (words[..words.len() - 4].join(" "), nums))
        })
        .collect()
}

#[test]
fn a_flight_log_identifies_as_its_imported_csv() {
    let dir = tempfile::tempdir().unwrap();
    let log = flight("crazyflie/log16");
    let csv = dir.path().join("log16.csv");
    let import = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .arg("import")
        .arg(&log)
        .args(["--rate", "50", "--out"])
        .arg(&csv)
        .output()
        .unwrap();
    assert!(
        import.status.success(),
        "{}",
        String::from_utf8_lossy(&import.stderr)
    );
    let common = [
        "--order",
        "2",
        "--no-auto",
        "--validate",
        "2@0:1e9",
        "--estimate",
        "1@0:1e9",
    ];
    let mut from_log = vec!["identify", "--out"];
    let m1 = dir.path().join("from-log.json");
    let m2 = dir.path().join("from-csv.json");
    from_log.push(m1.to_str().unwrap());
    from_log.extend(common);
    from_log.push("--data");
    let a = kestrel(&from_log, &[&log]);
    let sa = String::from_utf8_lossy(&a.stdout).to_string();
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    let mut from_csv = vec!["identify", "--out", m2.to_str().unwrap()];
    from_csv.extend(common);
    from_csv.extend(["--inputs", "m1,m2,m3,m4", "--outputs", "p,q,r", "--data"]);
    let b = kestrel(&from_csv, &[&csv]);
    let sb = String::from_utf8_lossy(&b.stdout).to_string();
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    let (ra, rb) = (fit_rows(&sa), fit_rows(&sb));
    assert!(ra.len() >= 4, "{sa}");
    assert_eq!(ra.len(), rb.len(), "{sa}\n{sb}");
    for ((la, va), (lb, vb)) in ra.iter().zip(&rb) {
        assert_eq!(la, lb);
        for (x, y) in va.iter().zip(vb) {
            // The CSV holds the grid to its printed digits.
            assert!((x - y).abs() <= 0.02, "{la}: {x} vs {y}\n{sa}\n{sb}");
        }
    }
    let model = std::fs::read_to_string(&m1).unwrap();
    assert!(
        model.contains("\"m1\"") && model.contains("\"r\""),
        "{model}"
    );
}

#[test]
fn flags_of_the_other_kind_of_file_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let log = flight("crazyflie/log16");
    let out = dir.path().join("m.json");
    let o = out.to_str().unwrap();
    let r = kestrel(&["identify", "--out", o, "--ts", "0.02", "--data"], &[&log]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("its own clock"));
    let csv = dir.path().join("d.csv");
    std::fs::write(&csv, "t,u,y\n0,1,2\n0.02,2,3\n0.04,1,2\n").unwrap();
    let r = kestrel(&["identify", "--out", o, "--data"], &[&csv]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("--inputs and --outputs"));
    let r = kestrel(
        &[
            "identify",
            "--out",
            o,
            "--inputs",
            "u",
            "--outputs",
            "y",
            "--rate",
            "50",
            "--data",
        ],
        &[&csv],
    );
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("kestrel import"));
    for bad in ["0", "nan", "inf"] {
        let r = kestrel(
            &["identify", "--out", o, "--work-budget", bad, "--data"],
            &[&log],
        );
        assert!(!r.status.success());
        assert!(String::from_utf8_lossy(&r.stderr).contains("--work-budget must be a positive"));
    }
    assert!(!out.exists(), "nothing written on an error");
}
