//! End-to-end tests of `kestrel pipeline`: a shortened run whose report is
//! checked for internal consistency, and malformed inputs that must stop
//! the command without leaving a report behind.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn kestrel() -> Command {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
}

fn scratch(name: &str) -> PathBuf {
    let d = common::temp_dir(&format!("pipeline-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Reads a CSV table written by the report: header and rows.
fn read_table(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut rdr =
        csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let headers = rdr.headers().unwrap().iter().map(str::to_string).collect();
    let rows = rdr
        .records()
        .map(|r| r.unwrap().iter().map(str::to_string).collect())
        .collect();
    (headers, rows)
}

fn col(headers: &[String], name: &str) -> usize {
    headers
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {headers:?}"))
}

fn num(s: &str) -> f64 {
    s.trim()
        .parse()
        .unwrap_or_else(|_| panic!("not a number: {s:?}"))
}

#[test]
fn quick_pipeline_report_is_complete_and_consistent() {
    let base = scratch("quick");
    let out = base.join("report");
    let o = kestrel()
        .args(["pipeline", "--quick", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "pipeline failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    // Files present and parseable.
    for f in [
        "report.md",
        "summary.json",
        "config.toml",
        "flight-1-hover.csv",
        "flight-2-decoupled.csv",
        "flight-3-coupled.csv",
        "flight-4-ground.csv",
        "kalman.json",
        "firmware/empc_tables.rs",
        "firmware/fgm_tables.rs",
        "firmware/generated.rs",
        "firmware/kalman.json",
        "figures/partition.svg",
        "figures/kalman.svg",
        "figures/blackbox-simulation.svg",
        "figures/blackbox-residuals.svg",
        "figures/closed-loop-step-pwm.svg",
    ] {
        assert!(out.join(f).is_file(), "missing {f}");
    }
    for m in [
        "models/blackbox-5.json",
        "models/virtual-5.json",
        "models/blackbox-8.json",
    ] {
        let model = kestrel_core::formats::SsModel::read(&out.join(m)).unwrap();
        assert_eq!(model.ny(), 3, "{m}");
    }
    let bb = kestrel_core::formats::SsModel::read(&out.join("models/blackbox-5.json")).unwrap();
    assert_eq!((bb.nx(), bb.nu()), (5, 4));
    // theta = [x (5); d (3, offset-free); r (3); throttle].
    for p in ["problems/thesis.json", "problems/larger.json"] {
        let prob = kestrel_core::formats::MpqpProblem::read(&out.join(p)).unwrap();
        assert_eq!(prob.p(), 5 + 3 + 3 + 1, "{p}");
    }
    let thesis =
        kestrel_core::formats::MpqpProblem::read(&out.join("problems/thesis.json")).unwrap();
    assert_eq!(thesis.n(), 4);
    let larger =
        kestrel_core::formats::MpqpProblem::read(&out.join("problems/larger.json")).unwrap();
    assert_eq!(larger.n(), 16);
    for entry in std::fs::read_dir(out.join("figures")).unwrap() {
        let p = entry.unwrap().path();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(
            text.starts_with("<svg") && text.trim_end().ends_with("</svg>"),
            "{}",
            p.display()
        );
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    for section in 1..=11 {
        assert!(
            md.contains(&format!("\n## {section}. ")),
            "section {section} missing"
        );
    }

    // Explicit MPC equals the QP: at the Table 7.2 state ...
    let (h, rows) = read_table(&out.join("tables/table_7_2.csv"));
    let find = |name: &str| rows.iter().find(|r| r[0] == name).unwrap().clone();
    let (qp, ex) = (find("QP (clarabel)"), find("explicit MPC"));
    let jstar = num(&qp[col(&h, "J(U, theta)")]);
    for u in ["U1 [us]", "U2 [us]", "U3 [us]", "U4 [us]"] {
        let (a, b) = (num(&qp[col(&h, u)]), num(&ex[col(&h, u)]));
        assert!((a - b).abs() <= 2e-3, "{u}: QP {a}, explicit {b}");
    }
    assert!((num(&ex[col(&h, "J(U, theta)")]) - jstar).abs() <= 1e-5 * (1.0 + jstar.abs()));
    // The exact active-set solver too, with its iteration count.
    let active = find("active set (kestrel-qp)");
    for u in ["U1 [us]", "U2 [us]", "U3 [us]", "U4 [us]"] {
        let (a, b) = (num(&qp[col(&h, u)]), num(&active[col(&h, u)]));
        assert!((a - b).abs() <= 2e-3, "{u}: QP {a}, active set {b}");
    }
    assert!((num(&active[col(&h, "J(U, theta)")]) - jstar).abs() <= 1e-5 * (1.0 + jstar.abs()));
    assert!(active[col(&h, "iterations")].parse::<usize>().is_ok());
    // ... and at the random parameters of the check table.
    let (h2, rows2) = read_table(&out.join("tables/explicit_check.csv"));
    let dz = num(&rows2[0][col(&h2, "max |z_explicit - z_QP| [us]")]);
    assert!(dz < 0.05, "explicit vs QP: {dz} us");
    assert!(
        num(&rows2[0][col(&h2, "outside explored set")]) < num(&rows2[0][col(&h2, "random theta")])
    );

    // Certified fast-gradient iterations meet their eps: in the check table ...
    let (h, rows) = read_table(&out.join("tables/fgm_certificates.csv"));
    assert!(rows.len() >= 5);
    for r in &rows {
        let eps = num(r[col(&h, "eps")].split_whitespace().next().unwrap());
        let gap = num(&r[col(&h, "max J(z_i) - J*")]);
        assert!(gap <= eps * (1.0 + 1e-9) + 1e-6, "{r:?}");
        assert_eq!(r[col(&h, "holds")], "yes");
    }
    // ... and in Table 7.2, where the certified rows have an eps.
    let (h, rows) = read_table(&out.join("tables/table_7_2.csv"));
    let mut certified = 0;
    for r in rows.iter().filter(|r| r[0] == "fast gradient") {
        let eps_cell = &r[col(&h, "eps")];
        if eps_cell == "(fixed)" {
            continue;
        }
        let eps = num(eps_cell.split_whitespace().next().unwrap());
        let gap = num(&r[col(&h, "J - J*")]);
        assert!(gap <= eps * (1.0 + 1e-9) + 1e-6, "{r:?}");
        assert!(
            gap >= -1e-6 * (1.0 + jstar.abs()),
            "below the optimum: {r:?}"
        );
        certified += 1;
    }
    assert!(certified >= 4);
    // More iterations never leave a worse certified bound than fewer.
    assert_eq!(summary["fgm_all_certificates_hold"], true);

    // Closed-loop inputs within limits, read from every trace.
    let mut traces = 0;
    for entry in std::fs::read_dir(out.join("closed-loop")).unwrap() {
        let p = entry.unwrap().path();
        let (h, rows) = read_table(&p);
        assert!(rows.len() > 50, "{}", p.display());
        for r in &rows {
            for m in ["pwm1", "pwm2", "pwm3"] {
                let v = num(&r[col(&h, m)]);
                assert!(
                    (1000.0 - 1e-9..=2000.0 + 1e-9).contains(&v),
                    "{}: {m} = {v}",
                    p.display()
                );
            }
            let s = num(&r[col(&h, "servo")]);
            let (lo, hi) = kestrel_tricopter_model::SERVO_PWM_RANGE;
            assert!(
                s >= lo - 1e-9 && s <= hi + 1e-9,
                "{}: servo = {s}",
                p.display()
            );
            for v in ["p", "q", "r"] {
                assert!(num(&r[col(&h, v)]).is_finite());
            }
        }
        traces += 1;
    }
    // PI, QP, explicit and two FGM counts, step and noisy.
    assert_eq!(traces, 2 * 5);
    // The MPC laws track the step scenario: 90 % of each step reached
    // (a finite 10-90 % rise time) on every axis, in calm air and noisy.
    let (h, rows) = read_table(&out.join("tables/closed_loop.csv"));
    for r in rows.iter().filter(|r| r[1] == "QP" || r[1] == "explicit") {
        let rise: Vec<f64> = r[col(&h, "rise time p/q/r [s]")]
            .split(" / ")
            .map(num)
            .collect();
        assert_eq!(rise.len(), 3, "{r:?}");
        assert!(rise.iter().all(|t| t.is_finite() && *t > 0.0), "{r:?}");
    }
    assert_eq!(summary["closed_loop_max_bound_violation"], 0.0);
    // The report replaced the staging directory: nothing else left beside it.
    let left: Vec<_> = std::fs::read_dir(&base)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 1, "{left:?}");
    std::fs::remove_dir_all(&base).unwrap();
}

fn assert_fails_without_report(args: &[&str], base: &Path, expect: &[&str]) {
    let out = base.join("report");
    let o = kestrel()
        .args(args)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "should fail");
    for e in expect {
        assert!(err.contains(e), "stderr does not name {e:?}: {err}");
    }
    assert!(!out.exists(), "a report was left behind");
    let left: Vec<_> = std::fs::read_dir(base)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("report"))
        .collect();
    assert!(left.is_empty(), "staging left behind: {left:?}");
}

const DEFAULT: &str = include_str!("../kestrel.toml");

#[test]
fn malformed_config_stops_with_file_and_key() {
    let base = scratch("config");
    // An unknown key.
    let bad = base.join("typo.toml");
    std::fs::write(
        &bad,
        DEFAULT.replace("reduced_order = 5", "reduced_ordre = 5"),
    )
    .unwrap();
    let bad_s = bad.to_str().unwrap();
    assert_fails_without_report(
        &["pipeline", "--config", bad_s],
        &base,
        &[bad_s, "reduced_ordre"],
    );
    // A wrong type.
    std::fs::write(
        &bad,
        DEFAULT.replace("seconds = 250.0", "seconds = \"long\""),
    )
    .unwrap();
    assert_fails_without_report(&["pipeline", "--config", bad_s], &base, &[bad_s, "seconds"]);
    // A bad value.
    std::fs::write(
        &bad,
        DEFAULT.replace("larger = { horizon = 10", "larger = { horizon = 12"),
    )
    .unwrap();
    assert_fails_without_report(
        &["pipeline", "--config", bad_s],
        &base,
        &[bad_s, "mpc.larger"],
    );
    // Not TOML at all.
    std::fs::write(&bad, "[experiments\nseconds = 1").unwrap();
    assert_fails_without_report(&["pipeline", "--config", bad_s], &base, &[bad_s]);
    // Missing file.
    let missing = base.join("none.toml");
    assert_fails_without_report(
        &["pipeline", "--config", missing.to_str().unwrap()],
        &base,
        &["none.toml"],
    );
    // The committed file is the built-in default.
    let good = base.join("default.toml");
    let o = kestrel()
        .args(["pipeline", "--print-config"])
        .output()
        .unwrap();
    assert!(o.status.success());
    assert_eq!(String::from_utf8(o.stdout).unwrap(), DEFAULT);
    std::fs::write(&good, DEFAULT).unwrap();
    std::fs::remove_dir_all(&base).unwrap();
}

#[test]
fn malformed_flight_log_stops_with_file_line_and_column() {
    let base = scratch("flights");
    let dir = base.join("logs");
    std::fs::create_dir_all(&dir).unwrap();
    let header = "t,pwm1,pwm2,pwm3,servo,throttle,u_roll,u_pitch,u_yaw,p,q,r,airborne";
    let good = "0,1500,1500,1500,1500,1500,0,0,0,0,0,0,0";
    std::fs::write(
        dir.join("flight-1-hover.csv"),
        format!("{header}\n{good}\n0.02,1500,1500,abc,1500,1500,0,0,0,0,0,0,0\n"),
    )
    .unwrap();
    let d = dir.to_str().unwrap();
    assert_fails_without_report(
        &["pipeline", "--flights", d],
        &base,
        &["flight-1-hover.csv", "line 3", "pwm3"],
    );
    // A missing column.
    std::fs::write(dir.join("flight-1-hover.csv"), "t,pwm1\n0,1500\n").unwrap();
    assert_fails_without_report(
        &["pipeline", "--flights", d],
        &base,
        &["flight-1-hover.csv", "pwm2"],
    );
    // A missing file.
    std::fs::remove_file(dir.join("flight-1-hover.csv")).unwrap();
    assert_fails_without_report(
        &["pipeline", "--flights", d],
        &base,
        &["flight-1-hover.csv"],
    );
    std::fs::remove_dir_all(&base).unwrap();
}

/// The estimator the report tunes (stage 4) is the one the closed loop
/// flies (stage 9) and the one the firmware tables carry (stage 10): the
/// same measurement-update gain, bit for bit, on the `--quick`
/// configuration; the firmware's `kestrel.kalman.v1` text reads back to
/// the same gain exactly.
#[test]
fn report_filter_is_flown_and_flashed() {
    let cfg: kestrel_tricopter::pipeline::Config = toml::from_str(DEFAULT).unwrap();
    let res = kestrel_tricopter::pipeline::run(&cfg.quick(), None).unwrap();
    let tuned = res.kalman.gain();
    // The filter is the MPC's estimator: its state is the problem's x (and d).
    let layout = &res.problems.thesis.problem.layout;
    assert_eq!(tuned.shape(), (layout.nx, 3));
    assert_eq!(
        res.kalman.design.kalman.nx(),
        res.problems.estimator_model.nx()
    );
    // Tuned on the measured gyro statistics, not the thesis's constants.
    let r = &res.kalman.design.kalman.r;
    assert_eq!(r, &res.sensor.covariance);
    assert_eq!(res.kalman.design.kalman.bias.as_slice(), &res.sensor.bias);
    // Flown: every MPC run of the closed loop.
    let mut mpc_runs = 0;
    for run in &res.closed_loop.runs {
        match &run.estimator_gain {
            Some(g) => {
                assert_eq!(g, tuned, "{:?} {:?}", run.kind, run.controller);
                mpc_runs += 1;
            }
            None => assert_eq!(
                run.controller,
                kestrel_tricopter::pipeline::closed_loop::Controller::Pi
            ),
        }
    }
    assert!(mpc_runs >= 6, "{mpc_runs} MPC runs");
    // Flashed: the firmware's filter and its file.
    assert_eq!(&res.firmware.kalman.filter.m, tuned);
    let back = kestrel_kalman::KalmanDesign::from_json_str(&res.firmware.kalman_json).unwrap();
    assert_eq!(&back.filter.m, tuned);
    assert_eq!(back.filter.l, res.kalman.design.kalman.filter.l);
    assert_eq!((&back.r, &back.bias), (r, &res.kalman.design.kalman.bias));
    // ... and the firmware's table file: its design's f64 gains are the
    // tuned gain bit for bit, its 16-bit rows are that gain quantised row by
    // row (`quantize_row`: c = round(m 2^shift)), within half a step.
    let fw = &res.firmware.design;
    assert_eq!(&fw.kalman.filter.m, tuned);
    assert_eq!(
        fw.nx(),
        8,
        "the quick configuration is offset-free: 5 + 3 states"
    );
    let g = fw.gains::<8>().unwrap();
    for i in 0..8 {
        for j in 0..3 {
            assert_eq!(g.m.data[i][j].to_bits(), tuned[(i, j)].to_bits());
        }
    }
    let q = &res.firmware.kalman16;
    assert_eq!(q.m.len(), 8);
    for (i, row) in q.m.iter().enumerate() {
        let want: Vec<f64> = tuned.row(i).iter().copied().collect();
        assert_eq!(
            row,
            &kestrel_tricopter::firmware::quantize_row(&want).unwrap()
        );
        let step = 2f64.powi(-i32::from(row.shift));
        for (c, m) in row.c.iter().zip(&want) {
            assert!(
                (f64::from(*c) * step - m).abs() <= 0.5 * step,
                "row {i}: {c} vs {m}"
            );
        }
    }
    assert!(res.firmware.tables_source.contains("KF16"));
}
