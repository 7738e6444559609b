//! Settings of [`levenberg_marquardt`](super::levenberg_marquardt).

/// A box on the leading parameters: `lower[k] <= theta[k] <= upper[k]`
/// for `k < lower.len()` (infinite bounds allowed).
#[derive(Clone, Debug, PartialEq)]
pub struct Bounds {
    /// Lower bounds of the leading parameters.
    pub lower: Vec<f64>,
    /// Upper bounds, as many as `lower`, each at least its lower bound.
    pub upper: Vec<f64>,
}

/// Settings of [`levenberg_marquardt`](super::levenberg_marquardt).
#[derive(Clone, Debug, PartialEq)]
pub struct LmSettings {
    /// Largest number of iterations (linearisations).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub cost_tolerance: f64,
    /// Stop when `max |J'r| / gradient_divisor` is at most this times the cost.
    pub gradient_tolerance: f64,
    /// Stop when the step taken is shorter than this times `1 + |theta|`
    /// (with [`LmSettings::bounds`]: the clamped displacement, otherwise
    /// the solved step).
    pub step_tolerance: f64,
    /// Divides `J'r` in the gradient test: the cost is
    /// `|r|^2 / gradient_divisor` (for example a mean square over `M`
    /// residuals: `M`), so that the test is relative to the cost.
    pub gradient_divisor: f64,
    /// The damping `mu` at the start.
    pub initial_damping: f64,
    /// The search stops ([`StopReason::NoProgress`](super::StopReason::NoProgress)) when no trial
    /// step is accepted before the damping reaches this.
    pub max_damping: f64,
    /// A box on the leading parameters (see [`Bounds`]): trial points are
    /// clamped into it and a parameter on a bound whose descent direction
    /// points outward is held (its gradient entry zero, its Hessian row
    /// and column those of the identity, in the coordinates before any
    /// [`basis`](super::LeastSquares::basis)).
    pub bounds: Option<Bounds>,
}

impl Default for LmSettings {
    fn default() -> Self {
        LmSettings {
            max_iterations: 30,
            cost_tolerance: 1e-5,
            gradient_tolerance: 1e-7,
            step_tolerance: 1e-8,
            gradient_divisor: 1.0,
            initial_damping: 1e-3,
            max_damping: 1e12,
            bounds: None,
        }
    }
}
