//! The closed loop's Kalman filter design from the thesis's numbers
//! ([`crate::constants`]): process noise through the inputs and on the
//! outputs' state directions, the gyro covariance and bias as measurement
//! noise.

use crate::constants::{DISTURBANCE_WALK, GUST_NOISE, GYRO_BIAS, GYRO_COVARIANCE, INPUT_NOISE_US};
use crate::error::TricopterError;
use kestrel_core::formats::SsModel;
use kestrel_kalman::{AugmentedModel, DisturbanceNoise, KalmanDesign, NoiseModel};
use nalgebra::{DMatrix, DVector};

/// The noise model of the closed loop's filter for `model` (4 pulse
/// inputs, the 3 gyro outputs) whose last `nd` states are constant
/// disturbances: `G = [B, C', E_d]` with standard deviations
/// [`INPUT_NOISE_US`] per pulse, [`GUST_NOISE`] on the outputs' state
/// directions (the gusts) and [`DISTURBANCE_WALK`] on the disturbances;
/// the thesis's gyro covariance [`GYRO_COVARIANCE`] (7.6) and bias
/// [`GYRO_BIAS`] (7.5) as measurement noise. It is the
/// [`NoiseModel`] of [`thesis_disturbance_noise`] on the model read as a
/// kestrel-kalman [`AugmentedModel`].
///
/// # Errors
/// [`MpcError::Dimension`](kestrel_mpc::MpcError::Dimension) (in
/// [`TricopterError::Mpc`]) if the model does not have the gyro's 3
/// outputs; [`MpcError::InvalidSetting`](kestrel_mpc::MpcError::InvalidSetting)
/// for `nd > nx`, or when
/// the last `nd` states are not integrating disturbances or cannot be
/// estimated.
pub fn thesis_noise(model: &SsModel, nd: usize) -> Result<NoiseModel, TricopterError> {
    let aug = thesis_augmented(model, nd)?;
    aug.noise_model(&thesis_disturbance_noise(&aug))
        .map_err(|e| TricopterError::setting("Kalman filter", e.to_string()))
}

/// The thesis's noise levels on an augmented model (see [`thesis_noise`]):
/// `Gx = [B, C']` of the augmented model (full height, so with an output
/// disturbance `Cd != 0` the output noise also drives the disturbance
/// states), `Qx = diag(INPUT_NOISE_US^2 I, GUST_NOISE^2 I)`,
/// `Qd = DISTURBANCE_WALK^2 I`, the gyro covariance and bias.
pub fn thesis_disturbance_noise(aug: &AugmentedModel) -> DisturbanceNoise {
    let r = DMatrix::from_fn(3, 3, |i, j| GYRO_COVARIANCE[i][j]);
    let mut noise =
        DisturbanceNoise::inputs_and_outputs(aug, INPUT_NOISE_US, GUST_NOISE, DISTURBANCE_WALK, r);
    let (b, c) = (&aug.model.b, &aug.model.c);
    let mut g = DMatrix::zeros(b.nrows(), b.ncols() + c.nrows());
    g.columns_mut(0, b.ncols()).copy_from(b);
    g.columns_mut(b.ncols(), c.nrows())
        .copy_from(&c.transpose());
    noise.plant_g = g;
    noise.bias = Some(DVector::from_column_slice(&GYRO_BIAS));
    noise
}

/// `model` (3 gyro outputs) read as an augmented model whose last `nd`
/// states are disturbances.
fn thesis_augmented(model: &SsModel, nd: usize) -> Result<AugmentedModel, TricopterError> {
    let (nx, ny) = (model.nx(), model.ny());
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
    AugmentedModel::from_augmented(model, nd)
        .map_err(|e| TricopterError::setting("Kalman filter design model", e.to_string()))
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
/// [`DISTURBANCE_WALK`] per sample so the filter tracks them. The
/// filter is kestrel-kalman's [`AugmentedModel::design`] of
/// [`thesis_disturbance_noise`].
///
/// # Errors
/// As [`thesis_noise`], and the filter design's.
pub fn kalman_design_with_disturbance(
    model: &SsModel,
    nd: usize,
) -> Result<KalmanDesign, TricopterError> {
    let aug = thesis_augmented(model, nd)?;
    aug.design(&thesis_disturbance_noise(&aug))
        .map(|d| d.kalman)
        .map_err(|e| TricopterError::setting("Kalman filter", e.to_string()))
}
