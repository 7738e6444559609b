//! End-to-end tests of `kestrel qp solve`: the dual active-set solver at
//! given parameters, against a closed form, the explicit law and the
//! certificate.

mod common;

use common::{MODEL, kestrel, thesis_problem_of};
use std::path::{Path, PathBuf};

/// A folder of the test's own, removed when dropped.
fn temp_dir() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// `count` parameters spread over the box `[lb, ub]` (a Kronecker
/// sequence: fractional parts of multiples of square roots of primes).
fn spread(lb: &[f64], ub: &[f64], count: usize) -> Vec<Vec<f64>> {
    let primes = [2.0_f64, 3.0, 5.0, 7.0, 11.0, 13.0, 17.0, 19.0, 23.0, 29.0];
    (1..=count)
        .map(|k| {
            (0..lb.len())
                .map(|j| {
                    let a = (k as f64 * primes[j % primes.len()].sqrt()).fract();
                    lb[j] + a * (ub[j] - lb[j])
                })
                .collect()
        })
        .collect()
}

fn write_rows(path: &Path, rows: &[Vec<f64>]) {
    let text: String = rows
        .iter()
        .map(|r| {
            let cells: Vec<String> = r.iter().map(|v| format!("{v:?}")).collect();
            cells.join(",") + "\n"
        })
        .collect();
    std::fs::write(path, text).unwrap();
}

fn read_rows(path: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect()
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn numbers(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `kestrel qp solve` with the given extra flags into `out`.
fn solve(problem: &Path, thetas: &Path, out: &Path, extra: &[&str]) -> (bool, String) {
    let mut args = vec![
        "qp",
        "solve",
        "--problem",
        problem.to_str().unwrap(),
        "--thetas",
        thetas.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let (ok, _, err) = kestrel(&args);
    (ok, err)
}

/// Diagonal H and bounds only: the optimum is the unconstrained one
/// clipped to the bounds, exactly; warm and f32 too.
#[test]
fn solutions_equal_the_clipped_optimum_of_a_separable_problem() {
    let tmp = temp_dir();
    let dir = tmp.path();
    // min z0^2 + 2 z1^2 + t0 z0 + t1 z1, -1 <= z0 <= 1 + t2, -0.5 <= z1 <= 0.5.
    let problem = dir.join("sep.json");
    std::fs::write(
        &problem,
        r#"{"format": "kestrel.mpqp.v1", "H": [[2, 0], [0, 4]],
        "F": [[1, 0], [0, 1], [0, 0]],
        "G": [[1, 0], [-1, 0], [0, 1], [0, -1]], "W": [1, 1, 0.5, 0.5],
        "E": [[0, 0, 1], [0, 0, 0], [0, 0, 0], [0, 0, 0]],
        "theta_lb": [-6, -6, 0], "theta_ub": [6, 6, 1]}"#,
    )
    .unwrap();
    let thetas = spread(&[-6.0, -6.0, 0.0], &[6.0, 6.0, 1.0], 400);
    let exact: Vec<[f64; 2]> = thetas
        .iter()
        .map(|t| {
            [
                (-t[0] / 2.0).clamp(-1.0, 1.0 + t[2]),
                (-t[1] / 4.0).clamp(-0.5, 0.5),
            ]
        })
        .collect();
    let input = dir.join("thetas.csv");
    write_rows(&input, &thetas);
    for (flags, tol) in [
        (&[][..], 1e-15),
        (&["--warm"][..], 1e-15),
        (&["--f32"][..], 1e-6),
        (&["--warm", "--f32"][..], 1e-6),
    ] {
        let out = dir.join("z.csv");
        let mut all = flags.to_vec();
        all.extend(["--with-iterations", "--force"]);
        let (ok, err) = solve(&problem, &input, &out, &all);
        assert!(ok, "{flags:?}: {err}");
        assert!(err.contains("400 parameters solved"), "{err}");
        let rows = read_rows(&out);
        assert_eq!(rows.len(), 400);
        for (r, e) in rows.iter().zip(&exact) {
            assert_eq!(r.len(), 3, "z0, z1, iterations");
            for j in 0..2 {
                assert!(
                    (r[j] - e[j]).abs() <= tol * (1.0 + e[j].abs()),
                    "{flags:?}: {r:?} {e:?}"
                );
            }
        }
        if !flags.contains(&"--warm") {
            // From a cold start, one change per clipped variable.
            for ((r, e), t) in rows.iter().zip(&exact).zip(&thetas) {
                let free = [-t[0] / 2.0, -t[1] / 4.0];
                let clipped = (0..2).filter(|&j| e[j] != free[j]).count();
                assert_eq!(r[2], clipped as f64, "{flags:?}: {r:?} {t:?}");
            }
        }
    }
}

/// With general rows (20 of 28): the exact solution equals the explicit
/// law's (kestrel empc, a different algorithm) to 1e-9 relative, cold and
/// warm.
#[test]
fn solutions_equal_the_explicit_law() {
    let tmp = temp_dir();
    let dir = tmp.path();
    let problem = repo().join("crates/empc/tests/data/noconverge-seed4.mpqp.json");
    let p = read_json(&problem);
    let (lb, ub) = (numbers(&p["theta_lb"]), numbers(&p["theta_ub"]));
    let input = dir.join("thetas.csv");
    write_rows(&input, &spread(&lb, &ub, 1000));
    let sol = dir.join("sol.json");
    let (ok, _, err) = kestrel(&[
        "empc",
        "solve",
        "--problem",
        problem.to_str().unwrap(),
        "--out",
        sol.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let explicit = dir.join("explicit.csv");
    let (ok, _, err) = kestrel(&[
        "empc",
        "eval",
        "--solution",
        sol.to_str().unwrap(),
        "--thetas",
        input.to_str().unwrap(),
        "--out",
        explicit.to_str().unwrap(),
    ]);
    assert!(ok && !err.contains("warning"), "{err}");
    let reference = read_rows(&explicit);
    for flags in [&[][..], &["--warm"][..]] {
        let out = dir.join("z.csv");
        let mut all = flags.to_vec();
        all.push("--force");
        let (ok, err) = solve(&problem, &input, &out, &all);
        assert!(ok && !err.contains("warning"), "{err}");
        let rows = read_rows(&out);
        assert_eq!(rows.len(), reference.len());
        for (r, e) in rows.iter().zip(&reference) {
            let scale = e.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
            for (a, b) in r.iter().zip(e) {
                assert!((a - b).abs() <= 1e-9 * scale, "{flags:?}: {r:?} {e:?}");
            }
        }
    }
}

/// The certificate's worst region: its interior point takes exactly the
/// certified iterations, and no parameter of the box more.
#[test]
fn the_certified_worst_case_is_met_and_never_exceeded() {
    let tmp = temp_dir();
    let dir = tmp.path();
    let problem = thesis_problem_of(MODEL, &dir.join("thesis.json"));
    let cert = dir.join("cert.json");
    let (ok, _, err) = kestrel(&[
        "qp",
        "certify",
        problem.to_str().unwrap(),
        "--json",
        cert.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let c = read_json(&cert);
    let worst = c["cold"]["worst_iterations"].as_f64().unwrap();
    let worst_theta = numbers(&c["cold"]["worst_region"]["theta"]);
    // The worst case is rare (a few small regions of the partition): a
    // spread of the box need not meet it, the worst region's point does.
    assert!(worst >= 5.0, "{c}");
    let p = read_json(&problem);
    let (lb, ub) = (numbers(&p["theta_lb"]), numbers(&p["theta_ub"]));
    let mut thetas = vec![worst_theta];
    thetas.extend(spread(&lb, &ub, 2000));
    let input = dir.join("thetas.csv");
    write_rows(&input, &thetas);
    let out = dir.join("z.csv");
    let (ok, err) = solve(&problem, &input, &out, &["--with-iterations"]);
    assert!(ok, "{err}");
    let rows = read_rows(&out);
    let iterations: Vec<f64> = rows.iter().map(|r| *r.last().unwrap()).collect();
    assert_eq!(iterations[0], worst, "the worst region's point");
    assert!(iterations.iter().all(|&k| k <= worst), "{iterations:?}");
}

/// A theta with no feasible z, a short row and an existing output are
/// errors naming what is wrong, and nothing is written; a parameter
/// outside the set is solved with a warning.
#[test]
fn bad_parameters_are_named_and_nothing_is_written() {
    let tmp = temp_dir();
    let dir = tmp.path();
    // z0 + z1 <= t, z >= -1: infeasible for t < -2.
    let problem = dir.join("p.json");
    std::fs::write(
        &problem,
        r#"{"format": "kestrel.mpqp.v1", "H": [[1, 0], [0, 1]], "F": [[1, 1]],
        "G": [[1, 1], [-1, 0], [0, -1]], "W": [0, 1, 1], "E": [[1], [0], [0]],
        "theta_lb": [-1], "theta_ub": [1]}"#,
    )
    .unwrap();
    let input = dir.join("thetas.csv");
    let out = dir.join("z.csv");
    // Lines are the file's (the blank one counted), not row indices.
    std::fs::write(&input, "0.5\n\n-10\n").unwrap();
    let (ok, err) = solve(&problem, &input, &out, &[]);
    assert!(!ok, "{err}");
    assert!(
        err.contains("thetas.csv: line 3: the constraints are infeasible"),
        "{err}"
    );
    assert!(!out.exists(), "a half-written output");
    std::fs::write(&input, "0.5\n0.5,1\n").unwrap();
    let (ok, err) = solve(&problem, &input, &out, &[]);
    assert!(!ok && err.contains("line 2"), "{err}");
    assert!(!out.exists());
    // Outside the box but feasible: solved, with a warning.
    std::fs::write(&input, "\n0.5\n-1.5\n").unwrap();
    let (ok, err) = solve(&problem, &input, &out, &[]);
    assert!(ok, "{err}");
    assert!(
        err.contains("warning: 1 of 2 parameters lie outside") && err.contains("line 3"),
        "{err}"
    );
    // The free optimum (-t, -t) = (1.5, 1.5) projected onto z0 + z1 <= -1.5.
    let rows = read_rows(&out);
    assert!(rows[1].iter().all(|v| (v + 0.75).abs() < 1e-12), "{rows:?}");
    // The output exists now: refused without --force, left as it was.
    let before = std::fs::read(&out).unwrap();
    let (ok, err) = solve(&problem, &input, &out, &[]);
    assert!(!ok && err.contains("--force"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), before);
}
