//! Sections 1 (flight experiments) and 2 (gyro statistics and trim).

use super::fmt::{f3, f4, series_t};
use crate::report::document::Report;
use crate::report::plot::{Panel, Series, panels_svg};
use crate::report::table::{Table, fmt_sig};
use kestrel_tricopter::pipeline::PipelineResult;
use kestrel_tricopter::pipeline::experiments::file_name;
use kestrel_tricopter::pipeline::sensor::THESIS_TRIM;
use std::path::Path;

/// Section 1: the four flights.
pub fn experiments(r: &mut Report, res: &PipelineResult, dir: Option<&Path>) -> anyhow::Result<()> {
    let cfg = &res.config;
    let flights = &res.experiments.flights;
    r.text("\n## 1. Flight experiments (section 7.1)\n");
    for f in flights {
        r.write(&file_name(f.experiment), &f.csv)?;
    }
    r.text(match dir {
        Some(d) => format!(
            "The flight logs were read from `{}` (the simulator's CSV columns).",
            d.display()
        ),
        None => format!(
            "Simulated with kestrel-tricopter-model (6-DOF tricopter, motor and servo dynamics, gyro bias, \
             noise and quantisation, gusts), flown by the baseline ACRO rate PI and a simulated pilot: \
             {} s each, 50 Hz logs, RK4 step {} s, seed {} + k - 1 for experiment k.",
            cfg.experiments.seconds, cfg.experiments.dt, cfg.experiments.seed
        ),
    });
    let mut t = Table::new([
        "no.",
        "experiment",
        "file",
        "samples",
        "airborne [s]",
        "std p",
        "std q",
        "std r",
    ]);
    for f in flights {
        let std = f.gyro_std();
        t.row([
            f.experiment.number().to_string(),
            f.experiment.name().to_string(),
            format!("`{}`", file_name(f.experiment)),
            f.t.len().to_string(),
            format!("{:.1}", f.airborne_seconds()),
            f4(std[0]),
            f4(std[1]),
            f4(std[2]),
        ]);
    }
    r.table(
        "experiments",
        "The four experiments (gyro standard deviations in rad/s)",
        &t,
    )?;
    // Figures 7.1-7.3: inputs and outputs of the excitation flights.
    for f in flights
        .iter()
        .filter(|f| matches!(f.experiment.number(), 2 | 3))
    {
        let name = format!("figures/flight-{}.svg", f.experiment.number());
        let gyro = Panel {
            title: "gyro".into(),
            x_label: "time [s]".into(),
            y_label: "rad/s".into(),
            series: ["p", "q", "r"]
                .iter()
                .enumerate()
                .map(|(j, n)| Series::line(*n, series_t(&f.t, f.gyro.iter().map(|g| g[j]))))
                .collect(),
            hlines: vec![],
        };
        let pwm = Panel {
            title: "pulses".into(),
            x_label: "time [s]".into(),
            y_label: "us".into(),
            series: ["pwm1", "pwm2", "pwm3", "servo"]
                .iter()
                .enumerate()
                .map(|(j, n)| Series::line(*n, series_t(&f.t, f.pwm.iter().map(|g| g[j]))))
                .collect(),
            hlines: vec![],
        };
        panels_svg(
            &r.path(&name),
            &format!(
                "Flight experiment no. {} ({})",
                f.experiment.number(),
                f.experiment.name()
            ),
            &[gyro, pwm],
        )?;
        r.figure(
            &name,
            &format!(
                "Flight experiment no. {} (figures 7.2-7.3)",
                f.experiment.number()
            ),
        );
    }
    Ok(())
}

/// Section 2: bias and covariance from experiment 4, trim from experiment 1.
pub fn sensor(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    let s = &res.sensor;
    r.text("\n## 2. Gyro bias, noise covariance and trim (sections 7.1.1, 7.1.4, 7.2)\n");
    let mut t = Table::new([
        "quantity",
        "estimated",
        "simulator's true value",
        "thesis (7.5)-(7.6)",
    ]);
    for j in 0..3 {
        t.row([
            format!("bias e0[{}] [rad/s]", ["p", "q", "r"][j]),
            f4(s.bias[j]),
            s.truth.map_or("-".into(), |tr| f4(tr.bias[j])),
            f4(kestrel_tricopter_model::THESIS_GYRO_BIAS[j]),
        ]);
    }
    for i in 0..3 {
        for j in i..3 {
            t.row([
                format!("R[{},{}] [(rad/s)^2]", i + 1, j + 1),
                f3(s.covariance[(i, j)]),
                s.truth.map_or("-".into(), |tr| f3(tr.covariance[i][j])),
                f3(kestrel_tricopter_model::THESIS_GYRO_COVARIANCE[i][j]),
            ]);
        }
    }
    r.table(
        "gyro",
        "Gyro bias and noise covariance from experiment 4 (motors off)",
        &t,
    )?;
    let mut t = Table::new([
        "input",
        "estimated U0 [us]",
        "true trim [us]",
        "thesis (7.2) [us]",
    ]);
    for j in 0..4 {
        t.row([
            [
                "pwm1 - throttle",
                "pwm2 - throttle",
                "pwm3 - throttle",
                "servo",
            ][j]
                .to_string(),
            format!("{:.2}", s.u0[j]),
            s.true_u0.map_or("-".into(), |o| format!("{:.2}", o[j])),
            format!("{}", THESIS_TRIM[j]),
        ]);
    }
    r.table(
        "trim",
        "Linearisation point U0 from experiment 1 (hover)",
        &t,
    )?;
    let list = |v: &[f64]| {
        v.iter()
            .map(|v| fmt_sig(*v, 2))
            .collect::<Vec<_>>()
            .join(", ")
    };
    r.text(format!(
        "Bias and covariance by kestrel-kalman's `estimate_sensor_statistics` over {} samples \
         (bias standard errors {} rad/s; lag-1 autocorrelations {}, white noise stays within about {}).",
        s.samples,
        list(&s.bias_standard_error),
        list(&s.lag1_autocorrelation),
        fmt_sig(2.0 / (s.samples as f64).sqrt(), 2)
    ));
    Ok(())
}
