//! Unstable modes of a start model moved inside the unit circle.

use crate::error::{Result, SysidError};
use crate::linalg::{spectral_radius, stable_split};
use crate::model::InnovationModel;
use crate::n4sid::stabilise_k;
use nalgebra::DMatrix;

/// The model with the modes of `A` outside `|z| <= max_radius` moved
/// radially onto that circle (the stable modes kept, `B`, `C`, `D` kept,
/// `K` shrunk if `A - K C` would be unstable), so that
/// [`pem`](crate::pem()), which needs a stable start, can refine it.
/// Meant for starts whose integrators came out slightly unstable
/// (ARX, ARMAX or PBSID on rate-loop data); the moved model predicts
/// differently, so refit it. A model already inside is returned as is.
///
/// ```
/// use kestrel_sysid::{stabilise_a, InnovationModel};
/// # use nalgebra::DMatrix;
/// let m = InnovationModel::new(
///     0.01,
///     DMatrix::from_row_slice(2, 2, &[1.02, 0.0, 0.0, 0.5]),
///     DMatrix::from_row_slice(2, 1, &[1.0, 1.0]),
///     DMatrix::from_row_slice(1, 2, &[1.0, 1.0]),
///     DMatrix::zeros(1, 1),
///     DMatrix::zeros(2, 1),
/// )
/// .unwrap();
/// let s = stabilise_a(&m, 0.999).unwrap();
/// assert!((s.radius_a() - 0.999).abs() < 1e-9);
/// ```
pub fn stabilise_a(model: &InnovationModel, max_radius: f64) -> Result<InnovationModel> {
    if !(max_radius.is_finite() && max_radius > 0.0) {
        return Err(SysidError::invalid(format!(
            "max_radius must be finite and > 0, found {max_radius}"
        )));
    }
    model.validate()?;
    if model.radius_a() <= max_radius {
        return Ok(model.clone());
    }
    let a = pull_inside(&model.a, max_radius);
    let k = stabilise_k(&a, &model.c, model.k.clone());
    InnovationModel::new(
        model.ts,
        a,
        model.b.clone(),
        model.c.clone(),
        model.d.clone(),
        k,
    )
}

/// `A` with its modes outside `|z| < r` moved radially inside: the
/// unstable part of a block-diagonal split ([`stable_split`]) scaled by
/// `r / rho`; if the split fails, all of `A` is scaled.
pub(crate) fn pull_inside(a: &DMatrix<f64>, r: f64) -> DMatrix<f64> {
    let scale_all = || a * (r / spectral_radius(a));
    let Ok(split) = stable_split(a, r) else {
        return scale_all();
    };
    let n = a.nrows();
    let ns = split.n_stable;
    let mut blocks = &split.ti * a * &split.t;
    let mut au = blocks.view((ns, ns), (n - ns, n - ns)).into_owned();
    let rho = spectral_radius(&au);
    if !(rho.is_finite() && rho > 0.0) {
        return scale_all();
    }
    au *= r / rho;
    blocks.view_mut((ns, ns), (n - ns, n - ns)).copy_from(&au);
    // The split makes the off-diagonal blocks zero up to rounding.
    blocks.view_mut((0, ns), (ns, n - ns)).fill(0.0);
    blocks.view_mut((ns, 0), (n - ns, ns)).fill(0.0);
    let out = &split.t * blocks * &split.ti;
    if spectral_radius(&out) <= r * (1.0 + 1e-9) {
        out
    } else {
        scale_all()
    }
}
