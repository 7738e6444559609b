//! The constraint rows of the condensed problem and their names.

use nalgebra::{DMatrix, DVector};

/// Which constraint a row of `G` belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConstraintKind {
    /// A bound on an input `u_j`.
    Input,
    /// A bound on an input move `du_j = u_j - u_{j-1}`.
    InputMove,
    /// A bound on a predicted output `y_j`.
    Output,
    /// A bound on a predicted state `x_j`.
    State,
    /// A row of the terminal set `A x_N <= b`.
    TerminalSet,
    /// A slack variable's sign `s >= 0`.
    Slack,
}

/// Which side of a bound a row is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// `v <= upper`.
    Upper,
    /// `v >= lower`.
    Lower,
}

/// What one row of `G z <= W + E theta` states.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RowLabel {
    /// The constraint.
    pub kind: ConstraintKind,
    /// Upper or lower side (terminal-set rows are `Upper`, slack signs `Lower`).
    pub side: Side,
    /// The entry (input, output, state, terminal-set row or slack number).
    pub index: usize,
    /// The step of the horizon (the first step of the block for inputs
    /// and input moves; 0 for slack signs).
    pub step: usize,
    /// Whether the row is softened by a slack variable.
    pub soft: bool,
}

impl core::fmt::Display for RowLabel {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let side = match self.side {
            Side::Upper => "upper",
            Side::Lower => "lower",
        };
        let soft = if self.soft { " (soft)" } else { "" };
        match self.kind {
            ConstraintKind::Input => write!(
                f,
                "input {} {side} bound at step {}{soft}",
                self.index, self.step
            ),
            ConstraintKind::InputMove => write!(
                f,
                "input move du {} {side} bound at step {}{soft}",
                self.index, self.step
            ),
            ConstraintKind::Output => write!(
                f,
                "output {} {side} bound at step {}{soft}",
                self.index, self.step
            ),
            ConstraintKind::State => write!(
                f,
                "state {} {side} bound at step {}{soft}",
                self.index, self.step
            ),
            ConstraintKind::TerminalSet => {
                write!(f, "terminal set row {} at step {}", self.index, self.step)
            }
            ConstraintKind::Slack => write!(f, "slack variable {} >= 0", self.index),
        }
    }
}

/// Rows collected one by one: `g z <= w + e theta`.
pub(crate) struct RowSet {
    pub g: Vec<DVector<f64>>,
    pub w: Vec<f64>,
    pub e: Vec<DVector<f64>>,
    pub labels: Vec<RowLabel>,
}

impl RowSet {
    pub fn new() -> Self {
        RowSet {
            g: Vec::new(),
            w: Vec::new(),
            e: Vec::new(),
            labels: Vec::new(),
        }
    }

    /// Adds a row unless it does not involve `z` at all (a bound at a step
    /// no input reaches constrains the parameter, not the decision; such
    /// rows are left out).
    pub fn push(&mut self, g: DVector<f64>, w: f64, e: DVector<f64>, label: RowLabel) {
        if g.iter().all(|v| *v == 0.0) {
            return;
        }
        self.g.push(g);
        self.w.push(w);
        self.e.push(e);
        self.labels.push(label);
    }

    /// `(G, W, E)` as matrices for `n` variables and `p` parameters.
    pub fn matrices(&self, n: usize, p: usize) -> (DMatrix<f64>, DVector<f64>, DMatrix<f64>) {
        let m = self.g.len();
        let g = DMatrix::from_fn(m, n, |i, j| self.g[i][j]);
        let e = DMatrix::from_fn(m, p, |i, j| self.e[i][j]);
        (g, DVector::from_column_slice(&self.w), e)
    }
}
