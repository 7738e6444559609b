//! Solver settings.

use crate::QpError;

/// Tolerances and the iteration cap of [`crate::QpSolver`].
///
/// The defaults suit `f64`; for `f32` use [`QpSettings::for_f32`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QpSettings {
    /// A constraint counts as violated when it exceeds its bound by more
    /// than this (absolute, in the units of `G z`). Default `1e-10`.
    pub primal_tol: f64,
    /// A multiplier counts as having the wrong sign when it is beyond zero
    /// by more than this. Default `1e-12`.
    pub dual_tol: f64,
    /// A constraint entering the active set is linearly dependent on the
    /// active ones when its new LDL' pivot is below this fraction of its
    /// squared (H^-1-weighted) norm. Default `1e-11`.
    pub pivot_tol: f64,
    /// The most active-set changes (a constraint added or removed) per
    /// solve before [`QpError::IterationLimit`]. Default 1000.
    pub max_iterations: usize,
}

impl Default for QpSettings {
    fn default() -> Self {
        QpSettings {
            primal_tol: 1e-10,
            dual_tol: 1e-12,
            pivot_tol: 1e-11,
            max_iterations: 1000,
        }
    }
}

impl QpSettings {
    /// Tolerances for `f32` arithmetic (`primal_tol = 1e-5`,
    /// `dual_tol = 1e-6`, `pivot_tol = 1e-5`).
    pub fn for_f32() -> Self {
        QpSettings {
            primal_tol: 1e-5,
            dual_tol: 1e-6,
            pivot_tol: 1e-5,
            ..QpSettings::default()
        }
    }

    /// Checks that the tolerances are finite and non-negative, the pivot
    /// tolerance below one, and the iteration cap at least one.
    pub fn validate(&self) -> Result<(), QpError> {
        let tol_ok = |t: f64| t.is_finite() && t >= 0.0;
        if tol_ok(self.primal_tol)
            && tol_ok(self.dual_tol)
            && tol_ok(self.pivot_tol)
            && self.pivot_tol < 1.0
            && self.max_iterations >= 1
        {
            Ok(())
        } else {
            Err(QpError::InvalidSettings)
        }
    }
}
