//! Sections 4 (the Kalman filter) and 5 (the MPC problems).

use super::fmt::{f3, f4, series_t};
use crate::report::document::Report;
use crate::report::plot::{Panel, Series, panels_svg};
use crate::report::table::{Table, fmt_sig};
use kestrel_tricopter::pipeline::PipelineResult;

/// Section 4: the tuned filter, flown in section 9 and carried by the
/// firmware tables of section 10.
pub fn kalman(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    let k = &res.kalman;
    let cfg = &res.config;
    let nd = k.design.nd();
    r.text("\n## 4. Stationary Kalman filter (section 7.5)\n");
    r.write("kalman.json", k.design.kalman.to_json_string())?;
    let f = res
        .experiments
        .flights
        .iter()
        .find(|f| f.experiment.number() == k.flight)
        .ok_or_else(|| anyhow::anyhow!("kalman.flight = {}: no such flight", k.flight))?;
    let gust = k
        .chosen
        .gust_noise
        .map_or_else(|| "-".to_string(), |g| fmt_sig(g, 2));
    r.text(format!(
        "dlqe (kestrel-kalman's `AugmentedModel::design`) on the MPC's estimator model of section 5: the \
         black-box model of order {nx}{aug}, process noise through [B, C', 0; 0, 0, I] ({} us per pulse, \
         rate and disturbance noise per sample), R = the gyro covariance of step 2, bias removed by the \
         filter. Rate and disturbance noise are chosen on flight no. {} by innovation consistency (mean \
         normalised innovation squared closest to 1): {} and {} rad/s (NIS {}; {} on flight no. {}). The \
         design is `kalman.json` (`kestrel.kalman.v1`): the filter the closed loop of section 9 flies and \
         the firmware tables of section 10 carry. The filter runs over flight no. {} with the logged pulses.",
        k.input_noise,
        k.training_flight,
        fmt_sig(k.chosen.rate_noise, 2),
        gust,
        fmt_sig(k.chosen.nis, 3),
        fmt_sig(k.flight_nis, 3),
        k.flight,
        k.flight,
        nx = k.design.kalman.nx() - nd,
        aug = if nd > 0 {
            format!(
                " augmented with the offset-free MPC's {nd} constant disturbance states (a random walk \
                 entering the rate states, Bd = C')"
            )
        } else {
            String::new()
        },
    ));
    let mut choice = Table::new(["rate noise [rad/s]", "gust noise [rad/s]", "mean NIS"]);
    for p in &k.grid {
        choice.row([
            fmt_sig(p.rate_noise, 2),
            p.gust_noise.map_or_else(|| "-".into(), |g| fmt_sig(g, 2)),
            fmt_sig(p.nis, 3),
        ]);
    }
    r.table(
        "kalman_noise",
        "Innovation consistency on the training flight (a mean NIS well below 1: the filter \
         over-states its innovation covariance, the pulse noise covering the model error; with less \
         pulse noise the NIS reaches 1 but the estimate of r falls behind the gyro, the model's error \
         being far from white)",
        &choice,
    )?;
    if let Some(rms) = &k.rms {
        let mut t = Table::new(["signal", "RMS error p", "RMS error q", "RMS error r"]);
        t.row(
            std::iter::once("gyro minus bias".to_string()).chain(rms.gyro.iter().map(|v| f4(*v))),
        );
        t.row(
            std::iter::once("Kalman estimate C x + y0".to_string())
                .chain(rms.kalman.iter().map(|v| f4(*v))),
        );
        r.table(
            "kalman",
            "Error against the simulator's true body rates over the airborne part (rad/s)",
            &t,
        )?;
        r.text(
            "The filter is only as good as the model: the disturbance states carry the slowly varying \
             part the identified model misses (gusts, model error), so the filter can average the \
             gyro noise where the model predicts well; the thesis found the gain leaning on the gyro \
             for its roll rate (section 7.5).",
        );
    }
    let idx: Vec<usize> = (0..f.t.len())
        .filter(|&i| f.t[i] >= cfg.kalman.plot_from && f.t[i] <= cfg.kalman.plot_to)
        .collect();
    let tt: Vec<f64> = idx.iter().map(|&i| f.t[i]).collect();
    let names = ["p", "q", "r"];
    let panels: Vec<Panel> = (0..3)
        .map(|j| {
            let mut series = vec![
                Series::line("measured", series_t(&tt, idx.iter().map(|&i| f.gyro[i][j]))),
                Series::line(
                    "Kalman estimate",
                    series_t(&tt, idx.iter().map(|&i| k.estimate[i][j])),
                ),
            ];
            if let Some(truth) = &f.truth {
                series.push(Series::dashed(
                    "true",
                    series_t(&tt, idx.iter().map(|&i| truth[i][j])),
                ));
            }
            Panel {
                title: names[j].into(),
                x_label: "time [s]".into(),
                y_label: "rad/s".into(),
                series,
                hlines: vec![],
            }
        })
        .collect();
    let name = "figures/kalman.svg";
    panels_svg(
        &r.path(name),
        &format!("Kalman filter on flight no. {}", k.flight),
        &panels,
    )?;
    r.figure(name, "Kalman estimates over the measurement (figure 7.14)");
    Ok(())
}

/// Section 5: the thesis-sized and the larger MPC problem.
pub fn problems(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    let pr = &res.problems;
    let m = &res.config.mpc;
    r.text("\n## 5. MPC problems (sections 6.1, 7.6)\n");
    let mut t = Table::new([
        "problem",
        "N",
        "blocks",
        "variables n",
        "parameters p",
        "constraints m",
        "cond(H)",
        "file",
    ]);
    for p in pr.list() {
        let file = format!("problems/{}.json", p.name.as_str());
        // With the fingerprint of the model theta starts with (kestrel export checks it).
        r.write(&file, p.mpqp.to_json_string_for_model(&pr.estimator_model))?;
        t.row([
            p.name.as_str().to_string(),
            p.horizon.horizon.to_string(),
            format!("{:?}", p.horizon.blocks),
            p.mpqp.n().to_string(),
            p.mpqp.p().to_string(),
            p.mpqp.m().to_string(),
            f3(p.condition),
            format!("`{file}`"),
        ]);
    }
    r.text(format!(
        "Condensed MPC (6.19)-(6.26) on the black-box model of order {}: Q1 = {}, Q2 = {}, LQ terminal \
         weight (7.18)-(7.19) from the DARE, move blocking, pulses bounded to 1000-2000 us (motors, moving \
         with the throttle) and +-300 us (servo) around the identified trim; {}",
        pr.model.nx(),
        m.q1,
        m.q2,
        if m.offset_free {
            "offset-free (`mpc.offset_free`): the model is augmented with three constant torque \
             disturbances d on the rate states (Bd = C', Cd = 0, detectability checked), the Kalman filter \
             estimates them, and the steady-state target (x_s, u_s) solves [A - I, B; C, 0] [x_s; u_s] = \
             [-Bd d; r] (least norm), so the cost weighs u - u_s and the terminal state against x_s; \
             theta = [x; d; r_roll; r_pitch; r_yaw; throttle]. Without it the target comes from the \
             model's steady-state gain alone, and the identified model's gain is off (the step 3 fits \
             are of the dynamics, not of the DC gain), which leaves the closed loop short of the reference."
        } else {
            "theta = [x; r_roll; r_pitch; r_yaw; throttle]."
        }
    ));
    r.table("mpc", "The MPC problems (`kestrel.mpqp.v1`)", &t)
}
