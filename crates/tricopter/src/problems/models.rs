//! The design models: the identified 5-state black-box model (the
//! default, embedded) and the physical linearisation, and the
//! feed-through delay that makes a model strictly proper for the MPC.

use crate::constants::SAMPLE_TIME;
use crate::error::TricopterError;
use kestrel_core::formats::SsModel;
use kestrel_tricopter_model::{Params, RateInputs, RateModelKind};

/// The physical design model (for comparison with [`identified_model`],
/// which is the default): the rates-plus-actuators linearisation of kestrel-tricopter-model's default
/// aircraft at hover (`[p, q, r, w1, w2, w3, alpha, alpha_dot]`, 8 states,
/// PWM inputs with absolute `u0`), discretised at 50 Hz.
pub fn design_model() -> Result<SsModel, TricopterError> {
    kestrel_tricopter_model::rate_model_discrete(
        &Params::default(),
        RateModelKind::WithActuators,
        RateInputs::Pwm,
        SAMPLE_TIME,
    )
    .map_err(|e| TricopterError::setting("tricopter design model", e.to_string()))
}

/// The identified design model: `data/tricopter-blackbox-5.json` of
/// this crate (`kestrel.ss.v1`, a copy of the repository's
/// `models/tricopter-blackbox-5.json`), the 5-state black-box rate model of
/// kestrel-tricopter-model's default aircraft identified as in section 7.4
/// (inputs `pwm1, pwm2, pwm3, servo` in us, outputs `p, q, r` in rad/s,
/// 50 Hz, operating point `u0`/`y0` in absolute pulses and rad/s), in the
/// form the MPC uses: a feed-through `D` (from a DC-matched reduction) is
/// moved behind one sample ([`delay_feedthrough`]). It is embedded at
/// compile time, so a re-identified model is picked up by the next build.
///
/// ```
/// let m = kestrel_tricopter::identified_model().unwrap();
/// assert_eq!((m.nu(), m.ny()), (4, 3));
/// assert!(m.d.iter().all(|v| *v == 0.0) && m.u0.is_some());
/// ```
pub fn identified_model() -> Result<SsModel, TricopterError> {
    delay_feedthrough(&SsModel::from_json_str(IDENTIFIED_MODEL_JSON)?)
}

/// A model with feed-through `y_k = C x_k + D u_k` as a strictly proper
/// one for the MPC: `D` acts one sample later, through `nu` added states
/// holding the previous input (`x_u+ = u`, `y = C x + D x_u`); a model
/// with `D = 0` is returned unchanged.
///
/// In the control loop the gyro sample `y_k` is taken before `u_k` is
/// computed and applied, so `D u_k` cannot show before `k + 1` anyway;
/// kestrel-kalman's filter uses `D` on the previous input the same way.
///
/// ```
/// use kestrel_core::formats::SsModel;
/// use nalgebra::dmatrix;
/// let m = SsModel::new(0.1, dmatrix![0.5], dmatrix![1.0], dmatrix![1.0], dmatrix![0.2]).unwrap();
/// let s = kestrel_tricopter::delay_feedthrough(&m).unwrap();
/// assert_eq!(s.nx(), 2);
/// assert_eq!(s.c, dmatrix![1.0, 0.2]);
/// assert_eq!(s.d, dmatrix![0.0]);
/// ```
pub fn delay_feedthrough(model: &SsModel) -> Result<SsModel, TricopterError> {
    if model.d.iter().all(|v| *v == 0.0) {
        return Ok(model.clone());
    }
    let (nx, nu, ny) = (model.nx(), model.nu(), model.ny());
    let n = nx + nu;
    let mut a = nalgebra::DMatrix::zeros(n, n);
    a.view_mut((0, 0), (nx, nx)).copy_from(&model.a);
    let mut b = nalgebra::DMatrix::zeros(n, nu);
    b.view_mut((0, 0), (nx, nu)).copy_from(&model.b);
    b.view_mut((nx, 0), (nu, nu))
        .copy_from(&nalgebra::DMatrix::identity(nu, nu));
    let mut c = nalgebra::DMatrix::zeros(ny, n);
    c.view_mut((0, 0), (ny, nx)).copy_from(&model.c);
    c.view_mut((0, nx), (ny, nu)).copy_from(&model.d);
    let mut out = SsModel::new(model.ts, a, b, c, nalgebra::DMatrix::zeros(ny, nu))?;
    out.u0 = model.u0.clone();
    out.y0 = model.y0.clone();
    out.inputs = model.inputs.clone();
    out.outputs = model.outputs.clone();
    Ok(out)
}

/// The text of [`identified_model`] (`data/tricopter-blackbox-5.json`).
pub const IDENTIFIED_MODEL_JSON: &str = include_str!("../../data/tricopter-blackbox-5.json");
