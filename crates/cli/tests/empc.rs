//! End-to-end tests of `kestrel empc solve|eval|export` on good and malformed files.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn kestrel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
}

fn dir() -> PathBuf {
    common::temp_dir("empc")
}

fn file(name: &str, text: &str) -> PathBuf {
    let p = dir().join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `kestrel empc eval --solution SOL --thetas THETAS EXTRA...`.
fn eval(sol: &Path, thetas: &Path, extra: &[&str]) -> Output {
    kestrel()
        .args(["empc", "eval", "--solution"])
        .arg(sol)
        .arg("--thetas")
        .arg(thetas)
        .args(extra)
        .output()
        .unwrap()
}

/// The comma-separated numbers `kestrel empc eval` printed, one row per line.
fn csv_rows(o: &Output) -> Vec<Vec<f64>> {
    String::from_utf8(o.stdout.clone())
        .unwrap()
        .lines()
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// min 1/2 |z|^2 + theta'z on the box |z_i| <= 1: z = clamp(-theta), 9 regions.
const BOX2: &str = r#"{"format": "kestrel.mpqp.v1",
  "H": [[1, 0], [0, 1]], "F": [[1, 0], [0, 1]],
  "G": [[1, 0], [0, 1], [-1, 0], [0, -1]], "W": [1, 1, 1, 1],
  "E": [[0, 0], [0, 0], [0, 0], [0, 0]],
  "theta_lb": [-3, -3], "theta_ub": [3, 3]}"#;

fn solve_box(name: &str, extra: &[&str]) -> PathBuf {
    let prob = file(&format!("{name}-problem.json"), BOX2);
    let out = dir().join(format!("{name}-solution.json"));
    let o = kestrel()
        .args(["empc", "solve", "--problem"])
        .arg(&prob)
        .arg("--out")
        .arg(&out)
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    out
}

#[test]
fn solve_eval_export() {
    // Without clipping the tree separates the 9 laws; with clipping (the
    // default) one leaf holds z = -theta, clamped to the box: same answers.
    for (name, extra) in [("box", &["--no-clipping"][..]), ("clipped", &[][..])] {
        solve_eval_export_one(name, extra);
    }
}

fn solve_eval_export_one(name: &str, extra: &[&str]) {
    let sol = solve_box(name, extra);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&sol).unwrap()).unwrap();
    assert_eq!(v["format"], "kestrel.empc.v1");
    assert_eq!(v["regions"], 9);
    assert_eq!(v["distinct_laws"], 9);
    assert!(v["solve_seconds"].as_f64().unwrap() > 0.0);
    if extra.is_empty() {
        assert_eq!(v["tree"]["nodes"].as_u64().unwrap(), 0);
    } else {
        assert!(v["tree"]["depth"].as_u64().unwrap() >= 2);
        assert!(v["tree"]["nodes"].as_u64().unwrap() >= 4);
    }
    assert!(v["tree"]["bytes"].as_u64().unwrap() > 0);
    assert_eq!(v["region_list"].as_array().unwrap().len(), 9);

    let thetas = file(
        &format!("{name}-thetas.csv"),
        "0.5, -0.25\n2, -3\n-1.5,0.75\n10,0\n",
    );
    let o = eval(&sol, &thetas, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = csv_rows(&o);
    let want = [[-0.5, 0.25], [-1.0, 1.0], [1.0, -0.75], [-1.0, 0.0]];
    assert_eq!(rows.len(), 4);
    for (r, w) in rows.iter().zip(want) {
        for j in 0..2 {
            assert!((r[j] - w[j]).abs() < 1e-12, "{r:?} vs {w:?}");
        }
    }
    // The last theta is outside the box: flagged on stderr.
    assert!(stderr(&o).contains("1 of 4 parameters lie outside"));

    for scalar in ["f32", "q16"] {
        let out = dir().join(format!("{name}-tables-{scalar}.rs"));
        let o = kestrel()
            .args(["empc", "export", "--solution"])
            .arg(&sol)
            .args(["--scalar", scalar, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        let src = std::fs::read_to_string(&out).unwrap();
        assert!(src.contains("pub static TABLES: kestrel_empc::SliceTables<'static,"));
        assert!(src.contains("pub static NODES: [[u16; 4];"));
    }
}

#[test]
fn first_move_only() {
    let sol = solve_box("first", &["--first-move", "1", "--no-regions"]);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&sol).unwrap()).unwrap();
    assert_eq!(v["regions"], 9);
    assert_eq!(v["distinct_laws"], 3); // z_0 = clamp(-theta_0): three laws
    assert!(v.get("region_list").is_none());
    let thetas = file("first.csv", "0.5,2\n");
    let o = eval(&sol, &thetas, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(String::from_utf8(o.stdout).unwrap().trim(), "-0.5");
}

#[test]
fn help_names_inputs_and_outputs() {
    for (sub, words) in [
        (
            "solve",
            ["kestrel.mpqp.v1", "kestrel.empc.v1", "--no-clipping"],
        ),
        ("eval", ["CSV", "one row per theta", "--thetas"]),
        ("export", ["SliceTables", "static", "--scalar"]),
    ] {
        let o = kestrel().args(["empc", sub, "--help"]).output().unwrap();
        assert!(o.status.success());
        let text = String::from_utf8_lossy(&o.stdout);
        for w in words {
            assert!(
                text.contains(w),
                "`kestrel empc {sub} --help` lacks {w:?}:\n{text}"
            );
        }
    }
}

#[test]
fn bad_inputs_give_clear_errors() {
    let run = |args: &[&str], files: &[&PathBuf]| {
        let mut c = kestrel();
        c.args(args);
        for f in files {
            c.arg(f);
        }
        c.output().unwrap()
    };
    let indefinite = file(
        "indef.json",
        &BOX2.replace("[[1, 0], [0, 1]], \"F\"", "[[1, 0], [0, -1]], \"F\""),
    );
    let o = run(&["empc", "solve", "--problem"], &[&indefinite]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("H is not positive definite"),
        "{}",
        stderr(&o)
    );

    let empty = file(
        "empty.json",
        &BOX2.replace("\"W\": [1, 1, 1, 1]", "\"W\": [-1, 1, -1, 1]"),
    );
    let o = run(&["empc", "solve", "--problem"], &[&empty]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("feasible set is empty"),
        "{}",
        stderr(&o)
    );

    let unbounded = file(
        "unbounded.json",
        &BOX2.replace("\"theta_ub\": [3, 3]", "\"theta_ub\": [3, 1e13]"),
    );
    let o = run(&["empc", "solve", "--problem"], &[&unbounded]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("parameter set is unbounded"),
        "{}",
        stderr(&o)
    );

    let sol = solve_box("bad", &["--no-clipping"]);
    let thetas = file("short.csv", "1\n");
    let o = run(&["empc", "eval", "--solution"], &[&sol]);
    assert!(!o.status.success()); // --thetas missing
    let o = eval(&sol, &thetas, &[]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("row 1 has 1 values, expected 2"),
        "{}",
        stderr(&o)
    );
    let nan = file("nan.csv", "1,nan\n");
    let o = eval(&sol, &nan, &[]);
    assert!(
        stderr(&o).contains("column 2: expected a finite number"),
        "{}",
        stderr(&o)
    );

    // A corrupted node table is rejected before evaluation.
    let text = std::fs::read_to_string(&sol).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["tables"]["nodes"][0][0] = serde_json::json!(999);
    let broken = file("broken.json", &v.to_string());
    let o = kestrel()
        .args(["empc", "export", "--solution"])
        .arg(&broken)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(stderr(&o).contains("node 0"), "{}", stderr(&o));
    let wrong = file("wrong.json", r#"{"format": "kestrel.ss.v1"}"#);
    let o = kestrel()
        .args(["empc", "export", "--solution"])
        .arg(&wrong)
        .output()
        .unwrap();
    assert!(stderr(&o).contains("kestrel.empc.v1"), "{}", stderr(&o));
}

#[test]
fn compact_layout_in_the_solution_file() {
    let read = |p: &PathBuf| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let plain = read(&solve_box("plain", &["--no-regions"]));
    let v = read(&solve_box("compact", &["--no-regions", "--compact"]));
    // The default layout is unchanged; the compact one is added.
    assert_eq!(plain["tree"], v["tree"]);
    assert_eq!(plain["tables"], v["tables"]);
    assert!(plain.get("tree_compact").is_none());
    // z_i = clamp(-theta_i): three laws per output, one tree each.
    let t = &v["tree_compact"];
    assert_eq!(t["laws_per_output"], serde_json::json!([3, 3]));
    assert_eq!(
        v["compact_tables"]["roots"].as_array().unwrap().len(),
        2,
        "{t}"
    );
    let bytes = t["bytes"].as_u64().unwrap();
    assert!(bytes > 0 && bytes < plain["tree"]["bytes"].as_u64().unwrap());
}

#[test]
fn compact_layout_eval_and_export() {
    let sol = solve_box("cmp", &["--no-regions", "--compact"]);
    // 400 parameters on a grid over and beyond the box: the compact layout
    // answers as the default tree, row for row.
    let mut csv = String::new();
    for i in 0..20 {
        for j in 0..20 {
            let _ = std::fmt::Write::write_fmt(
                &mut csv,
                format_args!("{},{}\n", -3.5 + 0.37 * i as f64, 3.6 - 0.33 * j as f64),
            );
        }
    }
    let thetas = file("cmp.csv", &csv);
    let eval_rows = |extra: &[&str]| {
        let o = eval(&sol, &thetas, extra);
        assert!(o.status.success(), "{}", stderr(&o));
        (csv_rows(&o), stderr(&o))
    };
    let (default, warn_default) = eval_rows(&[]);
    let (compact, warn_compact) = eval_rows(&["--compact"]);
    assert_eq!(default.len(), 400);
    assert_eq!(warn_default, warn_compact); // the same parameters flagged outside
    for (a, b) in default.iter().zip(&compact) {
        for j in 0..2 {
            assert!((a[j] - b[j]).abs() <= 1e-12, "{a:?} vs {b:?}");
        }
    }
    for scalar in ["f32", "f64", "q16"] {
        let out = dir().join(format!("cmp-tables-{scalar}.rs"));
        let o = kestrel()
            .args(["empc", "export", "--compact", "--solution"])
            .arg(&sol)
            .args(["--scalar", scalar, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        let src = std::fs::read_to_string(&out).unwrap();
        assert!(src.contains("pub static TABLES: kestrel_empc::ForestTables<'static,"));
        assert!(src.contains("pub static ROOTS: [u16; 2]"));
        assert!(src.contains("pub static NODES: [kestrel_empc::CompactNode;"));
    }
    // Without `solve --compact` the solution has no compact tables: a clear error.
    let plain = solve_box("cmp-plain", &["--no-regions"]);
    for sub in [&["export"][..], &["eval", "--thetas", "x.csv"][..]] {
        let o = kestrel()
            .arg("empc")
            .args(sub)
            .args(["--compact", "--solution"])
            .arg(&plain)
            .output()
            .unwrap();
        assert!(!o.status.success());
        assert!(stderr(&o).contains("compact_tables"), "{}", stderr(&o));
    }
}

#[test]
fn tree_method_and_node_cap() {
    // Both tree methods give the same answers (here z = clamp(-theta)).
    let thetas = file("methods.csv", "0.5,-0.25\n2,-3\n-1.5,0.75\n");
    let mut outputs = Vec::new();
    for method in ["lp", "sampled"] {
        let sol = solve_box(
            &format!("method-{method}"),
            &["--no-clipping", "--tree-method", method],
        );
        let o = eval(&sol, &thetas, &[]);
        assert!(o.status.success(), "{}", stderr(&o));
        outputs.push(String::from_utf8(o.stdout).unwrap());
    }
    assert_eq!(outputs[0], outputs[1]);
    assert_eq!(outputs[0].lines().next().unwrap(), "-0.5,0.25");
    // A node cap the tree exceeds is a clear error, not a truncated tree.
    let prob = file("cap-problem.json", BOX2);
    let o = kestrel()
        .args(["empc", "solve", "--no-clipping", "--tree-method", "sampled"])
        .args(["--max-nodes", "2", "--problem"])
        .arg(&prob)
        .output()
        .unwrap();
    assert!(!o.status.success());
    // It names the flag, not the library's setting.
    assert!(stderr(&o).contains("--max-nodes 2"), "{}", stderr(&o));
    // An unknown method is rejected by the argument parser.
    let o = kestrel()
        .args(["empc", "solve", "--tree-method", "fastest", "--problem"])
        .arg(&prob)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--tree-method"), "{}", stderr(&o));
}

#[test]
fn wide_layout_solve_eval_export() {
    // --layout u32 forces the wide tables (what trees beyond 32767 nodes
    // get with the default --layout auto): same answers as the u16 layout,
    // `tables.index = "u32"`, u32 arrays in the exported source.
    let thetas = file("wide.csv", "0.5,-0.25\n2,-3\n-1.5,0.75\n10,0\n0.1,2.5\n");
    let narrow = solve_box("layout-u16", &["--no-clipping"]);
    let wide = solve_box("layout-u32", &["--no-clipping", "--layout", "u32"]);
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (vn, vw) = (read(&narrow), read(&wide));
    assert!(vn["tables"].get("index").is_none());
    assert_eq!(vw["tables"]["index"], "u32");
    assert_eq!(vw["tree"]["nodes"], vn["tree"]["nodes"]);
    assert!(vw["tree"]["bytes"].as_u64() > vn["tree"]["bytes"].as_u64());
    let on = eval(&narrow, &thetas, &[]);
    let ow = eval(&wide, &thetas, &[]);
    assert!(ow.status.success(), "{}", stderr(&ow));
    assert_eq!(on.stdout, ow.stdout, "the same z, digit for digit");
    assert_eq!(csv_rows(&ow)[0], vec![-0.5, 0.25]);
    assert!(stderr(&ow).contains("1 of 5 parameters lie outside"));
    let out = dir().join("wide-tables.rs");
    let o = kestrel()
        .args(["empc", "export", "--solution"])
        .arg(&wide)
        .args(["--scalar", "f32", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let src = std::fs::read_to_string(&out).unwrap();
    assert!(src.contains("pub static NODES: [[u32; 4];"), "{src}");
    assert!(src.contains("kestrel_empc::eval::WideSliceTables<'static, f32>"));
    // --layout auto keeps u16 for a tree that fits; --compact needs u16.
    let auto = solve_box("layout-auto", &["--no-clipping", "--layout", "auto"]);
    assert!(read(&auto)["tables"].get("index").is_none());
    let prob = file("wide-compact.json", BOX2);
    let o = kestrel()
        .args(["empc", "solve", "--layout", "u32", "--compact", "--problem"])
        .arg(&prob)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--compact"), "{}", stderr(&o));
    // A corrupted wide file: a clear error naming the key.
    let mut v = vw.clone();
    v["tables"]["nodes"][0][2] = serde_json::json!(-3);
    let bad = file("wide-bad.json", &v.to_string());
    let o = eval(&bad, &thetas, &[]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("tables.nodes[0][2]"), "{}", stderr(&o));
}
