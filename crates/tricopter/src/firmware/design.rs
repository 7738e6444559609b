//! [`FirmwareDesign`]: the model, filter, problem and fast-gradient
//! certificate the firmware runs, in f64, and the real Schur coordinates.

use crate::closed_loop::kalman_design;
use crate::firmware::consistency::{
    Consistency, ProblemCheck, ProblemFile, check_problem, estimator_model,
};
use crate::firmware::error::{DesignError, DesignPart, dim};
use crate::firmware::settings::{
    DesignSettings, IterationBudget, NR, NU, NY, Realization, SERVO_CENTER,
};
use crate::problems::{TricopterTrim, default_weights, tricopter_problem, tricopter_trim};
use kestrel_core::Q16;
use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_fgm::{BoxQp, Certificate, FgmData, FgmDesign, FgmSettings};
use kestrel_kalman::{KalmanDesign, StationaryGains};

/// Everything the firmware tables are made of, in f64.
#[derive(Clone, Debug)]
pub struct FirmwareDesign {
    /// The 50 Hz design model (4 inputs, 3 outputs, `u0` the hover trim).
    pub model: SsModel,
    /// The stationary Kalman filter design.
    pub kalman: KalmanDesign,
    /// The condensed MPC problem, `theta = [x; p_ref, q_ref, r_ref; throttle]`.
    pub problem: MpqpProblem,
    /// Its box-QP form.
    pub qp: BoxQp,
    /// The fast-gradient design (preconditioning, folded data).
    pub fgm: FgmDesign,
    /// The certificate for [`FirmwareDesign::eps`].
    pub cert: Certificate,
    /// The suboptimality level that keeps every input within
    /// [`DesignSettings::max_input_error_us`].
    pub eps: f64,
    /// Folded solver data in f64 (the host reference).
    pub data_f64: FgmData<f64>,
    /// Folded solver data in f32.
    pub data_f32: FgmData<f32>,
    /// Folded solver data in Q16 (box shrunk by Q16's rounding bound).
    pub data_q16: FgmData<Q16>,
    /// Hover trim from the model's `u0`.
    pub trim: TricopterTrim,
    /// The settings used.
    pub settings: DesignSettings,
}

impl FirmwareDesign {
    /// The default pipeline from a design model alone: kestrel-mpc's Kalman
    /// noise design (`G = [B, C']`, thesis gyro covariance and bias) and
    /// its tricopter MPC problem of `settings.size` with the default weights.
    ///
    /// # Errors
    /// As [`FirmwareDesign::new`], and the Kalman or MPC design's errors.
    pub fn from_model(model: &SsModel, settings: &DesignSettings) -> Result<Self, DesignError> {
        check_model(model)?;
        let model = match settings.realization {
            Realization::AsGiven => model.clone(),
            Realization::Schur => schur_realization(model)?,
        };
        let kalman = kalman_design(&model)?;
        let (q1, q2) = default_weights();
        let problem = tricopter_problem(&model, settings.size, q1, q2)?.to_mpqp();
        Self::new(&model, kalman, problem, settings)
    }

    /// A design from the design model and, when given, the filter and the
    /// problem read from files (`kestrel.kalman.v1`, `kestrel.mpqp.v1` with
    /// its model fingerprint), checked to belong together: the filter must
    /// run the design model, or the design model with constant disturbance
    /// states (the offset-free MPC's estimator, as `kestrel pipeline`
    /// writes it); the problem's parameters must be the filter's states,
    /// and its model fingerprint, when it has one, that of the filter's
    /// model ([`estimator_model`], [`check_problem`]). The design runs the
    /// filter's model. A missing filter is the thesis's noise design on the
    /// model ([`kalman_design`]), a missing problem the tricopter problem of
    /// `settings.size` with the default weights; the model's coordinates
    /// are kept (`settings.realization` is not applied).
    ///
    /// # Errors
    /// [`DesignError::Mismatch`] naming the two parts that differ and how;
    /// as [`FirmwareDesign::new`].
    pub fn from_parts(
        model: &SsModel,
        kalman: Option<KalmanDesign>,
        problem: Option<ProblemFile>,
        settings: &DesignSettings,
    ) -> Result<(Self, Consistency), DesignError> {
        check_model(model)?;
        let kalman = match kalman {
            Some(k) => k,
            None => kalman_design(model)?,
        };
        let (estimator, nd) = estimator_model(model, &kalman)?;
        let (problem, checked) = match problem {
            Some(p) => {
                let checked = check_problem(&estimator, nd, &p)?;
                (p.problem, checked)
            }
            None if nd > 0 => {
                return Err(DesignError::Mismatch {
                    first: DesignPart::Problem,
                    second: DesignPart::Kalman,
                    detail: format!(
                        "the filter has {} states, the model's {} and {nd} disturbance states, and the tricopter problem built here has the model's {}: give the problem built on the filter's model",
                        estimator.nx(),
                        model.nx(),
                        model.nx()
                    ),
                });
            }
            None => {
                let (q1, q2) = default_weights();
                let p = tricopter_problem(model, settings.size, q1, q2)?.to_mpqp();
                (p, ProblemCheck::BuiltHere)
            }
        };
        let design = Self::new(&estimator, kalman, problem, settings)?;
        Ok((
            design,
            Consistency {
                disturbance_states: nd,
                problem: checked,
            },
        ))
    }

    /// A design from its parts, the model being the one the filter runs
    /// (e.g. the pipeline's estimator model).
    ///
    /// # Errors
    /// [`DesignError::Dimension`] if the model is not 4-input 3-output,
    /// the filter's or the problem's sizes do not match it (the problem
    /// must have `nx + 4` parameters and at least 4 variables), or the
    /// sample times differ; [`DesignError::Mismatch`] if the filter's
    /// `A`, `B`, `C`, `D` or `u0` are not the model's; [`DesignError::Unsupported`] for a filter with
    /// feed-through or a noise cross term; [`DesignError::InvalidSetting`]
    /// for a non-positive or non-finite input error; the fast gradient's
    /// errors (e.g. a problem that is not a box QP).
    pub fn new(
        model: &SsModel,
        kalman: KalmanDesign,
        problem: MpqpProblem,
        settings: &DesignSettings,
    ) -> Result<Self, DesignError> {
        check_model(model)?;
        let nx = model.nx();
        if (kalman.nx(), kalman.nu(), kalman.ny()) != (nx, NU, NY) {
            return Err(dim(
                "Kalman filter (states, inputs, outputs)",
                format!("({nx}, {NU}, {NY}) as the model"),
                format!("({}, {}, {})", kalman.nx(), kalman.nu(), kalman.ny()),
            ));
        }
        if (kalman.ts - model.ts).abs() > 1e-9 * model.ts {
            return Err(dim("Kalman filter sample time", model.ts, kalman.ts));
        }
        estimator_model(model, &kalman)?;
        if kalman.d.iter().any(|v| *v != 0.0) {
            return Err(DesignError::Unsupported(
                "the firmware's filter has no feed-through (D = 0)".into(),
            ));
        }
        let cross = &kalman.filter.l - &kalman.a * &kalman.filter.m;
        if cross.norm() > 1e-12 * kalman.filter.l.norm().max(f64::MIN_POSITIVE) {
            return Err(DesignError::Unsupported(
                "the firmware's filter has no noise cross term (L = A M)".into(),
            ));
        }
        if problem.p() != nx + NR {
            return Err(dim(
                "MPC problem parameters",
                format!("{} = {nx} states + 3 references + throttle", nx + NR),
                problem.p(),
            ));
        }
        if problem.n() < NU {
            return Err(dim(
                "MPC problem variables",
                format!("at least {NU} (the first move)"),
                problem.n(),
            ));
        }
        let e = settings.max_input_error_us;
        if !(e.is_finite() && e > 0.0) {
            return Err(DesignError::InvalidSetting {
                what: "max_input_error_us",
                reason: format!("{e} is not a positive finite number"),
            });
        }
        if let IterationBudget::WarmFixed(0) = settings.budget {
            return Err(DesignError::InvalidSetting {
                what: "budget",
                reason: "zero iterations".into(),
            });
        }
        let qp = BoxQp::from_mpqp(&problem)?;
        let fgm = FgmDesign::new(
            qp.clone(),
            FgmSettings {
                preconditioner: settings.preconditioner,
                ..FgmSettings::default()
            },
        )?;
        let eps = kestrel_fgm::eps_for_input_error(fgm.preconditioning.before.mu, e);
        let cert = fgm.certify(eps)?;
        let data_f64 = fgm.data::<f64>(&cert, None)?;
        let data_f32 = fgm.data::<f32>(&cert, None)?;
        let data_q16 = fgm.data::<Q16>(&cert, None)?;
        let trim = tricopter_trim(model)?;
        Ok(FirmwareDesign {
            model: model.clone(),
            kalman,
            problem,
            qp,
            fgm,
            cert,
            eps,
            data_f64,
            data_f32,
            data_q16,
            trim,
            settings: *settings,
        })
    }

    /// States of the design model.
    pub fn nx(&self) -> usize {
        self.model.nx()
    }

    /// The filter's run-time tables in the firmware's conventions (inputs
    /// are moves from the trim, `u0 = 0`; the measurement offset is `y0`,
    /// the bias being removed by the loop).
    ///
    /// # Errors
    /// [`DesignError::Dimension`] if `NX` is not the model's order.
    pub fn gains<const NX: usize>(&self) -> Result<StationaryGains<f64, NX, NU, NY>, DesignError> {
        if NX != self.nx() {
            return Err(dim("Kalman gains NX", self.nx(), NX));
        }
        let mut g = self.kalman.gains::<f64, NX, NU, NY>()?;
        g.u0 = [0.0; NU];
        g.y_offset = g.y0;
        Ok(g)
    }

    /// Mixer offsets (us): motor trims from the throttle, servo centre plus trim.
    pub fn mixer_offset(&self) -> [f64; 4] {
        let o = self.trim.offsets;
        [o[0], o[1], o[2], SERVO_CENTER + o[3]]
    }

    /// The gyro bias removed by the loop (rad/s).
    pub fn bias(&self) -> [f64; NY] {
        core::array::from_fn(|i| self.kalman.bias.get(i).copied().unwrap_or(0.0))
    }

    /// Iterations the firmware runs each period.
    pub fn loop_iterations(&self) -> usize {
        match self.settings.budget {
            IterationBudget::Certified => self.cert.iterations,
            IterationBudget::WarmFixed(k) => k.min(self.cert.iterations),
        }
    }

    /// Whether each period starts warm from the previous solution.
    pub fn warm_start(&self) -> bool {
        matches!(self.settings.budget, IterationBudget::WarmFixed(_))
    }
}

/// The model in real Schur coordinates `z = Q' x` with `A = Q T Q'`
/// (`Q` orthogonal, `T` upper quasi-triangular): `A -> T`, `B -> Q' B`,
/// `C -> C Q`, `K -> Q' K`, `x0 -> Q' x0`; operating point and names kept.
///
/// # Errors
/// [`DesignError::Unsupported`] if the Schur decomposition does not converge.
pub fn schur_realization(model: &SsModel) -> Result<SsModel, DesignError> {
    let schur = nalgebra::linalg::Schur::try_new(model.a.clone(), f64::EPSILON, 10_000)
        .ok_or_else(|| DesignError::Unsupported("the Schur decomposition of A failed".into()))?;
    let (q, mut t) = schur.unpack();
    // Below the quasi-triangle the entries are rounding residue: zero them.
    let n = t.nrows();
    let scale = t.norm().max(f64::MIN_POSITIVE);
    for j in 0..n {
        for i in j + 2..n {
            t[(i, j)] = 0.0;
        }
        if j + 1 < n && t[(j + 1, j)].abs() <= 1e-15 * scale {
            t[(j + 1, j)] = 0.0;
        }
    }
    let qt = q.transpose();
    let mut m = SsModel::new(model.ts, t, &qt * &model.b, &model.c * &q, model.d.clone())
        .map_err(|e| DesignError::Unsupported(format!("Schur realization: {e}")))?;
    m.k = model.k.as_ref().map(|k| &qt * k);
    m.x0 = model.x0.as_ref().map(|x| &qt * x);
    m.u0 = model.u0.clone();
    m.y0 = model.y0.clone();
    m.inputs = model.inputs.clone();
    m.outputs = model.outputs.clone();
    Ok(m)
}

pub(super) fn check_model(model: &SsModel) -> Result<(), DesignError> {
    if (model.nu(), model.ny()) != (NU, NY) {
        return Err(dim(
            "design model (inputs, outputs)",
            "(4, 3): [pwm1, pwm2, pwm3, servo] -> [p, q, r]",
            format!("({}, {})", model.nu(), model.ny()),
        ));
    }
    if model.nx() == 0 || model.nx() > 16 {
        return Err(dim("design model states", "1 to 16", model.nx()));
    }
    if model.ts.is_nan() || model.ts <= 0.0 {
        return Err(dim("design model sample time", "> 0 s", model.ts));
    }
    Ok(())
}
