//! Design time (`std`): the firmware's controller tables from design files.
//!
//! [`FirmwareDesign`] gathers everything the example firmware runs — the
//! 50 Hz design model (`kestrel.ss.v1`), the stationary Kalman filter
//! (`kestrel.kalman.v1`, kestrel-kalman), the condensed MPC problem
//! (`kestrel.mpqp.v1`, kestrel-mpc's layout `theta = [x; r; throttle]`),
//! and kestrel-fgm's preconditioned fast-gradient certificate — and
//! [`generate_tables`] writes them as the Rust source of
//! `avr/firmware/src/generated.rs` (what `kestrel export` writes).
//!
//! Conventions of the firmware's loop (see [`crate::control`]): the filter
//! is fed the law's output, the input *move* from the trim (`u - u0`), so
//! its tables take `u0 = 0`; the gyro bias is removed by the loop's bias
//! stage, so the measurement offset is the model's `y0` alone; the mixer
//! adds the trim (motors from the throttle, servo from 1500 us).
//!
//! ```
//! use kestrel_avr_rt::design::{DesignSettings, FirmwareDesign, generate_tables};
//! use kestrel_core::formats::SsModel;
//! let model = SsModel::read("../../models/tricopter-blackbox-5.json".as_ref()).unwrap();
//! let design = FirmwareDesign::from_model(&model, &DesignSettings::default()).unwrap();
//! let source: String = generate_tables(&design).unwrap();
//! assert!(source.contains("pub const NX: usize = 5;"));
//! ```

use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_core::{Q16, Scalar};
use kestrel_fgm::{BoxQp, Certificate, FgmData, FgmDesign, FgmSettings, Preconditioner};
use kestrel_kalman::{KalmanDesign, StationaryGains};
use kestrel_mpc::{ProblemSize, TricopterTrim, default_weights, tricopter_problem, tricopter_trim};
use std::fmt::Write as _;

/// Inputs of the tricopter (`pwm1, pwm2, pwm3, servo`).
pub const NU: usize = 4;
/// Measured outputs (`p, q, r`).
pub const NY: usize = 3;
/// Law parameters beyond the states: three rate references and the throttle.
pub const NR: usize = 4;
/// Servo centre pulse (us) the mixer adds to the servo trim.
pub const SERVO_CENTER: f64 = 1500.0;

/// Errors of the firmware design.
#[derive(Debug, thiserror::Error)]
pub enum DesignError {
    /// A design file does not fit the firmware's loop.
    #[error("{what}: expected {expected}, found {found}")]
    Dimension {
        /// What was checked.
        what: &'static str,
        /// What the firmware needs.
        expected: String,
        /// What was given.
        found: String,
    },
    /// A design holds something the firmware's loop does not run.
    #[error("unsupported design: {0}")]
    Unsupported(String),
    /// A setting is outside its range.
    #[error("invalid setting {what}: {reason}")]
    InvalidSetting {
        /// The setting.
        what: &'static str,
        /// Why it is refused.
        reason: String,
    },
    /// kestrel-kalman refused the model.
    #[error("Kalman design: {0}")]
    Kalman(#[from] kestrel_kalman::KalmanError),
    /// kestrel-mpc refused the model.
    #[error("MPC problem: {0}")]
    Mpc(#[from] kestrel_mpc::MpcError),
    /// kestrel-fgm refused the problem.
    #[error("fast gradient: {0}")]
    Fgm(#[from] kestrel_fgm::FgmError),
    /// kestrel-empc refused the problem.
    #[error("explicit MPC: {0}")]
    Empc(#[from] kestrel_empc::EmpcError),
}

/// How many fast-gradient iterations the firmware runs each period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IterationBudget {
    /// The certified cold-start count (every period meets the accuracy).
    Certified,
    /// A fixed count, warm-started from the previous period (not certified).
    WarmFixed(usize),
}

/// The state coordinates the firmware runs in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Realization {
    /// The model's own coordinates.
    AsGiven,
    /// Real Schur form `z = Q' x` (`Q` orthogonal): `A` becomes upper
    /// quasi-triangular, so the Kalman time update skips the zeros below
    /// it. Kalman filtering and the output-weighted MPC are invariant
    /// under the change of coordinates.
    Schur,
}

/// Settings of the firmware design.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DesignSettings {
    /// Largest error (us) of any input of the fast-gradient solution
    /// against the exact optimum; sets the certificate's `eps`.
    pub max_input_error_us: f64,
    /// Preconditioner of the fast gradient method.
    pub preconditioner: Preconditioner,
    /// The MPC problem built when none is given ([`FirmwareDesign::from_model`]).
    pub size: ProblemSize,
    /// Iterations per period.
    pub budget: IterationBudget,
    /// Coordinates of the design model ([`FirmwareDesign::from_model`] only;
    /// [`FirmwareDesign::new`] keeps the given files' coordinates).
    pub realization: Realization,
}

impl Default for DesignSettings {
    /// 1 us, optimal diagonal preconditioning, the thesis-sized problem,
    /// the certified count, real Schur coordinates.
    fn default() -> Self {
        DesignSettings {
            max_input_error_us: 1.0,
            preconditioner: Preconditioner::OptimalDiagonal,
            size: ProblemSize::Thesis,
            budget: IterationBudget::Certified,
            realization: Realization::Schur,
        }
    }
}

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

fn dim(what: &'static str, expected: impl ToString, found: impl ToString) -> DesignError {
    DesignError::Dimension {
        what,
        expected: expected.to_string(),
        found: found.to_string(),
    }
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
        let kalman = kestrel_mpc::sim::kalman_design(&model)?;
        let (q1, q2) = default_weights();
        let problem = tricopter_problem(&model, settings.size, q1, q2)?.to_mpqp();
        Self::new(&model, kalman, problem, settings)
    }

    /// A design from its parts (e.g. read from `kestrel.kalman.v1` and
    /// `kestrel.mpqp.v1` files).
    ///
    /// # Errors
    /// [`DesignError::Dimension`] if the model is not 4-input 3-output,
    /// the filter's or the problem's sizes do not match it (the problem
    /// must have `nx + 4` parameters and at least 4 variables), or the
    /// sample times differ; [`DesignError::Unsupported`] for a filter with
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

/// One coefficient row quantised to `i16` with its binary point: the
/// largest shift (at most 40) that keeps the row's largest entry within
/// 16 bits, and the first non-zero column.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct QuantRow {
    /// Coefficients, `value = c / 2^shift`.
    pub c: Vec<i16>,
    /// Fraction bits.
    pub shift: u8,
    /// First non-zero column (the row's length if all are zero).
    pub start: usize,
}

/// Quantises a row (see [`QuantRow`]); `None` if a value is not finite.
pub fn quantize_row(row: &[f64]) -> Option<QuantRow> {
    if row.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let max = row.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut shift: i32 = 40;
    while shift > -15 && (max * 2f64.powi(shift)).round() > 32767.0 {
        shift -= 1;
    }
    if shift < 0 {
        return None; // |v| >= 2^15: not a Q15.16 coefficient
    }
    let c: Vec<i16> = row
        .iter()
        .map(|v| (v * 2f64.powi(shift)).round() as i16)
        .collect();
    let start = c.iter().position(|v| *v != 0).unwrap_or(c.len());
    Some(QuantRow {
        c,
        shift: shift as u8,
        start,
    })
}

/// The Kalman filter's rows for [`crate::kalman16::Kalman16`]: `C`, `M`,
/// `A - I` and `B`, each row quantised with its own binary point.
#[derive(Clone, Debug, PartialEq)]
pub struct Kalman16Design {
    /// Rows of `C`.
    pub c: Vec<QuantRow>,
    /// `y0` in Q15.16.
    pub y0: Vec<i32>,
    /// Rows of `M`.
    pub m: Vec<QuantRow>,
    /// Rows of `A - I`.
    pub a: Vec<QuantRow>,
    /// Rows of `B`.
    pub b: Vec<QuantRow>,
}

impl FirmwareDesign {
    /// The rows of the fast gradient's `M` in Q1.15 for
    /// [`crate::fgm16::Fgm16Law`] (entries of 1 saturate to `1 - 2^-15`).
    ///
    /// # Errors
    /// [`DesignError::Unsupported`] if an entry is outside `[-1, 1]`.
    pub fn fgm16_m(&self) -> Result<Vec<QuantRow>, DesignError> {
        let n = self.data_f64.n;
        let shift = crate::fgm16::M_SHIFT;
        let scale = 2f64.powi(shift as i32);
        self.data_f64
            .m
            .chunks(n.max(1))
            .map(|r| {
                if r.iter().any(|v| !v.is_finite() || v.abs() > 1.0 + 1e-9) {
                    return Err(DesignError::Unsupported(
                        "a fast-gradient M entry is outside [-1, 1]".into(),
                    ));
                }
                let c: Vec<i16> = r
                    .iter()
                    .map(|v| (v * scale).round().clamp(-32768.0, 32767.0) as i16)
                    .collect();
                let start = c.iter().position(|v| *v != 0).unwrap_or(c.len());
                Ok(QuantRow { c, shift, start })
            })
            .collect()
    }

    /// The momentum table in Q1.15 (`round(beta 2^15)`, at most 32767).
    pub fn fgm16_betas(&self) -> Vec<i16> {
        self.data_f64
            .betas
            .iter()
            .map(|b| (b * 32768.0).round().clamp(-32768.0, 32767.0) as i16)
            .collect()
    }

    /// The filter quantised for [`crate::kalman16::Kalman16`].
    ///
    /// # Errors
    /// [`DesignError::Unsupported`] if a coefficient is 2^15 or larger.
    pub fn kalman16(&self) -> Result<Kalman16Design, DesignError> {
        let k = &self.kalman;
        let nx = k.nx();
        let big = || DesignError::Unsupported("a Kalman coefficient does not fit Q15.16".into());
        let rows = |m: &nalgebra::DMatrix<f64>| -> Result<Vec<QuantRow>, DesignError> {
            (0..m.nrows())
                .map(|i| {
                    let r: Vec<f64> = m.row(i).iter().copied().collect();
                    quantize_row(&r).ok_or_else(big)
                })
                .collect()
        };
        let y0 =
            k.y0.iter()
                .map(|v| {
                    let q = (v * 65536.0).round();
                    if q.abs() < 2f64.powi(31) {
                        Ok(q as i32)
                    } else {
                        Err(big())
                    }
                })
                .collect::<Result<_, _>>()?;
        Ok(Kalman16Design {
            c: rows(&k.c)?,
            y0,
            m: rows(&k.filter.m)?,
            a: rows(&(&k.a - nalgebra::DMatrix::identity(nx, nx)))?,
            b: rows(&k.b)?,
        })
    }
}

fn check_model(model: &SsModel) -> Result<(), DesignError> {
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

/// The named parts of the flat table, in order, with their lengths.
fn layout(n: usize, p: usize, t: usize) -> Vec<(&'static str, usize)> {
    vec![
        ("FGM_M", n * n),
        ("FGM_K", n * p),
        ("FGM_K0", n),
        ("FGM_LO", n * p),
        ("FGM_LO0", n),
        ("FGM_HI", n * p),
        ("FGM_HI0", n),
        ("FGM_D", n),
        ("FGM_DINV", n),
        ("FGM_BETAS", t),
        ("MIX_OFFSET", 4),
        ("BIAS", NY),
    ]
}

/// The flat table in the order of [`layout`].
fn flat<S: Scalar>(d: &FirmwareDesign, data: &FgmData<S>) -> Vec<S> {
    let mut v: Vec<S> = Vec::new();
    for part in [
        &data.m,
        &data.k_theta,
        &data.k0,
        &data.lo_theta,
        &data.lo0,
        &data.hi_theta,
        &data.hi0,
        &data.d,
        &data.d_inv,
        &data.betas,
    ] {
        v.extend_from_slice(part);
    }
    v.extend(d.mixer_offset().iter().map(|x| S::from_f64(*x)));
    v.extend(d.bias().iter().map(|x| S::from_f64(*x)));
    v
}

/// The Rust source of the firmware's tables (`avr/firmware/src/generated.rs`):
/// dimensions, iteration counts, the Kalman filter with 16-bit coefficients
/// (`KF16`, a [`crate::kalman16::Kalman16Tables`]), the offsets of each part
/// of the flat solver table (fast-gradient data, mixer trim, gyro bias) and
/// that table in f32 and in Q16 raw bits.
///
/// # Errors
/// [`DesignError::Unsupported`] if a value does not fit Q16 (|v| >= 32768)
/// or is not finite.
pub fn generate_tables(d: &FirmwareDesign) -> Result<String, DesignError> {
    let (nx, n, p, t) = (d.nx(), d.data_f32.n, d.data_f32.p, d.data_f32.betas.len());
    let f = flat(d, &d.data_f32);
    let q = flat(d, &d.data_q16);
    let exact = flat(d, &d.data_f64);
    if let Some(bad) = exact.iter().find(|v| !v.is_finite() || v.abs() >= 32768.0) {
        return Err(DesignError::Unsupported(format!(
            "table value {bad} does not fit Q15.16"
        )));
    }
    let parts = layout(n, p, t);
    let total: usize = parts.iter().map(|(_, l)| l).sum();
    if total != f.len() {
        return Err(dim("table layout", total, f.len()));
    }
    let names = |v: &Option<Vec<String>>| v.as_ref().map(|v| v.join(", ")).unwrap_or_default();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// @generated by kestrel_avr_rt::design::generate_tables (`kestrel export`); do not edit.\n\
         //\n\
         // Design model: {nx} states, inputs [{}], outputs [{}], ts = {} s.\n\
         // Stationary Kalman filter: kestrel-kalman ({} multiply-adds).\n\
         // Fast gradient: kestrel-fgm, {n} variables, {p} parameters,\n\
         // eps = {:.6e} ({} us input error), condition {:.3e}, {:?} momentum,\n\
         // certified cold-start iterations {}; per period: {} ({}).\n",
        names(&d.model.inputs),
        names(&d.model.outputs),
        d.model.ts,
        nx * nx + nx * NU + 2 * NY * nx,
        d.eps,
        d.settings.max_input_error_us,
        d.cert.condition,
        d.cert.scheme,
        d.cert.iterations,
        d.loop_iterations(),
        if d.warm_start() {
            "warm start, not certified"
        } else {
            "cold start, certified"
        },
    );
    let consts: [(&str, &str, usize); 5] = [
        ("NX", "States of the design model.", nx),
        ("NZ", "Solver decision variables.", n),
        ("NP", "Solver parameters.", p),
        ("FGM_T", "Momentum table length.", t),
        (
            "FGM_ITERATIONS",
            "Certified cold-start iterations.",
            d.cert.iterations,
        ),
    ];
    for (name, doc, v) in consts {
        let _ = writeln!(s, "/// {doc}\npub const {name}: usize = {v};");
    }
    let _ = writeln!(
        s,
        "/// Iterations run per period.\npub const FGM_LOOP_ITERATIONS: usize = {};",
        d.loop_iterations()
    );
    let _ = writeln!(
        s,
        "/// Whether each period starts warm from the previous solution.\npub const FGM_WARM: bool = {};",
        d.warm_start()
    );
    let _ = writeln!(
        s,
        "/// Number of table values.\npub const N_VALUES: usize = {};",
        f.len()
    );
    let mut at = 0;
    for (name, len) in parts {
        let _ = writeln!(
            s,
            "/// Offset of `{name}` in the table.\npub const {name}: usize = {at};"
        );
        at += len;
    }
    let k16 = d.kalman16()?;
    let row = |r: &QuantRow, from: usize, to: usize| {
        let c: Vec<String> = r.c[from..to].iter().map(|v| v.to_string()).collect();
        let start = r.start.min(to - from);
        format!(
            "kestrel_avr_rt::kalman16::Row16::new([{}], {}, {start})",
            c.join(", "),
            r.shift
        )
    };
    let _ = writeln!(
        s,
        "/// The stationary Kalman filter with 16-bit coefficients ({} multiply-adds).\n#[rustfmt::skip]\npub const KF16: kestrel_avr_rt::kalman16::Kalman16Tables<{nx}, {NU}, {NY}> = kestrel_avr_rt::kalman16::Kalman16Tables {{",
        k16.c.iter().map(|r| nx - r.start).sum::<usize>()
            + k16.m.iter().map(|r| NY - r.start).sum::<usize>()
            + k16.a.iter().map(|r| nx - r.start).sum::<usize>()
            + k16.b.iter().map(|r| NU - r.start).sum::<usize>()
    );
    let list = |rows: Vec<String>| format!("[\n        {},\n    ]", rows.join(",\n        "));
    let _ = writeln!(
        s,
        "    c: {},",
        list(k16.c.iter().map(|r| row(r, 0, nx)).collect())
    );
    let y0: Vec<String> = k16.y0.iter().map(|v| v.to_string()).collect();
    let _ = writeln!(s, "    y0: [{}],", y0.join(", "));
    let _ = writeln!(
        s,
        "    m: {},",
        list(k16.m.iter().map(|r| row(r, 0, NY)).collect())
    );
    let _ = writeln!(
        s,
        "    a: {},",
        list(k16.a.iter().map(|r| row(r, 0, nx)).collect())
    );
    let _ = writeln!(
        s,
        "    b: {},\n}};",
        list(k16.b.iter().map(|r| row(r, 0, NU)).collect())
    );
    let _ = writeln!(
        s,
        "/// The fast gradient's `M` rows with 16-bit coefficients.\n#[rustfmt::skip]\npub const FGM16_M: [kestrel_avr_rt::kalman16::Row16<{n}>; {n}] = {};",
        list(d.fgm16_m()?.iter().map(|r| row(r, 0, n)).collect())
    );
    let betas: Vec<String> = d.fgm16_betas().iter().map(|b| b.to_string()).collect();
    let _ = writeln!(
        s,
        "/// The momentum table in Q1.15.\npub const FGM16_BETAS: [i16; {t}] = [{}];",
        betas.join(", ")
    );
    let _ = writeln!(
        s,
        "/// The table in f32.\n#[rustfmt::skip]\npub const VALUES_F32: [f32; N_VALUES] = ["
    );
    for c in f.chunks(6) {
        let line: Vec<String> = c.iter().map(|v| format!("{v:e}")).collect();
        let _ = writeln!(s, "    {},", line.join(", "));
    }
    let _ = writeln!(
        s,
        "];\n/// The table in Q16 (raw bits).\n#[rustfmt::skip]\npub const VALUES_Q16: [i32; N_VALUES] = ["
    );
    for c in q.chunks(8) {
        let line: Vec<String> = c.iter().map(|v| v.0.to_string()).collect();
        let _ = writeln!(s, "    {},", line.join(", "));
    }
    let _ = writeln!(s, "];");
    Ok(s)
}

// ---------------------------------------------------------------- explicit MPC

/// The explicit MPC problem with `Ns = 2` free moves (`N = 2`, blocks
/// `[1, 1]`, 8 variables) on `model` in the firmware's coordinates, with
/// kestrel-mpc's tricopter bounds and default weights.
///
/// # Errors
/// kestrel-mpc's errors (e.g. a model without 4 inputs).
pub fn ns2_problem(model: &SsModel) -> Result<MpqpProblem, DesignError> {
    let (q1, q2) = default_weights();
    let settings = kestrel_mpc::MpcSettings {
        blocking: Some(kestrel_mpc::Blocking::thesis(2, 2)?),
        ..kestrel_mpc::MpcSettings::thesis(q1, q2)
    };
    let trim = tricopter_trim(model)?;
    Ok(kestrel_mpc::MpcProblem::build(model, &trim.bounds(), &settings)?.to_mpqp())
}

/// The explicit controller of an MPC problem for the firmware: kestrel-empc's
/// exact mpQP solution, the first move kept (`NU` outputs), its search tree.
///
/// # Errors
/// [`DesignError::Dimension`] for fewer than `NU` variables; kestrel-empc's errors.
pub fn empc_controller(
    problem: &MpqpProblem,
) -> Result<kestrel_empc::ExplicitController, DesignError> {
    if problem.n() < NU {
        return Err(dim(
            "MPC problem variables",
            format!("at least {NU}"),
            problem.n(),
        ));
    }
    let solution = kestrel_empc::solve(problem, &kestrel_empc::Settings::default())?;
    let tree = kestrel_empc::TreeSettings {
        outputs: kestrel_empc::Outputs::First(NU),
        ..Default::default()
    };
    Ok(kestrel_empc::build_controller(problem, &solution, &tree)?)
}

/// The [`crate::explicit::TreeLayout`] of tables.
pub fn empc_layout(
    t: &kestrel_empc::OwnedTables<f64>,
) -> Result<crate::explicit::TreeLayout, DesignError> {
    let w = t.n_params + 1;
    let l = crate::explicit::TreeLayout {
        n_params: t.n_params,
        n_outputs: t.n_outputs,
        root: t.root,
        n_nodes: t.nodes.len(),
        n_laws: t.laws.len() / t.n_outputs.max(1),
        n_rows: t.rows.len() / w,
        n_hull: t.hull.len() / w,
    };
    if l.n_laws * t.n_outputs != t.laws.len()
        || l.n_rows * w != t.rows.len()
        || l.n_hull * w != t.hull.len()
        || t.theta_lb.len() != t.n_params
        || t.theta_ub.len() != t.n_params
        || t.bounds.len() != t.n_outputs
    {
        return Err(DesignError::Unsupported(
            "explicit MPC tables with inconsistent lengths".into(),
        ));
    }
    Ok(l)
}

/// The tables as the flat bytes [`crate::explicit::FlashTree`] reads:
/// numbers in f32, or with `fixed` the raw bits of Q15.16.
///
/// # Errors
/// [`DesignError::Unsupported`] for inconsistent tables, or (with `fixed`)
/// a non-finite number or one that does not fit Q15.16.
pub fn empc_table_bytes(
    t: &kestrel_empc::OwnedTables<f64>,
    fixed: bool,
) -> Result<Vec<u8>, DesignError> {
    let l = empc_layout(t)?;
    let mut b = Vec::with_capacity(l.bytes(4));
    for v in t
        .nodes
        .iter()
        .flatten()
        .chain(&t.laws)
        .chain(t.bounds.iter().flatten())
    {
        b.extend(v.to_le_bytes());
    }
    for &v in t
        .rows
        .iter()
        .chain(&t.hull)
        .chain(&t.theta_lb)
        .chain(&t.theta_ub)
    {
        if fixed {
            if !v.is_finite() || v.abs() >= 32768.0 {
                return Err(DesignError::Unsupported(format!(
                    "explicit MPC table value {v} does not fit Q15.16"
                )));
            }
            b.extend(Q16::from_f64(v).0.to_le_bytes());
        } else {
            b.extend((v as f32).to_le_bytes());
        }
    }
    debug_assert_eq!(b.len(), l.bytes(4));
    Ok(b)
}

/// The Rust source of `avr/firmware/src/generated_empc.rs`: the layout
/// (`EMPC_LAYOUT`) and the explicit controller's flat table in f32
/// (`EMPC_F32`) and Q15.16 (`EMPC_Q16`), `EMPC_BYTES` each (kestrel-empc's
/// generic evaluation through [`crate::explicit::FlashTree`]); then the
/// same tree with 16-bit rows for [`crate::explicit::tree16`] (`EMPC16`,
/// `EMPC16_LAYOUT`: what the firmware flies).
///
/// # Errors
/// As [`empc_table_bytes`] and [`crate::explicit::quantize::quantize_tree`].
pub fn generate_empc_tables(
    c: &kestrel_empc::ExplicitController,
    what: &str,
) -> Result<String, DesignError> {
    let l = empc_layout(&c.tables)?;
    let f = empc_table_bytes(&c.tables, false)?;
    let q = empc_table_bytes(&c.tables, true)?;
    let st = &c.stats;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// @generated by kestrel_avr_rt::design::generate_empc_tables; do not edit.\n\
         //\n\
         // Explicit MPC ({what}), kestrel-empc: {} regions, {} distinct laws,\n\
         // {} affine rows, tree of {} nodes, depth {}, {} explored-set rows; {} bytes.\n",
        st.regions,
        st.distinct_laws,
        l.n_rows,
        st.nodes,
        st.depth,
        l.n_hull,
        f.len()
    );
    let _ = writeln!(
        s,
        "/// Tree depth (most nodes on a root-to-leaf path).\npub const EMPC_DEPTH: usize = {};\n\
         /// Bytes of the table.\npub const EMPC_BYTES: usize = {};\n\
         /// Layout of the table.\npub const EMPC_LAYOUT: kestrel_avr_rt::explicit::TreeLayout = kestrel_avr_rt::explicit::TreeLayout {{\n    \
         n_params: {}, n_outputs: {}, root: {}, n_nodes: {}, n_laws: {}, n_rows: {}, n_hull: {},\n}};",
        st.depth,
        f.len(),
        l.n_params,
        l.n_outputs,
        l.root,
        l.n_nodes,
        l.n_laws,
        l.n_rows,
        l.n_hull
    );
    for (name, bytes) in [("EMPC_F32", &f), ("EMPC_Q16", &q)] {
        let _ = writeln!(
            s,
            "/// The table ({}).\n#[rustfmt::skip]\npub const {name}: [u8; EMPC_BYTES] = [",
            if name == "EMPC_F32" {
                "f32 numbers"
            } else {
                "Q15.16 numbers"
            }
        );
        for ch in bytes.chunks(24) {
            let line: Vec<String> = ch.iter().map(|v| v.to_string()).collect();
            let _ = writeln!(s, "    {},", line.join(", "));
        }
        let _ = writeln!(s, "];");
    }
    // The firmware's fast path: the same tree with 16-bit rows.
    let q = crate::explicit::quantize::quantize_tree(&c.tables)?;
    s.push_str(&crate::explicit::quantize::tree16_source(&q));
    Ok(s)
}
