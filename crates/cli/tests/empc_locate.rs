//! End-to-end tests of `kestrel empc solve --locate` and `--no-tree`: the
//! candidate lists answer as the exact tree does, `auto` picks the lists
//! above 200 regions, a solution without point location is refused by
//! `eval` and `export` with a message saying why, and the stages show with
//! `--progress`.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn dir() -> PathBuf {
    common::temp_dir("empc-locate")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `kestrel empc ARGS...`.
fn empc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .arg("empc")
        .args(args)
        .output()
        .unwrap()
}

/// Writes `testing::scaled_thesis(seed, horizon, free_moves)` (9 parameters).
fn problem(name: &str, seed: u64, horizon: usize, free_moves: usize) -> PathBuf {
    let p = dir().join(format!("{name}.mpqp.json"));
    let prob = kestrel_empc::testing::scaled_thesis(seed, horizon, free_moves);
    std::fs::write(&p, prob.to_json_string()).unwrap();
    p
}

fn solve(prob: &Path, name: &str, extra: &[&str]) -> (PathBuf, Output) {
    let out = dir().join(format!("{name}.empc.json"));
    let (p, o) = (prob.to_str().unwrap(), out.to_str().unwrap());
    let mut args = vec!["solve", "--problem", p, "--out", o];
    args.extend_from_slice(extra);
    let res = empc(&args);
    assert!(res.status.success(), "{}", stderr(&res));
    (out, res)
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Parameters inside the box (states in [-2, 2], references in [-1, 1],
/// throttle in [-0.3, 0.3]), from a fixed sequence.
fn thetas(n: usize) -> PathBuf {
    let mut text = String::new();
    let mut x = 0.5f64;
    for _ in 0..n {
        let row: Vec<String> = (0..9)
            .map(|j| {
                x = (x * 3.7 + 0.123).fract();
                let half = [2.0, 2.0, 2.0, 2.0, 2.0, 1.0, 1.0, 1.0, 0.3][j];
                format!("{}", (2.0 * x - 1.0) * half * 0.98)
            })
            .collect();
        text.push_str(&row.join(","));
        text.push('\n');
    }
    let p = dir().join("thetas.csv");
    std::fs::write(&p, text).unwrap();
    p
}

fn eval_rows(sol: &Path, th: &Path) -> Vec<Vec<f64>> {
    let o = empc(&[
        "eval",
        "--solution",
        sol.to_str().unwrap(),
        "--thetas",
        th.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

#[test]
fn lists_answer_as_the_tree_does() {
    let prob = problem("small", 1, 2, 1); // 75 regions
    let (tree, _) = solve(
        &prob,
        "small-tree",
        &["--first-move", "4", "--locate", "tree"],
    );
    let (lists, o) = solve(
        &prob,
        "small-lists",
        &["--first-move", "4", "--locate", "lists", "--progress"],
    );
    let err = stderr(&o);
    for stage in [
        "[1/3] exploring",
        "[2/3] point location for 75 regions",
        "[3/3] writing",
    ] {
        assert!(err.contains(stage), "{err}");
    }
    assert!(err.contains("candidate lists: depth"), "{err}");
    let (t, l) = (json(&tree), json(&lists));
    assert!(t.get("tables").is_some() && t.get("lists").is_none());
    assert!(l.get("tables").is_none() && l.get("tree").is_none());
    assert_eq!(l["locate"]["method"], "lists");
    assert_eq!(l["regions"], 75);
    assert_eq!(l["outputs"], 4);
    assert!(l["locate"]["bytes"].as_u64().unwrap() > 0);
    assert!(l["locate"]["worst_case_mul_adds"].as_u64().unwrap() > 0);
    let th = thetas(300);
    let (a, b) = (eval_rows(&tree, &th), eval_rows(&lists, &th));
    assert_eq!((a.len(), b.len()), (300, 300));
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.len(), 4);
        for (u, v) in x.iter().zip(y) {
            assert!((u - v).abs() <= 1e-9 * (1.0 + u.abs()), "{x:?} vs {y:?}");
        }
    }
    // Rust source of the lists: a static ListSlices.
    let o = empc(&[
        "export",
        "--solution",
        lists.to_str().unwrap(),
        "--scalar",
        "f32",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let src = String::from_utf8(o.stdout).unwrap();
    assert!(
        src.contains("kestrel_empc::ListSlices<'static, f32"),
        "{}",
        &src[..src.len().min(400)]
    );
    let o = empc(&["export", "--solution", lists.to_str().unwrap(), "--compact"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("candidate lists"), "{}", stderr(&o));
    // The compact layout is a tree layout.
    let o = empc(&[
        "solve",
        "--problem",
        prob.to_str().unwrap(),
        "--locate",
        "lists",
        "--compact",
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--compact"), "{}", stderr(&o));
}

#[test]
fn auto_takes_the_lists_above_200_regions_and_the_tree_below() {
    let small = problem("auto-small", 1, 2, 1); // 75 regions
    let (sol, _) = solve(&small, "auto-small", &["--first-move", "4", "--no-regions"]);
    let v = json(&sol);
    assert!(v.get("tables").is_some() && v["tree"]["nodes"].as_u64().unwrap() > 1);
    let large = problem("auto-large", 0, 5, 2); // 437 regions
    let (sol, _) = solve(&large, "auto-large", &["--first-move", "4", "--no-regions"]);
    let v = json(&sol);
    assert_eq!(v["regions"], 437);
    assert_eq!(v["locate"]["method"], "lists");
    assert!(v.get("region_list").is_none());
    assert_eq!(eval_rows(&sol, &thetas(20)).len(), 20);
}

#[test]
fn no_tree_writes_the_regions_alone() {
    let prob = problem("alone", 1, 2, 1);
    let (sol, o) = solve(&prob, "alone", &["--no-tree"]);
    assert!(
        stderr(&o).contains("no point location (--no-tree)"),
        "{}",
        stderr(&o)
    );
    let v = json(&sol);
    assert_eq!(v["format"], "kestrel.empc.v1");
    assert_eq!(v["regions"], 75);
    assert_eq!(v["region_list"].as_array().unwrap().len(), 75);
    assert!(v["stats"]["lps"].as_u64().unwrap() > 0);
    assert!(v.get("tables").is_none() && v.get("lists").is_none());
    let th = thetas(2);
    for sub in ["eval", "export"] {
        let mut args = vec![sub, "--solution", sol.to_str().unwrap()];
        if sub == "eval" {
            args.extend(["--thetas", th.to_str().unwrap()]);
        }
        let o = empc(&args);
        assert!(!o.status.success());
        assert!(stderr(&o).contains("--no-tree"), "{sub}: {}", stderr(&o));
    }
    // Nothing would be left to write.
    let o = empc(&[
        "solve",
        "--problem",
        prob.to_str().unwrap(),
        "--no-tree",
        "--no-regions",
    ]);
    assert!(!o.status.success());
}
