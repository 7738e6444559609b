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
    if model.ny() != 3 {
        return Err(MpcError::dim(
            "closed-loop model outputs",
            "3 rate outputs [p, q, r]",
            format!("{} outputs", model.ny()),
        ));
    }
    let trim = crate::tricopter::tricopter_trim(model)?;
    let u0 = model.u0.clone().unwrap_or_else(|| DVector::zeros(4));
    let y0 = model.y0.clone().unwrap_or_else(|| DVector::zeros(3));
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
    let x_first = &pinv * (DVector::from_column_slice(&y_first) - &y0);
    estimator.reset(x_first.as_slice())?;
    let mut u = [0.0; 4];
    for k in 0..steps {
        let t = k as f64 * ts;
        let reference = scenario.reference_at(t);
        let y = if k == 0 { y_first } else { plant.measure() };
        estimator.measurement_update(&y)?;
        let x_hat = estimator.estimate().to_vec();
        // The law works in the model's deviation outputs: `r - y0`.
        let r = [
            reference[0] - y0[0],
            reference[1] - y0[1],
            reference[2] - y0[2],
            throttle,
        ];
        law.control(&x_hat, &r, &mut u)?;
        let act = trim.actuate(&u, throttle)?;
        let cost = match z_of(law) {
            Some(z) => problem.cost(
                &DVector::from_vec(z),
                &problem.theta(&x_hat, &r[..problem.layout.n_law_reference()])?,
            ),
            None => f64::NAN,
        };
        let y_est = &model.c * DVector::from_column_slice(&x_hat) + &y0;
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

/// Which plant a closed-loop run flies.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PlantKind {
    /// The nonlinear tricopter of kestrel-tricopter-model ([`NonlinearPlant`]).
    #[default]
    Nonlinear,
    /// The design model itself ([`LinearPlant`]), with the same gyro.
    Linear,
}

/// Settings of a closed-loop run ([`fly_mpc`], [`fly_offset_free`], [`fly_pi`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RunSettings {
    /// Initial rates, references and their steps, throttle, duration.
    pub scenario: Scenario,
    /// The plant.
    pub plant: PlantKind,
    /// The nonlinear plant's configuration (aircraft, gyro, gusts); the
    /// linear plant uses its gyro.
    pub config: PlantConfig,
    /// Seed of the gyro noise and the gusts.
    pub seed: u64,
}

impl Default for RunSettings {
    /// The step scenario of 7.7.1 on the nonlinear plant in calm air with
    /// an ideal gyro (no bias, no noise), seed 1.
    fn default() -> Self {
        RunSettings {
            scenario: Scenario::thesis_step(),
            plant: PlantKind::Nonlinear,
            config: PlantConfig {
                gyro: GyroConfig::ideal(),
                gust: kestrel_tricopter_model::GustConfig::calm(),
                ..PlantConfig::default()
            },
            seed: 1,
        }
    }
}

impl RunSettings {
    /// The noisy runs of figures 7.18-7.21: the thesis's gyro noise and
    /// bias (7.5)-(7.6) and kestrel-tricopter-model's default gusts.
    pub fn noisy() -> Self {
        RunSettings {
            config: PlantConfig::default(),
            ..RunSettings::default()
        }
    }

    fn plant(&self, model: &SsModel) -> Result<Box<dyn RatePlant>, MpcError> {
        let rates = self.scenario.initial_rates;
        Ok(match self.plant {
            PlantKind::Nonlinear => {
                Box::new(NonlinearPlant::hovering(self.config, rates, self.seed)?)
            }
            PlantKind::Linear => {
                Box::new(LinearPlant::new(model, rates, self.config.gyro, self.seed)?)
            }
        })
    }
}

impl RatePlant for Box<dyn RatePlant> {
    fn measure(&mut self) -> [f64; 3] {
        (**self).measure()
    }
    fn rates(&self) -> [f64; 3] {
        (**self).rates()
    }
    fn advance(&mut self, pwm: &[f64; 4]) -> Result<(), MpcError> {
        (**self).advance(pwm)
    }
}

impl Scenario {
    /// The first reference step as `(time, from, to)`; without steps, a
    /// "step" at `t = 0` from and to the initial reference.
    pub fn first_step(&self) -> (f64, [f64; 3], [f64; 3]) {
        match self.steps.first() {
            Some(s) => (s.time, self.initial_reference, s.rates),
            None => (0.0, self.initial_reference, self.initial_reference),
        }
    }
}

/// A closed-loop run: the trace and the step-response figures of the
/// scenario's first step.
#[derive(Clone, Debug, PartialEq)]
pub struct RunResult {
    /// One row per sample, with the pulses and the cost `J`.
    pub trace: Trace,
    /// Rise time, overshoot, RMS error, effort, bound violation.
    pub metrics: StepMetrics,
}

/// Largest model order the closed-loop helpers support (the estimator is
/// kestrel-kalman's const-dimension stationary filter).
pub const MAX_STATES: usize = 16;

macro_rules! with_filter {
    ($design:expr, |$f:ident| $body:expr) => {{
        let design = $design;
        let kf_err =
            |e: kestrel_kalman::KalmanError| MpcError::setting("Kalman filter", e.to_string());
        match design.nx() {
            1 => {
                let mut $f = design.filter::<f64, 1, 4, 3>().map_err(kf_err)?;
                $body
            }
            2 => {
                let mut $f = design.filter::<f64, 2, 4, 3>().map_err(kf_err)?;
                $body
            }
            3 => {
                let mut $f = design.filter::<f64, 3, 4, 3>().map_err(kf_err)?;
                $body
            }
            4 => {
                let mut $f = design.filter::<f64, 4, 4, 3>().map_err(kf_err)?;
                $body
            }
            5 => {
                let mut $f = design.filter::<f64, 5, 4, 3>().map_err(kf_err)?;
                $body
            }
            6 => {
                let mut $f = design.filter::<f64, 6, 4, 3>().map_err(kf_err)?;
                $body
            }
            7 => {
                let mut $f = design.filter::<f64, 7, 4, 3>().map_err(kf_err)?;
                $body
            }
            8 => {
                let mut $f = design.filter::<f64, 8, 4, 3>().map_err(kf_err)?;
                $body
            }
            9 => {
                let mut $f = design.filter::<f64, 9, 4, 3>().map_err(kf_err)?;
                $body
            }
            10 => {
                let mut $f = design.filter::<f64, 10, 4, 3>().map_err(kf_err)?;
                $body
            }
            11 => {
                let mut $f = design.filter::<f64, 11, 4, 3>().map_err(kf_err)?;
                $body
            }
            12 => {
                let mut $f = design.filter::<f64, 12, 4, 3>().map_err(kf_err)?;
                $body
            }
            13 => {
                let mut $f = design.filter::<f64, 13, 4, 3>().map_err(kf_err)?;
                $body
            }
            14 => {
                let mut $f = design.filter::<f64, 14, 4, 3>().map_err(kf_err)?;
                $body
            }
            15 => {
                let mut $f = design.filter::<f64, 15, 4, 3>().map_err(kf_err)?;
                $body
            }
            16 => {
                let mut $f = design.filter::<f64, 16, 4, 3>().map_err(kf_err)?;
                $body
            }
            n => {
                return Err(MpcError::dim(
                    "closed-loop design model",
                    format!("1 to {MAX_STATES} states"),
                    format!("{n} states"),
                ));
            }
        }
    }};
}

fn fly_with<S: crate::law::ParametricQpSolver>(
    model: &SsModel,
    nd: usize,
    problem: &MpcProblem,
    law: &mut crate::law::MpcLaw<S>,
    settings: &RunSettings,
) -> Result<RunResult, MpcError> {
    if model.nu() != 4 || model.ny() != 3 {
        return Err(MpcError::dim(
            "closed-loop design model",
            "4 pulse inputs and 3 rate outputs",
            format!("{} inputs and {} outputs", model.nu(), model.ny()),
        ));
    }
    let mut plant = settings.plant(model)?;
    let sc = &settings.scenario;
    let trace = with_filter!(kalman_design_with_disturbance(model, nd)?, |f| run_mpc(
        &mut plant,
        law,
        &mut f,
        model,
        problem,
        sc,
        |l| Some(l.last_z().to_vec())
    )?);
    let (t, from, to) = sc.first_step();
    let metrics = trace.step_metrics(t, from, to);
    Ok(RunResult { trace, metrics })
}

/// Flies an MPC law in the closed loop of section 7.7: the plant of
/// `settings`, the stationary Kalman filter of [`kalman_design`] for
/// `model`, the law (any [`crate::ParametricQpSolver`]: clarabel,
/// explicit, fast gradient) on `theta = [x_hat; r - y0; throttle]`, the
/// actuation with clipping; the trace holds the cost `J` of the law's
/// whole move sequence at every step.
///
/// ```
/// use kestrel_mpc::sim::{RunSettings, fly_mpc};
/// use kestrel_mpc::{MpcLaw, ProblemSize, QpSettings, default_weights, identified_model, tricopter_problem};
/// let model = identified_model().unwrap();
/// let (q1, q2) = default_weights();
/// let problem = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).unwrap();
/// let mut law = MpcLaw::clarabel(&problem, QpSettings::default()).unwrap();
/// let run = fly_mpc(&model, &problem, &mut law, &RunSettings::default()).unwrap();
/// assert_eq!(run.metrics.max_bound_violation, 0.0);          // inputs inside their ranges
/// let last = run.trace.rows.last().unwrap();                // on the step [1, -1, 0.5] at the end
/// assert!((0..3).all(|k| (last.rates[k] - last.reference[k]).abs() < 0.15));
/// ```
pub fn fly_mpc<S: crate::law::ParametricQpSolver>(
    model: &SsModel,
    problem: &MpcProblem,
    law: &mut crate::law::MpcLaw<S>,
    settings: &RunSettings,
) -> Result<RunResult, MpcError> {
    fly_with(model, 0, problem, law, settings)
}

/// [`fly_mpc`] for an offset-free design: the filter of
/// [`kalman_design_with_disturbance`] on the augmented model.
pub fn fly_offset_free<S: crate::law::ParametricQpSolver>(
    design: &crate::OffsetFreeDesign,
    law: &mut crate::law::MpcLaw<S>,
    settings: &RunSettings,
) -> Result<RunResult, MpcError> {
    fly_with(&design.augmented, design.nd, &design.problem, law, settings)
}

/// Flies the baseline PI rate controller (kestrel-tricopter-model's
/// `RatePid` with its default gains, mixing around `model`'s trim) on the
/// raw gyro samples.
pub fn fly_pi(model: &SsModel, settings: &RunSettings) -> Result<RunResult, MpcError> {
    let trim = crate::tricopter::tricopter_trim(model)?;
    let o = trim.offsets;
    let mut pid = RatePid::new(
        kestrel_tricopter_model::RatePidGains::default(),
        kestrel_tricopter_model::Mixer::new([o[0], o[1], o[2], 1500.0 + o[3]]),
    );
    let mut plant = settings.plant(model)?;
    let sc = &settings.scenario;
    let trace = run_pid(&mut plant, &mut pid, &trim, sc, model.ts)?;
    let (t, from, to) = sc.first_step();
    let metrics = trace.step_metrics(t, from, to);
    Ok(RunResult { trace, metrics })
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
    use crate::tricopter::{ProblemSize, default_weights, identified_model, tricopter_problem};

    fn qp_settings() -> QpSettings {
        QpSettings {
            kkt_tolerance: Some(1e-7),
            ..QpSettings::default()
        }
    }

    fn settings(noisy: bool) -> RunSettings {
        let mut s = if noisy {
            RunSettings::noisy()
        } else {
            RunSettings::default()
        };
        s.seed = 5;
        s
    }

    fn run(size: ProblemSize, noisy: bool) -> RunResult {
        let model = identified_model().unwrap();
        let (q1, q2) = default_weights();
        let problem = tricopter_problem(&model, size, q1, q2).unwrap();
        let mut law = MpcLaw::clarabel(&problem, qp_settings()).unwrap();
        fly_mpc(&model, &problem, &mut law, &settings(noisy)).unwrap()
    }

    #[test]
    fn both_sizes_track_the_thesis_step_with_the_identified_model() {
        for size in [ProblemSize::Thesis, ProblemSize::Larger] {
            for noisy in [false, true] {
                let RunResult { trace, metrics: m } = run(size, noisy);
                eprintln!("{size:?} noisy={noisy}: {m:?}");
                // Inputs inside their ranges without clipping (to solver accuracy).
                assert!(m.max_bound_violation <= 0.0, "{m:?}");
                assert!(trace.rows.iter().all(|r| !r.saturated));
                assert!(
                    trace
                        .rows
                        .iter()
                        .all(|r| r.cost.is_finite() && r.cost >= -1e-9)
                );
                // Settled from [2, 2, 2] before the step and near the new reference at the end.
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
                    assert!(m.rise_time[k].is_finite() && m.rise_time[k] < 0.3, "{m:?}");
                }
                // The filter follows the true rates (it is what the law sees).
                let est_err = trace
                    .rows
                    .iter()
                    .skip(5)
                    .flat_map(|r| (0..3).map(move |k| (r.estimated[k] - r.rates[k]).abs()))
                    .fold(0.0, f64::max);
                assert!(
                    est_err < 0.1,
                    "{size:?} noisy={noisy}: estimate off by {est_err}"
                );
            }
        }
    }

    #[test]
    fn mpc_against_the_pi_baseline() {
        // The same step on the same plant: the PI on the raw gyro, the MPC
        // (both sizes) on the Kalman estimate of the identified model.
        let model = identified_model().unwrap();
        for noisy in [false, true] {
            let pi = fly_pi(&model, &settings(noisy)).unwrap().metrics;
            eprintln!("PI noisy={noisy}: {pi:?}");
            assert!(pi.max_bound_violation <= 0.0);
            for size in [ProblemSize::Thesis, ProblemSize::Larger] {
                let m = run(size, noisy).metrics;
                eprintln!("{size:?} noisy={noisy}: {m:?}");
                for k in 0..3 {
                    // The MPC rises faster than the PI on every axis ...
                    assert!(
                        m.rise_time[k] < pi.rise_time[k],
                        "axis {k}: {m:?} vs {pi:?}"
                    );
                }
                // ... and its total RMS tracking error over the step window is
                // at most that of the PI.
                let total = |v: &[f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
                assert!(
                    total(&m.rms_error) <= total(&pi.rms_error),
                    "{m:?} vs {pi:?}"
                );
            }
        }
    }

    /// Mean absolute tracking error over the last second.
    fn steady_error(trace: &Trace) -> f64 {
        let end = trace.rows.last().map_or(0.0, |r| r.t);
        let tail: Vec<&TraceRow> = trace.rows.iter().filter(|r| r.t > end - 1.0).collect();
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
        let model = identified_model().unwrap();
        let (q1, q2) = default_weights();
        let trim = crate::tricopter_trim(&model).unwrap();
        let design = MpcProblem::build_offset_free(
            &model,
            &trim.bounds(),
            &ProblemSize::Thesis.settings(q1.clone(), q2.clone()),
            &crate::DisturbanceModel::OutputStates,
        )
        .unwrap();
        let mut law = MpcLaw::clarabel(&design.problem, qp_settings()).unwrap();
        // Hold the step for 4 s so the disturbance estimate settles.
        let mut s = settings(false);
        s.scenario.duration = 6.0;
        let of = fly_offset_free(&design, &mut law, &s).unwrap();
        let problem = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).unwrap();
        let mut plain_law = MpcLaw::clarabel(&problem, qp_settings()).unwrap();
        let plain = fly_mpc(&model, &problem, &mut plain_law, &s).unwrap();
        let (e_of, e_plain) = (steady_error(&of.trace), steady_error(&plain.trace));
        eprintln!(
            "steady error: offset-free {e_of:.4}, plain {e_plain:.4} rad/s; {:?}",
            of.metrics
        );
        assert!(of.metrics.max_bound_violation <= 0.0);
        assert!(
            e_of < 0.5 * e_plain,
            "offset-free {e_of} vs plain {e_plain}"
        );
    }

    #[test]
    fn linear_plant_and_bad_models_through_the_run_helpers() {
        let model = identified_model().unwrap();
        let (q1, q2) = default_weights();
        let problem = tricopter_problem(&model, ProblemSize::Thesis, q1, q2).unwrap();
        let mut law = MpcLaw::clarabel(&problem, qp_settings()).unwrap();
        // On its own design model (no mismatch) the MPC settles on the reference.
        let s = RunSettings {
            plant: PlantKind::Linear,
            ..RunSettings::default()
        };
        let run = fly_mpc(&model, &problem, &mut law, &s).unwrap();
        assert!(
            steady_error(&run.trace) < 0.05,
            "{}",
            steady_error(&run.trace)
        );
        // A model with the wrong number of outputs is refused, not flown.
        let mut two = model.clone();
        two.c = two.c.rows(0, 2).into_owned();
        two.d = two.d.rows(0, 2).into_owned();
        two.y0 = None;
        two.outputs = None;
        let e = fly_mpc(&two, &problem, &mut law, &s).unwrap_err();
        assert!(e.to_string().contains("3 rate outputs"), "{e}");
    }
}
