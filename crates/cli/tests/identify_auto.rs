//! End-to-end tests of `kestrel identify`'s automatic structure choice
//! and its baseline rows.

mod common;

use kestrel_core::formats::SsModel;
use std::process::Command;

/// A log `t,a,b,p,q` from a known 3rd-order model, 50 Hz.
fn write_log(path: &std::path::Path) {
    common::write_synthetic_log(path, (3, 2, 2, 17), (1200, 4), "a,b,p,q");
}

/// A fresh directory with the log in it: (directory, log path).
fn temp_log(name: &str) -> (std::path::PathBuf, String) {
    let d = common::temp_dir(&format!("identify-{name}"));
    let log = d.join("log.csv");
    write_log(&log);
    let l = log.display().to_string();
    (d, l)
}

/// The data, signal and interval flags for the log at `l`.
fn log_args(l: &str) -> [&str; 10] {
    [
        "--data",
        l,
        "--inputs",
        "a,b",
        "--outputs",
        "p,q",
        "--estimate",
        "0:15.98",
        "--validate",
        "16:23.98",
    ]
}

fn kestrel(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .arg("identify")
        .args(args)
        .output()
        .unwrap()
}

/// The default (and `--order auto`) chooses the order by cross-validation
/// inside the estimation data, prints the candidates and the choice, and
/// puts persistence and the best ARX beside the model in the table; a
/// flag fixes its dimension; `--order x` is refused.
#[test]
fn default_chooses_the_structure_and_prints_the_baselines() {
    let (d, l) = temp_log("auto");
    let base = [&log_args(&l)[..], &["--max-order", "5"]].concat();
    let o = kestrel(&[&base[..], &["--order", "auto"]].concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("structure chosen by 3-fold blocked cross-validation"),
        "{err}"
    );
    // The true order, or one more: a nested order-4 model fits the
    // folds as well as order 3 to within their noise (0.01 points), so
    // which of the two wins is not decided by the data.
    assert!(
        err.contains("chosen: order 3") || err.contains("chosen: order 4"),
        "{err}"
    );
    for row in [
        "persistence 1-step",
        "best ARX 1-step (",
        "best ARX 5-step (",
        "mean fit against the baselines: 1-step: ",
    ] {
        assert!(err.contains(row), "{row} missing in {err}");
    }
    let m = SsModel::from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
    assert!(m.nx() == 3 || m.nx() == 4, "order {}", m.nx());
    // A given order and focus stay fixed.
    let o = kestrel(&[&base[..], &["--order", "2", "--focus", "prediction"]].concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("fixed: order, focus and prediction horizon"),
        "{err}"
    );
    assert!(!err.contains("order 3,"), "{err}");
    // --no-auto: the flags as given, no choice printed.
    let o = kestrel(&[&base[..], &["--order", "2", "--no-auto"]].concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && !err.contains("structure chosen"),
        "{err}"
    );
    // --model-rate: the model at 10 Hz (factor 5), the table at 50 Hz;
    // a rate that does not divide 50 Hz is refused.
    let o = kestrel(
        &[
            &base[..],
            &["--order", "2", "--no-auto", "--model-rate", "10"],
        ]
        .concat(),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let m = SsModel::from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
    assert!((m.ts - 0.1).abs() < 1e-9, "{}", m.ts);
    assert!(
        err.contains("model resampled from 50.000000 Hz to 10 Hz (factor 5"),
        "{err}"
    );
    let o = kestrel(
        &[
            &base[..],
            &["--order", "2", "--no-auto", "--model-rate", "7"],
        ]
        .concat(),
    );
    assert!(!o.status.success());
    let o = kestrel(&[&base[..], &["--order", "x"]].concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("`auto`"), "{err}");
    std::fs::remove_dir_all(&d).ok();
}

/// `--method arx` (`armax`): PEM started from a high-order ARX (ARMAX)
/// reduced by balanced truncation, `--horizon` its lags; an order beyond
/// the realisation's states is refused with the reason.
#[test]
fn method_arx_starts_from_the_reduced_arx() {
    let (d, l) = temp_log("arx");
    let base = [&log_args(&l)[..], &["--no-auto", "--method", "arx"]].concat();
    let o = kestrel(&[&base[..], &["--order", "3", "--horizon", "8"]].concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("ARX reduction order 3 (suggested") && err.contains("lags 8"),
        "{err}"
    );
    let m = SsModel::from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
    assert_eq!(m.a.nrows(), 3);
    // The data come from a 3rd-order model: the one-step validation fit
    // is that of the best ARX of 2-10 lags (measured 83.03 and 82.95).
    let mean_of = |row: &str| -> f64 {
        err.lines()
            .find(|l| l.starts_with(row))
            .and_then(|l| l.split_whitespace().last())
            .and_then(|v| v.parse().ok())
            .unwrap()
    };
    let (model, arx) = (mean_of("model 1-step"), mean_of("best ARX 1-step"));
    assert!(model > arx - 0.5, "{err}");
    // --method armax: an ARMAX of 2 lags, 2 outputs: 4 states, kept.
    let o = kestrel(
        &[
            &log_args(&l)[..],
            &[
                "--no-auto",
                "--method",
                "armax",
                "--order",
                "4",
                "--horizon",
                "2",
            ],
        ]
        .concat(),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && err.contains("ARMAX reduction order 4 (suggested"),
        "{err}"
    );
    // 2 outputs x 1 lag: a 2-state realisation cannot give order 3.
    let o = kestrel(&[&base[..], &["--order", "3", "--horizon", "1"]].concat());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("exceeds the 2 states of the ARX realisation"),
        "{err}"
    );
    std::fs::remove_dir_all(&d).ok();
}
