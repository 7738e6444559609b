//! End-to-end tests of `kestrel qp certify`.

mod common;

use common::{MODEL, kestrel, thesis_problem_of};

/// A folder of the test's own (tests run in parallel and some write
/// files of the same name), removed when dropped.
fn temp_dir() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

#[test]
fn certify_the_thesis_sized_problem_cold_and_warm() {
    let tmp = temp_dir();
    let dir = tmp.path();
    let problem = thesis_problem_of(MODEL, &dir.join("thesis.json"));
    let out = dir.join("cert.json");
    let (ok, stdout, err) = kestrel(&[
        "qp",
        "certify",
        problem.to_str().unwrap(),
        "--warm-step",
        "0.05",
        "--box-scale",
        "0.5",
        "--json",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(
        stdout.contains("cold start") && stdout.contains("warm start"),
        "{stdout}"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(v["format"], "kestrel.qp-certificate.v1");
    for start in ["cold", "warm"] {
        let c = &v[start];
        let worst = c["worst_iterations"].as_u64().unwrap();
        assert!(worst >= 1, "{start}: {c}");
        assert_eq!(c["worst_region"]["iterations"].as_u64(), Some(worst));
        assert_eq!(c["worst_region"]["theta"].as_array().unwrap().len(), 9);
        let hist: u64 = c["histogram"]
            .as_array()
            .unwrap()
            .iter()
            .map(|h| h.as_u64().unwrap())
            .sum();
        assert_eq!(hist, c["regions"].as_u64().unwrap());
    }
    assert_eq!(
        v["warm"]["worst_region"]["theta_prev"]
            .as_array()
            .unwrap()
            .len(),
        9
    );
}

#[test]
fn bad_flags_and_limits_are_clear_errors() {
    let tmp = temp_dir();
    let dir = tmp.path();
    let problem = thesis_problem_of(MODEL, &dir.join("thesis2.json"));
    let p = problem.to_str().unwrap();
    let (ok, _, err) = kestrel(&["qp", "certify", p, "--warm-step", "2"]);
    assert!(!ok && err.contains("warm_step"), "{err}");
    let (ok, _, err) = kestrel(&["qp", "certify", p, "--box-scale", "0"]);
    assert!(!ok && err.contains("--box-scale"), "{err}");
    let (ok, _, err) = kestrel(&["qp", "certify", p, "--max-regions", "10"]);
    assert!(!ok && err.contains("is estimated at"), "{err}");
    // The merged exact mode is refused up front too (its breadth-first
    // frontier would otherwise grow until the limits stop it).
    let args = ["qp", "certify", p, "--max-regions", "10", "--exact-merge"];
    let (ok, _, err) = kestrel(&args);
    assert!(!ok && err.contains("is estimated at"), "{err}");
    let args = [
        "qp",
        "certify",
        p,
        "--max-regions",
        "10",
        "--estimate-probes",
        "0",
    ];
    let (ok, _, err) = kestrel(&args);
    assert!(!ok && err.contains("region limit reached"), "{err}");
}

#[test]
fn merged_certificate_is_an_upper_bound_of_the_exact_one() {
    let tmp = temp_dir();
    let dir = tmp.path();
    let problem = thesis_problem_of(MODEL, &dir.join("thesis3.json"));
    let p = problem.to_str().unwrap();
    let read = |path: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    };
    let exact_out = dir.join("exact.json");
    let (ok, _, err) = kestrel(&[
        "qp",
        "certify",
        p,
        "--box-scale",
        "0.5",
        "--json",
        exact_out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let merged_out = dir.join("merged.json");
    let (ok, stdout, err) = kestrel(&[
        "qp",
        "certify",
        p,
        "--box-scale",
        "0.5",
        "--merge",
        "--warm-step",
        "0.05",
        "--json",
        merged_out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(
        stdout.contains("upper bound") && stdout.contains("worst chain"),
        "{stdout}"
    );
    let (e, m) = (read(&exact_out), read(&merged_out));
    assert_eq!(e["cold"]["exact"], true);
    assert_eq!(m["cold"]["exact"], false);
    assert_eq!(m["merge_history"], 2);
    assert!(e.get("merge_history").is_none());
    let worst = |v: &serde_json::Value, key: &str| v["cold"][key].as_u64().unwrap();
    assert!(worst(&m, "worst_iterations") >= worst(&e, "worst_iterations"));
    assert!(worst(&m, "worst_flops") >= worst(&e, "worst_flops"));
    assert!(m["warm"]["worst_iterations"].as_u64().unwrap() >= 1);
    assert!(m["cold"]["canonical_states"].as_u64().unwrap() >= 1);
    let (ok, _, err) = kestrel(&["qp", "certify", p, "--merge", "0"]);
    assert!(!ok && err.contains("merge"), "{err}");
}

#[test]
fn exact_merge_gives_the_exact_worst_case_with_fewer_regions() {
    let tmp = temp_dir();
    let dir = tmp.path();
    let problem = thesis_problem_of(MODEL, &dir.join("thesis4.json"));
    let p = problem.to_str().unwrap();
    let read = |path: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    };
    let mut docs = Vec::new();
    for (name, extra) in [("exact.json", None), ("union.json", Some("--exact-merge"))] {
        let out = dir.join(name);
        let mut args = vec![
            "qp",
            "certify",
            p,
            "--box-scale",
            "0.5",
            "--warm-step",
            "0.05",
        ];
        args.extend(extra);
        args.extend(["--json", out.to_str().unwrap()]);
        let (ok, stdout, err) = kestrel(&args);
        assert!(ok, "{err}");
        assert_eq!(stdout.contains("union merge:"), extra.is_some(), "{stdout}");
        docs.push(read(&out));
    }
    for start in ["cold", "warm"] {
        let (e, u) = (&docs[0][start], &docs[1][start]);
        assert_eq!(u["exact"], true);
        assert_eq!(u["worst_iterations"], e["worst_iterations"], "{start}");
        assert!(u["worst_flops"].as_u64() >= e["worst_flops"].as_u64());
        assert!(u["regions"].as_u64() <= e["regions"].as_u64());
        assert!(u["union_merge"]["merges"].as_u64().is_some());
        assert!(e.get("union_merge").is_none());
    }
    let (ok, _, err) = kestrel(&["qp", "certify", p, "--merge", "--exact-merge"]);
    assert!(!ok && err.contains("cannot be used"), "{err}");
}
