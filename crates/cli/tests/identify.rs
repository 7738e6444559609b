//! End-to-end tests of `kestrel identify` on generated logs.

mod common;

use kestrel_core::formats::SsModel;
use kestrel_sysid::synthetic;
use std::path::{Path, PathBuf};
use std::process::Command;

fn dir(name: &str) -> PathBuf {
    common::temp_dir(&format!("identify-{name}"))
}

/// A log `t,a,b,p` from a known 2nd-order model, 50 Hz, with offsets.
fn write_log(path: &Path, rows: usize, edit: impl Fn(usize, &mut Vec<String>)) {
    let m = synthetic::random_model(2, 2, 1, 9, 0.9);
    let d = synthetic::simulate(&m, rows, 0.05, 3).unwrap();
    let e = &d.experiments()[0];
    let mut text = String::from("t,a,b,p\n");
    for k in 0..rows {
        let mut f = vec![
            format!("{:.2}", k as f64 * 0.02),
            format!("{}", 1500.0 + e.u[(k, 0)]),
            format!("{}", -3.0 + e.u[(k, 1)]),
            format!("{}", 0.01 + e.y[(k, 0)]),
        ];
        edit(k, &mut f);
        text.push_str(&f.join(","));
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

fn kestrel(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .arg("identify")
        .args(args)
        .output()
        .unwrap()
}

/// `kestrel identify` on the log written by [`write_log`] (inputs `a`,
/// `b`, output `p`, order 1) with the `extra` flags.
fn identify_order_one(log: &Path, extra: &[&str]) -> std::process::Output {
    let l = log.display().to_string();
    let mut args = vec![
        "--data",
        &l,
        "--inputs",
        "a,b",
        "--outputs",
        "p",
        "--order",
        "1",
    ];
    args.extend_from_slice(extra);
    kestrel(&args)
}

/// The model a successful run printed on stdout.
fn printed_model(o: &std::process::Output) -> SsModel {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    SsModel::from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap()
}

#[test]
fn identifies_and_writes_ss_v1_with_offsets() {
    let d = dir("good");
    let log = d.join("log.csv");
    write_log(&log, 1500, |_, _| {});
    let out = d.join("model.json");
    let o = kestrel(&[
        "--data",
        log.to_str().unwrap(),
        "--inputs",
        "a,b",
        "--outputs",
        "p",
        "--estimate",
        "0:19.98",
        "--validate",
        "20:29.98",
        "--order",
        "3",
        "--reduce",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for want in [
        "model simulation",
        "persistence 5-step",
        "model 1-step",
        "residuals",
        "PEM:",
        "balred 3 -> 2",
        "PEM refit after balred",
    ] {
        assert!(stdout.contains(want), "missing {want:?} in\n{stdout}");
    }
    let m = SsModel::read(&out).unwrap();
    assert_eq!((m.nx(), m.nu(), m.ny()), (2, 2, 1));
    let u0 = m.u0.unwrap();
    assert!(
        (u0[0] - 1500.0).abs() < 0.5 && (u0[1] + 3.0).abs() < 0.5,
        "{u0:?}"
    );
    assert!(m.k.is_some() && m.y0.is_some());
    assert_eq!(m.inputs.unwrap(), vec!["a".to_string(), "b".to_string()]);
    // The simulation fit on validation data is high for a correct model.
    let line = stdout
        .lines()
        .find(|l| l.starts_with("model simulation"))
        .unwrap();
    let fit: f64 = line.split_whitespace().nth(2).unwrap().parse().unwrap();
    assert!(fit > 80.0, "{line}");
    // --after-reduction keep: balred's model as is, same dynamics, other K.
    let kept = d.join("kept.json");
    let mut args = vec![
        "--data",
        log.to_str().unwrap(),
        "--inputs",
        "a,b",
        "--outputs",
        "p",
        "--estimate",
        "0:19.98",
        "--validate",
        "20:29.98",
        "--order",
        "3",
        "--reduce",
        "2",
        "--after-reduction",
        "keep",
        "--out",
        kept.to_str().unwrap(),
    ];
    let o = kestrel(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!String::from_utf8_lossy(&o.stdout).contains("PEM refit after balred"));
    let k = SsModel::read(&kept).unwrap();
    assert!((&k.a - &m.a).amax() < 1e-9 * (1.0 + k.a.amax()));
    assert!((k.k.unwrap() - m.k.unwrap()).amax() > 1e-9);
    args[15] = "nonsense";
    let o = kestrel(&args);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--after-reduction"));
}

/// Two logs as two flights, intervals picked per flight with `N@`, the
/// two-stage focus; the table and the written model agree with a single-file
/// run on the same samples.
#[test]
fn several_files_with_per_flight_segments() {
    let d = dir("multi");
    let (a, b) = (d.join("a.csv"), d.join("b.csv"));
    write_log(&a, 1500, |_, _| {});
    write_log(&b, 800, |_, _| {});
    let data = format!("{},{}", a.display(), b.display());
    let o = kestrel(&[
        "--data",
        &data,
        "--inputs",
        "a,b",
        "--outputs",
        "p",
        "--estimate",
        "1@0:19.98",
        "--validate",
        "1@20:29.98,2@0:15.98",
        "--order",
        "2",
        "--focus",
        "simulation-then-noise",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("1000 estimation samples in 1 experiment(s), ts = 0.02 s"),
        "{err}"
    );
    assert!(err.contains("PEM noise model (K, dynamics fixed)"), "{err}");
    assert!(!err.contains("reaches beyond"), "{err}");
    let m = SsModel::from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
    assert_eq!((m.nx(), m.nu(), m.ny()), (2, 2, 1));
    let o = kestrel(&[
        "--data",
        &data,
        "--inputs",
        "a,b",
        "--outputs",
        "p",
        "--estimate",
        "3@0:10",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("2 experiment(s)"));
}

/// `--focus multi-step-then-noise --dynamics-horizon 3` runs both stages
/// and writes a model; a zero dynamics horizon is a clear error.
/// An interval reaching beyond the samples is said on standard error with
/// the part it takes (a mistyped end would otherwise pass unseen); the
/// model is the one of the interval cut to the samples.
#[test]
fn intervals_beyond_the_samples_are_noted() {
    let d = dir("beyond");
    let log = d.join("log.csv");
    write_log(&log, 1500, |_, _| {});
    let cut = identify_order_one(&log, &["--estimate", "0:19.98", "--validate", "20:29.98"]);
    let o = identify_order_one(&log, &["--estimate", "0:19.98", "--validate", "20:299.8"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(
            "note: --validate 20:299.8 reaches beyond the data's samples (0.000..29.980); it takes 20.000..29.980"
        ),
        "{err}"
    );
    assert_eq!(printed_model(&o), printed_model(&cut));
    assert!(!String::from_utf8_lossy(&cut.stderr).contains("reaches beyond"));
    // Per experiment, and at the start.
    let o = identify_order_one(&log, &["--estimate", "1@-5:19.98"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("note: --estimate 1@-5:19.98 reaches beyond experiment 1's samples (0.000..29.980); it takes 0.000..19.980"),
        "{err}"
    );
    assert!(o.status.success(), "{err}");
}

#[test]
fn multi_step_then_noise_focus() {
    let d = dir("multistep");
    let log = d.join("log.csv");
    write_log(&log, 1000, |_, _| {});
    let args = |h: &'static str| {
        vec![
            "--data".to_string(),
            log.display().to_string(),
            "--inputs".into(),
            "a,b".into(),
            "--outputs".into(),
            "p".into(),
            "--order".into(),
            "2".into(),
            "--focus".into(),
            "multi-step-then-noise".into(),
            "--dynamics-horizon".into(),
            h.into(),
        ]
    };
    let run = |a: Vec<String>| {
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        kestrel(&a)
    };
    let o = run(args("3"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("PEM noise model (K, dynamics fixed)"), "{err}");
    let m = SsModel::from_json_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
    assert_eq!((m.nx(), m.nu(), m.ny()), (2, 2, 1));
    let o = run(args("0"));
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("horizon"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `--criterion fit` weighs the prediction steps by their RMS error: a
/// different model from the trace on the same multi-step fit; an unknown
/// criterion is refused with the choices.
#[test]
fn criterion_flag() {
    let d = dir("criterion");
    let log = d.join("log.csv");
    write_log(&log, 1000, |_, _| {});
    let run = |criterion: &str| {
        identify_order_one(
            &log,
            &[
                "--focus",
                "multi-step-then-noise",
                "--dynamics-horizon",
                "4",
                "--criterion",
                criterion,
            ],
        )
    };
    let (fit, trace) = (printed_model(&run("fit")), printed_model(&run("trace")));
    assert_eq!((fit.nx(), fit.nu(), fit.ny()), (1, 2, 1));
    assert!((fit.a[(0, 0)] - trace.a[(0, 0)]).abs() > 1e-9);
    let o = run("median");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("determinant") && err.contains("fit"), "{err}");
}

/// `--n4sid-matrices state-regression` takes the N4SID matrices from the
/// state sequence: a different subspace model from the output-error
/// default; an unknown value is refused with the choices.
#[test]
fn n4sid_matrices_flag() {
    let d = dir("n4sid-matrices");
    let log = d.join("log.csv");
    write_log(&log, 1000, |_, _| {});
    let run = |matrices: &str| {
        identify_order_one(&log, &["--method", "n4sid", "--n4sid-matrices", matrices])
    };
    let sr = printed_model(&run("state-regression"));
    let oe = printed_model(&run("output-error"));
    assert_eq!((sr.nx(), sr.nu(), sr.ny()), (1, 2, 1));
    let gain = |m: &SsModel| m.c[(0, 0)] * m.b[(0, 0)] / (1.0 - m.a[(0, 0)]);
    assert!((gain(&sr) - gain(&oe)).abs() > 1e-9);
    assert!((gain(&sr) - gain(&oe)).abs() < 0.1 * gain(&oe).abs());
    let o = run("both");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("state-regression"), "{err}");
}

#[test]
fn bad_logs_give_clear_errors() {
    let d = dir("bad");
    type Edit = Box<dyn Fn(usize, &mut Vec<String>)>;
    struct Case {
        name: &'static str,
        edit: Edit,
        rows: usize,
        extra: Vec<&'static str>,
        want: &'static str,
    }
    let case = |name, edit: Edit, rows, extra, want| Case {
        name,
        edit,
        rows,
        extra,
        want,
    };
    let cases = vec![
        case(
            "nan",
            Box::new(|k, f: &mut Vec<String>| {
                if k == 7 {
                    f[3] = "NaN".into()
                }
            }),
            500,
            vec![],
            "line 9",
        ),
        case(
            "short",
            Box::new(|_, _: &mut Vec<String>| {}),
            30,
            vec!["--order", "8"],
            "too few samples",
        ),
        case(
            "const",
            Box::new(|_, f: &mut Vec<String>| f[2] = "4".into()),
            500,
            vec![],
            "\"b\" is constant",
        ),
        case(
            "ragged",
            Box::new(|k, f: &mut Vec<String>| {
                if k == 3 {
                    f.pop();
                }
            }),
            500,
            vec![],
            "line 5",
        ),
    ];
    for Case {
        name,
        edit,
        rows,
        extra,
        want,
    } in cases
    {
        let log = d.join(format!("{name}.csv"));
        write_log(&log, rows, edit);
        let mut args = vec![
            "--data",
            log.to_str().unwrap(),
            "--inputs",
            "a,b",
            "--outputs",
            "p",
        ];
        args.extend(extra);
        let o = kestrel(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{name} should fail");
        assert!(err.contains(want), "{name}: {err}");
    }
    let log = d.join("ok.csv");
    write_log(&log, 300, |_, _| {});
    let o = kestrel(&[
        "--data",
        log.to_str().unwrap(),
        "--inputs",
        "a,zz",
        "--outputs",
        "p",
    ]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("no column \"zz\""));
    let o = kestrel(&[
        "--data",
        log.to_str().unwrap(),
        "--inputs",
        "a,b",
        "--outputs",
        "p",
        "--estimate",
        "9:3",
    ]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("start < end"));
}

/// Issue 20, finding 11: a `t` column in milliseconds gave ts = 20 s, and
/// a log without `t` and without `--ts` gave ts = 1 s, both silently. A
/// step of 1 s or more now needs the unit stated (`--time-unit ms`, or
/// `--time-unit s` for a log that is really sampled that slowly), and a
/// log without `t` needs `--ts`.
#[test]
fn the_sample_time_is_never_guessed() {
    let d = dir("time-unit");
    let ms = d.join("ms.csv");
    write_log(&ms, 1500, |k, f| f[0] = format!("{}", k * 20));
    let o = identify_order_one(&ms, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "a 20 s step was accepted");
    assert!(
        err.contains("ms.csv") && err.contains("20 s") && err.contains("--time-unit ms"),
        "{err}"
    );
    assert_eq!(
        printed_model(&identify_order_one(&ms, &["--time-unit", "ms"])).ts,
        0.02
    );
    // Stated seconds: a slow log is taken as it is.
    assert_eq!(
        printed_model(&identify_order_one(&ms, &["--time-unit", "s"])).ts,
        20.0
    );

    // No `t` column: --ts is required, and then used.
    let no_t = d.join("no-t.csv");
    write_log(&no_t, 1500, |_, _| {});
    let text = std::fs::read_to_string(&no_t).unwrap();
    let stripped: String = text
        .lines()
        .map(|l| l.split_once(',').unwrap().1.to_string() + "\n")
        .collect();
    std::fs::write(&no_t, stripped).unwrap();
    let o = identify_order_one(&no_t, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "ts = 1 s was guessed");
    assert!(
        err.contains("no-t.csv") && err.contains("no time column") && err.contains("--ts"),
        "{err}"
    );
    assert_eq!(
        printed_model(&identify_order_one(&no_t, &["--ts", "0.02"])).ts,
        0.02
    );
    // --ts and a `t` column that disagree: refused, naming both.
    let log = d.join("log.csv");
    write_log(&log, 1500, |_, _| {});
    let o = identify_order_one(&log, &["--ts", "0.01"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("0.01") && err.contains("0.02"),
        "{err}"
    );
    assert_eq!(
        printed_model(&identify_order_one(&log, &["--ts", "0.02"])).ts,
        0.02
    );
}
