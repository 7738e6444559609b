//! The steps of the pipeline, each a section of `report.md`.

use super::Report;
use super::config::{Config, FirmwareScalar, PreconditionerChoice};
use super::flights::{self, Flight};
use crate::report::plot::{Panel, Polygon, Series, panels_svg, partition_svg};
use crate::report::table::{Table, fmt_sig};
use anyhow::{Context, bail};
use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_empc::{ExplicitController, MpqpSolution, Outputs, TreeSettings, build_controller};
use kestrel_fgm::{BoxQp, Certificate, FgmDesign, FgmSettings, Preconditioner};
use kestrel_kalman::noise::{NoiseSettings, estimate_sensor_statistics};
use kestrel_kalman::{KalmanDesign, NoiseModel};
use kestrel_mpc::sim::{
    PlantKind, ReferenceStep, RunSettings, Scenario, Trace, fly_mpc, fly_offset_free, fly_pi,
    kalman_design_with_disturbance,
};
use kestrel_mpc::{
    Blocking, DisturbanceModel, ExplicitSolver, FastGradientSolver, FgmOptions, FgmStart, MpcLaw,
    MpcProblem, MpcSettings, OffsetFreeDesign, ParametricQpSolver, QpSettings, ReferenceSolver,
    Terminal, tricopter_trim,
};
use kestrel_sysid::tricopter::{ModelKind, thesis_spec};
use kestrel_sysid::workflow::{Segment, identify, select_segments};
use kestrel_sysid::{
    InnovationModel, IoData, TimeInterval, ValidationReport, estimate_x0_predictor, resid,
    transmission_zeros,
};
use kestrel_tricopter_model::{Experiment, GustConfig, GyroConfig, PlantConfig};
use nalgebra::{DMatrix, DVector};
use serde_json::json;
use std::time::Instant;

/// Calls `$f::<NX>(args)` for the model order `$nx` (1 to 10).
macro_rules! with_nx {
    ($nx:expr, $f:ident ( $($arg:expr),* )) => {
        match $nx {
            1 => $f::<1>($($arg),*),
            2 => $f::<2>($($arg),*),
            3 => $f::<3>($($arg),*),
            4 => $f::<4>($($arg),*),
            5 => $f::<5>($($arg),*),
            6 => $f::<6>($($arg),*),
            7 => $f::<7>($($arg),*),
            8 => $f::<8>($($arg),*),
            9 => $f::<9>($($arg),*),
            10 => $f::<10>($($arg),*),
            n => bail!("the pipeline's run-time filters support 1 to 10 states, found {n}"),
        }
    };
}

/// A small deterministic generator for the random check points (SplitMix64).
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A point of the parameter box.
    fn theta(&mut self, p: &MpqpProblem) -> DVector<f64> {
        DVector::from_fn(p.p(), |i, _| {
            p.theta_lb[i] + (p.theta_ub[i] - p.theta_lb[i]) * self.uniform()
        })
    }
}

/// `1/2 z'Hz + (F'theta + f)'z`, the QP's objective, evaluated directly.
fn qp_cost(p: &MpqpProblem, z: &DVector<f64>, theta: &DVector<f64>) -> f64 {
    0.5 * z.dot(&(&p.h * z)) + p.linear_term(theta).dot(z)
}

fn f3(v: f64) -> String {
    fmt_sig(v, 3)
}

fn f4(v: f64) -> String {
    fmt_sig(v, 4)
}

fn series_t(t: &[f64], v: impl Iterator<Item = f64>) -> Vec<(f64, f64)> {
    t.iter().copied().zip(v).collect()
}

// ---------------------------------------------------------------- step 1

/// Step 1: the four flights.
pub fn experiments(
    r: &mut Report,
    cfg: &Config,
    dir: Option<&std::path::Path>,
) -> anyhow::Result<Vec<Flight>> {
    r.text("\n## 1. Flight experiments (section 7.1)\n");
    let mut out = Vec::new();
    for e in Experiment::ALL {
        let f = match dir {
            Some(d) => Flight::read(e, &d.join(flights::file_name(e)))?,
            None => Flight::simulate(e, &cfg.experiments)?,
        };
        r.write(&flights::file_name(e), &f.csv)?;
        out.push(f);
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
    for f in &out {
        let air = f.airborne.iter().filter(|a| **a).count() as f64 * f.ts();
        let std = |j: usize| {
            let n = f.gyro.len() as f64;
            let m = f.gyro.iter().map(|g| g[j]).sum::<f64>() / n;
            (f.gyro.iter().map(|g| (g[j] - m).powi(2)).sum::<f64>() / n).sqrt()
        };
        t.row([
            f.experiment.number().to_string(),
            f.experiment.name().to_string(),
            format!("`{}`", flights::file_name(f.experiment)),
            f.t.len().to_string(),
            format!("{air:.1}"),
            f4(std(0)),
            f4(std(1)),
            f4(std(2)),
        ]);
    }
    r.table(
        "experiments",
        "The four experiments (gyro standard deviations in rad/s)",
        &t,
    )?;
    // Figures 7.1-7.3: inputs and outputs of the excitation flights.
    for f in out
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
    Ok(out)
}

// ---------------------------------------------------------------- step 2

/// Gyro bias, covariance and trim estimated from the flights.
pub struct SensorStats {
    /// Gyro bias (rad/s).
    pub bias: [f64; 3],
    /// Gyro noise covariance.
    pub cov: DMatrix<f64>,
}

/// Step 2: bias and covariance from experiment 4, trim from experiment 1.
pub fn sensor(r: &mut Report, cfg: &Config, fl: &[Flight]) -> anyhow::Result<SensorStats> {
    r.text("\n## 2. Gyro bias, noise covariance and trim (sections 7.1.1, 7.1.4, 7.2)\n");
    let ground = &fl[3];
    let rows: Vec<[f64; 3]> = ground
        .t
        .iter()
        .zip(&ground.gyro)
        .filter(|(t, _)| **t >= cfg.sensor.ground_skip)
        .map(|(_, g)| *g)
        .collect();
    if rows.len() < 10 {
        bail!(
            "experiment 4 (ground): fewer than 10 samples after sensor.ground_skip = {} s",
            cfg.sensor.ground_skip
        );
    }
    // kestrel-kalman's sensor statistics (true rate zero on the ground).
    let stats = estimate_sensor_statistics(&rows, &NoiseSettings::default())
        .context("gyro statistics of experiment 4")?;
    let bias: [f64; 3] = std::array::from_fn(|j| stats.bias[j]);
    // A quantised, silent channel would give a singular R.
    let cov = stats.covariance_with_floor(1e-12);
    let truth = PlantConfig::default().gyro;
    let simulated = ground.true_offsets.is_some();
    let mut t = Table::new([
        "quantity",
        "estimated",
        "simulator's true value",
        "thesis (7.5)-(7.6)",
    ]);
    for j in 0..3 {
        t.row([
            format!("bias e0[{}] [rad/s]", ["p", "q", "r"][j]),
            f4(bias[j]),
            if simulated {
                f4(truth.bias[j])
            } else {
                "-".into()
            },
            f4(kestrel_tricopter_model::THESIS_GYRO_BIAS[j]),
        ]);
    }
    for i in 0..3 {
        for j in i..3 {
            t.row([
                format!("R[{},{}] [(rad/s)^2]", i + 1, j + 1),
                f3(cov[(i, j)]),
                if simulated {
                    f3(truth.covariance[i][j])
                } else {
                    "-".into()
                },
                f3(kestrel_tricopter_model::THESIS_GYRO_COVARIANCE[i][j]),
            ]);
        }
    }
    r.table(
        "gyro",
        "Gyro bias and noise covariance from experiment 4 (motors off)",
        &t,
    )?;
    // Trim (7.2): hover flight, airborne, ends cut.
    let hover = &fl[0];
    let t_end = hover.t.last().copied().unwrap_or(0.0);
    let idx: Vec<usize> = (0..hover.t.len())
        .filter(|&k| {
            hover.airborne[k]
                && hover.t[k] >= cfg.sensor.hover_trim
                && hover.t[k] <= t_end - cfg.sensor.hover_trim
        })
        .collect();
    if idx.len() < 10 {
        bail!("experiment 1 (hover): fewer than 10 airborne samples after sensor.hover_trim");
    }
    let m = idx.len() as f64;
    let u0: [f64; 4] = std::array::from_fn(|j| {
        idx.iter()
            .map(|&k| {
                if j < 3 {
                    hover.pwm[k][j] - hover.throttle[k]
                } else {
                    hover.pwm[k][3]
                }
            })
            .sum::<f64>()
            / m
    });
    let thesis_u0 = [15.63, 0.85, -16.01, 1467.7];
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
            format!("{:.2}", u0[j]),
            hover
                .true_offsets
                .map_or("-".into(), |o| format!("{:.2}", o[j])),
            format!("{}", thesis_u0[j]),
        ]);
    }
    r.table(
        "trim",
        "Linearisation point U0 from experiment 1 (hover)",
        &t,
    )?;
    r.text(format!(
        "Bias and covariance by kestrel-kalman's `estimate_sensor_statistics` over {} samples \
         (bias standard errors {} rad/s; lag-1 autocorrelations {}, white noise stays within about {}).",
        stats.samples,
        stats.bias_standard_error.iter().map(|v| fmt_sig(*v, 2)).collect::<Vec<_>>().join(", "),
        stats.lag1_autocorrelation.iter().map(|v| fmt_sig(*v, 2)).collect::<Vec<_>>().join(", "),
        fmt_sig(2.0 / (stats.samples as f64).sqrt(), 2)
    ));
    r.summary(
        "sensor",
        json!({"bias": bias, "covariance_diag": [cov[(0,0)], cov[(1,1)], cov[(2,2)]], "u0": u0,
               "true_u0": hover.true_offsets}),
    );
    Ok(SensorStats { bias, cov })
}

// ---------------------------------------------------------------- step 3

/// An identified model.
pub struct IdModel {
    /// The reduced model as `kestrel.ss.v1` (with `u0`/`y0`).
    pub ss: SsModel,
    /// The removed output offsets.
    pub y0: DVector<f64>,
}

/// The identified models.
pub struct Identified {
    /// Black-box model (pulses in).
    pub blackbox: IdModel,
}

fn fit_rows(t: &mut Table, label: &str, rep: &ValidationReport) {
    for row in &rep.rows {
        let mut cells = vec![label.to_string(), row.label.clone()];
        cells.extend(row.fit.iter().map(|v| format!("{v:.2}")));
        cells.push(format!("{:.2}", row.mean()));
        t.row(cells);
    }
}

/// Step 3: black-box and virtual models.
pub fn identification(r: &mut Report, cfg: &Config, fl: &[Flight]) -> anyhow::Result<Identified> {
    r.text("\n## 3. System identification (section 7.4)\n");
    let id = &cfg.identification;
    r.text(format!(
        "kestrel-sysid's identification workflow (`workflow::identify` with `tricopter::thesis_spec`): \
         N4SID start, PEM at order {} (at most {} iterations) fitting A, B, C on simulation errors and \
         then the noise model K on one-step errors (the rate dynamics are integrators flown in closed \
         loop, so a one-step fit drifts in simulation), balanced truncation to order {} (`match_dc` \
         off: the MPC needs D = 0). Operating point: the means of the estimation data (stored as \
         `u0`/`y0`). Fits are on the validation intervals (4.11), k-step fits (4.12) beside the \
         persistence predictor y(t+k) = y(t); residual tests with lags -{l}..{l} and 99% bands.",
        id.order, id.pem_max_iterations, id.reduced_order, l = id.residual_lags
    ));
    let mut fit = Table::new(["model", "predictor", "p", "q", "r", "mean"]);
    let mut res = Table::new([
        "model",
        "output",
        "autocorr outside band",
        "white",
        "cross-corr (tau >= 0) outside band",
        "independent of inputs",
    ]);
    let mut about = Table::new([
        "model",
        "estimation samples",
        "validation samples",
        "PEM (simulation focus; noise model): iterations, cost",
        "Hankel singular values",
        "zeros outside unit circle",
    ]);
    let mut excitation = Table::new(["model", "data set", "samples", "std p", "std q", "std r"]);
    let mut blackbox = None;
    for (key, sets, virt) in [
        ("blackbox", &id.blackbox, false),
        ("virtual", &id.virtual_, true),
    ] {
        let label = if virt {
            "black-box virtual"
        } else {
            "black-box"
        };
        r.step(&format!("3. identification: {label}"));
        let est = flights::select(
            fl,
            &sets.estimate,
            virt,
            &format!("identification.{key}.estimate"),
        )?;
        let val = flights::select(
            fl,
            &sets.validate,
            virt,
            &format!("identification.{key}.validate"),
        )?;
        let mut val_std = Vec::new();
        for (set, d) in [("estimation", &est), ("validation", &val)] {
            let n = d.n_samples() as f64;
            let std: Vec<f64> = (0..d.ny())
                .map(|j| {
                    let m = d
                        .experiments()
                        .iter()
                        .map(|e| e.y.column(j).sum())
                        .sum::<f64>()
                        / n;
                    (d.experiments()
                        .iter()
                        .map(|e| e.y.column(j).iter().map(|v| (v - m).powi(2)).sum::<f64>())
                        .sum::<f64>()
                        / n)
                        .sqrt()
                })
                .collect();
            let mut cells = vec![
                label.to_string(),
                set.to_string(),
                d.n_samples().to_string(),
            ];
            cells.extend(std.iter().map(|v| f3(*v)));
            excitation.row(cells);
            if set == "validation" {
                val_std = std;
            }
        }
        // kestrel-sysid's workflow on flights no. 2 and 3 (experiments 1, 2).
        let flights23 = IoData::merge(&[fl[1].io_data(false)?, fl[2].io_data(false)?])?;
        let segments =
            |list: &[super::config::Interval], what: &str| -> anyhow::Result<Vec<Segment>> {
                list.iter()
                    .enumerate()
                    .map(|(i, iv)| {
                        Ok(Segment {
                            experiment: Some(usize::from(iv.flight) - 2),
                            interval: TimeInterval::new(iv.from, iv.to)
                                .with_context(|| format!("identification.{key}.{what}[{i}]"))?,
                        })
                    })
                    .collect()
            };
        let mut spec = thesis_spec(if virt {
            ModelKind::Virtual
        } else {
            ModelKind::BlackBox
        });
        spec.estimate = segments(&sets.estimate, "estimate")?;
        spec.validate = segments(&sets.validate, "validate")?;
        spec.order = Some(id.order);
        spec.reduce = Some(id.reduced_order);
        spec.match_dc = id.match_dc;
        spec.max_iterations = id.pem_max_iterations;
        spec.horizons = id.horizons.clone();
        let idr = identify(&flights23, &spec)
            .with_context(|| format!("identifying the {label} model"))?;
        let offsets = idr.offsets.clone();
        let mapped = match &spec.input_map {
            Some(m) => flights23.map_inputs(&m.matrix, m.names.clone())?,
            None => flights23.clone(),
        };
        let est0 = select_segments(&mapped, &spec.estimate)?.subtract(&offsets)?;
        let val0 = select_segments(&mapped, &spec.validate)?.subtract(&offsets)?;
        let mut rep = idr.validation.clone();
        let mut rep_full = idr.full_validation.clone().unwrap_or_else(|| rep.clone());
        let model = idr.model.clone();
        if id.residual_lags != 25 {
            rep_full.residuals = resid(&idr.full_model, &val0, id.residual_lags)?;
            rep.residuals = resid(&model, &val0, id.residual_lags)?;
        }
        fit_rows(&mut fit, &format!("{label}, order {}", id.order), &rep_full);
        fit_rows(
            &mut fit,
            &format!("{label}, order {}", id.reduced_order),
            &rep,
        );
        for o in &rep.residuals.outputs {
            res.row([
                format!("{label}, order {}", id.reduced_order),
                o.name.clone(),
                format!("{}/{}", o.auto_outside, rep.residuals.max_lag),
                if o.white { "yes" } else { "no" }.to_string(),
                format!(
                    "{}/{}",
                    o.cross_outside,
                    (rep.residuals.max_lag + 1) * rep.residuals.inputs.len()
                ),
                if o.independent { "yes" } else { "no" }.to_string(),
            ]);
        }
        let zeros = match transmission_zeros(&model) {
            Ok(z) => {
                let nmp: Vec<String> = z
                    .iter()
                    .filter(|z| z.non_minimum_phase)
                    .map(|z| format!("{:.3}{:+.3}i", z.z.re, z.z.im))
                    .collect();
                format!(
                    "{} of {}{}{}",
                    nmp.len(),
                    z.len(),
                    if nmp.is_empty() { "" } else { ": " },
                    nmp.join(", ")
                )
            }
            Err(e) => format!("not computed ({e})"),
        };
        let pem_text = [&idr.pem, &idr.pem_noise]
            .iter()
            .filter_map(|p| p.as_ref())
            .map(|p| {
                format!(
                    "{} it., {} -> {}",
                    p.iterations,
                    f4(p.initial_cost),
                    f4(p.cost)
                )
            })
            .collect::<Vec<_>>()
            .join("; ");
        about.row([
            label.to_string(),
            est0.n_samples().to_string(),
            val0.n_samples().to_string(),
            pem_text,
            idr.reduction
                .as_ref()
                .map(|r| {
                    r.hankel_singular_values
                        .iter()
                        .map(|v| f3(*v))
                        .collect::<Vec<_>>()
                        .join(", ")
                })
                .unwrap_or_default(),
            zeros,
        ]);
        let ss = model.to_ss_model(
            Some(&offsets.u0),
            Some(&offsets.y0),
            Some(&idr.input_names),
            Some(&idr.output_names),
        )?;
        let full = idr.full_model.to_ss_model(
            Some(&offsets.u0),
            Some(&offsets.y0),
            Some(&idr.input_names),
            Some(&idr.output_names),
        )?;
        r.write(
            &format!("models/{key}-{}.json", id.reduced_order),
            ss.to_json_string(),
        )?;
        r.write(
            &format!("models/{key}-{}.json", id.order),
            full.to_json_string(),
        )?;
        // Figures 7.8-7.13.
        identification_figures(r, key, label, &model, &val0, &offsets.y0, &rep)?;
        r.summary(
            &format!("fit_{key}"),
            json!({
                "simulation": rep.row("model simulation").map(|x| x.fit.clone()),
                "five_step": rep.row("model 5-step").map(|x| x.fit.clone()),
                "order": id.reduced_order,
                "validation_std": val_std,
            }),
        );
        if !virt {
            blackbox = Some(IdModel {
                ss,
                y0: offsets.y0.clone(),
            });
        }
    }
    r.table(
        "excitation",
        "Excitation of the data sets: standard deviation of the measured rates (rad/s)",
        &excitation,
    )?;
    r.table("identification", "Identified models", &about)?;
    r.table(
        "fit",
        "Fit [%] on the validation data (simulation, k-step prediction, persistence baseline)",
        &fit,
    )?;
    r.table("residuals", "Residual tests on the validation data", &res)?;
    r.text(format!(
        "Models: `models/blackbox-{o}.json`, `models/virtual-{o}.json` (reduced) and `models/*-{f}.json` \
         (before reduction), all `kestrel.ss.v1`.",
        o = id.reduced_order,
        f = id.order
    ));
    Ok(Identified {
        blackbox: blackbox.context("no black-box model")?,
    })
}

/// One panel per rate: the measured output of experiment `e` against a model
/// output (`model_out`, deviations like `e.y`), both around `y0`; written as
/// the figure `name` of the report.
#[allow(clippy::too_many_arguments)]
fn measured_against(
    r: &mut Report,
    e: &kestrel_sysid::Experiment,
    y0: &DVector<f64>,
    model_out: &DMatrix<f64>,
    legend: impl Fn(usize) -> String,
    name: &str,
    title: &str,
    caption: &str,
) -> anyhow::Result<()> {
    let names = ["p (roll rate)", "q (pitch rate)", "r (yaw rate)"];
    let panels: Vec<Panel> = (0..3)
        .map(|j| Panel {
            title: names[j].into(),
            x_label: "time [s]".into(),
            y_label: "rad/s".into(),
            series: vec![
                Series::line(
                    "measured",
                    series_t(&e.t, e.y.column(j).iter().map(|v| v + y0[j])),
                ),
                Series::dashed(
                    legend(j),
                    series_t(&e.t, model_out.column(j).iter().map(|v| v + y0[j])),
                ),
            ],
            hlines: vec![],
        })
        .collect();
    panels_svg(&r.path(name), title, &panels)?;
    r.figure(name, caption);
    Ok(())
}

fn identification_figures(
    r: &mut Report,
    key: &str,
    label: &str,
    model: &InnovationModel,
    val: &IoData,
    y0: &DVector<f64>,
    rep: &ValidationReport,
) -> anyhow::Result<()> {
    // The longest validation experiment.
    let cmp = kestrel_sysid::compare(model, val)?;
    let (ei, e) = val
        .experiments()
        .iter()
        .enumerate()
        .max_by_key(|(_, e)| e.len())
        .context("no validation data")?;
    let sim = &cmp.simulated[ei];
    measured_against(
        r,
        e,
        y0,
        sim,
        |j| format!("simulated (fit {:.1}%)", cmp.fit[j]),
        &format!("figures/{key}-simulation.svg"),
        &format!("{label} model: simulation on validation data"),
        &format!("Measured and simulated outputs, {label} model (figures 7.8-7.9)"),
    )?;
    let x0 = estimate_x0_predictor(model, &e.u, &e.y)?;
    let pred = model.predict_k_step(&e.u, &e.y, &x0, 5)?;
    measured_against(
        r,
        e,
        y0,
        &pred,
        |_| "5-step prediction".to_string(),
        &format!("figures/{key}-5step.svg"),
        &format!("{label} model: 5-step prediction on validation data"),
        &format!("5-step prediction, {label} model (figures 7.10-7.11)"),
    )?;
    // Residuals of the yaw rate: autocorrelation and cross-correlation with
    // the yaw input (servo, or the virtual yaw input).
    let ra = &rep.residuals;
    let o = &ra.outputs[2];
    let m = ra.max_lag as f64;
    let band = vec![
        (ra.bound, "99% band".to_string()),
        (-ra.bound, "99% band".to_string()),
    ];
    let q = ra.inputs.len() - 1;
    let panels = vec![
        Panel {
            title: format!("autocorrelation of the residuals of {}", o.name),
            x_label: "lag [samples]".into(),
            y_label: "".into(),
            series: vec![Series::stems(
                o.name.clone(),
                o.autocorr
                    .iter()
                    .enumerate()
                    .map(|(k, v)| (k as f64, *v))
                    .collect(),
            )],
            hlines: band.clone(),
        },
        Panel {
            title: format!(
                "cross-correlation of {} and the residuals of {}",
                ra.inputs[q], o.name
            ),
            x_label: "lag [samples]".into(),
            y_label: "".into(),
            series: vec![Series::stems(
                format!("{} -> {}", ra.inputs[q], o.name),
                o.crosscorr[q]
                    .iter()
                    .enumerate()
                    .map(|(k, v)| (k as f64 - m, *v))
                    .collect(),
            )],
            hlines: band,
        },
    ];
    let name = format!("figures/{key}-residuals.svg");
    panels_svg(
        &r.path(&name),
        &format!("{label} model: residual analysis of the yaw rate"),
        &panels,
    )?;
    r.figure(
        &name,
        &format!("Residual correlations with 99% bands, {label} model (figures 7.12-7.13)"),
    );
    Ok(())
}

// ---------------------------------------------------------------- step 4

/// Runs the filter over the flight: the output estimates and the mean
/// normalised innovation squared `e' S^-1 e / ny` over the airborne samples.
fn filter_flight<const NX: usize>(
    design: &KalmanDesign,
    f: &Flight,
) -> anyhow::Result<(Vec<[f64; 3]>, f64)> {
    let mut filt = design.filter::<f64, NX, 4, 3>()?;
    let s_inv = design
        .filter
        .innovation_covariance
        .clone()
        .try_inverse()
        .context("the innovation covariance is singular")?;
    let mut out = Vec::with_capacity(f.t.len());
    let (mut nis, mut n) = (0.0, 0usize);
    for k in 0..f.t.len() {
        filt.update(&f.gyro[k])
            .map_err(|e| anyhow::anyhow!("Kalman update at t = {}: {e}", f.t[k]))?;
        if f.airborne[k] {
            let e = DVector::from_column_slice(filt.innovation());
            nis += (e.transpose() * &s_inv * &e)[(0, 0)] / 3.0;
            n += 1;
        }
        out.push(filt.output_estimate());
        filt.predict(&f.pwm[k])
            .map_err(|e| anyhow::anyhow!("Kalman time update at t = {}: {e}", f.t[k]))?;
    }
    Ok((out, nis / n.max(1) as f64))
}

/// The filter design on the model augmented with three gust states: a
/// random walk `d` added to the rates every sample (`x+ = A x + B u +
/// pinv(C) d`, `d+ = d + w`), process noise through `[B, C', 0; 0, 0, I]`.
fn gust_design(
    model: &SsModel,
    noise: (f64, f64, f64),
    r: &DMatrix<f64>,
    bias: &DVector<f64>,
) -> anyhow::Result<KalmanDesign> {
    let (nx, nu, ny) = (model.nx(), model.nu(), model.ny());
    let na = nx + ny;
    let bd = model
        .c
        .clone()
        .pseudo_inverse(1e-12)
        .map_err(|e| anyhow::anyhow!("pseudo-inverse of C: {e}"))?;
    let mut a = DMatrix::identity(na, na);
    a.view_mut((0, 0), (nx, nx)).copy_from(&model.a);
    a.view_mut((0, nx), (nx, ny)).copy_from(&bd);
    let mut b = DMatrix::zeros(na, nu);
    b.view_mut((0, 0), (nx, nu)).copy_from(&model.b);
    let mut c = DMatrix::zeros(ny, na);
    c.view_mut((0, 0), (ny, nx)).copy_from(&model.c);
    let mut aug = SsModel::new(model.ts, a, b, c, DMatrix::zeros(ny, nu))?;
    aug.u0 = model.u0.clone();
    aug.y0 = model.y0.clone();
    aug.inputs = model.inputs.clone();
    aug.outputs = model.outputs.clone();
    let nw = nu + 2 * ny;
    let mut g = DMatrix::zeros(na, nw);
    g.view_mut((0, 0), (nx, nu)).copy_from(&model.b);
    g.view_mut((0, nu), (nx, ny))
        .copy_from(&model.c.transpose());
    g.view_mut((nx, nu + ny), (ny, ny))
        .copy_from(&DMatrix::identity(ny, ny));
    let (input, rate, gust) = noise;
    let q = DMatrix::from_diagonal(&DVector::from_fn(nw, |i, _| {
        if i < nu {
            input * input
        } else if i < nu + ny {
            rate * rate
        } else {
            gust * gust
        }
    }));
    let noise = NoiseModel {
        g: Some(g),
        q,
        r: r.clone(),
        cross: None,
        bias: Some(bias.clone()),
    };
    KalmanDesign::new(&aug, &noise).context("dlqe on the black-box model with gust states")
}

/// Step 4: the stationary Kalman filter of the black-box model.
pub fn kalman(
    r: &mut Report,
    cfg: &Config,
    fl: &[Flight],
    id: &Identified,
    s: &SensorStats,
) -> anyhow::Result<()> {
    r.text("\n## 4. Stationary Kalman filter (section 7.5)\n");
    let mut model = id.blackbox.ss.clone();
    let nx = model.nx();
    // The bias is removed by the filter; y0 keeps the rest of the offset.
    let bias = DVector::from_column_slice(&s.bias);
    model.y0 = Some(&id.blackbox.y0 - &bias);
    let k = &cfg.kalman;
    let train = fl
        .iter()
        .find(|f| f.experiment.number() == k.training_flight)
        .context("kalman.training_flight")?;
    // Rate and gust noise chosen by innovation consistency on the training
    // flight: the mean NIS closest to 1 (nothing tuned on the true rates).
    let mut choice = Table::new(["rate noise [rad/s]", "gust noise [rad/s]", "mean NIS"]);
    let mut best: Option<(f64, f64, f64)> = None;
    let na = nx + model.ny();
    for &rate in &k.rate_noise {
        for &gust in &k.gust_noise {
            let d = gust_design(&model, (k.input_noise, rate, gust), &s.cov, &bias)?;
            let (_, nis) = with_nx!(na, filter_flight(&d, train))?;
            choice.row([fmt_sig(rate, 2), fmt_sig(gust, 2), fmt_sig(nis, 3)]);
            if best.is_none_or(|b| (nis - 1.0).abs() < (b.2 - 1.0).abs()) {
                best = Some((rate, gust, nis));
            }
        }
    }
    let (rate, gust, nis) = best.context("kalman.rate_noise / kalman.gust_noise: empty grid")?;
    let design = gust_design(&model, (k.input_noise, rate, gust), &s.cov, &bias)?;
    r.write("kalman.json", design.to_json_string())?;
    let f = fl
        .iter()
        .find(|f| f.experiment.number() == k.flight)
        .context("kalman.flight")?;
    let (est, nis_test) = with_nx!(na, filter_flight(&design, f))?;
    r.text(format!(
        "dlqe on the black-box model augmented with three gust states (a random walk added to the rates \
         every sample, as in kestrel-kalman's flight-test design), process noise through \
         [B, C', 0; 0, 0, I] ({} us per pulse, rate and gust noise per sample), R = the gyro covariance \
         of step 2, bias removed by the filter. Rate and gust noise are chosen on flight no. {} by \
         innovation consistency (mean normalised innovation squared closest to 1): {} and {} rad/s \
         (NIS {}; {} on flight no. {}). The design is `kalman.json` (`kestrel.kalman.v1`); the filter runs \
         over flight no. {} with the logged pulses.",
        k.input_noise,
        k.training_flight,
        fmt_sig(rate, 2),
        fmt_sig(gust, 2),
        fmt_sig(nis, 3),
        fmt_sig(nis_test, 3),
        k.flight,
        k.flight
    ));
    r.table(
        "kalman_noise",
        "Innovation consistency on the training flight (a mean NIS well below 1: the filter \
         over-states its innovation covariance, the pulse noise covering the model error; with less \
         pulse noise the NIS reaches 1 but the estimate of r falls behind the gyro, the model's error \
         being far from white)",
        &choice,
    )?;
    let mut t = Table::new(["signal", "RMS error p", "RMS error q", "RMS error r"]);
    if let Some(truth) = &f.truth {
        let idx: Vec<usize> = (0..f.t.len()).filter(|&k| f.airborne[k]).collect();
        let rms = |g: &dyn Fn(usize) -> [f64; 3], j: usize| {
            (idx.iter()
                .map(|&k| (g(k)[j] - truth[k][j]).powi(2))
                .sum::<f64>()
                / idx.len().max(1) as f64)
                .sqrt()
        };
        let raw = |k: usize| -> [f64; 3] { std::array::from_fn(|j| f.gyro[k][j] - s.bias[j]) };
        let kf = |k: usize| -> [f64; 3] { est[k] };
        t.row(
            std::iter::once("gyro minus bias".to_string()).chain((0..3).map(|j| f4(rms(&raw, j)))),
        );
        t.row(
            std::iter::once("Kalman estimate C x + y0".to_string())
                .chain((0..3).map(|j| f4(rms(&kf, j)))),
        );
        r.table(
            "kalman",
            "Error against the simulator's true body rates over the airborne part (rad/s)",
            &t,
        )?;
        r.text(
            "The filter is only as good as the model: the gust states carry the slowly varying \
             part the identified model misses (gusts, model error), so the filter can average the \
             gyro noise where the model predicts well; the thesis found the gain leaning on the gyro \
             for its roll rate (section 7.5).",
        );
        r.summary(
            "kalman_rms",
            json!({"gyro": (0..3).map(|j| rms(&raw, j)).collect::<Vec<_>>(),
                   "kalman": (0..3).map(|j| rms(&kf, j)).collect::<Vec<_>>()}),
        );
    }
    let idx: Vec<usize> = (0..f.t.len())
        .filter(|&k| f.t[k] >= cfg.kalman.plot_from && f.t[k] <= cfg.kalman.plot_to)
        .collect();
    let tt: Vec<f64> = idx.iter().map(|&k| f.t[k]).collect();
    let names = ["p", "q", "r"];
    let panels: Vec<Panel> = (0..3)
        .map(|j| {
            let mut series = vec![
                Series::line("measured", series_t(&tt, idx.iter().map(|&k| f.gyro[k][j]))),
                Series::line(
                    "Kalman estimate",
                    series_t(&tt, idx.iter().map(|&k| est[k][j])),
                ),
            ];
            if let Some(truth) = &f.truth {
                series.push(Series::dashed(
                    "true",
                    series_t(&tt, idx.iter().map(|&k| truth[k][j])),
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
        &format!("Kalman filter on flight no. {}", cfg.kalman.flight),
        &panels,
    )?;
    r.figure(name, "Kalman estimates over the measurement (figure 7.14)");
    Ok(())
}

// ---------------------------------------------------------------- step 5

/// The two MPC problems.
pub struct Problems {
    /// Design model (the identified black-box model).
    pub model: SsModel,
    /// The estimator's model: the design model, or with `mpc.offset_free`
    /// the model augmented with `nd` constant disturbance states.
    pub estimator_model: SsModel,
    /// Number of disturbance states (0 without `mpc.offset_free`).
    pub nd: usize,
    /// `(name, problem)`: thesis-sized, larger.
    pub list: Vec<(String, MpcProblem, MpqpProblem)>,
}

/// Step 5: the thesis-sized and the larger MPC problem.
pub fn mpc(r: &mut Report, cfg: &Config, id: &Identified) -> anyhow::Result<Problems> {
    r.text("\n## 5. MPC problems (sections 6.1, 7.6)\n");
    let model = id.blackbox.ss.clone();
    let trim = tricopter_trim(&model).context("the black-box model's u0")?;
    let bounds = trim.bounds();
    let m = &cfg.mpc;
    let mut list = Vec::new();
    let (mut estimator_model, mut nd) = (model.clone(), 0);
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
    for (name, h) in [("thesis", &m.thesis), ("larger", &m.larger)] {
        let settings = MpcSettings {
            horizon: h.horizon,
            blocking: Some(
                Blocking::new(h.blocks.clone()).with_context(|| format!("mpc.{name}.blocks"))?,
            ),
            q1: m.q1.weight(),
            q2: m.q2.weight(),
            terminal: Terminal::Lq,
            state_bound: m.state_bound,
            reference_bound: m.reference_bound,
        };
        let p = if m.offset_free {
            let d = MpcProblem::build_offset_free(
                &model,
                &bounds,
                &settings,
                &DisturbanceModel::OutputStates,
            )
            .with_context(|| format!("building the offset-free {name} MPC problem"))?;
            estimator_model = d.augmented;
            nd = d.nd;
            d.problem
        } else {
            MpcProblem::build(&model, &bounds, &settings)
                .with_context(|| format!("building the {name} MPC problem"))?
        };
        let mpqp = p.to_mpqp();
        let file = format!("problems/{name}.json");
        r.write(&file, mpqp.to_json_string())?;
        let eig = mpqp.h.clone().symmetric_eigenvalues();
        let cond = eig.max() / eig.min();
        t.row([
            name.to_string(),
            h.horizon.to_string(),
            format!("{:?}", h.blocks),
            mpqp.n().to_string(),
            mpqp.p().to_string(),
            mpqp.m().to_string(),
            f3(cond),
            format!("`{file}`"),
        ]);
        list.push((name.to_string(), p, mpqp));
    }
    r.text(format!(
        "Condensed MPC (6.19)-(6.26) on the black-box model of order {}: Q1 = {}, Q2 = {}, LQ terminal \
         weight (7.18)-(7.19) from the DARE, move blocking, pulses bounded to 1000-2000 us (motors, moving \
         with the throttle) and +-300 us (servo) around the identified trim; {}",
        model.nx(),
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
    r.table("mpc", "The MPC problems (`kestrel.mpqp.v1`)", &t)?;
    r.summary("offset_free", json!(m.offset_free));
    Ok(Problems {
        model,
        estimator_model,
        nd,
        list,
    })
}

// ---------------------------------------------------------------- step 6

/// The explicit solution of the thesis-sized problem.
pub struct Explicit {
    /// Tree over the whole `z` (for the closed loop and Table 7.2).
    pub full: ExplicitController,
    /// Tree over the first move (the firmware's).
    pub first: ExplicitController,
}

/// Step 6: explicit MPC.
pub fn explicit(r: &mut Report, cfg: &Config, pr: &Problems) -> anyhow::Result<Explicit> {
    r.text("\n## 6. Explicit MPC (sections 6.2, 7.6.1)\n");
    let mut t = Table::new([
        "problem",
        "tree over",
        "regions",
        "distinct laws",
        "tree depth",
        "nodes",
        "bytes (f32)",
        "solve [s]",
        "tree build [s]",
    ]);
    let mut check = Table::new([
        "problem",
        "random theta",
        "outside explored set",
        "max |z_explicit - z_QP| [us]",
        "max |J_explicit - J_QP|",
    ]);
    let mut result = None;
    for (name, _p, mpqp) in &pr.list {
        if name != "thesis" && !cfg.empc.solve_larger {
            continue;
        }
        r.step(&format!("6. explicit MPC: {name}"));
        let sol = kestrel_empc::solve(
            mpqp,
            &kestrel_empc::Settings {
                parallel: true,
                progress: false,
                ..kestrel_empc::Settings::default()
            },
        )
        .with_context(|| format!("explicit solution of the {name} problem"))?;
        let full = build_controller(mpqp, &sol, &TreeSettings::default())?;
        let nu = 4;
        // With one block the first move is all of z: the same tree.
        let first = if mpqp.n() == nu {
            full.clone()
        } else {
            build_controller(
                mpqp,
                &sol,
                &TreeSettings {
                    outputs: Outputs::First(nu),
                    ..TreeSettings::default()
                },
            )?
        };
        for (over, c) in [("all of z", &full), ("first move", &first)] {
            t.row([
                name.clone(),
                over.to_string(),
                sol.regions.len().to_string(),
                c.stats.distinct_laws.to_string(),
                c.stats.depth.to_string(),
                c.stats.nodes.to_string(),
                c.tables.bytes(4).to_string(),
                format!("{:.4}", sol.stats.solve_seconds),
                format!("{:.4}", c.stats.build_seconds),
            ]);
        }
        // Check against clarabel at random parameters.
        let mut qp = ReferenceSolver::new(mpqp, QpSettings::default())?;
        let mut solver = ExplicitSolver::new(full.tables.clone());
        let mut rng = Rng(0x5EED + mpqp.p() as u64);
        let (mut dz, mut dj) = (0.0f64, 0.0f64);
        let mut z = vec![0.0; mpqp.n()];
        for _ in 0..cfg.empc.check_points {
            let th = rng.theta(mpqp);
            let before = solver.outside();
            solver.solve_into(th.as_slice(), &mut z)?;
            if solver.outside() > before {
                continue;
            }
            let q = qp.solve(&th)?;
            let ze = DVector::from_column_slice(&z);
            dz = dz.max((&ze - &q.z).amax());
            dj = dj.max((qp_cost(mpqp, &ze, &th) - qp_cost(mpqp, &q.z, &th)).abs());
        }
        check.row([
            name.clone(),
            cfg.empc.check_points.to_string(),
            solver.outside().to_string(),
            fmt_sig(dz, 3),
            fmt_sig(dj, 3),
        ]);
        r.summary(
            &format!("empc_{name}"),
            json!({"regions": sol.regions.len(), "distinct_laws": full.stats.distinct_laws,
                   "depth": first.stats.depth, "nodes": first.stats.nodes,
                   "bytes_f32_first_move": first.tables.bytes(4),
                   "bytes_f32_all": full.tables.bytes(4),
                   "solve_seconds": sol.stats.solve_seconds,
                   "check_points": cfg.empc.check_points, "outside": solver.outside(),
                   "max_dz": dz, "max_dj": dj}),
        );
        let json_text = kestrel_empc::export::solution_json(&sol, &full, false);
        r.write(&format!("explicit-{name}.json"), json_text)?;
        if name == "thesis" {
            partition_slice(r, cfg, pr.nd, mpqp, &sol, &full)?;
            result = Some(Explicit { full, first });
        }
    }
    r.table(
        "explicit",
        "Explicit solutions and search trees (f32 tables)",
        &t,
    )?;
    r.table(
        "explicit_check",
        "The explicit law against the clarabel QP at random parameters of the box",
        &check,
    )?;
    if !cfg.empc.solve_larger {
        r.text("The larger problem is not solved explicitly by default (`empc.solve_larger`).");
    }
    result.context("no explicit solution of the thesis-sized problem")
}

/// Clips the polygon `poly` by `a . v <= b`.
fn clip(poly: &[(f64, f64)], a: (f64, f64), b: f64) -> Vec<(f64, f64)> {
    let inside = |p: &(f64, f64)| a.0 * p.0 + a.1 * p.1 <= b + 1e-12;
    let mut out = Vec::new();
    for i in 0..poly.len() {
        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
        let (ip, iq) = (inside(&p), inside(&q));
        if ip {
            out.push(p);
        }
        if ip != iq {
            let fp = a.0 * p.0 + a.1 * p.1 - b;
            let fq = a.0 * q.0 + a.1 * q.1 - b;
            let s = fp / (fp - fq);
            out.push((p.0 + s * (q.0 - p.0), p.1 + s * (q.1 - p.1)));
        }
    }
    out
}

fn partition_slice(
    r: &mut Report,
    cfg: &Config,
    nd: usize,
    mpqp: &MpqpProblem,
    sol: &MpqpSolution,
    ctl: &ExplicitController,
) -> anyhow::Result<()> {
    let [i, j] = cfg.empc.slice_axes;
    let p = mpqp.p();
    if i >= p || j >= p {
        bail!("empc.slice_axes = [{i}, {j}]: the problem has {p} parameters (0..{p})");
    }
    let mut theta0 = DVector::zeros(p);
    theta0[p - 1] = cfg.empc.slice_throttle;
    let [xr, yr] = cfg.empc.slice_range;
    let square = vec![
        (xr[0], yr[0]),
        (xr[1], yr[0]),
        (xr[1], yr[1]),
        (xr[0], yr[1]),
    ];
    let mut polys = Vec::new();
    for (k, reg) in sol.regions.iter().enumerate() {
        let rhs = &reg.b - &reg.a * &theta0;
        let mut poly = square.clone();
        for row in 0..reg.a.nrows() {
            poly = clip(&poly, (reg.a[(row, i)], reg.a[(row, j)]), rhs[row]);
            if poly.len() < 3 {
                break;
            }
        }
        if poly.len() >= 3 {
            polys.push(Polygon {
                vertices: poly,
                group: ctl.region_law.get(k).copied().unwrap_or(0) as usize,
            });
        }
    }
    let names = |k: usize| -> String {
        let (na, nx) = (p - 4, p - 4 - nd);
        if k < nx {
            format!("x{}", k + 1)
        } else if k < na {
            format!("d{}", k - nx + 1)
        } else {
            [
                "r_roll [rad/s]",
                "r_pitch [rad/s]",
                "r_yaw [rad/s]",
                "throttle [us]",
            ][k - na]
                .to_string()
        }
    };
    let name = "figures/partition.svg";
    partition_svg(
        &r.path(name),
        &format!(
            "Explicit MPC: {} regions cut by the slice (other parameters 0, throttle {} us)",
            polys.len(),
            cfg.empc.slice_throttle
        ),
        (&names(i), &names(j)),
        (xr[0], xr[1]),
        (yr[0], yr[1]),
        &polys,
    )?;
    r.figure(
        name,
        "A 2-D slice of the explicit-MPC partition (colours: distinct laws)",
    );
    r.summary("partition_slice_regions", json!(polys.len()));
    Ok(())
}

// ---------------------------------------------------------------- step 7

/// The fast-gradient designs.
pub struct Fgm {
    /// Per problem: name, design, certificate for the PWM error.
    pub designs: Vec<(String, FgmDesign, Certificate)>,
}

fn preconditioner(c: PreconditionerChoice) -> Preconditioner {
    match c {
        PreconditionerChoice::None => Preconditioner::None,
        PreconditionerChoice::Jacobi => Preconditioner::Jacobi,
        PreconditionerChoice::OptimalDiagonal => Preconditioner::OptimalDiagonal,
    }
}

/// Step 7: fast-gradient certification.
pub fn fast_gradient(r: &mut Report, cfg: &Config, pr: &Problems) -> anyhow::Result<Fgm> {
    r.text("\n## 7. Fast gradient method: certification (sections 6.3, 7.6.2)\n");
    let mut scaling = Table::new([
        "problem",
        "preconditioner",
        "L",
        "mu",
        "L/mu before",
        "L/mu after",
        "iterations (eps = 1e2) unscaled",
        "iterations (eps = 1e2) scaled",
    ]);
    let mut cert_t = Table::new([
        "problem",
        "eps",
        "certified iterations",
        "random theta",
        "max J(z_i) - J*",
        "holds",
    ]);
    let mut designs = Vec::new();
    let mut all_hold = true;
    for (name, _p, mpqp) in &pr.list {
        r.step(&format!("7. fast gradient: {name}"));
        let qp =
            BoxQp::from_mpqp(mpqp).with_context(|| format!("the {name} problem as a box QP"))?;
        let d = FgmDesign::new(
            qp.clone(),
            FgmSettings {
                preconditioner: preconditioner(cfg.fgm.preconditioner),
                ..FgmSettings::default()
            },
        )?;
        let plain = FgmDesign::new(
            qp,
            FgmSettings {
                preconditioner: Preconditioner::None,
                ..FgmSettings::default()
            },
        )?;
        let pc = &d.preconditioning;
        scaling.row([
            name.clone(),
            pc.method.name().to_string(),
            f4(pc.before.l),
            f4(pc.before.mu),
            f4(pc.before.condition()),
            f4(pc.after.condition()),
            plain.certify(1e2)?.iterations.to_string(),
            d.certify(1e2)?.iterations.to_string(),
        ]);
        let eps_pwm = kestrel_fgm::eps_for_input_error(pc.before.mu, cfg.fgm.pwm_error);
        let mut eps_list: Vec<(String, f64)> = cfg
            .fgm
            .eps_table
            .iter()
            .map(|e| (fmt_sig(*e, 2), *e))
            .collect();
        if eps_pwm > 0.0 {
            eps_list.push((
                format!(
                    "{} ({} us PWM error)",
                    fmt_sig(eps_pwm, 3),
                    cfg.fgm.pwm_error
                ),
                eps_pwm,
            ));
        }
        let certs: Vec<Certificate> = eps_list
            .iter()
            .map(|(_, e)| d.certify(*e))
            .collect::<Result<_, _>>()?;
        // Check every certificate at random theta against clarabel.
        let mut ref_qp = ReferenceSolver::new(mpqp, QpSettings::default())?;
        let mut rng = Rng(0xF6 + mpqp.n() as u64);
        let mut worst = vec![f64::NEG_INFINITY; certs.len()];
        for _ in 0..cfg.fgm.check_points {
            let th = rng.theta(mpqp);
            let q = ref_qp.solve(&th)?;
            let jstar = qp_cost(mpqp, &q.z, &th);
            for (c, w) in certs.iter().zip(worst.iter_mut()) {
                let z = d.solve(c, th.as_slice(), None, c.iterations)?;
                let j = qp_cost(mpqp, &DVector::from_vec(z), &th);
                *w = w.max(j - jstar);
            }
        }
        let mut rows = Vec::new();
        for (((label, eps), c), w) in eps_list.iter().zip(&certs).zip(&worst) {
            // clarabel's own tolerance: allow 1e-6 relative slack on J*.
            let holds = *w <= *eps + 1e-6 * (1.0 + w.abs());
            all_hold &= holds;
            cert_t.row([
                name.clone(),
                label.clone(),
                c.iterations.to_string(),
                cfg.fgm.check_points.to_string(),
                fmt_sig(*w, 3),
                if holds { "yes" } else { "NO" }.to_string(),
            ]);
            rows.push(
                json!({"eps": eps, "iterations": c.iterations, "max_gap": w, "holds": holds}),
            );
        }
        r.summary(
            &format!("fgm_{name}"),
            json!({"certificates": rows, "eps_pwm": eps_pwm,
            "L": pc.before.l, "mu": pc.before.mu}),
        );
        let pwm_cert = if eps_pwm > 0.0 {
            certs.last().cloned().context("no certificate")?
        } else {
            d.certify(
                cfg.fgm
                    .eps_table
                    .iter()
                    .copied()
                    .fold(f64::INFINITY, f64::min),
            )?
        };
        designs.push((name.clone(), d, pwm_cert));
    }
    r.text(format!(
        "Cold-start certificates (Richter, Jones, Morari 2012) of the constant-step fast gradient method on \
         the box-constrained condensed QP, after {} preconditioning. Each certificate is checked at {} \
         random parameters of the box against the clarabel optimum.",
        preconditioner(cfg.fgm.preconditioner).name(),
        cfg.fgm.check_points
    ));
    r.table(
        "fgm_scaling",
        "Conditioning before and after preconditioning",
        &scaling,
    )?;
    r.table(
        "fgm_certificates",
        "Certified iterations for J(z_i) - J* <= eps, checked",
        &cert_t,
    )?;
    r.summary("fgm_all_certificates_hold", json!(all_hold));
    Ok(Fgm { designs })
}

// ---------------------------------------------------------------- step 8

/// Step 8: Table 7.2.
pub fn table_7_2(
    r: &mut Report,
    cfg: &Config,
    _id: &Identified,
    pr: &Problems,
    ex: &Explicit,
    fg: &Fgm,
) -> anyhow::Result<()> {
    r.text("\n## 8. Explicit MPC and fast gradient against the QP (Table 7.2, section 7.7.2)\n");
    let (_, p, mpqp) = &pr.list[0];
    // With the disturbance states, C = [C 0]: x = [pinv(C) y; 0], d = 0.
    let c = &pr.estimator_model.c;
    let rates = DVector::from_column_slice(&cfg.comparison.rates);
    let x = c
        .clone()
        .pseudo_inverse(1e-12)
        .map_err(|e| anyhow::anyhow!("pseudo-inverse of C: {e}"))?
        * &rates;
    let mut rr: Vec<f64> = cfg.comparison.reference.to_vec();
    rr.push(cfg.comparison.throttle);
    let theta = p.theta(x.as_slice(), &rr[..p.layout.n_law_reference()])?;
    let reps = 200;
    let mut qp = ReferenceSolver::new(mpqp, QpSettings::default())?;
    let t0 = Instant::now();
    let mut sol = qp.solve(&theta)?;
    for _ in 1..reps {
        sol = qp.solve(&theta)?;
    }
    let t_qp = t0.elapsed().as_secs_f64() / reps as f64;
    let jstar = qp_cost(mpqp, &sol.z, &theta);
    let mut t = Table::new([
        "solver",
        "iterations",
        "eps",
        "J(U, theta)",
        "J - J*",
        "U1 [us]",
        "U2 [us]",
        "U3 [us]",
        "U4 [us]",
        "max |U - U*| [us]",
        "host time [us]",
    ]);
    let row =
        |t: &mut Table, solver: &str, it: String, eps: String, z: &DVector<f64>, secs: f64| {
            let j = qp_cost(mpqp, z, &theta);
            let du = (0..4).map(|i| (z[i] - sol.z[i]).abs()).fold(0.0, f64::max);
            let mut cells = vec![
                solver.to_string(),
                it,
                eps,
                fmt_sig(j, 7),
                fmt_sig(j - jstar, 3),
            ];
            cells.extend((0..4).map(|i| format!("{:.3}", z[i])));
            cells.push(fmt_sig(du, 3));
            cells.push(format!("{:.2}", secs * 1e6));
            t.row(cells);
        };
    row(
        &mut t,
        "QP (clarabel)",
        "-".into(),
        "-".into(),
        &sol.z.clone(),
        t_qp,
    );
    let mut es = ExplicitSolver::new(ex.full.tables.clone());
    let mut z = vec![0.0; mpqp.n()];
    let t0 = Instant::now();
    for _ in 0..reps {
        es.solve_into(theta.as_slice(), &mut z)?;
    }
    let t_ex = t0.elapsed().as_secs_f64() / reps as f64;
    row(
        &mut t,
        "explicit MPC",
        "-".into(),
        "-".into(),
        &DVector::from_column_slice(&z),
        t_ex,
    );
    let (_, d, _) = &fg.designs[0];
    let mut runs: Vec<(usize, String)> = cfg
        .comparison
        .iterations
        .iter()
        .map(|k| (*k, "(fixed)".to_string()))
        .collect();
    for e in &cfg.fgm.eps_table {
        runs.push((d.certify(*e)?.iterations, fmt_sig(*e, 2)));
    }
    let cpwm = &fg.designs[0].2;
    runs.push((cpwm.iterations, format!("{} (PWM)", fmt_sig(cpwm.eps, 3))));
    let mut fgm_rows = Vec::new();
    for (k, eps) in runs {
        let t0 = Instant::now();
        let mut zf = d.solve(cpwm, theta.as_slice(), None, k)?;
        for _ in 1..reps {
            zf = d.solve(cpwm, theta.as_slice(), None, k)?;
        }
        let secs = t0.elapsed().as_secs_f64() / reps as f64;
        let zf = DVector::from_vec(zf);
        fgm_rows.push(json!({"iterations": k, "J": qp_cost(mpqp, &zf, &theta)}));
        row(&mut t, "fast gradient", k.to_string(), eps, &zf, secs);
    }
    r.text(format!(
        "Thesis-sized problem, initial body rates {:?} rad/s (x = pinv(C) y), references {:?} rad/s, \
         throttle {} us. U is the first move, pulses from the trim (us). Host times are means over {reps} \
         solves on this machine (the AVR figures are kestrel-avr-rt's).",
        cfg.comparison.rates, cfg.comparison.reference, cfg.comparison.throttle
    ));
    r.table(
        "table_7_2",
        "Table 7.2: cost and first move of each solver",
        &t,
    )?;
    r.summary(
        "table_7_2",
        json!({"J_qp": jstar, "U_qp": sol.z.as_slice()[..4], "U_explicit": z[..4], "fgm": fgm_rows}),
    );
    Ok(())
}

// ---------------------------------------------------------------- step 9

/// Step 9: closed-loop runs on the nonlinear tricopter.
pub fn closed_loop(
    r: &mut Report,
    cfg: &Config,
    _id: &Identified,
    pr: &Problems,
    ex: &Explicit,
    fg: &Fgm,
) -> anyhow::Result<()> {
    r.text("\n## 9. Closed loop on the nonlinear tricopter (section 7.7)\n");
    let cl = &cfg.closed_loop;
    let model = &pr.model;
    let (_, problem, mpqp) = &pr.list[0];
    let (_, d, _) = &fg.designs[0];
    let scenario = Scenario {
        duration: cl.duration,
        initial_rates: cl.initial_rates,
        initial_reference: [0.0; 3],
        steps: vec![ReferenceStep {
            time: cl.step_time,
            rates: cl.step,
        }],
        throttle: None,
    };
    let quiet = PlantConfig {
        gyro: GyroConfig::ideal(),
        gust: GustConfig::calm(),
        ..PlantConfig::default()
    };
    let noisy = PlantConfig::default();
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
    let mut traces: Vec<(String, String, Trace)> = Vec::new();
    let mut worst_violation = 0.0f64;
    for (run, config) in [("step", quiet), ("noisy", noisy)] {
        let settings = RunSettings {
            scenario: scenario.clone(),
            plant: PlantKind::Nonlinear,
            config,
            seed: cl.seed,
        };
        // The plain or the offset-free design, the same law either way.
        let offset_free = OffsetFreeDesign {
            augmented: pr.estimator_model.clone(),
            problem: problem.clone(),
            nd: pr.nd,
        };
        fn fly_law<S: ParametricQpSolver>(
            pr: &Problems,
            design: &OffsetFreeDesign,
            law: &mut MpcLaw<S>,
            settings: &RunSettings,
        ) -> Result<kestrel_mpc::sim::RunResult, kestrel_mpc::MpcError> {
            if pr.nd > 0 {
                fly_offset_free(design, law, settings)
            } else {
                fly_mpc(&pr.model, &design.problem, law, settings)
            }
        }
        macro_rules! fly {
            ($law:expr) => {
                fly_law(pr, &offset_free, $law, &settings)
            };
        }
        let mut ctrls: Vec<String> = vec!["PI".into(), "QP".into(), "explicit".into()];
        ctrls.extend(cl.fgm_iterations.iter().map(|k| format!("FGM-{k}")));
        for c in ctrls {
            r.step(&format!("9. closed loop: {run} {c}"));
            let res = match c.as_str() {
                "PI" => fly_pi(model, &settings)?,
                "QP" => {
                    let s = ReferenceSolver::new(mpqp, QpSettings::default())?;
                    fly!(&mut MpcLaw::new(problem, s)?)?
                }
                "explicit" => {
                    let s = ExplicitSolver::new(ex.full.tables.clone());
                    fly!(&mut MpcLaw::new(problem, s)?)?
                }
                other => {
                    let k: usize = other.trim_start_matches("FGM-").parse()?;
                    let s = FastGradientSolver::from_design(
                        d,
                        &FgmOptions {
                            iterations: k,
                            start: FgmStart::Cold,
                            settings: d.settings,
                        },
                    )?;
                    fly!(&mut MpcLaw::new(problem, s)?)?
                }
            };
            let (trace, m) = (res.trace, res.metrics);
            let file = format!("closed-loop/{run}-{}.csv", c.to_lowercase());
            r.write(&file, trace.to_csv())?;
            let (mut lo, mut hi, mut slo, mut shi) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            for row in &trace.rows {
                for v in &row.pwm[..3] {
                    lo = lo.min(*v);
                    hi = hi.max(*v);
                }
                slo = slo.min(row.pwm[3]);
                shi = shi.max(row.pwm[3]);
            }
            worst_violation = worst_violation.max(m.max_bound_violation);
            let j3 = |v: &[f64]| {
                v.iter()
                    .map(|x| fmt_sig(*x, 3))
                    .collect::<Vec<_>>()
                    .join(" / ")
            };
            t.row([
                run.to_string(),
                c.clone(),
                j3(&m.rise_time),
                j3(&m.overshoot),
                j3(&m.rms_error),
                j3(&m.effort),
                format!("{lo:.0}..{hi:.0}"),
                format!("{slo:.0}..{shi:.0}"),
                fmt_sig(m.max_bound_violation, 3),
                format!("`{file}`"),
            ]);
            if run == "step" && (c == "QP" || c == "PI") {
                r.summary(
                    &format!("closed_loop_step_{}", c.to_lowercase()),
                    json!({"effort": m.effort, "rise_time": m.rise_time, "overshoot": m.overshoot,
                           "rms_error": m.rms_error}),
                );
            }
            traces.push((run.to_string(), c, trace));
        }
    }
    r.text(format!(
        "The identified black-box model's MPC (thesis-sized problem) with kestrel-mpc's closed-loop Kalman \
         filter flies kestrel-tricopter-model's nonlinear aircraft: released at {:?} rad/s, a step to {:?} \
         rad/s at {} s, {} s in all. `step`: no gyro noise or gusts (7.7.1); `noisy`: gyro noise, bias and \
         gusts, seed {} (figures 7.18-7.21). The baseline is the ACRO rate PI of kestrel-tricopter-model. \
         FGM-k: the fast gradient method with k iterations, cold start.",
        cl.initial_rates, cl.step, cl.step_time, cl.duration, cl.seed
    ));
    r.table(
        "closed_loop",
        "Closed-loop runs against the baseline PI",
        &t,
    )?;
    r.summary("closed_loop_max_bound_violation", json!(worst_violation));
    // Figures 7.16-7.17: the step scenario, outputs and pulses.
    let pick = |run: &str, c: &str| {
        traces
            .iter()
            .find(|(a, b, _)| a == run && b == c)
            .map(|x| &x.2)
    };
    let rate_panels = |run: &str, ctrls: &[String]| -> Vec<Panel> {
        (0..3)
            .map(|j| {
                let mut series = Vec::new();
                if let Some(tr) = pick(run, &ctrls[0]) {
                    series.push(Series::dashed(
                        "reference",
                        tr.rows.iter().map(|w| (w.t, w.reference[j])).collect(),
                    ));
                }
                for c in ctrls {
                    if let Some(tr) = pick(run, c) {
                        series.push(Series::line(
                            c.clone(),
                            tr.rows.iter().map(|w| (w.t, w.rates[j])).collect(),
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
    let main: Vec<String> = vec!["QP".into(), "explicit".into(), "PI".into()];
    panels_svg(
        &r.path("figures/closed-loop-step-rates.svg"),
        "Step scenario: body rates",
        &rate_panels("step", &main),
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
                    pick("step", c).map(|tr| {
                        Series::line(c.clone(), tr.rows.iter().map(|w| (w.t, w.pwm[i])).collect())
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
    for k in &cl.fgm_iterations {
        let ctrls: Vec<String> = vec!["QP".into(), "explicit".into(), format!("FGM-{k}")];
        let name = format!("figures/closed-loop-noisy-fgm-{k}.svg");
        panels_svg(
            &r.path(&name),
            &format!(
                "Noisy run: QP, explicit MPC and the fast gradient method with {k} iterations"
            ),
            &rate_panels("noisy", &ctrls),
        )?;
        r.figure(
            &name,
            &format!("Noisy run with {k} fast-gradient iterations (figures 7.18-7.21)"),
        );
    }
    let _ = mpqp;
    Ok(())
}

// ---------------------------------------------------------------- step 10

/// Step 10: firmware tables.
pub fn firmware(
    r: &mut Report,
    cfg: &Config,
    pr: &Problems,
    ex: &Explicit,
    fg: &Fgm,
) -> anyhow::Result<()> {
    r.text("\n## 10. Firmware tables (section 7.8)\n");
    let mut t = Table::new(["file", "what", "scalar", "bytes of source"]);
    let (escalar, fscalar, name) = match cfg.firmware.scalar {
        FirmwareScalar::F32 => (
            kestrel_empc::export::ExportScalar::F32,
            kestrel_fgm::ExportScalar::F32,
            "f32",
        ),
        FirmwareScalar::Q16 => (
            kestrel_empc::export::ExportScalar::Q16,
            kestrel_fgm::ExportScalar::Q16,
            "q16",
        ),
    };
    let src = kestrel_empc::export::rust_source(&ex.first.tables, escalar)?;
    r.write("firmware/empc_tables.rs", &src)?;
    t.row([
        "`firmware/empc_tables.rs`".to_string(),
        format!(
            "explicit MPC search tree, first move ({} bytes of tables in f32)",
            ex.first.tables.bytes(4)
        ),
        name.to_string(),
        src.len().to_string(),
    ]);
    let (_, d, cert) = &fg.designs[0];
    let src = match cfg.firmware.scalar {
        FirmwareScalar::F32 => {
            kestrel_fgm::export_rust("FGM", &d.data::<f32>(cert, None)?, fscalar)
        }
        FirmwareScalar::Q16 => {
            kestrel_fgm::export_rust("FGM", &d.data::<kestrel_core::Q16>(cert, None)?, fscalar)
        }
    };
    r.write("firmware/fgm_tables.rs", &src)?;
    t.row([
        "`firmware/fgm_tables.rs`".to_string(),
        format!(
            "fast gradient data, thesis-sized problem, {} certified iterations",
            cert.iterations
        ),
        name.to_string(),
        src.len().to_string(),
    ]);
    let design = kalman_design_with_disturbance(&pr.estimator_model, pr.nd)?;
    let text = design.to_json_string();
    r.write("firmware/kalman.json", &text)?;
    t.row([
        "`firmware/kalman.json`".to_string(),
        "the closed loop's stationary Kalman filter (kestrel.kalman.v1)".to_string(),
        "f64".to_string(),
        text.len().to_string(),
    ]);
    r.table("firmware", "Tables for avr/firmware", &t)?;
    r.text(
        "The example firmware in `avr/firmware` is generated by kestrel-avr-rt's own table generator \
         (`cargo run -p kestrel-avr-rt --example avr_tables`); these files are the same kinds of tables for \
         the pipeline's identified model.",
    );
    Ok(())
}

// ---------------------------------------------------------------- step 11

/// Step 11: where our numbers differ from the thesis's, and why.
pub fn differences(r: &mut Report, cfg: &Config) -> anyhow::Result<()> {
    r.text("\n## 11. Differences from the thesis\n");
    let s = r.summary.clone();
    let get = |path: &[&str]| -> Option<serde_json::Value> {
        let mut v = s.get(path[0])?.clone();
        for p in &path[1..] {
            v = v.get(*p)?.clone();
        }
        Some(v)
    };
    let fmt_fit = |v: Option<serde_json::Value>| -> String {
        v.and_then(|v| {
            v.as_array().map(|a| {
                a.iter()
                    .filter_map(|x| x.as_f64())
                    .map(|x| format!("{x:.1}"))
                    .collect::<Vec<_>>()
                    .join(" / ")
            })
        })
        .unwrap_or_else(|| "-".into())
    };
    let mut t = Table::new(["quantity", "thesis", "here", "why they differ"]);
    t.row([
        "black-box simulation fit p/q/r [%]".to_string(),
        "41.41 / 43.08 / 42.7".into(),
        fmt_fit(get(&["fit_blackbox", "simulation"])),
        "a simulated aircraft (no vibration, no unmodelled frame dynamics, known noise) instead of the real \
         one; PEM from an N4SID start with exact gradients instead of MATLAB's ssest"
            .into(),
    ]);
    t.row([
        "black-box 5-step fit p/q/r [%]".to_string(),
        "31.39 / 41.54 / 52.18".into(),
        fmt_fit(get(&["fit_blackbox", "five_step"])),
        "as above".into(),
    ]);
    t.row([
        "black-box virtual simulation fit p/q/r [%]".to_string(),
        "58.62 / 45.23 / 42.25".into(),
        fmt_fit(get(&["fit_virtual", "simulation"])),
        "as above; the virtual inputs here are the logged mixer inputs".into(),
    ]);
    t.row([
        "trim U0 [us]".to_string(),
        "15.63, 0.85, -16.01, 1467.7".into(),
        get(&["sensor", "u0"])
            .and_then(|v| v.as_array().cloned())
            .map(|a| {
                a.iter()
                    .filter_map(|x| x.as_f64())
                    .map(|x| format!("{x:.2}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_default(),
        "kestrel-tricopter-model's default aircraft is physically consistent (ERRATA: Table 7.1 is not), \
         so its trim differs from the real aircraft's"
            .into(),
    ]);
    t.row([
        "explicit MPC, thesis-sized: tables".to_string(),
        "about 35 kB, about 3 ms on the ATmega2560".into(),
        format!(
            "{} regions, {} bytes (f32, first move), depth {}",
            get(&["empc_thesis", "regions"]).unwrap_or_default(),
            get(&["empc_thesis", "bytes_f32_first_move"]).unwrap_or_default(),
            get(&["empc_thesis", "depth"]).unwrap_or_default()
        ),
        "a binary search tree over the regions' hyperplanes with shared identical laws and u16 indices \
         (MPT's exported tree stores every region's full law); the AVR cycle figures are kestrel-avr-rt's"
            .into(),
    ]);
    let certs = get(&["fgm_thesis", "certificates"])
        .and_then(|v| v.as_array().cloned())
        .unwrap_or_default();
    let cert_text = certs
        .iter()
        .map(|c| {
            format!(
                "{} (eps {})",
                c.get("iterations").cloned().unwrap_or_default(),
                c.get("eps")
                    .and_then(|e| e.as_f64())
                    .map(|e| fmt_sig(e, 2))
                    .unwrap_or_default()
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    t.row([
        "fast gradient, certified iterations".to_string(),
        "25, 56, 73, 91 for eps 1e5 ... 1e2".into(),
        cert_text,
        "our weights and model differ (Q1, Q2 and the identified model set the scale of J), the bound is \
         the cold-start certificate of Richter et al. after an optimal diagonal preconditioner; the \
         thesis's FiOrdOs numbers are for its own scaling"
            .into(),
    ]);
    t.row([
        "Table 7.2 optimal cost J*".to_string(),
        "4039.228".into(),
        get(&["table_7_2", "J_qp"])
            .and_then(|v| v.as_f64())
            .map(|v| fmt_sig(v, 7))
            .unwrap_or_default(),
        "J here is the condensed QP objective 1/2 z'Hz + theta'F z without the constant term in theta \
         (so it can be negative); it depends on the weights and the model; the initial state is the \
         least-norm state with the thesis's rates y = [0.2, 0.3, 0.4], not the thesis's x (a different \
         state basis)"
            .into(),
    ]);
    let arr = |path: &[&str]| -> String {
        get(path)
            .and_then(|v| v.as_array().cloned())
            .map(|a| {
                a.iter()
                    .filter_map(|x| x.as_f64())
                    .map(|x| fmt_sig(x, 3))
                    .collect::<Vec<_>>()
                    .join(" / ")
            })
            .unwrap_or_default()
    };
    t.row([
        "closed loop, black-box MPC: pulse effort pwm1/2/3/servo".to_string(),
        "motors 1 and 2 peak at about 150 us, motor 3 at about 400 us: only motor 3 works (7.7.1)"
            .into(),
        format!(
            "RMS {} us (QP); the PI: {} us",
            arr(&["closed_loop_step_qp", "effort"]),
            arr(&["closed_loop_step_pi", "effort"])
        ),
        "our model is identified from a simulated, symmetric aircraft with a consistent mixer; the \
         thesis's black-box model was fitted to a real, unbalanced one"
            .into(),
    ]);
    t.row([
        "closed loop: rise time p/q/r after the step".to_string(),
        "not reported (figures only)".into(),
        format!(
            "{} s (QP) against {} s (PI)",
            arr(&["closed_loop_step_qp", "rise_time"]),
            arr(&["closed_loop_step_pi", "rise_time"])
        ),
        "the thesis compared solvers, not the MPC against the PI".into(),
    ]);
    t.row([
        "closed loop: MPC design".to_string(),
        "plain MPC, Q2 the same on all four pulses".into(),
        format!(
            "{}; Q2 = {}",
            if get(&["offset_free"]).and_then(|v| v.as_bool()) == Some(true) {
                "offset-free MPC (three torque disturbances estimated by the Kalman filter)"
            } else {
                "plain MPC"
            },
            cfg.mpc.q2
        ),
        "the identified 5-state model's steady-state gain is off (truncation from order 8 keeps \
         D = 0 but not the DC gain, and the near-integrating rate dynamics make the gain hard to \
         identify): the plain MPC then stops short of the pitch reference (never 90 % of the step). \
         With the offset-free MPC and the same weight on every pulse the yaw loop bangs the servo \
         between its limits; a ten times larger weight on the servo settles it"
            .into(),
    ]);
    r.table(
        "differences",
        "Where our numbers differ from the thesis's",
        &t,
    )?;
    // Outputs whose validation data hardly move: their fit says little.
    let noise: Vec<f64> = get(&["sensor", "covariance_diag"])
        .and_then(|v| v.as_array().cloned())
        .unwrap_or_default()
        .iter()
        .filter_map(|x| x.as_f64())
        .map(f64::sqrt)
        .collect();
    for (key, label) in [("blackbox", "black-box"), ("virtual", "black-box virtual")] {
        let stds: Vec<f64> = get(&[&format!("fit_{key}"), "validation_std"])
            .and_then(|v| v.as_array().cloned())
            .unwrap_or_default()
            .iter()
            .filter_map(|x| x.as_f64())
            .collect();
        let weak: Vec<String> = stds
            .iter()
            .zip(&noise)
            .zip(["p", "q", "r"])
            .filter(|((s, n), _)| **s < 10.0 * **n)
            .map(|((s, n), o)| {
                format!(
                    "{o} (std {} rad/s, gyro noise {} rad/s)",
                    fmt_sig(*s, 2),
                    fmt_sig(*n, 2)
                )
            })
            .collect();
        if !weak.is_empty() {
            r.text(format!(
                "\nThe {label} model's validation intervals (the thesis's, chosen for its own flights) hardly \
                 excite {}: less than ten times the gyro noise, so the fit of those outputs (normalised by \
                 their variance) says little about the model. kestrel-tricopter-model's flight no. 2 excites \
                 the axes in turn, which does not line up with the real flight's intervals (see the excitation \
                 table of section 3).\n",
                weak.join(", ")
            ));
        }
    }
    r.text(
        "Beyond the numbers:\n\n\
         - Printed equations corrected (ERRATA.md): the S_u block column (6.13), the constraint \
           matrices (6.22d-e), the active-set law with the linear cost term (6.28), the Riccati \
           equation (7.18), the Kalman time update from the filtered estimate (5.12c, 5.15b), \
           the mixer constants C_r = 1/sqrt(3), C_p = 2/3, C_y = 1 and Nesterov's beta.\n\
         - The thesis's MPC ran with Ns = 1 because MPT's tree did not fit; here the explicit law of \
           the thesis-sized problem is small enough to keep whole, and the larger problem \
           (N = 10, blocks [1, 1, 2, 6]) is solved by the fast gradient method with a certificate.\n\
         - The fast gradient method is cold-started here in the closed loop as in the thesis; the \
           AVR runtime warm-starts it (kestrel-avr-rt).\n\
         - The thesis found the estimated models non-minimum phase; the transmission zeros of our \
           models are in the identification table, from the simulator, which has no propeller \
           flexibility or frame vibration.\n\
         - The closed loop here flies the nonlinear 6-DOF simulator, not the identified linear model \
           as in the thesis's figures 7.16-7.21, so model error is part of every run.\n\
         - The identification is kestrel-sysid's workflow (PEM on simulation errors, then the noise \
           model), not MATLAB's one-step `ssest`: on closed-loop flights of near-integrating rate \
           dynamics the one-step optimum drifts in simulation.",
    );
    Ok(())
}
