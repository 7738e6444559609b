//! The parametrisation: physical parameters to the discrete rate model.

use crate::error::sysid_invalid;
use crate::ident::greybox::spec::GreyBoxSpec;
use kestrel_core::formats::SsModel;
use kestrel_sysid::{InnovationModel, Result, SysidError};
use kestrel_tricopter_model::{GreyBoxParams, ModelError, grey_box_rate_model};
use nalgebra::DMatrix;

/// The discrete grey-box model of `g` at sample time `ts` (`K = 0`): the
/// map the search fits (trim, linearisation, zero-order hold).
pub fn grey_box_model(g: &GreyBoxParams, spec: &GreyBoxSpec, ts: f64) -> Result<InnovationModel> {
    let mut m =
        grey_box_rate_model(g, &spec.base, spec.kind, spec.inputs).map_err(|e| model_error(&e))?;
    if spec.disturbance {
        // Integrating angular-acceleration disturbances on p, q, r.
        let (n, ny, nu) = (m.a.nrows(), m.c.nrows(), m.b.ncols());
        let mut a = DMatrix::zeros(n + ny, n + ny);
        a.view_mut((0, 0), (n, n)).copy_from(&m.a);
        a.view_mut((0, n), (n, ny)).copy_from(&m.c.transpose());
        let mut b = DMatrix::zeros(n + ny, nu);
        b.view_mut((0, 0), (n, nu)).copy_from(&m.b);
        let mut c = DMatrix::zeros(ny, n + ny);
        c.view_mut((0, 0), (ny, n)).copy_from(&m.c);
        m = SsModel::new(0.0, a, b, c, m.d.clone())
            .map_err(|e| sysid_invalid(format!("grey-box model: {e}")))?;
    }
    let d = m
        .c2d(ts)
        .map_err(|e| sysid_invalid(format!("discretising the grey-box model: {e}")))?;
    let ny = d.c.nrows();
    let nx = d.a.nrows();
    InnovationModel::new(ts, d.a, d.b, d.c, d.d, DMatrix::zeros(nx, ny))
}

pub(super) fn model_error(e: &ModelError) -> SysidError {
    sysid_invalid(format!("grey-box model: {e}"))
}
