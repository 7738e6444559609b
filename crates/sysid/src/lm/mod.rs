//! Levenberg-Marquardt search for nonlinear least squares on an exact
//! Jacobian: the one loop behind [`pem`](crate::pem()) and
//! kestrel-tricopter's grey-box identification.
//!
//! A problem ([`LeastSquares`]) gives the Gauss-Newton normal equations
//! `J'J`, `J'r` and the cost at the current point, and the cost of a trial
//! point; [`levenberg_marquardt`] solves `(J'J + mu D) d = -J'r` with
//! Marquardt's diagonal scaling `D = diag(J'J)` (floored at `1e-12` of
//! its largest entry), accepts a trial step that lowers the cost
//! (dividing the damping `mu` by 5), and otherwise raises the damping
//! (by 5 after a rejected trial, by 10 when the damped matrix is not
//! positive definite) until it reaches [`LmSettings::max_damping`].
//!
//! What the users of the loop differ in is a setting or a trait method:
//!
//! - [`LmSettings::bounds`]: a box on the leading parameters (trial
//!   points are clamped into it, and a parameter on a bound whose descent
//!   direction points outward is held: projected Levenberg-Marquardt);
//! - [`LeastSquares::admissible`]: a validity predicate of trial points
//!   (for example the stability of a model), an inadmissible trial is
//!   rejected like one that raises the cost;
//! - [`LeastSquares::basis`]: a basis of the search directions at the
//!   current point (for example the local coordinates that remove a
//!   similarity freedom);
//! - [`LmSettings::max_damping`], [`LmSettings::gradient_divisor`] and
//!   the stop tolerances.
//!
//! ```
//! use kestrel_sysid::lm::{LeastSquares, LmSettings, NormalEquations, levenberg_marquardt};
//! use nalgebra::{DMatrix, DVector};
//! use std::convert::Infallible;
//!
//! /// Fits y = a exp(b t) to five points.
//! struct Exp { t: Vec<f64>, y: Vec<f64> }
//! impl Exp {
//!     fn residuals(&self, p: &DVector<f64>) -> DVector<f64> {
//!         DVector::from_iterator(5, self.t.iter().zip(&self.y).map(|(t, y)| p[0] * (p[1] * t).exp() - y))
//!     }
//! }
//! impl LeastSquares for Exp {
//!     type Error = Infallible;
//!     type Trial = ();
//!     fn linearise(&mut self, p: &DVector<f64>) -> Result<NormalEquations, Infallible> {
//!         let r = self.residuals(p);
//!         let j = DMatrix::from_fn(5, 2, |i, k| {
//!             let e = (p[1] * self.t[i]).exp();
//!             if k == 0 { e } else { p[0] * self.t[i] * e }
//!         });
//!         Ok(NormalEquations { cost: r.norm_squared(), hessian: j.transpose() * &j, gradient: j.transpose() * r })
//!     }
//!     fn trial(&mut self, p: &DVector<f64>) -> Option<(f64, ())> {
//!         Some((self.residuals(p).norm_squared(), ()))
//!     }
//! }
//!
//! let t: Vec<f64> = (0..5).map(|k| k as f64 * 0.5).collect();
//! let y = t.iter().map(|t| 2.0 * (-0.7 * t).exp()).collect();
//! let mut problem = Exp { t, y };
//! let settings = LmSettings { cost_tolerance: 0.0, ..LmSettings::default() };
//! let Ok(r) = levenberg_marquardt(&mut problem, DVector::from_vec(vec![1.0, 0.0]), &settings);
//! assert!((r.theta[0] - 2.0).abs() < 1e-6 && (r.theta[1] + 0.7).abs() < 1e-6);
//! assert!(r.cost < 1e-12 * r.initial_cost);
//! ```

mod problem;
mod search;
mod settings;

pub use problem::{LeastSquares, NormalEquations};
pub use search::{LmResult, StopReason, levenberg_marquardt};
pub use settings::{Bounds, LmSettings};
