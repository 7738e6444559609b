//! Stage 5: the thesis-sized and the larger MPC problem on the identified
//! black-box model (sections 6.1, 7.6), plain or offset-free.

use super::config::{Config, Horizon};
use super::error::{Context, Result};
use super::identification::Identification;
use crate::problems::tricopter_trim;
use kestrel_core::formats::{MpqpProblem, SsModel};
use kestrel_mpc::{Blocking, DisturbanceModel, MpcProblem, MpcSettings, Terminal};

/// Which of the two problems.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProblemName {
    /// The thesis-sized problem (`mpc.thesis`).
    Thesis,
    /// The larger problem (`mpc.larger`).
    Larger,
}

impl ProblemName {
    /// `thesis` or `larger` (file names, `summary.json` keys).
    pub fn as_str(self) -> &'static str {
        match self {
            ProblemName::Thesis => "thesis",
            ProblemName::Larger => "larger",
        }
    }
}

/// One condensed problem.
#[derive(Clone, Debug)]
pub struct Problem {
    /// Which.
    pub name: ProblemName,
    /// Horizon and blocks.
    pub horizon: Horizon,
    /// The problem with its layout and cost.
    pub problem: MpcProblem,
    /// As `kestrel.mpqp.v1`.
    pub mpqp: MpqpProblem,
    /// Condition number of `H`.
    pub condition: f64,
}

impl Problem {
    /// Inputs of the model (the first move's length).
    pub fn nu(&self) -> usize {
        self.problem.nu
    }
}

/// Stage 5's result.
#[derive(Clone, Debug)]
pub struct Problems {
    /// Design model (the identified black-box model).
    pub model: SsModel,
    /// The estimator's model: the design model, or with `mpc.offset_free`
    /// the model augmented with `nd` constant disturbance states. The
    /// Kalman stage designs the filter on it.
    pub estimator_model: SsModel,
    /// Number of disturbance states (0 without `mpc.offset_free`).
    pub nd: usize,
    /// The disturbance model (`None` without `mpc.offset_free`).
    pub disturbance: Option<DisturbanceModel>,
    /// The thesis-sized problem.
    pub thesis: Problem,
    /// The larger problem.
    pub larger: Problem,
}

impl Problems {
    /// Both problems, thesis-sized first.
    pub fn list(&self) -> [&Problem; 2] {
        [&self.thesis, &self.larger]
    }

    /// Name of parameter `k` of `theta = [x; d; r; throttle]`: `x1`...,
    /// `d1`..., `r_roll [rad/s]`, `r_pitch [rad/s]`, `r_yaw [rad/s]`,
    /// `throttle [us]`.
    pub fn parameter_name(&self, k: usize) -> String {
        let layout = &self.thesis.problem.layout;
        let (na, nx) = (layout.nx, layout.nx - self.nd);
        const REFS: [&str; 3] = ["r_roll [rad/s]", "r_pitch [rad/s]", "r_yaw [rad/s]"];
        if k < nx {
            format!("x{}", k + 1)
        } else if k < na {
            format!("d{}", k - nx + 1)
        } else if layout.parameters().contains(&k) {
            "throttle [us]".into()
        } else {
            REFS.get(k - na)
                .map_or_else(|| format!("r{}", k - na + 1), |s| s.to_string())
        }
    }
}

/// Stage 5.
///
/// # Errors
/// Bad blocks; kestrel-mpc's errors (e.g. an undetectable disturbance model).
pub fn run(cfg: &Config, id: &Identification) -> Result<Problems> {
    let model = id.blackbox.ss.clone();
    let trim = tricopter_trim(&model).ctx(|| "the black-box model's u0".into())?;
    let m = &cfg.mpc;
    let disturbance = m.offset_free.then_some(DisturbanceModel::OutputStates);
    let (mut estimator_model, mut nd) = (model.clone(), 0);
    let mut build = |name: ProblemName, h: &Horizon| -> Result<Problem> {
        let key = name.as_str();
        let settings = MpcSettings {
            horizon: h.horizon,
            blocking: Some(Blocking::new(h.blocks.clone()).ctx(|| format!("mpc.{key}.blocks"))?),
            q1: m.q1.weight(),
            q2: m.q2.weight(),
            terminal: Terminal::Lq,
            state_bound: m.state_bound,
            reference_bound: m.reference_bound,
            ..MpcSettings::default()
        };
        let settings = trim.constrain(settings);
        let problem = match &disturbance {
            Some(dm) => {
                let d = MpcProblem::build_offset_free(&model, &settings, dm)
                    .ctx(|| format!("building the offset-free {key} MPC problem"))?;
                estimator_model = d.augmented;
                nd = d.nd;
                d.problem
            }
            None => MpcProblem::build(&model, &settings)
                .ctx(|| format!("building the {key} MPC problem"))?,
        };
        let mpqp = problem.to_mpqp();
        let eig = mpqp.h.clone().symmetric_eigenvalues();
        Ok(Problem {
            name,
            horizon: h.clone(),
            problem,
            mpqp,
            condition: eig.max() / eig.min(),
        })
    };
    let thesis = build(ProblemName::Thesis, &m.thesis)?;
    let larger = build(ProblemName::Larger, &m.larger)?;
    Ok(Problems {
        model,
        estimator_model,
        nd,
        disturbance,
        thesis,
        larger,
    })
}
