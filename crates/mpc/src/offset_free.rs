//! Offset-free tracking with a disturbance model (Pannocchia and Rawlings
//! 2003; Maeder, Borrelli and Morari 2009).
//!
//! The model is augmented with a constant disturbance `d` (`nd` states):
//! `x+ = A x + B u + Bd d`, `d+ = d`, `y = C x + Cd d`. The estimator runs
//! on the augmented model, and the MPC steers to the steady-state target
//! `(x_s, u_s)` of the estimated disturbance:
//! `[A - I, B; C, 0] [x_s; u_s] = [-Bd d; r - Cd d]` (least-norm solution),
//! with the input cost on `u - u_s` and the terminal cost on `x_N - x_s`.
//! Both targets are linear in `theta = [x; d; ...; r; ...]`, so the
//! problem stays a parametric QP of the same form and the same solvers
//! apply. When the disturbance estimate has converged and the target is
//! feasible, the outputs reach the reference without offset.

use crate::condense::{ModelMatrices, MpcProblem, Prediction};
use crate::constraints::InputTarget;
use crate::design::MpcSettings;
use crate::error::MpcError;
use crate::layout::ThetaLayout;
use kestrel_core::formats::SsModel;
use kestrel_kalman::{AugmentedModel, Disturbance, KalmanError};
use nalgebra::DMatrix;

/// How the constant disturbance enters the model.
#[derive(Clone, Debug, PartialEq)]
pub enum DisturbanceModel {
    /// `nd = ny` disturbances on the states the outputs measure: `Bd = C'`,
    /// `Cd = 0` (for the tricopter: constant torques on the rates).
    OutputStates,
    /// `nd = ny` disturbances added to the outputs: `Bd = 0`, `Cd = I`
    /// (not detectable when `A` has an integrator).
    Output,
    /// Any `Bd` (`nx x nd`) and `Cd` (`ny x nd`).
    Custom {
        /// State disturbance map.
        bd: DMatrix<f64>,
        /// Output disturbance map.
        cd: DMatrix<f64>,
    },
}

/// An offset-free design: the augmented model (for the estimator and the
/// simulator) and the condensed problem on it.
#[derive(Clone, Debug, PartialEq)]
pub struct OffsetFreeDesign {
    /// `[x; d]` model (kestrel-kalman's [`AugmentedModel`] with `D = 0`)
    /// with the same inputs, outputs, `u0` and `y0` (`x0`, if any,
    /// extended by a zero disturbance).
    pub augmented: SsModel,
    /// The condensed problem, `theta = [x; d; u_prev; r; u_target; p]`
    /// ([`ThetaLayout`] with the disturbances counted as states).
    pub problem: MpcProblem,
    /// Number of disturbance states.
    pub nd: usize,
}

impl MpcProblem {
    /// Builds the offset-free problem of `model` with the given disturbance
    /// model. Errors when `(A, B, C)` with the disturbance is not
    /// detectable, i.e. `rank [A - I, Bd; C, Cd] < nx + nd`.
    ///
    /// ```
    /// use kestrel_mpc::{Bounds, DisturbanceModel, MpcProblem, MpcSettings};
    /// use kestrel_core::formats::SsModel;
    /// use nalgebra::{dmatrix, dvector};
    /// let m = SsModel::new(0.1, dmatrix![0.9], dmatrix![0.1], dmatrix![1.0], dmatrix![0.0]).unwrap();
    /// let settings = MpcSettings { horizon: 3,
    ///     input_bounds: Some(Bounds::new(dvector![-5.0], dvector![5.0])), ..MpcSettings::default() };
    /// let d = MpcProblem::build_offset_free(&m, &settings, &DisturbanceModel::Output).unwrap();
    /// assert_eq!((d.augmented.nx(), d.problem.p()), (2, 3)); // theta = [x, d, r]
    /// ```
    pub fn build_offset_free(
        model: &SsModel,
        settings: &MpcSettings,
        disturbance: &DisturbanceModel,
    ) -> Result<OffsetFreeDesign, MpcError> {
        let mm = ModelMatrices::from_model(model)?;
        let (nx, nu, ny) = (mm.a.nrows(), mm.b.ncols(), mm.c.nrows());
        // The augmentation and its detectability test (Maeder et al.,
        // Prop. 1) are kestrel-kalman's.
        let disturbance = match disturbance {
            DisturbanceModel::OutputStates => Disturbance::OutputStates,
            DisturbanceModel::Output => Disturbance::Output,
            DisturbanceModel::Custom { bd, cd } => Disturbance::Custom {
                bd: bd.clone(),
                cd: cd.clone(),
            },
        };
        let mut aug = AugmentedModel::new(model, &disturbance).map_err(augmentation_error)?;
        // The MPC's model has y = C x (a feed-through below from_model's
        // threshold is dropped).
        aug.model.d = DMatrix::zeros(ny, nu);
        let AugmentedModel {
            model: augmented,
            nd,
            bd,
            cd,
            ..
        } = aug;
        let na = nx + nd;
        if settings.input_target != InputTarget::Zero {
            return Err(MpcError::setting(
                "input_target",
                "the offset-free design steers the inputs to its own steady-state target; leave the input target at zero",
            ));
        }
        settings.validate(nu, ny, nx)?;
        let layout = ThetaLayout {
            nx: na,
            nu_prev: if settings.uses_previous_input() {
                nu
            } else {
                0
            },
            ny,
            preview: settings.preview,
            nu_target: 0,
            np: settings.parameters.len(),
        };
        let p = layout.len();
        // The steady-state target follows the last reference of the preview.
        let r_last = layout.reference(layout.preview - 1).start;
        // Target map: [x_s; u_s] = M [-Bd d; r - Cd d].
        let mut kkt = DMatrix::zeros(nx + ny, nx + nu);
        kkt.view_mut((0, 0), (nx, nx))
            .copy_from(&(&mm.a - DMatrix::identity(nx, nx)));
        kkt.view_mut((0, nx), (nx, nu)).copy_from(&mm.b);
        kkt.view_mut((nx, 0), (ny, nx)).copy_from(&mm.c);
        let m = kkt
            .pseudo_inverse(1e-10)
            .map_err(|e| MpcError::setting("target map", e.to_string()))?;
        let mut rhs = DMatrix::zeros(nx + ny, p);
        rhs.view_mut((0, nx), (nx, nd)).copy_from(&(-&bd));
        rhs.view_mut((nx, nx), (ny, nd)).copy_from(&(-&cd));
        rhs.view_mut((nx, r_last), (ny, ny))
            .copy_from(&DMatrix::identity(ny, ny));
        let target = m * rhs;
        let mut terminal_sel = DMatrix::zeros(nx, na);
        terminal_sel
            .view_mut((0, 0), (nx, nx))
            .copy_from(&DMatrix::identity(nx, nx));
        let pred = Prediction {
            a: augmented.a.clone(),
            b: augmented.b.clone(),
            c: augmented.c.clone(),
            terminal_sel,
            x_ref: target.rows(0, nx).into_owned(),
            u_ref: target.rows(nx, nu).into_owned(),
            u_ref_const: nalgebra::DVector::zeros(nu),
            lq_model: (mm.a, mm.b, mm.c),
        };
        let problem = MpcProblem::condense(&pred, layout, settings)?;
        Ok(OffsetFreeDesign {
            augmented,
            problem,
            nd,
        })
    }
}

/// kestrel-kalman's refusal of the augmentation as the MPC's error.
///
/// [`AugmentedModel::new`] refuses a non-detectable disturbance, maps
/// that do not fit the model or hold NaN, and a continuous-time model;
/// the model itself has passed `ModelMatrices::from_model` before. The
/// other variants are mapped for completeness, each keeping its message.
fn augmentation_error(e: KalmanError) -> MpcError {
    match e {
        KalmanError::DisturbanceNotDetectable { rank, required } => MpcError::setting(
            "disturbance model",
            format!("not detectable: rank [A - I, Bd; C, Cd] = {rank} < nx + nd = {required}"),
        ),
        KalmanError::DimensionMismatch {
            name,
            expected_rows,
            expected_cols,
            found_rows,
            found_cols,
        } => MpcError::dim(
            format!("disturbance model {name}"),
            format!("{expected_rows} x {expected_cols}"),
            format!("{found_rows} x {found_cols}"),
        ),
        KalmanError::NonFinite { name, .. } => {
            MpcError::NonFinite(format!("disturbance model {name}"))
        }
        KalmanError::InvalidArgument { name, reason } => MpcError::setting(name, reason),
        KalmanError::NotSymmetric { name, asymmetry } => MpcError::NotSymmetric {
            what: name.into(),
            asymmetry,
        },
        KalmanError::Core(e) => MpcError::Core(e),
        e @ (KalmanError::NotPositiveDefinite { .. }
        | KalmanError::NotPositiveSemidefinite { .. }
        | KalmanError::NotStabilizable { .. }
        | KalmanError::NotDetectable { .. }
        | KalmanError::NoStabilizingSolution { .. }
        | KalmanError::NotConverged { .. }) => {
            MpcError::setting("disturbance model", e.to_string())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::condense::tests::{Rng, random_model};
    use crate::constraints::Bounds;
    use crate::design::Terminal;
    use crate::law::MpcLaw;
    use crate::qp::QpSettings;
    use kestrel_core::ControlLaw;
    use nalgebra::DVector;

    #[test]
    fn removes_offset_of_a_constant_input_disturbance() {
        // Plant = model + a constant unknown input bias; the disturbance is
        // known here (perfect estimate) to isolate the target map.
        let mut rng = Rng::new(5);
        let m = random_model(&mut rng, 3, 2, 2);
        let bounds = Bounds::new(
            DVector::from_element(2, -50.0),
            DVector::from_element(2, 50.0),
        );
        let settings = MpcSettings {
            horizon: 5,
            terminal: Terminal::Lq,
            input_bounds: Some(bounds),
            ..MpcSettings::default()
        };
        let design = MpcProblem::build_offset_free(
            &m,
            &settings,
            &DisturbanceModel::Custom {
                bd: m.b.clone(),
                cd: DMatrix::zeros(2, 2),
            },
        )
        .unwrap();
        let plain = MpcProblem::build(&m, &settings).unwrap();
        let mut law = MpcLaw::clarabel(&design.problem, QpSettings::default()).unwrap();
        let mut plain_law = MpcLaw::clarabel(&plain, QpSettings::default()).unwrap();
        let bias = DVector::from_vec(vec![0.3, -0.2]);
        let r = [0.5, -0.4];
        let (mut x, mut xp) = (DVector::zeros(3), DVector::zeros(3));
        let mut u = [0.0; 2];
        for _ in 0..300 {
            let mut th: Vec<f64> = x.iter().copied().collect();
            th.extend(bias.iter());
            law.control(&th, &r, &mut u).unwrap();
            x = &m.a * &x + &m.b * (DVector::from_column_slice(&u) + &bias);
            plain_law.control(xp.as_slice(), &r, &mut u).unwrap();
            xp = &m.a * &xp + &m.b * (DVector::from_column_slice(&u) + &bias);
        }
        let y = &m.c * &x;
        let yp = &m.c * &xp;
        let err = (y - DVector::from_column_slice(&r)).amax();
        let err_plain = (yp - DVector::from_column_slice(&r)).amax();
        assert!(err < 1e-6, "offset-free error {err}");
        assert!(
            err_plain > 1e-3,
            "the plain MPC should show an offset, found {err_plain}"
        );
    }

    #[test]
    fn undetectable_disturbance_is_refused() {
        // An integrator with an output disturbance cannot tell d from x.
        let m = SsModel::new(
            0.1,
            DMatrix::from_element(1, 1, 1.0),
            DMatrix::from_element(1, 1, 0.1),
            DMatrix::from_element(1, 1, 1.0),
            DMatrix::zeros(1, 1),
        )
        .unwrap();
        let bounds = Bounds::new(
            DVector::from_element(1, -1.0),
            DVector::from_element(1, 1.0),
        );
        let e = MpcProblem::build_offset_free(
            &m,
            &MpcSettings {
                input_bounds: Some(bounds.clone()),
                ..MpcSettings::default()
            },
            &DisturbanceModel::Output,
        )
        .unwrap_err();
        assert!(e.to_string().contains("not detectable"), "{e}");
    }

    #[test]
    fn disturbance_maps_that_do_not_fit_are_refused() {
        let m = SsModel::new(
            0.1,
            DMatrix::from_element(1, 1, 0.9),
            DMatrix::from_element(1, 1, 0.1),
            DMatrix::from_element(1, 1, 1.0),
            DMatrix::zeros(1, 1),
        )
        .unwrap();
        let bounds = Bounds::new(
            DVector::from_element(1, -1.0),
            DVector::from_element(1, 1.0),
        );
        let custom = |bd, cd| DisturbanceModel::Custom { bd, cd };
        let e = MpcProblem::build_offset_free(
            &m,
            &MpcSettings {
                input_bounds: Some(bounds.clone()),
                ..MpcSettings::default()
            },
            &custom(DMatrix::zeros(2, 1), DMatrix::zeros(1, 1)),
        )
        .unwrap_err();
        assert!(
            matches!(&e, MpcError::Dimension { what, expected, found }
                if what == "disturbance model Bd" && expected == "1 x 1" && found == "2 x 1"),
            "{e}"
        );
        let e = MpcProblem::build_offset_free(
            &m,
            &MpcSettings {
                input_bounds: Some(bounds.clone()),
                ..MpcSettings::default()
            },
            &custom(DMatrix::from_element(1, 1, f64::NAN), DMatrix::zeros(1, 1)),
        )
        .unwrap_err();
        assert!(
            matches!(&e, MpcError::NonFinite(what) if what == "disturbance model Bd"),
            "{e}"
        );
    }
}
