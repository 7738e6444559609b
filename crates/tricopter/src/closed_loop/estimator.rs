//! The closed loop's Kalman filter design from the thesis's numbers
//! ([`crate::constants`]): process noise through the inputs and on the
//! outputs' state directions, the gyro covariance and bias as measurement
//! noise.

use crate::constants::{DISTURBANCE_WALK, GUST_NOISE, GYRO_BIAS, GYRO_COVARIANCE, INPUT_NOISE_US};
use crate::error::TricopterError;
use kestrel_core::formats::SsModel;
use kestrel_kalman::{KalmanDesign, NoiseModel};
use nalgebra::{DMatrix, DVector};

/// The noise model of the closed loop's filter for `model` (4 pulse
/// inputs, the 3 gyro outputs) whose last `nd` states are constant
/// disturbances: `G = [B, C', E_d]` with standard deviations
/// [`INPUT_NOISE_US`] per pulse, [`GUST_NOISE`] on the outputs' state
/// directions (the gusts) and [`DISTURBANCE_WALK`] on the disturbances;
/// the thesis's gyro covariance [`GYRO_COVARIANCE`] (7.6) and bias
/// [`GYRO_BIAS`] (7.5) as measurement noise.
///
/// # Errors
/// [`TricopterError::Dimension`] if the model does not have the gyro's
/// 3 outputs; [`TricopterError::InvalidSetting`] for `nd > nx`.
pub fn thesis_noise(model: &SsModel, nd: usize) -> Result<NoiseModel, TricopterError> {
    let (nx, nu, ny) = (model.nx(), model.nu(), model.ny());
    if ny != 3 {
        return Err(TricopterError::dim(
            "Kalman filter design model",
            "3 outputs (the gyro's p, q, r)",
            format!("{ny} outputs"),
        ));
    }
    if nd > nx {
        return Err(TricopterError::setting(
            "nd",
            format!("{nd} disturbance states in a model of {nx}"),
        ));
    }
    let nw = nu + ny + nd;
    let mut g = DMatrix::zeros(nx, nw);
    g.view_mut((0, 0), (nx, nu)).copy_from(&model.b);
    g.view_mut((0, nu), (nx, ny))
        .copy_from(&model.c.transpose());
    g.view_mut((nx - nd, nu + ny), (nd, nd))
        .copy_from(&DMatrix::identity(nd, nd));
    let q = DMatrix::from_diagonal(&DVector::from_fn(nw, |i, _| {
        if i < nu {
            INPUT_NOISE_US.powi(2)
        } else if i < nu + ny {
            GUST_NOISE.powi(2)
        } else {
            DISTURBANCE_WALK.powi(2)
        }
    }));
    Ok(NoiseModel {
        g: Some(g),
        q,
        r: DMatrix::from_fn(3, 3, |i, j| GYRO_COVARIANCE[i][j]),
        cross: None,
        bias: Some(DVector::from_column_slice(&GYRO_BIAS)),
    })
}

/// The stationary Kalman filter the closed loop flies by default: the
/// filter of [`thesis_noise`] for `model` (no disturbance states).
///
/// ```
/// let model = kestrel_tricopter::identified_model().unwrap();
/// let kalman = kestrel_tricopter::closed_loop::kalman_design(&model).unwrap();
/// assert_eq!((kalman.nx(), kalman.nu(), kalman.ny()), (5, 4, 3));
/// ```
pub fn kalman_design(model: &SsModel) -> Result<KalmanDesign, TricopterError> {
    kalman_design_with_disturbance(model, 0)
}

/// [`kalman_design`] for a model whose last `nd` states are constant
/// disturbances (an offset-free design's augmented model,
/// `kestrel_mpc::OffsetFreeDesign`): they get a random walk of
/// [`DISTURBANCE_WALK`] per sample so the filter tracks them.
pub fn kalman_design_with_disturbance(
    model: &SsModel,
    nd: usize,
) -> Result<KalmanDesign, TricopterError> {
    KalmanDesign::new(model, &thesis_noise(model, nd)?)
        .map_err(|e| TricopterError::setting("Kalman filter", e.to_string()))
}
