//! The multi-parametric QP solver: critical regions by facet-to-facet exploration.
//!
//! For an active set `A` whose rows `G_A` are linearly independent (LICQ),
//! the KKT conditions give the affine laws (ERRATA's corrected (6.27c)/(6.28),
//! with the constant linear term `f`):
//!
//! ```text
//! lambda_A(theta) = -(G_A H^-1 G_A')^-1 (W_A + E_A theta + G_A H^-1 (F'theta + f))
//! z(theta)        = -H^-1 (F'theta + f + G_A' lambda_A(theta))
//! ```
//!
//! and the critical region `{theta in Theta : lambda_A >= 0, G_i z <= W_i + E_i theta (i not in A)}`.
//! The exploration starts from the optimal active set at an interior
//! feasible parameter and crosses every facet of every region: a facet
//! where constraint `i` becomes active leads to `A + {i}`, a facet where
//! `lambda_j` reaches zero to `A - {j}`. The guess is checked at a point just
//! beyond the facet; when it fails (degeneracy: LICQ violated, weakly active
//! constraints, coincident facets), the QP is solved at that point and every
//! linearly independent subset of its active constraints that represents the
//! optimum is tried. Exact duplicate constraints (move blocking produces
//! them) are removed beforehand; constraints without `z` become parameter
//! constraints. Regions whose inscribed ball is smaller than
//! [`Settings::radius_tol`] are lower-dimensional and discarded.
//!
//! One file per step: `settings`, preprocessing (`prepare`), a
//! region's law and half-spaces (`critical`) and its facets
//! (`facets`), degeneracy (`degenerate`), the exploration
//! (`explore`) and the brute-force reference (`brute_force`).

mod brute_force;
mod critical;
mod degenerate;
mod explore;
mod facets;
mod prepare;
mod region;
mod settings;
mod solution;
#[cfg(test)]
mod tests;
mod wave;

pub use brute_force::brute_force_active_sets;
pub use explore::solve;
pub use settings::Settings;
pub use solution::{CriticalRegion, MpqpSolution, SolveStats};

/// The seeded generator of the probe perturbations (defined in a leaf
/// module; also [`crate::testing::Rng`]).
pub use crate::rng::Rng;
