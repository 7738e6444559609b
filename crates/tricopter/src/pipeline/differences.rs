//! Stage 11: where the pipeline's numbers differ from the thesis's, and
//! why, from the typed results of the other stages.

use super::closed_loop::{ClosedLoop, Controller, RunKind};
use super::config::Config;
use super::explicit::Explicit;
use super::fast_gradient::FastGradient;
use super::identification::{Identification, ModelKey};
use super::sensor::SensorStats;
use super::table_7_2::Table72;

/// What the pipeline found for a quantity.
#[derive(Clone, Debug, PartialEq)]
pub enum Here {
    /// Fits per output (%).
    Fits(Option<Vec<f64>>),
    /// The trim `U0` (us).
    Trim([f64; 4]),
    /// The explicit law's tables.
    ExplicitTables {
        /// Regions.
        regions: usize,
        /// Bytes of the first-move tables in f32.
        bytes: usize,
        /// Depth of the first-move tree.
        depth: usize,
    },
    /// Certified iterations and their `eps`.
    Certificates(Vec<(usize, f64)>),
    /// An optimal cost.
    Cost(f64),
    /// A per-channel figure of the MPC (QP) and of the PI.
    AgainstPi {
        /// The MPC with the reference QP.
        qp: Vec<f64>,
        /// The PI.
        pi: Vec<f64>,
    },
    /// The MPC design: offset-free or plain, and its input weight.
    Design {
        /// Offset-free MPC.
        offset_free: bool,
        /// The input weight as configured.
        q2: String,
    },
}

/// What a row is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// Black-box simulation fit.
    BlackBoxSimulationFit,
    /// Black-box 5-step fit.
    BlackBoxFiveStepFit,
    /// Black-box virtual simulation fit.
    VirtualSimulationFit,
    /// The trim.
    Trim,
    /// The explicit tables.
    ExplicitTables,
    /// Certified iterations.
    CertifiedIterations,
    /// Table 7.2's `J*`.
    OptimalCost,
    /// Closed-loop pulse effort.
    Effort,
    /// Closed-loop rise time.
    RiseTime,
    /// The MPC design.
    MpcDesign,
}

/// One row: the quantity, the pipeline's value (the renderer supplies the
/// thesis's value and the explanation for each [`Quantity`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Difference {
    /// What.
    pub quantity: Quantity,
    /// The pipeline's value.
    pub here: Here,
}

/// Outputs whose validation data hardly move (less than ten times the
/// gyro noise): their fit says little.
#[derive(Clone, Debug, PartialEq)]
pub struct WeakOutputs {
    /// Which model.
    pub model: ModelKey,
    /// `(output, validation std, gyro noise std)` (rad/s).
    pub outputs: Vec<(String, f64, f64)>,
}

/// Stage 11's result.
#[derive(Clone, Debug, PartialEq)]
pub struct Differences {
    /// The rows.
    pub rows: Vec<Difference>,
    /// Models with weakly excited outputs.
    pub weak: Vec<WeakOutputs>,
}

/// Stage 11.
pub fn run(
    cfg: &Config,
    s: &SensorStats,
    id: &Identification,
    ex: &Explicit,
    fg: &FastGradient,
    t72: &Table72,
    cl: &ClosedLoop,
) -> Differences {
    let step = |c: Controller| cl.run(RunKind::Step, c).map(|r| &r.metrics);
    let against = |f: &dyn Fn(&crate::closed_loop::StepMetrics) -> Vec<f64>| Here::AgainstPi {
        qp: step(Controller::Qp).map(f).unwrap_or_default(),
        pi: step(Controller::Pi).map(f).unwrap_or_default(),
    };
    let row = |quantity, here| Difference { quantity, here };
    let rows = vec![
        row(
            Quantity::BlackBoxSimulationFit,
            Here::Fits(id.blackbox.fit("model simulation")),
        ),
        row(
            Quantity::BlackBoxFiveStepFit,
            Here::Fits(id.blackbox.fit("model 5-step")),
        ),
        row(
            Quantity::VirtualSimulationFit,
            Here::Fits(id.virtual_.fit("model simulation")),
        ),
        row(Quantity::Trim, Here::Trim(s.u0)),
        row(
            Quantity::ExplicitTables,
            Here::ExplicitTables {
                regions: ex.thesis.solution.regions.len(),
                bytes: ex.thesis.first.tables.bytes(4),
                depth: ex.thesis.first.stats.depth,
            },
        ),
        row(
            Quantity::CertifiedIterations,
            Here::Certificates(
                fg.thesis
                    .certificates
                    .iter()
                    .map(|c| (c.certificate.iterations, c.eps))
                    .collect(),
            ),
        ),
        row(Quantity::OptimalCost, Here::Cost(t72.j_star)),
        row(Quantity::Effort, against(&|m| m.effort.to_vec())),
        row(Quantity::RiseTime, against(&|m| m.rise_time.to_vec())),
        row(
            Quantity::MpcDesign,
            Here::Design {
                offset_free: cfg.mpc.offset_free,
                q2: cfg.mpc.q2.to_string(),
            },
        ),
    ];
    let noise: Vec<f64> = (0..3).map(|j| s.covariance[(j, j)].sqrt()).collect();
    let weak = id
        .models()
        .iter()
        .filter_map(|m| {
            let outputs: Vec<(String, f64, f64)> = m
                .validation_data
                .std
                .iter()
                .zip(&noise)
                .zip(["p", "q", "r"])
                .filter(|((s, n), _)| **s < 10.0 * **n)
                .map(|((s, n), o)| (o.to_string(), *s, *n))
                .collect();
            (!outputs.is_empty()).then_some(WeakOutputs {
                model: m.kind,
                outputs,
            })
        })
        .collect();
    Differences { rows, weak }
}
