//! Output limits on an identified plant: the CD player arm of DaISy
//! (two inputs, two outputs, 2048 samples), identified by kestrel-sysid's
//! N4SID at order 8, controlled with `|y_i| <= 0.5` towards the reference
//! `[0.8, -0.3]`, the first entry beyond the limit:
//!
//! - hard limits: the first output is held at the limit, the second
//!   reaches its reference;
//! - soft limits with a weak quadratic penalty (no linear one): the first
//!   output settles between the limit and the reference, beyond the limit
//!   by no more than the slack the QP reported for the step;
//! - soft limits with the default, exact penalty: as the hard limits (the
//!   hard problem is feasible, so the exact penalty gives its solution).
//!
//! `cargo run -p kestrel-mpc --example cd_player [path/to/cd_player_arm.csv]`
//!
//! The closed loops run on the identified model with its state known.
#![allow(dead_code)] // tests/tests/mpc_examples.rs includes this file as a module

use kestrel_core::formats::SsModel;
use kestrel_core::{ControlLaw, DiscreteLinearModel};
use kestrel_mpc::{
    Bounds, MpcLaw, MpcProblem, MpcSettings, QpSettings, SoftPenalty, Terminal, Weight,
};
use kestrel_sysid::{CsvColumns, IoData, N4sidSettings, n4sid};
use nalgebra::dvector;
use std::error::Error;
use std::path::{Path, PathBuf};

/// The output limit `|y_i| <= Y_MAX` (the data's outputs span about +-1.5).
pub const Y_MAX: f64 = 0.5;
/// The reference, its first entry beyond the limit.
pub const REFERENCE: [f64; 2] = [0.8, -0.3];

/// One closed loop.
#[derive(Clone, Debug)]
pub struct LoopSummary {
    /// The largest `|y_i|`.
    pub max_output: f64,
    /// The largest amount an output went beyond its limit.
    pub max_violation: f64,
    /// The largest slack the QP reported (0 for hard limits).
    pub max_slack: f64,
    /// The outputs at the end.
    pub final_output: [f64; 2],
}

/// The three closed loops.
#[derive(Clone, Debug)]
pub struct Summary {
    /// Hard limits.
    pub hard: LoopSummary,
    /// Soft limits with penalty `15/2 s^2`.
    pub soft_weak: LoopSummary,
    /// Soft limits with the default (exact) penalty.
    pub soft_exact: LoopSummary,
}

/// Where the data lies from this crate's folder.
fn default_data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/daisy/cd_player_arm.csv")
}

/// The arm's model: N4SID of order 8 on all samples, means removed
/// (DaISy gives no sample time: 1).
pub fn identify(data: &Path) -> Result<SsModel, Box<dyn Error>> {
    let columns = CsvColumns {
        ts: Some(1.0),
        ..CsvColumns::new(&["u1", "u2"], &["y1", "y2"])
    };
    let (data, _offsets) = IoData::read_csv(data, &columns)?.remove_means()?;
    let settings = N4sidSettings {
        order: Some(8),
        ..N4sidSettings::default()
    };
    Ok(n4sid(&data, &settings)?
        .model
        .to_ss_model(None, None, None, None)?)
}

/// `steps` samples from rest towards [`REFERENCE`] with `output_bounds`,
/// checking at every sample that the outputs stay within the limits
/// plus the largest slack of the QP that chose the input.
pub fn closed_loop(
    model: &SsModel,
    output_bounds: Bounds,
    steps: usize,
) -> Result<LoopSummary, Box<dyn Error>> {
    let settings = MpcSettings {
        horizon: 15,
        q1: Weight::Scalar(1.0),
        q2: Weight::Scalar(1e-3),
        terminal: Terminal::Lq,
        input_bounds: Some(Bounds::new(dvector![-0.7, -3.0], dvector![0.7, 3.0])),
        output_bounds: Some(output_bounds),
        ..MpcSettings::default()
    };
    let problem = MpcProblem::build(model, &settings)?;
    let moves = problem.n() - problem.n_slack;
    let mut law = MpcLaw::clarabel(&problem, QpSettings::default())?;
    let mut x = vec![0.0; model.nx()];
    let mut next = x.clone();
    let mut u = [0.0; 2];
    let mut summary = LoopSummary {
        max_output: 0.0,
        max_violation: 0.0,
        max_slack: 0.0,
        final_output: [0.0; 2],
    };
    for k in 0..steps {
        law.control(&x, &REFERENCE, &mut u)?;
        let slack = law.last_z()[moves..].iter().fold(0.0_f64, |a, s| a.max(*s));
        model.step_into(&x, &u, &mut next)?;
        std::mem::swap(&mut x, &mut next);
        let y = &model.c * nalgebra::DVector::from_column_slice(&x);
        for (i, yi) in y.iter().enumerate() {
            let violation = (yi.abs() - Y_MAX).max(0.0);
            // The QP's first predicted output is this one (same model, same
            // state): it exceeds the limit by at most the slack.
            assert!(
                violation <= slack + 1e-7,
                "sample {k}: output {i} = {yi} beyond the limit {Y_MAX} by more than the slack {slack}"
            );
            summary.max_output = summary.max_output.max(yi.abs());
            summary.max_violation = summary.max_violation.max(violation);
            summary.final_output[i] = *yi;
        }
        summary.max_slack = summary.max_slack.max(slack);
    }
    Ok(summary)
}

/// Identifies the arm from `data` and runs the three closed loops.
pub fn run(data: &Path, steps: usize) -> Result<Summary, Box<dyn Error>> {
    let model = identify(data)?;
    let limits = || Bounds::new(dvector![-Y_MAX, -Y_MAX], dvector![Y_MAX, Y_MAX]);
    let weak = SoftPenalty {
        quadratic: 15.0,
        linear: 0.0,
    };
    Ok(Summary {
        hard: closed_loop(&model, limits(), steps)?,
        soft_weak: closed_loop(&model, limits().with_soft(weak), steps)?,
        soft_exact: closed_loop(&model, limits().with_soft(SoftPenalty::default()), steps)?,
    })
}

fn main() -> Result<(), Box<dyn Error>> {
    let data = std::env::args_os()
        .nth(1)
        .map_or_else(default_data, PathBuf::from);
    let s = run(&data, 80)?;
    for (name, l) in [
        ("hard limits", &s.hard),
        ("soft limits (15/2 s^2)", &s.soft_weak),
        ("soft limits (exact penalty)", &s.soft_exact),
    ] {
        println!(
            "{name}: largest |y| {:.4}, violation {:.2e} (largest slack {:.2e}), \
             final outputs [{:.4}, {:.4}]",
            l.max_output, l.max_violation, l.max_slack, l.final_output[0], l.final_output[1]
        );
    }
    Ok(())
}
