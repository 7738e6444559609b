//! Box-constrained parametric QPs and their conversion from `kestrel.mpqp.v1`.

use crate::FgmError;
use kestrel_core::formats::MpqpProblem;
use nalgebra::{DMatrix, DVector};

/// The message for a problem without decision variables.
pub(crate) const NO_VARIABLES: &str =
    "the problem has no decision variables (H is empty): there is nothing to solve";

/// Relative size below which a constraint coefficient counts as zero.
const ZERO_TOL: f64 = 1e-12;

/// A parametric QP with a box that moves affinely with the parameter:
///
/// minimise over `z`: `1/2 z'Hz + (F'theta + f)'z`
/// subject to `lo(theta) <= z <= hi(theta)`,
/// `lo(theta) = lo0 + Lo theta`, `hi(theta) = hi0 + Hi theta`,
/// for `theta_lb <= theta <= theta_ub`.
///
/// The fast gradient method needs exactly this: its projection is a clamp.
#[derive(Clone, Debug, PartialEq)]
pub struct BoxQp {
    /// Hessian, `n x n`, symmetric positive (semi)definite.
    pub h: DMatrix<f64>,
    /// Parameter-to-linear-term map, `p x n` (as in `kestrel.mpqp.v1`).
    pub f_theta: DMatrix<f64>,
    /// Constant linear term, `n`.
    pub f: DVector<f64>,
    /// Lower bound offset, `n`.
    pub lo0: DVector<f64>,
    /// Lower bound parameter map, `n x p`.
    pub lo_theta: DMatrix<f64>,
    /// Upper bound offset, `n`.
    pub hi0: DVector<f64>,
    /// Upper bound parameter map, `n x p`.
    pub hi_theta: DMatrix<f64>,
    /// Parameter box, lower end, `p`.
    pub theta_lb: DVector<f64>,
    /// Parameter box, upper end, `p`.
    pub theta_ub: DVector<f64>,
}

/// The box at one parameter value.
#[derive(Clone, Debug, PartialEq)]
pub struct Bounds {
    /// Lower bounds.
    pub lo: DVector<f64>,
    /// Upper bounds.
    pub hi: DVector<f64>,
}

/// One affine bound `a0 + a theta` found in a constraint row.
#[derive(Clone, Debug)]
struct AffineBound {
    row: usize,
    a0: f64,
    a: DVector<f64>,
}

impl BoxQp {
    /// Number of decision variables.
    pub fn n(&self) -> usize {
        self.h.nrows()
    }
    /// Number of parameters.
    pub fn p(&self) -> usize {
        self.f_theta.nrows()
    }

    /// Converts an mp-QP whose constraint rows each bound a single
    /// variable (any order, any positive or negative scaling, right-hand
    /// side affine in `theta`) into a box `lo(theta) <= z <= hi(theta)`.
    ///
    /// Several bounds on the same side of a variable are accepted when one
    /// of them is the tighter for every `theta` in the parameter box (the
    /// looser is dropped); rows that are exact duplicates up to scaling
    /// therefore pass. The optional parameter polytope `theta_A theta <=
    /// theta_b` is ignored: the certificate then covers the whole box,
    /// which is conservative.
    ///
    /// # Errors
    /// [`FgmError::NotBoxConstraint`] for a row with zero or several
    /// non-zero coefficients, [`FgmError::UnboundedBox`] for a variable
    /// without a lower or an upper bound, [`FgmError::CrossingBounds`] for
    /// two bounds neither of which dominates, [`FgmError::EmptyBox`] if
    /// `lo(theta) > hi(theta)` somewhere in the parameter box, and
    /// [`FgmError::Problem`] for a problem that fails its own validation
    /// or has no decision variables.
    pub fn from_mpqp(prob: &MpqpProblem) -> Result<Self, FgmError> {
        prob.validate()
            .map_err(|e| FgmError::Problem(e.to_string()))?;
        let (n, p, m) = (prob.n(), prob.p(), prob.m());
        if n == 0 {
            return Err(FgmError::Problem(NO_VARIABLES.into()));
        }
        let mut lower: Vec<Vec<AffineBound>> = vec![Vec::new(); n];
        let mut upper: Vec<Vec<AffineBound>> = vec![Vec::new(); n];
        for i in 0..m {
            let row = prob.g.row(i);
            let scale = row.amax();
            let nz: Vec<usize> = (0..n)
                .filter(|&j| row[j].abs() > ZERO_TOL * scale && row[j] != 0.0)
                .collect();
            if nz.len() != 1 {
                return Err(FgmError::NotBoxConstraint {
                    row: i,
                    nonzeros: nz.len(),
                });
            }
            let j = nz[0];
            let g = row[j];
            // g z_j <= W_i + E_i theta  =>  z_j <= or >= (W_i + E_i theta) / g.
            let bound = AffineBound {
                row: i,
                a0: prob.w[i] / g,
                a: prob.e.row(i).transpose() / g,
            };
            if g > 0.0 {
                upper[j].push(bound);
            } else {
                lower[j].push(bound);
            }
        }
        let mut lo0 = DVector::zeros(n);
        let mut hi0 = DVector::zeros(n);
        let mut lo_theta = DMatrix::zeros(n, p);
        let mut hi_theta = DMatrix::zeros(n, p);
        for j in 0..n {
            let lo = pick(&lower[j], j, "lower", true, &prob.theta_lb, &prob.theta_ub)?;
            let hi = pick(&upper[j], j, "upper", false, &prob.theta_lb, &prob.theta_ub)?;
            lo0[j] = lo.a0;
            hi0[j] = hi.a0;
            lo_theta.row_mut(j).copy_from(&lo.a.transpose());
            hi_theta.row_mut(j).copy_from(&hi.a.transpose());
        }
        let qp = BoxQp {
            h: prob.h.clone(),
            f_theta: prob.f_theta.clone(),
            f: prob.f.clone(),
            lo0,
            lo_theta,
            hi0,
            hi_theta,
            theta_lb: prob.theta_lb.clone(),
            theta_ub: prob.theta_ub.clone(),
        };
        // Non-empty for every theta: min over the box of hi - lo >= 0.
        for j in 0..n {
            let w0 = qp.hi0[j] - qp.lo0[j];
            let w = (qp.hi_theta.row(j) - qp.lo_theta.row(j)).transpose();
            let min = affine_min(w0, &w, &qp.theta_lb, &qp.theta_ub);
            if min < -1e-9 * (1.0 + w0.abs()) {
                return Err(FgmError::EmptyBox {
                    variable: j,
                    width: min,
                });
            }
        }
        Ok(qp)
    }

    /// The box at `theta`.
    pub fn bounds(&self, theta: &DVector<f64>) -> Bounds {
        Bounds {
            lo: &self.lo0 + &self.lo_theta * theta,
            hi: &self.hi0 + &self.hi_theta * theta,
        }
    }

    /// The linear term `F'theta + f`.
    pub fn linear_term(&self, theta: &DVector<f64>) -> DVector<f64> {
        self.f_theta.tr_mul(theta) + &self.f
    }

    /// The cost `1/2 z'Hz + (F'theta + f)'z`.
    pub fn cost(&self, z: &DVector<f64>, theta: &DVector<f64>) -> f64 {
        0.5 * z.dot(&(&self.h * z)) + self.linear_term(theta).dot(z)
    }

    /// The largest width `hi_j(theta) - lo_j(theta)` of each variable over
    /// the parameter box (exact: a maximum of an affine function over a box).
    pub fn max_widths(&self) -> DVector<f64> {
        DVector::from_fn(self.n(), |j, _| {
            let w0 = self.hi0[j] - self.lo0[j];
            let w = (self.hi_theta.row(j) - self.lo_theta.row(j)).transpose();
            -affine_min(-w0, &(-w), &self.theta_lb, &self.theta_ub)
        })
    }

    /// The largest magnitude `max(|lo_j|, |hi_j|)` of each bound over the
    /// parameter box.
    pub fn max_bound_magnitudes(&self) -> DVector<f64> {
        DVector::from_fn(self.n(), |j, _| {
            let mut best: f64 = 0.0;
            for (a0, a) in [
                (self.lo0[j], self.lo_theta.row(j).transpose()),
                (self.hi0[j], self.hi_theta.row(j).transpose()),
            ] {
                best = best
                    .max(-affine_min(-a0, &(-&a), &self.theta_lb, &self.theta_ub))
                    .max(-affine_min(a0, &a, &self.theta_lb, &self.theta_ub));
            }
            best
        })
    }

    /// Checks that `theta` has `p` finite entries.
    pub fn check_theta(&self, theta: &[f64]) -> Result<(), FgmError> {
        if theta.len() != self.p() {
            return Err(FgmError::Dimension {
                what: "theta",
                expected: self.p(),
                found: theta.len(),
            });
        }
        if theta.iter().any(|v| !v.is_finite()) {
            return Err(FgmError::NonFinite("theta"));
        }
        Ok(())
    }

    /// The first entry of `theta` outside the parameter box
    /// `[theta_lb, theta_ub]` (`None` if inside, boundary included):
    /// certificates cover the box only, so callers warn about the others.
    pub fn outside_parameter_box(&self, theta: &[f64]) -> Option<usize> {
        (0..self.p().min(theta.len()))
            .find(|&j| !(self.theta_lb[j] <= theta[j] && theta[j] <= self.theta_ub[j]))
    }

    /// Writes the problem back as `kestrel.mpqp.v1` with `G = [I; -I]`.
    pub fn to_mpqp(&self) -> MpqpProblem {
        let (n, p) = (self.n(), self.p());
        let mut g = DMatrix::zeros(2 * n, n);
        let mut w = DVector::zeros(2 * n);
        let mut e = DMatrix::zeros(2 * n, p);
        for j in 0..n {
            g[(j, j)] = 1.0;
            w[j] = self.hi0[j];
            e.row_mut(j).copy_from(&self.hi_theta.row(j));
            g[(n + j, j)] = -1.0;
            w[n + j] = -self.lo0[j];
            e.row_mut(n + j).copy_from(&(-self.lo_theta.row(j)));
        }
        MpqpProblem {
            h: self.h.clone(),
            f_theta: self.f_theta.clone(),
            f: self.f.clone(),
            g,
            w,
            e,
            theta_lb: self.theta_lb.clone(),
            theta_ub: self.theta_ub.clone(),
            theta_poly: None,
        }
    }
}

/// The minimum of `a0 + a' theta` over the box `[lb, ub]`.
pub(crate) fn affine_min(a0: f64, a: &DVector<f64>, lb: &DVector<f64>, ub: &DVector<f64>) -> f64 {
    a0 + a
        .iter()
        .zip(lb.iter().zip(ub.iter()))
        .map(|(ai, (l, u))| if *ai >= 0.0 { ai * l } else { ai * u })
        .sum::<f64>()
}

/// Chooses the binding bound among several on one side of a variable.
fn pick(
    cands: &[AffineBound],
    var: usize,
    side: &'static str,
    lower: bool,
    lb: &DVector<f64>,
    ub: &DVector<f64>,
) -> Result<AffineBound, FgmError> {
    let first = cands.first().ok_or(FgmError::UnboundedBox {
        variable: var,
        side,
    })?;
    let mut best = first.clone();
    for c in &cands[1..] {
        // For a lower bound the tighter one is the larger everywhere.
        let (d0, d) = (c.a0 - best.a0, &c.a - &best.a);
        let (d0, d) = if lower { (d0, d) } else { (-d0, -d) };
        let tol = 1e-9 * (1.0 + best.a0.abs() + c.a0.abs());
        let min = affine_min(d0, &d, lb, ub);
        let max = -affine_min(-d0, &(-&d), lb, ub);
        if min >= -tol {
            best = c.clone(); // c is at least as tight everywhere
        } else if max <= tol {
            // best stays tighter everywhere
        } else {
            return Err(FgmError::CrossingBounds {
                variable: var,
                side,
                rows: [best.row, c.row],
            });
        }
    }
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mpqp(g: Vec<f64>, w: Vec<f64>, e: Vec<f64>, m: usize) -> MpqpProblem {
        MpqpProblem {
            h: DMatrix::from_row_slice(2, 2, &[2.0, 0.5, 0.5, 1.0]),
            f_theta: DMatrix::from_row_slice(1, 2, &[1.0, -1.0]),
            f: DVector::zeros(2),
            g: DMatrix::from_row_slice(m, 2, &g),
            w: DVector::from_vec(w),
            e: DMatrix::from_row_slice(m, 1, &e),
            theta_lb: DVector::from_vec(vec![0.0]),
            theta_ub: DVector::from_vec(vec![1.0]),
            theta_poly: None,
        }
    }

    #[test]
    fn converts_scaled_shuffled_rows() {
        // -2 z1 <= 2 - 2 theta  (z1 >= -1 + theta), 3 z0 <= 3, z1 <= 4 + theta, -z0 <= 1,
        // and a looser duplicate 0.5 z0 <= 5.
        let p = mpqp(
            vec![0.0, -2.0, 3.0, 0.0, 0.0, 1.0, -1.0, 0.0, 0.5, 0.0],
            vec![2.0, 3.0, 4.0, 1.0, 5.0],
            vec![-2.0, 0.0, 1.0, 0.0, 0.0],
            5,
        );
        let b = BoxQp::from_mpqp(&p).unwrap();
        let th = DVector::from_vec(vec![0.5]);
        let bounds = b.bounds(&th);
        assert_eq!(bounds.lo.as_slice(), &[-1.0, -0.5]);
        assert_eq!(bounds.hi.as_slice(), &[1.0, 4.5]);
        assert_eq!(b.max_widths().as_slice(), &[2.0, 5.0]);
        // Round trip through the [I; -I] form.
        assert_eq!(BoxQp::from_mpqp(&b.to_mpqp()).unwrap(), b);
    }

    #[test]
    fn refuses_non_box_rows_and_missing_bounds() {
        let coupled = mpqp(vec![1.0, 1.0, -1.0, 0.0], vec![1.0, 1.0], vec![0.0, 0.0], 2);
        assert!(matches!(
            BoxQp::from_mpqp(&coupled),
            Err(FgmError::NotBoxConstraint {
                row: 0,
                nonzeros: 2
            })
        ));
        let zero = mpqp(vec![0.0, 0.0], vec![1.0], vec![0.0], 1);
        assert!(matches!(
            BoxQp::from_mpqp(&zero),
            Err(FgmError::NotBoxConstraint {
                row: 0,
                nonzeros: 0
            })
        ));
        let open = mpqp(
            vec![1.0, 0.0, -1.0, 0.0, 0.0, 1.0],
            vec![1.0, 1.0, 1.0],
            vec![0.0; 3],
            3,
        );
        let e = BoxQp::from_mpqp(&open).unwrap_err();
        assert!(matches!(
            e,
            FgmError::UnboundedBox {
                variable: 1,
                side: "lower"
            }
        ));
        assert!(e.to_string().contains("unbounded"), "{e}");
    }

    #[test]
    fn takes_a_constant_linear_term_and_sign_rows() {
        // Three variables, rows in any order and scaling, as kestrel-mpc
        // writes them: z0 in [-1, 0.5 + 0.5 theta] (a bound moving with the
        // parameter), z1 in [theta - 1, theta + 1] (an input move around a
        // previous input), z2 >= 0 (a sign row, as a slack's) with z2 <= 2;
        // a constant linear term f, as a linear penalty or an input target
        // make.
        let p = MpqpProblem {
            h: DMatrix::from_row_slice(3, 3, &[2.0, 0.5, 0.0, 0.5, 1.0, 0.2, 0.0, 0.2, 1.5]),
            f_theta: DMatrix::from_row_slice(1, 3, &[1.0, -1.0, 0.5]),
            f: DVector::from_vec(vec![0.3, -0.2, -1.0]),
            g: DMatrix::from_row_slice(
                6,
                3,
                &[
                    0.0, 0.0, -1.0, // -z2 <= 0
                    2.0, 0.0, 0.0, // 2 z0 <= 1 + theta
                    0.0, -3.0, 0.0, // -3 z1 <= 3 - 3 theta
                    0.0, 0.0, 4.0, // 4 z2 <= 8
                    -0.5, 0.0, 0.0, // -0.5 z0 <= 0.5
                    0.0, 1.0, 0.0, // z1 <= 1 + theta
                ],
            ),
            w: DVector::from_vec(vec![0.0, 1.0, 3.0, 8.0, 0.5, 1.0]),
            e: DMatrix::from_row_slice(6, 1, &[0.0, 1.0, -3.0, 0.0, 0.0, 1.0]),
            theta_lb: DVector::from_vec(vec![-1.0]),
            theta_ub: DVector::from_vec(vec![1.0]),
            theta_poly: None,
        };
        let b = BoxQp::from_mpqp(&p).unwrap();
        assert_eq!(b.f, p.f);
        let at = b.bounds(&DVector::from_vec(vec![0.5]));
        assert_eq!(at.lo.as_slice(), &[-1.0, -0.5, 0.0]);
        assert_eq!(at.hi.as_slice(), &[0.75, 1.5, 2.0]);
        // The fast gradient method converges to the optimum of the original
        // problem, constant term included.
        let design = crate::FgmDesign::new(b.clone(), crate::FgmSettings::default()).unwrap();
        let cert = design.certify(1e-12).unwrap();
        let mut reference = crate::reference::ReferenceSolver::new(&b).unwrap();
        for th in [-1.0, -0.3, 0.4, 1.0] {
            let z = design.solve(&cert, &[th], None, cert.iterations).unwrap();
            let best = reference.solve(&DVector::from_vec(vec![th])).unwrap();
            let z = DVector::from_vec(z);
            let theta = DVector::from_vec(vec![th]);
            assert!(
                b.cost(&z, &theta) - best.cost <= 1e-10,
                "{th}: {z} vs {}",
                best.z
            );
            assert!((&z - &best.z).amax() < 1e-5, "{th}: {z} vs {}", best.z);
        }
    }

    #[test]
    fn refuses_crossing_and_empty_boxes() {
        // Two upper bounds on z0: 1 and 0.5 + theta cross at theta = 0.5.
        let crossing = mpqp(
            vec![1.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, -1.0],
            vec![1.0, 0.5, 1.0, 1.0, 1.0],
            vec![0.0, 1.0, 0.0, 0.0, 0.0],
            5,
        );
        assert!(matches!(
            BoxQp::from_mpqp(&crossing),
            Err(FgmError::CrossingBounds { variable: 0, .. })
        ));
        // z0 <= -1 + theta and z0 >= 0: empty for theta < 1.
        let empty = mpqp(
            vec![1.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, -1.0],
            vec![-1.0, 0.0, 1.0, 1.0],
            vec![1.0, 0.0, 0.0, 0.0],
            4,
        );
        assert!(matches!(
            BoxQp::from_mpqp(&empty),
            Err(FgmError::EmptyBox { variable: 0, .. })
        ));
    }
}
