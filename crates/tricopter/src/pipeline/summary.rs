//! The key figures of a [`PipelineResult`] as one serialisable struct:
//! `kestrel pipeline` writes it as `summary.json` (with the run time).

use super::closed_loop::{Controller, RunKind};
use super::explicit::ExplicitSolution;
use super::fast_gradient::FgmProblem;
use super::identification::IdentifiedModel;
use super::result::PipelineResult;
use super::table_7_2::Solver;
use serde::Serialize;

/// Stage 2's figures.
#[derive(Clone, Debug, Serialize)]
pub struct SensorSummary {
    /// Gyro bias (rad/s).
    pub bias: [f64; 3],
    /// Diagonal of the gyro covariance.
    pub covariance_diag: [f64; 3],
    /// Trim `U0` (us).
    pub u0: [f64; 4],
    /// The simulator's trim, when known.
    pub true_u0: Option<[f64; 4]>,
}

/// Stage 3's figures of one model.
#[derive(Clone, Debug, Serialize)]
pub struct FitSummary {
    /// Simulation fit per output (%).
    pub simulation: Option<Vec<f64>>,
    /// 5-step fit per output (%).
    pub five_step: Option<Vec<f64>>,
    /// Model order.
    pub order: usize,
    /// Standard deviation of the validation outputs (rad/s).
    pub validation_std: Vec<f64>,
}

/// Stage 4's errors against the true rates.
#[derive(Clone, Debug, Serialize)]
pub struct KalmanRmsSummary {
    /// Gyro minus bias.
    pub gyro: [f64; 3],
    /// Kalman estimate.
    pub kalman: [f64; 3],
}

/// Stage 4's design.
#[derive(Clone, Debug, Serialize)]
pub struct KalmanSummary {
    /// Filter states.
    pub states: usize,
    /// Of which disturbance states.
    pub disturbance_states: usize,
    /// Pulse noise (us).
    pub input_noise: f64,
    /// Chosen rate noise (rad/s per sample).
    pub rate_noise: f64,
    /// Chosen disturbance noise (rad/s per sample), if any.
    pub gust_noise: Option<f64>,
    /// Mean NIS on the training flight.
    pub training_nis: f64,
    /// Mean NIS on the filtered flight.
    pub flight_nis: f64,
}

/// Stage 6's figures of one problem.
#[derive(Clone, Debug, Serialize)]
pub struct EmpcSummary {
    /// Regions.
    pub regions: usize,
    /// Distinct laws.
    pub distinct_laws: usize,
    /// Depth of the first-move tree.
    pub depth: usize,
    /// Nodes of the first-move tree.
    pub nodes: usize,
    /// Bytes of the first-move tables (f32).
    pub bytes_f32_first_move: usize,
    /// Bytes of the whole-`z` tables (f32).
    pub bytes_f32_all: usize,
    /// Solve time (s).
    pub solve_seconds: f64,
    /// Random check points.
    pub check_points: usize,
    /// Of which outside the explored set.
    pub outside: usize,
    /// Largest `|z_explicit - z_QP|`.
    pub max_dz: f64,
    /// Largest `|J_explicit - J_QP|`.
    pub max_dj: f64,
}

/// One certificate.
#[derive(Clone, Debug, Serialize)]
pub struct CertificateSummary {
    /// Tolerance.
    pub eps: f64,
    /// Certified iterations.
    pub iterations: usize,
    /// Largest gap found.
    pub max_gap: f64,
    /// Whether it holds.
    pub holds: bool,
}

/// Stage 7's figures of one problem.
#[derive(Clone, Debug, Serialize)]
pub struct FgmSummary {
    /// The certificates.
    pub certificates: Vec<CertificateSummary>,
    /// The PWM-accuracy `eps`.
    pub eps_pwm: f64,
    /// Lipschitz constant before preconditioning.
    #[serde(rename = "L")]
    pub l: f64,
    /// Convexity constant before preconditioning.
    pub mu: f64,
}

/// One fast gradient row of Table 7.2.
#[derive(Clone, Debug, Serialize)]
pub struct FgmRowSummary {
    /// Iterations.
    pub iterations: usize,
    /// Cost.
    #[serde(rename = "J")]
    pub j: f64,
}

/// Stage 8's figures.
#[derive(Clone, Debug, Serialize)]
pub struct Table72Summary {
    /// `J*`.
    #[serde(rename = "J_qp")]
    pub j_qp: f64,
    /// The QP's first move.
    #[serde(rename = "U_qp")]
    pub u_qp: Vec<f64>,
    /// The explicit law's first move.
    #[serde(rename = "U_explicit")]
    pub u_explicit: Vec<f64>,
    /// The fast gradient rows.
    pub fgm: Vec<FgmRowSummary>,
}

/// Step-run figures of one controller.
#[derive(Clone, Debug, Serialize)]
pub struct StepSummary {
    /// RMS pulse effort (us).
    pub effort: Vec<f64>,
    /// Rise times (s).
    pub rise_time: Vec<f64>,
    /// Overshoots (%).
    pub overshoot: Vec<f64>,
    /// RMS errors (rad/s).
    pub rms_error: Vec<f64>,
}

/// The key figures (`summary.json`).
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Stage 2.
    pub sensor: SensorSummary,
    /// Stage 3, black-box.
    pub fit_blackbox: FitSummary,
    /// Stage 3, black-box virtual.
    pub fit_virtual: FitSummary,
    /// Stage 4 against the true rates (simulated flights).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kalman_rms: Option<KalmanRmsSummary>,
    /// Stage 4's design.
    pub kalman: KalmanSummary,
    /// Whether the MPC is offset-free.
    pub offset_free: bool,
    /// Stage 6, thesis-sized problem.
    pub empc_thesis: EmpcSummary,
    /// Regions cut by the partition slice.
    pub partition_slice_regions: usize,
    /// Stage 6, larger problem (when solved).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub empc_larger: Option<EmpcSummary>,
    /// Stage 7, thesis-sized problem.
    pub fgm_thesis: FgmSummary,
    /// Stage 7, larger problem.
    pub fgm_larger: FgmSummary,
    /// Whether every certificate holds.
    pub fgm_all_certificates_hold: bool,
    /// Stage 8.
    pub table_7_2: Table72Summary,
    /// Stage 9, the PI's step run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub closed_loop_step_pi: Option<StepSummary>,
    /// Stage 9, the QP MPC's step run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub closed_loop_step_qp: Option<StepSummary>,
    /// Largest bound violation of any run (us).
    pub closed_loop_max_bound_violation: f64,
}

fn fit(m: &IdentifiedModel) -> FitSummary {
    FitSummary {
        simulation: m.fit("model simulation"),
        five_step: m.fit("model 5-step"),
        order: m.reduced_order,
        validation_std: m.validation_data.std.clone(),
    }
}

fn empc(e: &ExplicitSolution) -> EmpcSummary {
    EmpcSummary {
        regions: e.solution.regions.len(),
        distinct_laws: e.full.stats.distinct_laws,
        depth: e.first.stats.depth,
        nodes: e.first.stats.nodes,
        bytes_f32_first_move: e.first.tables.bytes(4),
        bytes_f32_all: e.full.tables.bytes(4),
        solve_seconds: e.solution.stats.solve_seconds,
        check_points: e.check.points,
        outside: e.check.outside,
        max_dz: e.check.max_dz,
        max_dj: e.check.max_dj,
    }
}

fn fgm(f: &FgmProblem) -> FgmSummary {
    let pc = &f.design.preconditioning;
    FgmSummary {
        certificates: f
            .certificates
            .iter()
            .map(|c| CertificateSummary {
                eps: c.eps,
                iterations: c.certificate.iterations,
                max_gap: c.max_gap,
                holds: c.holds,
            })
            .collect(),
        eps_pwm: f.eps_pwm,
        l: pc.before.l,
        mu: pc.before.mu,
    }
}

impl PipelineResult {
    /// The key figures.
    pub fn summary(&self) -> Summary {
        let s = &self.sensor;
        let k = &self.kalman;
        let t = &self.table_7_2;
        let step = |c: Controller| {
            self.closed_loop.run(RunKind::Step, c).map(|r| {
                let m = &r.metrics;
                StepSummary {
                    effort: m.effort.to_vec(),
                    rise_time: m.rise_time.to_vec(),
                    overshoot: m.overshoot.to_vec(),
                    rms_error: m.rms_error.to_vec(),
                }
            })
        };
        Summary {
            sensor: SensorSummary {
                bias: s.bias,
                covariance_diag: std::array::from_fn(|j| s.covariance[(j, j)]),
                u0: s.u0,
                true_u0: s.true_u0,
            },
            fit_blackbox: fit(&self.identification.blackbox),
            fit_virtual: fit(&self.identification.virtual_),
            kalman_rms: k.rms.map(|r| KalmanRmsSummary {
                gyro: r.gyro,
                kalman: r.kalman,
            }),
            kalman: KalmanSummary {
                states: k.design.kalman.nx(),
                disturbance_states: k.design.nd(),
                input_noise: k.input_noise,
                rate_noise: k.chosen.rate_noise,
                gust_noise: k.chosen.gust_noise,
                training_nis: k.chosen.nis,
                flight_nis: k.flight_nis,
            },
            offset_free: self.config.mpc.offset_free,
            empc_thesis: empc(&self.explicit.thesis),
            partition_slice_regions: self.explicit.slice.polygons.len(),
            empc_larger: self.explicit.larger.as_ref().map(empc),
            fgm_thesis: fgm(&self.fast_gradient.thesis),
            fgm_larger: fgm(&self.fast_gradient.larger),
            fgm_all_certificates_hold: self.fast_gradient.all_hold,
            table_7_2: Table72Summary {
                j_qp: t.j_star,
                u_qp: t
                    .rows
                    .first()
                    .map(|r| t.first_move(r).to_vec())
                    .unwrap_or_default(),
                u_explicit: t
                    .rows
                    .get(1)
                    .map(|r| t.first_move(r).to_vec())
                    .unwrap_or_default(),
                fgm: t
                    .rows
                    .iter()
                    .filter_map(|r| match r.solver {
                        Solver::FgmFixed(k) | Solver::FgmCertified { iterations: k, .. } => {
                            Some(FgmRowSummary {
                                iterations: k,
                                j: r.cost,
                            })
                        }
                        Solver::Qp | Solver::Explicit | Solver::ActiveSet { .. } => None,
                    })
                    .collect(),
            },
            closed_loop_step_pi: step(Controller::Pi),
            closed_loop_step_qp: step(Controller::Qp),
            closed_loop_max_bound_violation: self.closed_loop.worst_violation,
        }
    }
}
