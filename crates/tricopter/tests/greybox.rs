//! Grey-box identification of the tricopter's physical parameters
//! (issue 4, grey-box item): recovery on simulated flights, convergence on
//! noiseless data, the analytic gradient against finite differences of
//! the cost, bad input.

use kestrel_sysid::workflow::{Segment, select_segments};
use kestrel_sysid::{Experiment, IoData, StopReason, SysidError};
use kestrel_tricopter::ident::greybox::{
    GreyBoxFocus, GreyBoxSpec, Stage, cost_gradient, estimate_grey_box, grey_box_model,
};
use kestrel_tricopter::ident::{ESTIMATE, ModelKind, VALIDATE, identify_thesis_model};
use kestrel_tricopter_model::{
    Experiment as Flight, GreyBoxParams, Params, RateInputs, RateModelKind, SimSettings, simulate,
};
use nalgebra::{DMatrix, DVector};

/// Deterministic multi-level pulses (a different period per input).
fn pulses(n: usize, nu: usize, seed: usize) -> DMatrix<f64> {
    DMatrix::from_fn(n, nu, |t, j| {
        let period = 9 + 4 * j + seed;
        let level = ((t / period) * 7 + j * 3 + seed) % 5;
        10.0 * (level as f64 - 2.0)
    })
}

/// Noiseless data of the grey-box model of `g`: two experiments with
/// non-zero initial states.
fn linear_data(g: &GreyBoxParams, spec: &GreyBoxSpec, n: usize) -> IoData {
    let m = grey_box_model(g, spec, 0.02).unwrap();
    let exps = (0..2)
        .map(|e| {
            let u = pulses(n, m.nu(), e);
            let x0 = DVector::from_fn(m.nx(), |i, _| 0.05 * ((i + e) % 3) as f64);
            let y = m.simulate(&u, &x0).unwrap();
            Experiment {
                t: (0..n).map(|k| k as f64 * 0.02).collect(),
                u,
                y,
            }
        })
        .collect();
    let inputs: Vec<String> = if m.nu() == 4 {
        ["pwm1", "pwm2", "pwm3", "servo"].map(String::from).to_vec()
    } else {
        ["u_roll", "u_pitch", "u_yaw"].map(String::from).to_vec()
    };
    IoData::from_experiments(
        0.02,
        inputs,
        ["p", "q", "r"].map(String::from).to_vec(),
        exps,
    )
    .unwrap()
}

fn truth() -> GreyBoxParams {
    GreyBoxParams::from_params(&SimSettings::new(Flight::Decoupled, 10.0, 1).plant.params)
}

/// The combinations the rate data determine best (see the module docs):
/// `sqrt(k_t)/I_xx`, `sqrt(k_t)/I_yy`, `I_zz`, `k_tau/sqrt(k_t)`.
fn combinations(g: &GreyBoxParams) -> [f64; 4] {
    let s = g.k_t.sqrt();
    [s / g.ixx, s / g.iyy, g.izz, g.k_tau / s]
}

#[test]
fn noiseless_data_converge_to_the_truth_from_table_7_1() {
    let spec = GreyBoxSpec::default();
    let truth = truth();
    let data = linear_data(&truth, &spec, 600);
    let initial = GreyBoxParams::thesis_initial_guess();
    let r = estimate_grey_box(&data, &spec, &initial).unwrap();
    // Table 7.1 cannot hover with the known aircraft: k_tau was reduced.
    assert!(r.start_adjusted && r.start.k_tau < initial.k_tau);
    for (i, (e, t)) in r
        .estimate
        .to_array()
        .iter()
        .zip(truth.to_array())
        .enumerate()
    {
        assert!(
            (e / t - 1.0).abs() < 1e-6,
            "{}: {e} vs {t}\n{r}",
            GreyBoxParams::NAMES[i]
        );
    }
    assert!(r.cost < 1e-12 * r.initial_cost, "{r}");
    // The fit table comes from the crate's validate: a perfect simulation.
    let sim = r.fit.row("model simulation").unwrap();
    assert!(sim.fit.iter().all(|f| *f > 99.99), "{r}");
    // Every free parameter has a (tiny) standard error, as printed.
    assert!(r.parameters.iter().all(|p| p.std_error.is_some()));
    assert!(r.to_string().contains("servo_zeta"));
}

#[test]
fn noiseless_prediction_focus_with_disturbance_converges() {
    let spec = GreyBoxSpec::closed_loop_flights(Params::default());
    let truth = truth();
    let data = linear_data(&truth, &spec, 500);
    let start = GreyBoxParams::from_array(&truth.to_array().map(|v| 1.3 * v));
    let r = estimate_grey_box(&data, &spec, &start).unwrap();
    for (e, t) in r.estimate.to_array().iter().zip(truth.to_array()) {
        assert!((e / t - 1.0).abs() < 1e-5, "{r}");
    }
    assert!(r.model.radius_predictor() < 1.0);
}

/// Central differences of `J` against the analytic gradient, for the
/// simulation and the prediction criterion (with `K` and the disturbance
/// states), in every parameter group: log physical parameters, `K`, `x0`.
#[test]
fn gradient_matches_finite_differences_of_the_cost() {
    for focus in [GreyBoxFocus::Simulation, GreyBoxFocus::Prediction] {
        let mut spec = GreyBoxSpec {
            focus,
            disturbance: focus == GreyBoxFocus::Prediction,
            ..Default::default()
        };
        let data = linear_data(&truth(), &spec, 150);
        // Evaluate away from the truth so that the residuals are not zero.
        let g = GreyBoxParams::from_array(&[0.05, 0.045, 0.085, 1.7e-5, 2.5e-7, 0.06, 25.0, 0.6]);
        let m = grey_box_model(&g, &spec, 0.02).unwrap();
        let (nx, ny) = (m.nx(), m.ny());
        let k = (focus == GreyBoxFocus::Prediction).then(|| {
            let mut k = &m.a * m.c.transpose() * 0.7;
            k[(nx - 1, 2)] = 3.0;
            k
        });
        let x0: Vec<DVector<f64>> = (0..2)
            .map(|e| DVector::from_fn(nx, |i, _| 0.01 * (i as f64 - e as f64)))
            .collect();
        let cg = cost_gradient(&data, &spec, &g, k.as_ref(), &x0).unwrap();
        let nk = if k.is_some() { nx * ny } else { 0 };
        assert_eq!(cg.gradient.len(), 8 + nk + 2 * nx);
        let j = |g: &GreyBoxParams, k: Option<&DMatrix<f64>>, x0: &[DVector<f64>]| {
            cost_gradient(&data, &spec, g, k, x0).unwrap().cost
        };
        let mut checked = 0;
        for p in 0..cg.gradient.len() {
            let h: f64 = if p < 8 { 1e-5 } else { 1e-6 };
            let (plus, minus) = if p < 8 {
                let mut gp = g.to_array();
                let mut gm = g.to_array();
                gp[p] *= h.exp();
                gm[p] *= (-h).exp();
                (
                    j(&GreyBoxParams::from_array(&gp), k.as_ref(), &x0),
                    j(&GreyBoxParams::from_array(&gm), k.as_ref(), &x0),
                )
            } else if p < 8 + nk {
                let (r, c) = ((p - 8) / ny, (p - 8) % ny);
                let mut kp = k.clone().unwrap();
                let mut km = kp.clone();
                kp[(r, c)] += h;
                km[(r, c)] -= h;
                (j(&g, Some(&kp), &x0), j(&g, Some(&km), &x0))
            } else {
                let q = p - 8 - nk;
                let (e, i) = (q / nx, q % nx);
                let mut xp = x0.clone();
                let mut xm = x0.clone();
                xp[e][i] += h;
                xm[e][i] -= h;
                (j(&g, k.as_ref(), &xp), j(&g, k.as_ref(), &xm))
            };
            let fd = (plus - minus) / (2.0 * h);
            let an = cg.gradient[p];
            let scale = an.abs().max(fd.abs()).max(1e-6 * cg.cost);
            assert!(
                (an - fd).abs() <= 2e-4 * scale,
                "{focus:?} parameter {p}: analytic {an:e}, finite differences {fd:e}"
            );
            checked += 1;
        }
        assert!(checked > 20);
        // Wrong shapes are errors, not panics.
        assert!(cost_gradient(&data, &spec, &g, k.as_ref(), &x0[..1]).is_err());
        spec.focus = GreyBoxFocus::Simulation;
        let bad_k = DMatrix::zeros(2, 2);
        assert!(cost_gradient(&data, &spec, &g, Some(&bad_k), &x0).is_err());
    }
}

#[test]
fn bad_input_gives_errors() {
    let spec = GreyBoxSpec::default();
    let truth = truth();
    let data = linear_data(&truth, &spec, 200);
    // NaN in the data.
    let mut exps = data.experiments().to_vec();
    exps[1].y[(17, 2)] = f64::NAN;
    let nan = IoData::from_experiments(
        0.02,
        data.input_names().to_vec(),
        data.output_names().to_vec(),
        exps,
    );
    let nan = match nan {
        Ok(d) => estimate_grey_box(&d, &spec, &truth).unwrap_err(),
        Err(e) => e,
    };
    assert!(matches!(nan, SysidError::NonFinite { .. }), "{nan}");
    // Wrong columns: three inputs for the PWM model.
    let e0 = &data.experiments()[0];
    let three = IoData::new(0.02, e0.u.columns(0, 3).into_owned(), e0.y.clone()).unwrap();
    let err = estimate_grey_box(&three, &spec, &truth).unwrap_err();
    assert!(matches!(err, SysidError::Dimension { .. }), "{err}");
    // Two outputs.
    let two = IoData::new(0.02, e0.u.clone(), e0.y.columns(0, 2).into_owned()).unwrap();
    assert!(matches!(
        estimate_grey_box(&two, &spec, &truth).unwrap_err(),
        SysidError::Dimension { .. }
    ));
    // Non-positive or non-finite initial parameters name the parameter.
    for (i, v) in [(0, 0.0), (3, -1e-5), (6, f64::NAN), (7, f64::INFINITY)] {
        let mut g = truth;
        g.set(i, v).unwrap();
        let e = estimate_grey_box(&data, &spec, &g).unwrap_err().to_string();
        assert!(e.contains(GreyBoxParams::NAMES[i]), "{e}");
    }
    // A parameter the static rate model does not depend on.
    let rates = GreyBoxSpec {
        kind: RateModelKind::Rates,
        ..Default::default()
    };
    let e = estimate_grey_box(&data, &rates, &truth)
        .unwrap_err()
        .to_string();
    assert!(e.contains("motor_tau"), "{e}");
    // No free parameter; an unknown name; bounds that exclude the start.
    let none = GreyBoxSpec {
        free: [false; 8],
        ..Default::default()
    };
    assert!(estimate_grey_box(&data, &none, &truth).is_err());
    assert!(GreyBoxSpec::with_free(&["ixx", "mass"]).is_err());
    let mut bounded = GreyBoxSpec::default();
    bounded.upper.ixx = 0.01;
    assert!(estimate_grey_box(&data, &bounded, &truth).is_err());
    // Too few samples for the parameters.
    let short = IoData::new(
        0.02,
        e0.u.rows(0, 12).into_owned(),
        e0.y.rows(0, 12).into_owned(),
    )
    .unwrap();
    assert!(matches!(
        estimate_grey_box(&short, &spec, &truth).unwrap_err(),
        SysidError::TooFewSamples { .. }
    ));
    // An initial guess that cannot hover with k_tau fixed.
    let fixed_tau = GreyBoxSpec::with_free(&["ixx", "iyy", "izz", "k_t"]).unwrap();
    let e = estimate_grey_box(&data, &fixed_tau, &GreyBoxParams::thesis_initial_guess())
        .unwrap_err()
        .to_string();
    assert!(e.contains("trim"), "{e}");
}

/// Flights no. 2 and 3 of the simulator, shortened (65 s, excitation from
/// 10 s): estimation on 12-60 s of both, the closed-loop spec with `k_t`,
/// `k_tau` from the operating point, started from the thesis's Table 7.1.
#[test]
fn short_flights_recover_the_identifiable_parameters() {
    let seconds = 65.0;
    let mut exps = Vec::new();
    for flight in [Flight::Decoupled, Flight::Coupled] {
        let log = simulate(&SimSettings::new(flight, seconds, 3)).unwrap();
        let n = log.rows.len();
        exps.push(Experiment {
            t: log.rows.iter().map(|r| r.t).collect(),
            u: DMatrix::from_fn(n, 4, |k, j| log.rows[k].pwm[j]),
            y: DMatrix::from_fn(n, 3, |k, j| log.rows[k].gyro[j]),
        });
    }
    let flights = IoData::from_experiments(
        0.02,
        ["pwm1", "pwm2", "pwm3", "servo"].map(String::from).to_vec(),
        ["p", "q", "r"].map(String::from).to_vec(),
        exps,
    )
    .unwrap();
    let est = select_segments(&flights, &Segment::parse_list("12:60").unwrap()).unwrap();
    let off = est.means();
    let est = est.subtract(&off).unwrap();
    let truth = truth();
    let u0 = &off.u0;
    let spec = GreyBoxSpec {
        operating_point: Some([u0[0], u0[1], u0[2], u0[3]]),
        ..GreyBoxSpec::closed_loop_flights(Params::default())
    };
    let r = estimate_grey_box(&est, &spec, &GreyBoxParams::thesis_initial_guess()).unwrap();
    assert!(r.from_operating_point);
    // What the rates determine: the roll and pitch gains sqrt(k_t)/I,
    // I_zz (servo column) and the actuators; k_t, k_tau from the
    // operating point. (I_xx, I_yy themselves inherit the few-percent
    // bias of the flight's mean throttle against the hover trim; the
    // full flights of the ignored test below recover them too.)
    let (ce, ct) = (combinations(&r.estimate), combinations(&truth));
    for i in 0..3 {
        assert!((ce[i] / ct[i] - 1.0).abs() < 0.05, "combination {i}\n{r}");
    }
    for i in 3..8 {
        let (e, t) = (r.estimate.to_array()[i], truth.to_array()[i]);
        assert!(
            (e / t - 1.0).abs() < 0.05,
            "{}: {e} vs {t}\n{r}",
            GreyBoxParams::NAMES[i]
        );
    }
}

/// `k_t` and `k_tau` from the hover pulses of the simulator's own trim are
/// the simulator's constants (an independent check of the trim inversion).
#[test]
fn thrust_and_drag_from_the_exact_trim() {
    let p = Params::default();
    let trim = kestrel_tricopter_model::Tricopter::new(p)
        .unwrap()
        .trim_hover()
        .unwrap();
    let g = kestrel_tricopter::ident::greybox::thrust_and_drag_from_trim(
        &p,
        &GreyBoxParams::thesis_initial_guess(),
        &trim.input,
    )
    .unwrap();
    assert!((g.k_t / p.k_t - 1.0).abs() < 1e-6, "{g:?}");
    assert!((g.k_tau / p.k_tau - 1.0).abs() < 1e-6, "{g:?}");
    assert!(
        kestrel_tricopter::ident::greybox::thrust_and_drag_from_trim(
            &p,
            &GreyBoxParams::thesis_initial_guess(),
            &[900.0, 900.0, 900.0, 1500.0]
        )
        .is_err()
    );
}

/// The issue's Done-when on the full flights (250 s, seed 1, the thesis's
/// intervals): every parameter within 5 %, the k-step fits on the
/// validation set at least the black-box model's minus 2 points, the
/// simulation fit at least the true linearised model's minus 2 points. Slow in
/// debug (two 250-s flights and the black-box identification): run with
/// `cargo test --release -p kestrel-tricopter --test greybox -- --ignored`
/// or see the example `greybox`.
#[test]
#[ignore]
fn thesis_flights_recover_the_simulator_parameters() {
    let flights = kestrel_tricopter::ident::simulated_flights(250.0, 1).unwrap();
    let est = select_segments(&flights, &Segment::parse_list(ESTIMATE).unwrap()).unwrap();
    let val = select_segments(&flights, &Segment::parse_list(VALIDATE).unwrap()).unwrap();
    let off = est.means();
    let (est, val) = (est.subtract(&off).unwrap(), val.subtract(&off).unwrap());
    let truth = truth();
    let u0 = &off.u0;
    let spec = GreyBoxSpec {
        operating_point: Some([u0[0], u0[1], u0[2], u0[3]]),
        ..GreyBoxSpec::closed_loop_flights(Params::default())
    };
    let r = estimate_grey_box(&est, &spec, &GreyBoxParams::thesis_initial_guess()).unwrap();
    for (i, (e, t)) in r
        .estimate
        .to_array()
        .iter()
        .zip(truth.to_array())
        .enumerate()
    {
        assert!(
            (e / t - 1.0).abs() < 0.05,
            "{}: {e} vs {t}\n{r}",
            GreyBoxParams::NAMES[i]
        );
    }
    let grey = r.validate(&val, &[1, 5]).unwrap();
    let black = identify_thesis_model(ModelKind::BlackBox, 250.0, 1).unwrap();
    for label in ["model 1-step", "model 5-step"] {
        let (g, b) = (
            grey.row(label).unwrap().mean(),
            black.validation.row(label).unwrap().mean(),
        );
        assert!(g > b - 2.0, "{label}: grey-box {g}, black-box {b}");
    }
    // The simulation fit is bounded by the unmeasured gust torque, which
    // any integrating physical model integrates: it is within 2 points of
    // the simulator's own linearised model (below the stable black-box
    // model's, see the module docs).
    let true_model = grey_box_model(&truth, &spec, 0.02).unwrap();
    let t = kestrel_sysid::validate(&true_model, &val, &[1]).unwrap();
    let (g, t) = (
        grey.row("model simulation").unwrap().mean(),
        t.row("model simulation").unwrap().mean(),
    );
    assert!(g > t - 2.0, "simulation: grey-box {g}, true model {t}");
}

/// White measurement noise on the outputs of the grey-box model: the
/// simulation focus is maximum likelihood there, so the standard errors
/// from the Gauss-Newton Hessian should match the spread of the estimates
/// over independent noise realisations (an independent Monte Carlo check).
#[test]
fn standard_errors_match_the_monte_carlo_spread() {
    let mut spec = GreyBoxSpec::with_free(&["ixx", "izz", "motor_tau"]).unwrap();
    spec.settings.equation_error_start = false;
    let truth = truth();
    let clean = linear_data(&truth, &spec, 300);
    let runs = 24;
    let mut est = vec![Vec::new(); 3];
    let mut se = [0.0; 3];
    // Standard normal noise from the workspace's seeded generator.
    let mut rng = kestrel_sysid::synthetic::Rng::new(0x2545_f491_4f6c_dd1d);
    for _ in 0..runs {
        let exps = clean
            .experiments()
            .iter()
            .map(|e| {
                let mut e = e.clone();
                e.y.iter_mut().for_each(|v| *v += 0.02 * rng.normal());
                e
            })
            .collect();
        let noisy = IoData::from_experiments(
            0.02,
            clean.input_names().to_vec(),
            clean.output_names().to_vec(),
            exps,
        )
        .unwrap();
        let r = estimate_grey_box(&noisy, &spec, &truth).unwrap();
        for (k, i) in [0, 2, 5].into_iter().enumerate() {
            est[k].push(r.estimate.to_array()[i]);
            se[k] += r.parameters[i].std_error.unwrap() / runs as f64;
        }
    }
    for k in 0..3 {
        let n = runs as f64;
        let mean = est[k].iter().sum::<f64>() / n;
        let sd = (est[k].iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        // 24 runs: the sample standard deviation is within about +-30 %.
        assert!(
            sd > 0.6 * se[k] && sd < 1.5 * se[k],
            "parameter {k}: Monte Carlo spread {sd:e}, reported standard error {:e}",
            se[k]
        );
    }
}

/// The two-stage focus: physics on simulation errors, then `K` alone.
#[test]
fn simulation_then_noise_estimates_a_stable_predictor() {
    let spec = GreyBoxSpec {
        focus: GreyBoxFocus::SimulationThenNoise,
        disturbance: true,
        ..Default::default()
    };
    let truth = truth();
    let clean = linear_data(&truth, &spec, 300);
    // Output noise that is a random walk plus white noise: the
    // disturbance states and K have something to model.
    let exps = clean
        .experiments()
        .iter()
        .map(|e| {
            let mut e = e.clone();
            let mut walk = [0.0; 3];
            for t in 0..e.y.nrows() {
                for (j, wj) in walk.iter_mut().enumerate() {
                    let w = (((t * 7 + j * 13) % 11) as f64 - 5.0) * 1e-3;
                    *wj += w;
                    e.y[(t, j)] += *wj + 0.5 * w;
                }
            }
            e
        })
        .collect();
    let data = IoData::from_experiments(
        0.02,
        clean.input_names().to_vec(),
        clean.output_names().to_vec(),
        exps,
    )
    .unwrap();
    let start = GreyBoxParams::from_array(&truth.to_array().map(|v| 1.1 * v));
    let r = estimate_grey_box(&data, &spec, &start).unwrap();
    let stages: Vec<Stage> = r.stages.iter().map(|s| s.stage).collect();
    assert_eq!(
        stages,
        vec![Stage::EquationError, Stage::Simulation, Stage::Noise]
    );
    assert!(r.model.k.amax() > 0.0 && r.model.radius_predictor() < 1.0);
    let noise = r.stages[2];
    assert!(noise.cost < noise.initial_cost);
    // The physical parameters are those of the simulation stage.
    assert!(r.parameters.iter().all(|p| p.std_error.is_some()));
    let one = r.fit.row("model 1-step").unwrap().mean();
    let sim = r.fit.row("model simulation").unwrap().mean();
    assert!(one >= sim, "{r}");
}

/// A bound that excludes the truth is kept: the estimate ends on it.
#[test]
fn bounds_are_kept() {
    let mut spec = GreyBoxSpec::with_free(&["ixx", "iyy", "izz"]).unwrap();
    spec.upper.ixx = 0.038; // the truth is 0.04
    spec.lower.iyy = 0.03;
    let truth = truth();
    let data = linear_data(&truth, &spec, 300);
    let mut start = truth;
    start.ixx = 0.03;
    start.iyy = 0.05;
    let r = estimate_grey_box(&data, &spec, &start).unwrap();
    assert!((r.estimate.ixx / 0.038 - 1.0).abs() < 1e-12, "{r}");
    // A projected-gradient stop: on the bound, nothing else to improve.
    assert_eq!(r.stop, StopReason::GradientTolerance, "{r}");
    assert!(r.estimate.iyy >= 0.03);
    assert!((r.estimate.iyy / truth.iyy - 1.0).abs() < 0.05, "{r}");
}

/// The static rate model (7.7) with the mixer's virtual inputs: the five
/// parameters it depends on converge on its noiseless data.
#[test]
fn virtual_inputs_and_the_static_rate_model_converge() {
    let spec = GreyBoxSpec {
        kind: RateModelKind::Rates,
        inputs: RateInputs::Virtual,
        ..GreyBoxSpec::with_free(&["ixx", "iyy", "izz", "k_t", "k_tau"]).unwrap()
    };
    let truth = truth();
    let data = linear_data(&truth, &spec, 300);
    assert_eq!(data.nu(), 3);
    let start = GreyBoxParams::from_array(&truth.to_array().map(|v| 1.25 * v));
    let r = estimate_grey_box(&data, &spec, &start).unwrap();
    assert_eq!(r.model.nx(), 3);
    for (i, (e, t)) in r
        .estimate
        .to_array()
        .iter()
        .zip(truth.to_array())
        .enumerate()
        .take(5)
    {
        // k_t, k_tau only through a weakly identifiable direction here too:
        // the noiseless data still pin them, less tightly.
        let tol = if i >= 3 { 1e-3 } else { 1e-5 };
        assert!(
            (e / t - 1.0).abs() < tol,
            "{}\n{r}",
            GreyBoxParams::NAMES[i]
        );
    }
    // The fixed actuator constants stay where they were.
    assert_eq!(r.estimate.motor_tau, start.motor_tau);
}
