//! Sections 9 (closed loop) and 10 (firmware tables).

use super::fmt::{f3, j3};
use crate::report::document::Report;
use crate::report::plot::{Panel, Series, panels_svg};
use crate::report::table::Table;
use kestrel_tricopter::pipeline::PipelineResult;
use kestrel_tricopter::pipeline::closed_loop::{Controller, RunKind};
use kestrel_tricopter::pipeline::config::FirmwareScalar;

/// Rise times `a / b / c`, "not reached" where the rate never crossed
/// 90 % of its step.
fn rise_times(v: &[f64]) -> String {
    v.iter()
        .map(|&x| {
            if x.is_finite() {
                f3(x)
            } else {
                "not reached".to_string()
            }
        })
        .collect::<Vec<_>>()
        .join(" / ")
}

/// Section 9: closed-loop runs on the nonlinear tricopter.
pub fn section(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    let cl = &res.closed_loop;
    let cfg = &res.config.closed_loop;
    let k = &res.kalman;
    r.text("\n## 9. Closed loop on the nonlinear tricopter (section 7.7)\n");
    let mut t = Table::new([
        "run",
        "controller",
        "rise time p/q/r [s]",
        "overshoot p/q/r [%]",
        "RMS error p/q/r [rad/s]",
        "effort pwm1/2/3/servo [us]",
        "pwm range [us]",
        "servo range [us]",
        "bound violation [us]",
        "trace",
    ]);
    for run in &cl.runs {
        let c = run.controller.name();
        let file = format!("closed-loop/{}-{}.csv", run.kind.as_str(), c.to_lowercase());
        r.write(&file, run.trace.to_csv())?;
        let m = &run.metrics;
        t.row([
            run.kind.as_str().to_string(),
            c,
            if m.diverged.is_some() {
                "diverged".to_string()
            } else {
                rise_times(&m.rise_time)
            },
            if m.diverged.is_some() {
                "diverged".to_string()
            } else {
                j3(&m.overshoot)
            },
            j3(&m.rms_error),
            j3(&m.effort),
            format!("{:.0}..{:.0}", run.pwm_range.0, run.pwm_range.1),
            format!("{:.0}..{:.0}", run.servo_range.0, run.servo_range.1),
            f3(m.max_bound_violation),
            format!("`{file}`"),
        ]);
    }
    r.text(format!(
        "The identified black-box model's MPC (thesis-sized problem) flies kestrel-tricopter-model's \
         nonlinear aircraft with the Kalman filter of section 4 (`kalman.json`, {} states, the gyro \
         bias and covariance of section 2): released at {:?} rad/s, a step to {:?} rad/s at {} s, {} s \
         in all. `step`: no gyro noise or gusts (7.7.1); `noisy`: gyro noise, bias and gusts, seed {} \
         (figures 7.18-7.21). The baseline is the ACRO rate PI of kestrel-tricopter-model. FGM-k: the \
         fast gradient method with k iterations, cold start.",
        k.design.kalman.nx(),
        cfg.initial_rates,
        cfg.step,
        cfg.step_time,
        cfg.duration,
        cfg.seed
    ));
    r.table(
        "closed_loop",
        "Closed-loop runs against the baseline PI",
        &t,
    )?;
    // Figures 7.16-7.17: the step scenario, outputs and pulses.
    let rate_panels = |kind: RunKind, ctrls: &[Controller]| -> Vec<Panel> {
        (0..3)
            .map(|j| {
                let mut series = Vec::new();
                if let Some(run) = cl.run(kind, ctrls[0]) {
                    series.push(Series::dashed(
                        "reference",
                        run.trace
                            .rows
                            .iter()
                            .map(|w| (w.t, w.reference[j]))
                            .collect(),
                    ));
                }
                for c in ctrls {
                    if let Some(run) = cl.run(kind, *c) {
                        series.push(Series::line(
                            c.name(),
                            run.trace.rows.iter().map(|w| (w.t, w.rates[j])).collect(),
                        ));
                    }
                }
                Panel {
                    title: ["p", "q", "r"][j].into(),
                    x_label: "time [s]".into(),
                    y_label: "rad/s".into(),
                    series,
                    hlines: vec![],
                }
            })
            .collect()
    };
    let main = [Controller::Qp, Controller::Explicit, Controller::Pi];
    panels_svg(
        &r.path("figures/closed-loop-step-rates.svg"),
        "Step scenario: body rates",
        &rate_panels(RunKind::Step, &main),
    )?;
    r.figure(
        "figures/closed-loop-step-rates.svg",
        "Step scenario, body rates: MPC (QP, explicit) and the baseline PI (figures 7.16a-7.17a)",
    );
    let pwm_panels: Vec<Panel> = (0..4)
        .map(|i| Panel {
            title: ["pwm1", "pwm2", "pwm3", "servo"][i].into(),
            x_label: "time [s]".into(),
            y_label: "us".into(),
            series: main
                .iter()
                .filter_map(|c| {
                    cl.run(RunKind::Step, *c).map(|run| {
                        Series::line(
                            c.name(),
                            run.trace.rows.iter().map(|w| (w.t, w.pwm[i])).collect(),
                        )
                    })
                })
                .collect(),
            hlines: if i < 3 {
                vec![(1000.0, "limits".into()), (2000.0, "limits".into())]
            } else {
                vec![]
            },
        })
        .collect();
    panels_svg(
        &r.path("figures/closed-loop-step-pwm.svg"),
        "Step scenario: pulses",
        &pwm_panels,
    )?;
    r.figure(
        "figures/closed-loop-step-pwm.svg",
        "Step scenario, pulses (figures 7.16b-7.17b)",
    );
    for k in &cfg.fgm_iterations {
        let ctrls = [Controller::Qp, Controller::Explicit, Controller::Fgm(*k)];
        let name = format!("figures/closed-loop-noisy-fgm-{k}.svg");
        panels_svg(
            &r.path(&name),
            &format!(
                "Noisy run: QP, explicit MPC and the fast gradient method with {k} iterations"
            ),
            &rate_panels(RunKind::Noisy, &ctrls),
        )?;
        r.figure(
            &name,
            &format!("Noisy run with {k} fast-gradient iterations (figures 7.18-7.21)"),
        );
    }
    Ok(())
}

/// Section 10: firmware tables.
pub fn firmware(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    let fw = &res.firmware;
    r.text("\n## 10. Firmware tables (section 7.8)\n");
    let mut t = Table::new(["file", "what", "scalar", "bytes of source"]);
    let name = match fw.scalar {
        FirmwareScalar::F32 => "f32",
        FirmwareScalar::Q16 => "q16",
    };
    r.write("firmware/empc_tables.rs", &fw.empc_source)?;
    t.row([
        "`firmware/empc_tables.rs`".to_string(),
        format!(
            "explicit MPC search tree, first move ({} bytes of tables in f32)",
            fw.empc_bytes_f32
        ),
        name.to_string(),
        fw.empc_source.len().to_string(),
    ]);
    r.write("firmware/fgm_tables.rs", &fw.fgm_source)?;
    t.row([
        "`firmware/fgm_tables.rs`".to_string(),
        format!(
            "fast gradient data, thesis-sized problem, {} certified iterations",
            fw.fgm_iterations
        ),
        name.to_string(),
        fw.fgm_source.len().to_string(),
    ]);
    r.write("firmware/kalman.json", &fw.kalman_json)?;
    t.row([
        "`firmware/kalman.json`".to_string(),
        "the stationary Kalman filter of section 4, flown in section 9 (kestrel.kalman.v1)"
            .to_string(),
        "f64".to_string(),
        fw.kalman_json.len().to_string(),
    ]);
    r.write("firmware/generated.rs", &fw.tables_source)?;
    t.row([
        "`firmware/generated.rs`".to_string(),
        format!(
            "the firmware's table file: the filter of section 4 ({} states) in Q15.16 rows, the fast \
             gradient data ({} certified iterations), trim and gyro bias",
            fw.design.nx(),
            fw.design.cert.iterations
        ),
        "q16 / f32".to_string(),
        fw.tables_source.len().to_string(),
    ]);
    r.table("firmware", "Tables for avr/firmware", &t)?;
    r.text(
        "The example firmware's committed tables (`avr/firmware/src/generated*.rs`) are written by \
         `kestrel codegen` from the thesis's design; these files are the same kinds of tables for the \
         pipeline's identified model and the filter tuned in section 4 (`firmware/generated.rs` has the \
         layout of `avr/firmware/src/generated.rs`).",
    );
    Ok(())
}
