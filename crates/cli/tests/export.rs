//! End-to-end tests of `kestrel export` (firmware tables from design files).

mod common;

use common::{kestrel, temp_dir};
use kestrel_core::formats::SsModel;
use kestrel_fgm::{BoxQp, FgmDesign, FgmSettings, eps_for_input_error};
use std::path::{Path, PathBuf};

fn dir() -> PathBuf {
    temp_dir("export-cli")
}

fn write(name: &str, text: &str) -> String {
    let p = dir().join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

fn fixture() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../models/tricopter-blackbox-5.json")
        .display()
        .to_string()
}

/// `pub const NAME: usize = V;` from the generated source.
fn usize_const(src: &str, name: &str) -> usize {
    let key = format!("pub const {name}: usize = ");
    let at = src.find(&key).unwrap_or_else(|| panic!("{name} in output")) + key.len();
    src[at..].split(';').next().unwrap().parse().unwrap()
}

/// The f32 table from the generated source.
fn values_f32(src: &str) -> Vec<f64> {
    let start = src.find("pub const VALUES_F32").unwrap();
    let body = &src[start..];
    let body = &body[body.find("= [").unwrap() + 3..body.find("];").unwrap()];
    body.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect()
}

/// The rows `Row16::new([c...], shift, start)` of block `name` of `KF16`,
/// dequantised (`c / 2^shift`).
fn kf16_rows(src: &str, name: &str) -> Vec<Vec<f64>> {
    let kf = &src[src.find("pub const KF16").unwrap()..];
    let block = &kf[kf.find(&format!("    {name}: [")).unwrap()..];
    let block = &block[..block.find("    ],").unwrap()];
    block
        .lines()
        .filter(|l| l.contains("Row16::new(["))
        .map(|l| {
            let inner = &l[l.find("([").unwrap() + 2..];
            let (coefs, rest) = inner.split_once("],").unwrap();
            let shift: i32 = rest.split(',').next().unwrap().trim().parse().unwrap();
            coefs
                .split(',')
                .map(|c| c.trim().parse::<f64>().unwrap() / 2f64.powi(shift))
                .collect()
        })
        .collect()
}

#[test]
fn tables_hold_the_model_filter_and_certified_solver() {
    let out = dir().join("generated.rs");
    let (ok, _, err) = kestrel(&[
        "export",
        "--model",
        &fixture(),
        "--realization",
        "as-given",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let src = std::fs::read_to_string(&out).unwrap();
    let model = SsModel::read(Path::new(&fixture())).unwrap();
    let v = values_f32(&src);
    assert_eq!(v.len(), usize_const(&src, "N_VALUES"));
    let nx = usize_const(&src, "NX");
    assert_eq!(nx, model.nx());
    // The filter's A - I and C are the model's (the file's numbers, to the
    // 16-bit rows' resolution: half a step of a row whose largest entry
    // uses at least 15 bits).
    let a = kf16_rows(&src, "a");
    let c = kf16_rows(&src, "c");
    assert_eq!((a.len(), c.len()), (nx, 3));
    let check = |got: &[Vec<f64>], want: &dyn Fn(usize, usize) -> f64, what: &str| {
        for (i, row) in got.iter().enumerate() {
            let max = (0..nx).map(|j| want(i, j).abs()).fold(0.0, f64::max);
            for (j, g) in row.iter().enumerate() {
                let err = (g - want(i, j)).abs();
                assert!(
                    err <= 1.01 * max / 32768.0 + 1e-15,
                    "{what}[{i}][{j}]: {err}"
                );
            }
        }
    };
    check(
        &a,
        &|i, j| model.a[(i, j)] - if i == j { 1.0 } else { 0.0 },
        "A - I",
    );
    check(&c, &|i, j| model.c[(i, j)], "C");
    // The mixer trim is the model's u0 around the mean motor pulse (the
    // hover throttle), the servo absolute.
    let u0 = model.u0.clone().unwrap();
    let throttle = (u0[0] + u0[1] + u0[2]) / 3.0;
    let mix = usize_const(&src, "MIX_OFFSET");
    for i in 0..3 {
        assert!((v[mix + i] - (u0[i] - throttle)).abs() < 1e-3);
    }
    assert!((v[mix + 3] - u0[3]).abs() < 1e-3);
    // The certified count is kestrel-fgm's for the 1 us eps of this
    // problem, computed here from kestrel-mpc's problem directly.
    let (q1, q2) = kestrel_tricopter::default_weights();
    let problem = kestrel_tricopter::tricopter_problem(
        &model,
        kestrel_tricopter::ProblemSize::Thesis,
        q1,
        q2,
    )
    .unwrap();
    let fgm = FgmDesign::new(
        BoxQp::from_mpqp(&problem.to_mpqp()).unwrap(),
        FgmSettings::default(),
    )
    .unwrap();
    let cert = fgm
        .certify(eps_for_input_error(fgm.preconditioning.before.mu, 1.0))
        .unwrap();
    assert_eq!(usize_const(&src, "FGM_ITERATIONS"), cert.iterations);
    assert_eq!(usize_const(&src, "FGM_LOOP_ITERATIONS"), cert.iterations);
    assert_eq!(
        (usize_const(&src, "NZ"), usize_const(&src, "NP")),
        (4, nx + 4)
    );
    // A looser accuracy needs no more iterations.
    let (ok, loose, err) = kestrel(&["export", "--model", &fixture(), "--max-input-error", "20"]);
    assert!(ok, "{err}");
    assert!(usize_const(&loose, "FGM_ITERATIONS") <= cert.iterations);
}

#[test]
fn design_files_give_the_same_tables_as_the_defaults() {
    let model = SsModel::read(Path::new(&fixture())).unwrap();
    let kalman = kestrel_tricopter::closed_loop::kalman_design(&model).unwrap();
    let (q1, q2) = kestrel_tricopter::default_weights();
    let problem = kestrel_tricopter::tricopter_problem(
        &model,
        kestrel_tricopter::ProblemSize::Thesis,
        q1,
        q2,
    )
    .unwrap()
    .to_mpqp();
    let kf = write("filter.json", &kalman.to_json_string());
    let pr = write("problem.json", &problem.to_json_string());
    let (ok, from_files, err) = kestrel(&[
        "export",
        "--model",
        &fixture(),
        "--kalman",
        &kf,
        "--problem",
        &pr,
    ]);
    assert!(ok, "{err}");
    let (ok, defaults, err) =
        kestrel(&["export", "--model", &fixture(), "--realization", "as-given"]);
    assert!(ok, "{err}");
    // JSON round trips are exact (float_roundtrip), so the tables agree to
    // the last digit except where the SDP preconditioner is re-solved.
    let (a, b) = (values_f32(&from_files), values_f32(&defaults));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert!(
            (x - y).abs() <= 1e-5 * x.abs().max(y.abs()).max(1e-6),
            "{x} vs {y}"
        );
    }
}

/// `--qp-out` writes the `qp` build's tables with the firmware tables:
/// for the repository's model they are the committed files `kestrel
/// codegen` generates, byte for byte; the pair is written together or not
/// at all.
#[test]
fn qp_tables_are_written_beside_the_firmware_tables() {
    let d = dir().join("qp-out");
    std::fs::create_dir_all(&d).unwrap();
    let (out, qp) = (d.join("generated.rs"), d.join("generated_qp.rs"));
    let (o, q) = (out.display().to_string(), qp.display().to_string());
    let qp16 = d.join("generated_qp16.rs");
    let q16 = qp16.display().to_string();
    let args = [
        "export",
        "--model",
        &fixture(),
        "--out",
        &o,
        "--qp-out",
        &q,
        "--qp16-out",
        &q16,
    ];
    let (ok, _, err) = kestrel(&args);
    assert!(ok, "{err}");
    assert!(
        err.contains("the qp build's tables") && err.contains("4 variables"),
        "{err}"
    );
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../avr/firmware/src");
    let committed = |name: &str| std::fs::read_to_string(repo.join(name)).unwrap();
    for (file, name) in [
        (&qp, "generated_qp.rs"),
        (&qp16, "generated_qp16.rs"),
        (&out, "generated.rs"),
    ] {
        assert_eq!(
            std::fs::read_to_string(file).unwrap(),
            committed(name),
            "{name}"
        );
    }
    // The QP file exists now: without --force nothing is written, not even
    // the firmware tables to a new name.
    let fresh = d.join("other.rs");
    let f = fresh.display().to_string();
    let (ok, _, err) = kestrel(&["export", "--model", &fixture(), "--out", &f, "--qp-out", &q]);
    assert!(!ok && err.contains("--force"), "{err}");
    assert!(!fresh.exists());
    // The fixed-point build is sized for the thesis's problem: the larger
    // one is refused, nothing written.
    let args = [
        "export",
        "--model",
        &fixture(),
        "--size",
        "larger",
        "--out",
        &f,
        "--qp16-out",
        &q16,
    ];
    let (ok, _, err) = kestrel(&[&args[..], &["--force"]].concat());
    assert!(
        !ok && err.contains("--qp16-out") && err.contains("(16, 9)"),
        "{err}"
    );
    assert!(!fresh.exists());
    assert_eq!(
        std::fs::read_to_string(&qp16).unwrap(),
        committed("generated_qp16.rs")
    );
    // Rust only.
    let c = d.join("c").display().to_string();
    let args = [
        "export",
        "--model",
        &fixture(),
        "--lang",
        "c",
        "--out",
        &c,
        "--qp-out",
        &f,
    ];
    let (ok, _, err) = kestrel(&args);
    assert!(
        !ok && err.contains("--qp-out") && err.contains("--lang rust"),
        "{err}"
    );
    assert!(!fresh.exists() && !d.join("c").exists());
}

#[test]
fn malformed_design_files_are_refused_with_a_reason() {
    // A model with the wrong inputs.
    let m = write(
        "two_inputs.json",
        r#"{"format": "kestrel.ss.v1", "ts": 0.02, "A": [[0.9]], "B": [[1, 1]],
            "C": [[1], [1], [1]], "D": [[0, 0], [0, 0], [0, 0]]}"#,
    );
    let (ok, _, err) = kestrel(&["export", "--model", &m]);
    assert!(!ok);
    assert!(err.contains("inputs"), "{err}");
    // A continuous-time model.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture()).unwrap()).unwrap();
    v["ts"] = serde_json::json!(0.0);
    let c = write("continuous.json", &v.to_string());
    let (ok, _, err) = kestrel(&["export", "--model", &c]);
    assert!(!ok);
    assert!(err.contains("continuous") || err.contains("ts"), "{err}");
    // A problem whose parameters are not [x; r; throttle].
    let p = write(
        "problem.json",
        r#"{"format": "kestrel.mpqp.v1", "H": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],
            "F": [[1,0,0,0]], "G": [[1,0,0,0]], "W": [1], "E": [[0]],
            "theta_lb": [-1], "theta_ub": [1]}"#,
    );
    let (ok, _, err) = kestrel(&["export", "--model", &fixture(), "--problem", &p]);
    assert!(!ok);
    assert!(err.contains("parameters"), "{err}");
    // A Kalman file of another format, a missing file, a bad accuracy.
    let (ok, _, err) = kestrel(&["export", "--model", &fixture(), "--kalman", &fixture()]);
    assert!(!ok);
    assert!(err.contains("format"), "{err}");
    let (ok, _, err) = kestrel(&["export", "--model", "/nonexistent/model.json"]);
    assert!(!ok && err.contains("nonexistent"), "{err}");
    for bad in ["0", "-1", "NaN"] {
        let flag = format!("--max-input-error={bad}");
        let (ok, _, err) = kestrel(&["export", "--model", &fixture(), &flag]);
        assert!(!ok);
        assert!(err.contains("max_input_error"), "{bad}: {err}");
    }
    let (ok, _, err) = kestrel(&["export", "--model", &fixture(), "--warm-iterations", "0"]);
    assert!(!ok && err.contains("zero iterations"), "{err}");
}

/// A model whose inputs are not the tricopter's (a quadrotor's four
/// motors) is exported as asked, with a note saying how the example
/// firmware drives them; the tricopter's own model gets no note.
#[test]
fn other_input_names_are_noted() {
    let (ok, _, err) = kestrel(&["export", "--model", &fixture()]);
    assert!(ok, "{err}");
    assert!(!err.contains("note:"), "{err}");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture()).unwrap()).unwrap();
    v["inputs"] = serde_json::json!(["m1", "m2", "m3", "m4"]);
    let m = write("quad_names.json", &v.to_string());
    let (ok, out, err) = kestrel(&["export", "--model", &m]);
    assert!(ok, "{err}");
    assert!(out.contains("pub const NX: usize"));
    assert!(
        err.contains("note:") && err.contains("m1, m2, m3, m4") && err.contains("tail servo"),
        "{err}"
    );
}

#[test]
fn help_says_what_goes_in_and_out() {
    let (ok, out, _) = kestrel(&["export", "--help"]);
    assert!(ok);
    for word in [
        "kestrel.ss.v1",
        "kestrel.kalman.v1",
        "kestrel.mpqp.v1",
        "Rust source",
        "--out",
    ] {
        assert!(out.contains(word), "--help lacks {word}");
    }
}
