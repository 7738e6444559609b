//! Why the fast gradient method refuses a kestrel-mpc problem, in the
//! problem's own words: [`FgmError`] carries row and variable indices of
//! the QP; here they become the constraints and inputs of the MPC
//! ([`MpcProblem::row_label`]).

use crate::FgmError;
use kestrel_mpc::MpcProblem;

/// What the message advises when the constraints are not a box.
const OTHER_SOLVERS: &str =
    "the fast gradient method takes box constraints only: use the explicit or the reference solver";

/// Decision variable `j` of `problem`: an input of a block (named by the
/// block's first step) or a slack variable.
fn variable_label(problem: &MpcProblem, j: usize) -> String {
    let moves = problem.n().saturating_sub(problem.n_slack);
    if j >= moves || problem.nu == 0 {
        return format!("slack variable {}", j - moves.min(j));
    }
    let (block, input) = (j / problem.nu, j % problem.nu);
    let step: usize = problem.blocks.iter().take(block).sum();
    format!("input {input} at step {step}")
}

/// Row `i` of `problem`'s `G`, named.
fn row(problem: &MpcProblem, i: usize) -> String {
    match problem.row_label(i) {
        label if label.is_empty() => format!("constraint row {i}"),
        label => label,
    }
}

/// The message of `e` for a solver of `problem`: the constraint or the
/// input at fault named as the MPC states it.
pub(crate) fn describe(e: &FgmError, problem: &MpcProblem) -> String {
    match e {
        FgmError::NotBoxConstraint { row: i, nonzeros } => format!(
            "{} is not a bound on one decision variable (row {i} of G has {nonzeros} \
             non-zero coefficients); {OTHER_SOLVERS}",
            row(problem, *i)
        ),
        FgmError::UnboundedBox { variable, side } => format!(
            "{} has no {side} bound; the fast gradient method needs every input bounded \
             on both sides (finite input bounds), or use the explicit or the reference solver",
            variable_label(problem, *variable)
        ),
        FgmError::CrossingBounds {
            variable,
            side,
            rows: [a, b],
        } => format!(
            "the {} and the {} both bound {} from {} and neither is the tighter for every \
             parameter, so the feasible set is not a box moving affinely with theta; \
             {OTHER_SOLVERS}",
            row(problem, *a),
            row(problem, *b),
            variable_label(problem, *variable),
            if *side == "lower" { "below" } else { "above" }
        ),
        FgmError::EmptyBox { variable, width } => format!(
            "the bounds on {} leave no value for some parameter in the parameter box \
             (width down to {width})",
            variable_label(problem, *variable)
        ),
        FgmError::Problem(_)
        | FgmError::NotConvex { .. }
        | FgmError::InvalidEps(_)
        | FgmError::NoIterationBound { .. }
        | FgmError::InvalidSetting(_)
        | FgmError::Dimension { .. }
        | FgmError::NonFinite(_)
        | FgmError::Solver(_)
        | FgmError::Range(_)
        | FgmError::Runtime(_) => e.to_string(),
    }
}
