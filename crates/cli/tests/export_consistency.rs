//! `kestrel export` checks that its design files belong together, not only
//! their sizes (issue 20, finding 4): a Kalman filter or MPC problem
//! designed for another model of the same size is refused with a message
//! naming both files and what differs; the report's own filter (the
//! black-box model with the offset-free MPC's disturbance states) and
//! problem are accepted and give the report's firmware tables.

mod common;

use common::{kestrel, temp_dir};
use kestrel_core::formats::{MpqpProblem, SsModel, json};
use std::path::{Path, PathBuf};

fn dir() -> PathBuf {
    temp_dir("export-consistency")
}

fn fixture() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../models/tricopter-blackbox-5.json")
        .display()
        .to_string()
}

/// Another 5-state model with the tricopter's inputs and outputs: the
/// fixture with one entry of `A` changed.
fn foreign_model() -> String {
    let mut m = SsModel::read(Path::new(&fixture())).unwrap();
    m.a[(1, 1)] *= 0.9;
    let p = dir().join("foreign-model.json");
    std::fs::write(&p, m.to_json_string()).unwrap();
    p.display().to_string()
}

/// `kestrel kalman` on `model`, written to `name`.
fn kalman_of(model: &str, name: &str) -> String {
    let out = dir().join(name).display().to_string();
    let (ok, _, err) = kestrel(&[
        "kalman", "--model", model, "--q", "1e-4", "--r", "1e-4", "--out", &out,
    ]);
    assert!(ok, "{err}");
    out
}

/// `kestrel mpc` (the thesis-sized problem) on `model`, written to `name`.
fn problem_of(model: &str, name: &str) -> String {
    common::thesis_problem_of(model, &dir().join(name))
        .display()
        .to_string()
}

fn export(args: &[&str]) -> (bool, String, String) {
    let mut all = vec!["export"];
    all.extend_from_slice(args);
    kestrel(&all)
}

#[test]
fn a_filter_of_another_model_is_refused() {
    let (model, foreign) = (fixture(), foreign_model());
    let kf = kalman_of(&foreign, "foreign-kalman.json");
    let (ok, _, err) = export(&["--model", &model, "--kalman", &kf]);
    assert!(!ok, "a filter of another 5-state model was accepted");
    for want in [
        kf.as_str(),
        model.as_str(),
        "A[1][1]",
        "do not belong together",
    ] {
        assert!(err.contains(want), "no {want:?} in: {err}");
    }
    // The same filter with its own model is accepted.
    let (ok, _, err) = export(&["--model", &foreign, "--kalman", &kf]);
    assert!(ok, "{err}");
}

#[test]
fn a_problem_of_another_model_is_refused() {
    let (model, foreign) = (fixture(), foreign_model());
    let pr = problem_of(&foreign, "foreign-problem.json");
    let (ok, _, err) = export(&["--model", &model, "--problem", &pr]);
    assert!(!ok, "a problem of another 5-state model was accepted");
    let text = std::fs::read_to_string(&pr).unwrap();
    let obj = json::parse_object(&text).unwrap();
    assert!(
        MpqpProblem::model_fingerprint_of(&obj).unwrap().is_some(),
        "kestrel mpc writes the model's fingerprint"
    );
    for want in [
        pr.as_str(),
        model.as_str(),
        "model_fingerprint",
        "do not belong together",
    ] {
        assert!(err.contains(want), "no {want:?} in: {err}");
    }
    // With the filter of the fixture too, the problem is still refused.
    let kf = kalman_of(&model, "own-kalman.json");
    let (ok, _, err) = export(&["--model", &model, "--kalman", &kf, "--problem", &pr]);
    assert!(!ok && err.contains(&pr), "{err}");
    // The problem with its own model and filter is accepted.
    let kf = kalman_of(&foreign, "foreign-kalman-2.json");
    let (ok, _, err) = export(&["--model", &foreign, "--kalman", &kf, "--problem", &pr]);
    assert!(ok, "{err}");
    assert!(!err.contains("warning"), "{err}");
}

#[test]
fn a_problem_without_fingerprint_is_accepted_with_a_warning() {
    let model = fixture();
    let pr = problem_of(&model, "own-problem.json");
    let mut obj = json::parse_object(&std::fs::read_to_string(&pr).unwrap()).unwrap();
    obj.remove(MpqpProblem::MODEL_FINGERPRINT_KEY);
    let old = dir().join("old-problem.json");
    std::fs::write(&old, json::to_pretty_string(&obj)).unwrap();
    let old = old.display().to_string();
    let (ok, _, err) = export(&["--model", &model, "--problem", &old]);
    assert!(ok, "{err}");
    assert!(
        err.contains("warning") && err.contains(&old) && err.contains("model_fingerprint"),
        "{err}"
    );
}

/// The report's own pair: `kalman.json` (8 states: the black-box model and
/// the offset-free MPC's 3 disturbance states) with `problems/thesis.json`
/// and the black-box model is accepted and gives the report's
/// `firmware/generated.rs` byte for byte; the same filter with another
/// 5-state model is refused.
#[test]
fn the_reports_own_files_are_accepted() {
    let report = dir().join("report");
    if report.exists() {
        std::fs::remove_dir_all(&report).unwrap();
    }
    let r = report.display().to_string();
    let (ok, _, err) = kestrel(&["pipeline", "--quick", "--out", &r]);
    assert!(ok, "{err}");
    let file = |name: &str| report.join(name).display().to_string();
    let (model, kf, thesis) = (
        file("models/blackbox-5.json"),
        file("kalman.json"),
        file("problems/thesis.json"),
    );
    assert_eq!(
        kestrel_kalman::KalmanDesign::read(Path::new(&kf))
            .unwrap()
            .nx(),
        8
    );
    let (ok, tables, err) = export(&["--model", &model, "--kalman", &kf, "--problem", &thesis]);
    assert!(ok, "the report's own files were refused: {err}");
    assert!(!err.contains("warning"), "{err}");
    let flashed = std::fs::read_to_string(file("firmware/generated.rs")).unwrap();
    assert!(
        tables == flashed,
        "export of the report's files differs from its firmware/generated.rs"
    );
    // The larger problem is built on the same estimator model.
    let larger = file("problems/larger.json");
    let (ok, _, err) = export(&["--model", &model, "--kalman", &kf, "--problem", &larger]);
    assert!(ok, "{err}");
    // The augmented filter's plant part must be the model.
    let foreign = foreign_model();
    let (ok, _, err) = export(&["--model", &foreign, "--kalman", &kf, "--problem", &thesis]);
    assert!(!ok, "an 8-state filter of another plant was accepted");
    assert!(err.contains(&kf) && err.contains(&foreign), "{err}");
    // The 8-state problem with the model's own 5-state filter, or the
    // 8-state filter with the default (5-state) problem: refused, saying
    // what to give.
    let own = kalman_of(&model, "report-model-kalman.json");
    let (ok, _, err) = export(&["--model", &model, "--kalman", &own, "--problem", &thesis]);
    assert!(!ok && err.contains(&thesis) && err.contains(&own), "{err}");
    let (ok, _, err) = export(&["--model", &model, "--kalman", &kf]);
    assert!(
        !ok && err.contains(&kf) && err.contains("--problem"),
        "{err}"
    );
    std::fs::remove_dir_all(&report).unwrap();
}
