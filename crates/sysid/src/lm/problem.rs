//! What a problem gives the search.

use nalgebra::{DMatrix, DVector};

/// The Gauss-Newton normal equations at one point.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalEquations {
    /// The cost at the point (the search compares it with trial costs).
    pub cost: f64,
    /// The Gauss-Newton Hessian `J'J` (of the residuals whose sum of
    /// squares is the cost, up to [`LmSettings::gradient_divisor`](super::LmSettings::gradient_divisor)).
    pub hessian: DMatrix<f64>,
    /// The gradient `J'r`.
    pub gradient: DVector<f64>,
}

/// A nonlinear least-squares problem for [`levenberg_marquardt`](super::levenberg_marquardt).
pub trait LeastSquares {
    /// Error of [`LeastSquares::linearise`] (ends the search).
    type Error;
    /// What a trial evaluation gives besides its cost; the search returns
    /// that of the last accepted trial ([`LmResult::accepted`](super::LmResult::accepted)).
    type Trial;

    /// The normal equations at `theta`: at the start and at every
    /// accepted point where the search goes on.
    fn linearise(&mut self, theta: &DVector<f64>) -> Result<NormalEquations, Self::Error>;

    /// The cost at a trial point (and its by-product), `None` when it
    /// cannot be evaluated (no model, diverging residuals): the trial is
    /// rejected.
    fn trial(&mut self, theta: &DVector<f64>) -> Option<(f64, Self::Trial)>;

    /// Whether a trial point is admissible (for example: the model is
    /// stable). An inadmissible trial is rejected like one that raises
    /// the cost, without calling [`LeastSquares::trial`]. Every point is
    /// admissible unless overridden.
    fn admissible(&mut self, _theta: &DVector<f64>) -> bool {
        true
    }

    /// A basis `Q` (columns) of the search directions at `theta`: the
    /// step is `Q d` with `d` from the reduced normal equations
    /// `Q'J'JQ`, `Q'J'r`. `None` (unless overridden): every coordinate.
    fn basis(&mut self, _theta: &DVector<f64>) -> Option<DMatrix<f64>> {
        None
    }
}
