//! The closed-loop simulator of section 7.7: a tricopter plant (the
//! nonlinear model of kestrel-tricopter-model or a linear model), the gyro,
//! a state estimator, any control law, the actuation with saturation, and a
//! trace with the cost of every step.

use crate::condense::MpcProblem;
use crate::error::MpcError;
use crate::tricopter::TricopterTrim;
use kestrel_core::formats::SsModel;
use kestrel_core::{ControlLaw, StateEstimator};
use kestrel_tricopter_model::{GyroConfig, GyroSensor, Plant, PlantConfig, RatePid, idx};
use nalgebra::{DMatrix, DVector};

/// A reference change at a given time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceStep {
    /// Time of the change (s).
    pub time: f64,
    /// New rate references `[p, q, r]` (rad/s).
    pub rates: [f64; 3],
}

/// A closed-loop scenario.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Length of the run (s).
    pub duration: f64,
    /// Body rates at `t = 0` (rad/s), in the air at the hover trim otherwise.
    pub initial_rates: [f64; 3],
    /// Rate references from `t = 0` until the first step.
    pub initial_reference: [f64; 3],
    /// Reference changes, in time order.
    pub steps: Vec<ReferenceStep>,
    /// Common throttle (us); `None` holds the hover throttle.
    pub throttle: Option<f64>,
}

impl Scenario {
    /// Section 7.7.1: released at rates `[2, 2, 2]` rad/s with zero
    /// reference; once settled (2 s) a step to `[1, -1, 0.5]` rad/s, held for 2 s.
    pub fn thesis_step() -> Self {
        Scenario {
            duration: 4.0,
            initial_rates: [2.0, 2.0, 2.0],
            initial_reference: [0.0; 3],
            steps: vec![ReferenceStep {
                time: 2.0,
                rates: [1.0, -1.0, 0.5],
            }],
            throttle: None,
        }
    }
    /// The rate references at time `t`.
    pub fn reference_at(&self, t: f64) -> [f64; 3] {
        self.steps
            .iter()
            .rev()
            .find(|s| t + 1e-9 >= s.time)
            .map_or(self.initial_reference, |s| s.rates)
    }
}

/// A tricopter plant sampled at the controller rate: pulses in, gyro out.
pub trait RatePlant {
    /// The gyro sample now (rad/s, with bias and noise).
    fn measure(&mut self) -> [f64; 3];
    /// The true body rates now (rad/s).
    fn rates(&self) -> [f64; 3];
    /// Holds the pulses `[pwm1, pwm2, pwm3, servo]` for one sample.
    fn advance(&mut self, pwm: &[f64; 4]) -> Result<(), MpcError>;
}

/// The nonlinear tricopter of kestrel-tricopter-model (RK4, gusts, gyro).
#[derive(Clone, Debug)]
pub struct NonlinearPlant(pub Plant);

impl NonlinearPlant {
    /// The plant in the air at the hover trim with the given body rates
    /// (ground off, so steady rotations do not end on the floor).
    pub fn hovering(mut config: PlantConfig, rates: [f64; 3], seed: u64) -> Result<Self, MpcError> {
        config.ground = false;
        let err =
            |e: kestrel_tricopter_model::ModelError| MpcError::setting("plant", e.to_string());
        let mut plant = Plant::new(config, seed).map_err(err)?;
        let trim = plant.model().trim_hover().map_err(err)?;
        let mut x = trim.state;
        x[idx::P] = rates[0];
        x[idx::Q] = rates[1];
        x[idx::R] = rates[2];
        plant.set_state(x).map_err(err)?;
        Ok(NonlinearPlant(plant))
    }
}

impl RatePlant for NonlinearPlant {
    fn measure(&mut self) -> [f64; 3] {
        self.0.measure()
    }
    fn rates(&self) -> [f64; 3] {
        let x = self.0.state();
        [x[idx::P], x[idx::Q], x[idx::R]]
    }
    fn advance(&mut self, pwm: &[f64; 4]) -> Result<(), MpcError> {
        self.0
            .advance(pwm)
            .map_err(|e| MpcError::setting("plant", e.to_string()))
    }
}

/// A linear 4-input, 3-output rate model as the plant (e.g. the design
/// model itself, or an identified one), with the gyro of
/// kestrel-tricopter-model.
#[derive(Clone, Debug)]
pub struct LinearPlant {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    x: DVector<f64>,
    u0: DVector<f64>,
    gyro: GyroSensor,
}

impl LinearPlant {
    /// The model's state set so that its outputs are `rates` (least-norm
    /// state `C^+ rates`). Pulses map to inputs as `u = pwm - shift`, where
    /// the shift `[t - t_h, t - t_h, t - t_h, 0]` removes a throttle `t`
    /// away from the model's hover throttle `t_h`.
    pub fn new(
        model: &SsModel,
        rates: [f64; 3],
        gyro: GyroConfig,
        seed: u64,
    ) -> Result<Self, MpcError> {
        if model.nu() != 4 || model.ny() != 3 {
            return Err(MpcError::dim(
                "linear plant",
                "4 inputs (pulses) and 3 outputs (rates)",
                format!("{} inputs and {} outputs", model.nu(), model.ny()),
            ));
        }
        let pinv = model
            .c
            .clone()
            .pseudo_inverse(1e-12)
            .map_err(|e| MpcError::setting("C", e.to_string()))?;
        let trim = crate::tricopter::tricopter_trim(model)?;
        // The pulses at hover in the model's convention.
        let u0 = match &model.u0 {
            Some(u) if trim.hover_throttle > 0.0 => u.clone(),
            _ => DVector::from_fn(4, |i, _| {
                if i < 3 {
                    trim.offsets[i]
                } else {
                    trim.offsets[3] + crate::design::pwm::SERVO_CENTER
                }
            }),
        };
        Ok(LinearPlant {
            a: model.a.clone(),
            b: model.b.clone(),
            c: model.c.clone(),
            x: pinv * DVector::from_column_slice(&rates),
            u0,
            gyro: GyroSensor::new(gyro, seed)
                .map_err(|e| MpcError::setting("gyro", e.to_string()))?,
        })
    }
}

impl RatePlant for LinearPlant {
    fn measure(&mut self) -> [f64; 3] {
        let r = self.rates();
        self.gyro.measure(&r)
    }
    fn rates(&self) -> [f64; 3] {
        let y = &self.c * &self.x;
        [y[0], y[1], y[2]]
    }
    fn advance(&mut self, pwm: &[f64; 4]) -> Result<(), MpcError> {
        if pwm.iter().any(|v| !v.is_finite()) {
            return Err(MpcError::NonFinite("pulses".into()));
        }
        let du = DVector::from_column_slice(pwm) - &self.u0;
        self.x = &self.a * &self.x + &self.b * du;
        Ok(())
    }
}

/// One row of the closed-loop trace.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceRow {
    /// Time (s).
    pub t: f64,
    /// Rate references (rad/s).
    pub reference: [f64; 3],
    /// Throttle (us).
    pub throttle: f64,
    /// True body rates (rad/s).
    pub rates: [f64; 3],
    /// Gyro sample (rad/s).
    pub measured: [f64; 3],
    /// Estimated outputs `C x_hat` (rad/s); the measurement for the PI.
    pub estimated: [f64; 3],
    /// Pulses sent `[pwm1, pwm2, pwm3, servo]` (us).
    pub pwm: [f64; 4],
    /// Whether any pulse was clipped.
    pub saturated: bool,
    /// The MPC's optimal cost `J` of this step (6.3a), `NaN` for laws without one.
    pub cost: f64,
}

/// A closed-loop run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// One row per sample.
    pub rows: Vec<TraceRow>,
    /// The pulses at hover (trim), for the effort measure.
    pub trim_pwm: [f64; 4],
}

/// Step-response figures per axis `[p, q, r]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepMetrics {
    /// 10 %-90 % rise time after the step (s); `NaN` if never reached.
    pub rise_time: [f64; 3],
    /// Overshoot beyond the new reference, percent of the step.
    pub overshoot: [f64; 3],
    /// RMS tracking error `r - y` over the step window (rad/s).
    pub rms_error: [f64; 3],
    /// RMS pulse deviation from the trim over the whole run, per channel
    /// `[pwm1, pwm2, pwm3, servo]` (us).
    pub effort: [f64; 4],
    /// Largest pulse excursion beyond its range (us); 0 when always inside.
    pub max_bound_violation: f64,
}

impl Trace {
    /// The CSV text: `t, r_p, r_q, r_r, throttle, p, q, r, p_meas, q_meas,
    /// r_meas, p_est, q_est, r_est, pwm1, pwm2, pwm3, servo, saturated, J`.
    pub fn to_csv(&self) -> String {
        let mut s = String::from(
            "t,r_p,r_q,r_r,throttle,p,q,r,p_meas,q_meas,r_meas,p_est,q_est,r_est,pwm1,pwm2,pwm3,servo,saturated,J\n",
        );
        for row in &self.rows {
            let mut v: Vec<String> = vec![format!("{:.4}", row.t)];
            v.extend(row.reference.iter().map(|x| format!("{x}")));
            v.push(format!("{}", row.throttle));
            for arr in [&row.rates, &row.measured, &row.estimated] {
                v.extend(arr.iter().map(|x| format!("{x:.6e}")));
            }
            v.extend(row.pwm.iter().map(|x| format!("{x:.4}")));
            v.push(u8::from(row.saturated).to_string());
            v.push(if row.cost.is_finite() {
                format!("{:.6e}", row.cost)
            } else {
                String::new()
            });
            s.push_str(&v.join(","));
            s.push('\n');
        }
        s
    }

    /// The step-response figures for a step at `step_time` from `from` to `to`.
    pub fn step_metrics(&self, step_time: f64, from: [f64; 3], to: [f64; 3]) -> StepMetrics {
        let after: Vec<&TraceRow> = self
            .rows
            .iter()
            .filter(|r| r.t >= step_time - 1e-9)
            .collect();
        let mut m = StepMetrics {
            rise_time: [f64::NAN; 3],
            overshoot: [0.0; 3],
            rms_error: [0.0; 3],
            effort: [0.0; 4],
            max_bound_violation: 0.0,
        };
        for k in 0..3 {
            let d = to[k] - from[k];
            if d.abs() > 1e-12 {
                let frac = |r: &TraceRow| (r.rates[k] - from[k]) / d;
                let t10 = after.iter().find(|r| frac(r) >= 0.1).map(|r| r.t);
                let t90 = after.iter().find(|r| frac(r) >= 0.9).map(|r| r.t);
                if let (Some(a), Some(b)) = (t10, t90) {
                    m.rise_time[k] = b - a;
                }
                let peak = after.iter().map(|r| frac(r)).fold(f64::MIN, f64::max);
                m.overshoot[k] = ((peak - 1.0) * 100.0).max(0.0);
            }
            let n = after.len().max(1) as f64;
            m.rms_error[k] = (after
                .iter()
                .map(|r| (r.reference[k] - r.rates[k]).powi(2))
                .sum::<f64>()
                / n)
                .sqrt();
        }
        let n = self.rows.len().max(1) as f64;
        for i in 0..4 {
            m.effort[i] = (self
                .rows
                .iter()
                .map(|r| (r.pwm[i] - self.trim_pwm[i]).powi(2))
                .sum::<f64>()
                / n)
                .sqrt();
        }
        let ranges = [
            kestrel_tricopter_model::ESC_PWM_RANGE,
            kestrel_tricopter_model::ESC_PWM_RANGE,
            kestrel_tricopter_model::ESC_PWM_RANGE,
            kestrel_tricopter_model::SERVO_PWM_RANGE,
        ];
        for r in &self.rows {
            for (i, &(lo, hi)) in ranges.iter().enumerate() {
                m.max_bound_violation = m.max_bound_violation.max(lo - r.pwm[i]).max(r.pwm[i] - hi);
            }
        }
        m
    }
}

/// Runs an MPC loop: gyro -> estimator measurement update -> law (theta =
/// `[x_hat; r; throttle]`) -> actuation (trim + move + throttle, clipped)
/// -> plant -> estimator time update with the applied input.
///
/// The estimator works in the model's input coordinates: its time update
/// gets `u0 + applied move` (with the model's `u0`, so a filter built from
/// the same `kestrel.ss.v1` model removes its operating point itself), its
/// measurement update the raw gyro sample. The law's cost `J` is evaluated
/// from `problem` when the law's whole move sequence is known (`z_of`).
#[allow(clippy::too_many_arguments)]
pub fn run_mpc<P: RatePlant, L: ControlLaw<Scalar = f64>, E: StateEstimator<Scalar = f64>>(
    plant: &mut P,
    law: &mut L,
    estimator: &mut E,
    model: &SsModel,
    problem: &MpcProblem,
    scenario: &Scenario,
    z_of: impl Fn(&L) -> Option<Vec<f64>>,
) -> Result<Trace, MpcError> {
    let trim = crate::tricopter::tricopter_trim(model)?;
    let u0 = model.u0.clone().unwrap_or_else(|| DVector::zeros(4));
    let throttle = scenario.throttle.unwrap_or(trim.hover_throttle);
    if law.nx() != estimator.nx() || law.nu() != 4 || law.nr() != 4 {
        return Err(MpcError::dim(
            "control law",
            format!(
                "{} states, 4 references (rates and throttle), 4 inputs",
                estimator.nx()
            ),
            format!(
                "{} states, {} references, {} inputs",
                law.nx(),
                law.nr(),
                law.nu()
            ),
        ));
    }
    let pinv = model
        .c
        .clone()
        .pseudo_inverse(1e-12)
        .map_err(|e| MpcError::setting("C", e.to_string()))?;
    let ts = model.ts;
    let steps = (scenario.duration / ts).round() as usize;
    let mut trace = Trace {
        rows: Vec::with_capacity(steps),
        trim_pwm: trim.actuate(&[0.0; 4], throttle)?.pwm,
    };
    // Start the estimator at the state that explains the first sample.
    let y_first = plant.measure();
    let x_first = &pinv * DVector::from_column_slice(&y_first);
    estimator.reset(x_first.as_slice())?;
    let mut u = [0.0; 4];
    for k in 0..steps {
        let t = k as f64 * ts;
        let reference = scenario.reference_at(t);
        let y = if k == 0 { y_first } else { plant.measure() };
        estimator.measurement_update(&y)?;
        let x_hat = estimator.estimate().to_vec();
        let r = [reference[0], reference[1], reference[2], throttle];
        law.control(&x_hat, &r, &mut u)?;
        let act = trim.actuate(&u, throttle)?;
        let cost = match z_of(law) {
            Some(z) => problem.cost(
                &DVector::from_vec(z),
                &problem.theta(&x_hat, &r[..problem.layout.n_law_reference()])?,
            ),
            None => f64::NAN,
        };
        let y_est = &model.c * DVector::from_column_slice(&x_hat);
        trace.rows.push(TraceRow {
            t,
            reference,
            throttle,
            rates: plant.rates(),
            measured: y,
            estimated: [y_est[0], y_est[1], y_est[2]],
            pwm: act.pwm,
            saturated: act.saturated.iter().any(|s| *s),
            cost,
        });
        plant.advance(&act.pwm)?;
        let u_model: Vec<f64> = (0..4).map(|i| u0[i] + act.applied[i]).collect();
        estimator.time_update(&u_model)?;
    }
    Ok(trace)
}

/// Runs the baseline PI rate controller on the raw gyro samples.
pub fn run_pid<P: RatePlant>(
    plant: &mut P,
    pid: &mut RatePid<f64>,
    trim: &TricopterTrim,
    scenario: &Scenario,
    ts: f64,
) -> Result<Trace, MpcError> {
    let throttle = scenario.throttle.unwrap_or(trim.hover_throttle);
    let steps = (scenario.duration / ts).round() as usize;
    let mut trace = Trace {
        rows: Vec::with_capacity(steps),
        trim_pwm: trim.actuate(&[0.0; 4], throttle)?.pwm,
    };
    for k in 0..steps {
        let t = k as f64 * ts;
        let reference = scenario.reference_at(t);
        let y = plant.measure();
        let out = pid.update(&y, &reference, throttle)?;
        trace.rows.push(TraceRow {
            t,
            reference,
            throttle,
            rates: plant.rates(),
            measured: y,
            estimated: y,
            pwm: out.pwm,
            saturated: out.any_saturated(),
            cost: f64::NAN,
        });
        plant.advance(&out.pwm)?;
    }
    Ok(trace)
}

/// The stationary Kalman filter design used in the closed loop: process
/// noise through the inputs (20 us per pulse) and on the outputs' state
/// directions (`G = [B, C']`, 0.02 rad/s per sample, the gusts), the
/// thesis's gyro covariance (7.6) and bias (7.5) as measurement noise.
pub fn kalman_design(model: &SsModel) -> Result<kestrel_kalman::KalmanDesign, MpcError> {
    kalman_design_with_disturbance(model, 0)
}

/// [`kalman_design`] for a model whose last `nd` states are constant
/// disturbances (an [`crate::OffsetFreeDesign`]'s augmented model): they
/// get a random walk of 0.005 per sample so the filter tracks them.
pub fn kalman_design_with_disturbance(
    model: &SsModel,
    nd: usize,
) -> Result<kestrel_kalman::KalmanDesign, MpcError> {
    let (nx, nu, ny) = (model.nx(), model.nu(), model.ny());
    if nd > nx {
        return Err(MpcError::setting(
            "nd",
            format!("{nd} disturbance states in a model of {nx}"),
        ));
    }
    let nw = nu + ny + nd;
    let mut g = DMatrix::zeros(nx, nw);
    g.view_mut((0, 0), (nx, nu)).copy_from(&model.b);
    g.view_mut((0, nu), (nx, ny))
        .copy_from(&model.c.transpose());
    g.view_mut((nx - nd, nu + ny), (nd, nd))
        .copy_from(&DMatrix::identity(nd, nd));
    let q = DMatrix::from_diagonal(&DVector::from_fn(nw, |i, _| {
        if i < nu {
            20.0f64.powi(2)
        } else if i < nu + ny {
            0.02f64.powi(2)
        } else {
            0.005f64.powi(2)
        }
    }));
    let (r, bias) = if ny == 3 {
        (
            DMatrix::from_fn(3, 3, |i, j| {
                kestrel_tricopter_model::THESIS_GYRO_COVARIANCE[i][j]
            }),
            Some(DVector::from_column_slice(
                &kestrel_tricopter_model::THESIS_GYRO_BIAS,
            )),
        )
    } else {
        (DMatrix::identity(ny, ny) * 1e-5, None)
    };
    let noise = kestrel_kalman::NoiseModel {
        g: Some(g),
        q,
        r,
        cross: None,
        bias,
    };
    kestrel_kalman::KalmanDesign::new(model, &noise)
        .map_err(|e| MpcError::setting("Kalman filter", e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::law::MpcLaw;
    use crate::qp::QpSettings;
    use crate::tricopter::{
        ProblemSize, default_weights, design_model, tricopter_problem, tricopter_trim,
    };
    use kestrel_tricopter_model::{Mixer, RatePidGains};

    fn qp_settings() -> QpSettings {
        QpSettings {
            kkt_tolerance: Some(1e-7),
            ..QpSettings::default()
        }
    }

    fn run(size: ProblemSize, noisy: bool) -> (Trace, StepMetrics) {
        let model = design_model().unwrap();
        let (q1, q2) = default_weights();
        let problem = tricopter_problem(&model, size, q1, q2).unwrap();
        let mut law = MpcLaw::clarabel(&problem, qp_settings()).unwrap();
        let mut kf = kalman_design(&model)
            .unwrap()
            .filter::<f64, 8, 4, 3>()
            .unwrap();
        let mut cfg = PlantConfig::default();
        if !noisy {
            cfg.gyro = GyroConfig::ideal();
            cfg.gust = kestrel_tricopter_model::GustConfig::calm();
        }
        let sc = Scenario::thesis_step();
        let mut plant = NonlinearPlant::hovering(cfg, sc.initial_rates, 5).unwrap();
        let trace = run_mpc(&mut plant, &mut law, &mut kf, &model, &problem, &sc, |l| {
            Some(l.last_z().to_vec())
        })
        .unwrap();
        let m = trace.step_metrics(2.0, [0.0; 3], [1.0, -1.0, 0.5]);
        (trace, m)
    }

    fn run_baseline(noisy: bool) -> (Trace, StepMetrics) {
        let model = design_model().unwrap();
        let trim = tricopter_trim(&model).unwrap();
        let o = trim.offsets;
        let mut pid = RatePid::new(
            RatePidGains::default(),
            Mixer::new([o[0], o[1], o[2], 1500.0 + o[3]]),
        );
        let mut cfg = PlantConfig::default();
        if !noisy {
            cfg.gyro = GyroConfig::ideal();
            cfg.gust = kestrel_tricopter_model::GustConfig::calm();
        }
        let sc = Scenario::thesis_step();
        let mut plant = NonlinearPlant::hovering(cfg, sc.initial_rates, 5).unwrap();
        let trace = run_pid(&mut plant, &mut pid, &trim, &sc, 0.02).unwrap();
        let m = trace.step_metrics(2.0, [0.0; 3], [1.0, -1.0, 0.5]);
        (trace, m)
    }

    #[test]
    fn both_sizes_track_the_thesis_step_on_the_nonlinear_plant() {
        for size in [ProblemSize::Thesis, ProblemSize::Larger] {
            for noisy in [false, true] {
                let (trace, m) = run(size, noisy);
                eprintln!("{size:?} noisy={noisy}: {m:?}");
                // Inputs inside their ranges without clipping (to solver accuracy).
                assert!(m.max_bound_violation <= 0.0, "{m:?}");
                assert!(
                    trace
                        .rows
                        .iter()
                        .all(|r| r.cost.is_finite() && r.cost >= -1e-9)
                );
                // Settled from [2, 2, 2] before the step and on the new reference at the end.
                let before = trace
                    .rows
                    .iter()
                    .find(|r| (r.t - 1.98).abs() < 1e-6)
                    .unwrap();
                let last = trace.rows.last().unwrap();
                for k in 0..3 {
                    assert!(
                        before.rates[k].abs() < 0.1,
                        "{size:?} axis {k} before step: {:?}",
                        before.rates
                    );
                    assert!(
                        (last.rates[k] - last.reference[k]).abs() < 0.15,
                        "{size:?} axis {k} at the end: {:?} vs {:?}",
                        last.rates,
                        last.reference
                    );
                    assert!(m.rise_time[k].is_finite() && m.rise_time[k] < 1.0, "{m:?}");
                }
            }
        }
        let (_, pid) = run_baseline(true);
        eprintln!("PI noisy: {pid:?}");
    }

    /// Mean absolute tracking error over the last second.
    fn steady_error(trace: &Trace) -> f64 {
        let tail: Vec<&TraceRow> = trace.rows.iter().filter(|r| r.t >= 3.0).collect();
        tail.iter()
            .map(|r| {
                (0..3)
                    .map(|k| (r.reference[k] - r.rates[k]).abs())
                    .sum::<f64>()
                    / 3.0
            })
            .sum::<f64>()
            / tail.len() as f64
    }

    #[test]
    fn offset_free_option_reduces_steady_error_on_the_nonlinear_plant() {
        let model = design_model().unwrap();
        let (q1, q2) = default_weights();
        let trim = tricopter_trim(&model).unwrap();
        let settings = ProblemSize::Thesis.settings(q1, q2);
        let design = MpcProblem::build_offset_free(
            &model,
            &trim.bounds(),
            &settings,
            &crate::DisturbanceModel::OutputStates,
        )
        .unwrap();
        let mut law = MpcLaw::clarabel(&design.problem, qp_settings()).unwrap();
        let mut kf = kalman_design_with_disturbance(&design.augmented, design.nd)
            .unwrap()
            .filter::<f64, 11, 4, 3>()
            .unwrap();
        let cfg = PlantConfig {
            gyro: GyroConfig::ideal(),
            gust: kestrel_tricopter_model::GustConfig::calm(),
            ..PlantConfig::default()
        };
        let sc = Scenario::thesis_step();
        let mut plant = NonlinearPlant::hovering(cfg, sc.initial_rates, 5).unwrap();
        let trace = run_mpc(
            &mut plant,
            &mut law,
            &mut kf,
            &design.augmented,
            &design.problem,
            &sc,
            |l| Some(l.last_z().to_vec()),
        )
        .unwrap();
        let (plain, _) = run(ProblemSize::Thesis, false);
        let (e_of, e_plain) = (steady_error(&trace), steady_error(&plain));
        eprintln!("steady error: offset-free {e_of:.4}, plain {e_plain:.4} rad/s");
        assert!(
            trace
                .step_metrics(2.0, [0.0; 3], [1.0, -1.0, 0.5])
                .max_bound_violation
                <= 0.0
        );
        assert!(
            e_of < 0.5 * e_plain,
            "offset-free {e_of} vs plain {e_plain}"
        );
    }
}
