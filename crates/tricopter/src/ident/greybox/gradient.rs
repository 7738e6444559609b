//! The criterion and its analytic gradient at one point, for checks.

use crate::error::{sysid_dim, sysid_invalid};
use crate::ident::greybox::model::grey_box_model;
use crate::ident::greybox::problem::{Gain, Problem, series_of};
use crate::ident::greybox::search::cost_of;
use crate::ident::greybox::spec::GreyBoxSpec;
use crate::ident::greybox::start::check_data;
use kestrel_sysid::{IoData, Result, SysidError};
use kestrel_tricopter_model::GreyBoxParams;
use nalgebra::{DMatrix, DVector};

/// The criterion `J` and its analytic gradient (from the sensitivity
/// recursion) at one point: see [`cost_gradient`].
#[derive(Clone, Debug, PartialEq)]
pub struct CostGradient {
    /// `J = 1/(N ny) sum (e_j / s_j)^2` (see the module docs).
    pub cost: f64,
    /// `dJ/dθ` with `θ` = the logarithms of the free parameters (in
    /// [`GreyBoxParams::NAMES`] order), then the entries of `K` row by row
    /// (when a gain is given), then the initial state of every experiment.
    pub gradient: Vec<f64>,
}

/// The grey-box criterion and its gradient at the parameters `g`, the
/// innovation gain `k` (`None`: simulation, `K = 0`) and the initial
/// states `x0` (one per experiment): the quantities the search uses,
/// for checking the gradient against finite differences of `J`.
pub fn cost_gradient(
    data: &IoData,
    spec: &GreyBoxSpec,
    g: &GreyBoxParams,
    k: Option<&DMatrix<f64>>,
    x0: &[DVector<f64>],
) -> Result<CostGradient> {
    let m = grey_box_model(g, spec, data.ts())?;
    let (nx, ny) = (m.nx(), m.ny());
    check_data(data, m.nu(), ny)?;
    if x0.len() != data.experiments().len() {
        return Err(sysid_dim(
            "initial states (one per experiment)",
            data.experiments().len(),
            x0.len(),
        ));
    }
    if let Some(x) = x0.iter().find(|x| x.len() != nx) {
        return Err(sysid_dim("initial state", nx, x.len()));
    }
    if let Some(k) = k
        && k.shape() != (nx, ny)
    {
        return Err(sysid_invalid(format!(
            "K is {}x{}, the model needs {nx}x{ny}",
            k.nrows(),
            k.ncols()
        )));
    }
    let (_, sy) = data.stds();
    let mut prob = Problem::new(spec, data, *g, nx, ny, series_of(data), &sy);
    prob.gain = if k.is_some() {
        Gain::Free
    } else {
        Gain::Fixed(DMatrix::zeros(nx, ny))
    };
    let mut theta = DVector::zeros(prob.n_params());
    let ga = g.to_array();
    for (i, &p) in prob.phys.iter().enumerate() {
        theta[i] = ga[p].ln();
    }
    if let Some(k) = k {
        for i in 0..nx {
            for j in 0..ny {
                theta[prob.off_k() + i * ny + j] = k[(i, j)];
            }
        }
    }
    for (e, x) in x0.iter().enumerate() {
        theta.rows_mut(prob.off_x0() + e * nx, nx).copy_from(x);
    }
    let ev = prob.evaluate(&theta, true)?;
    let jac = ev
        .jac
        .as_ref()
        .ok_or_else(|| SysidError::Numerical("internal: no Jacobian".into()))?;
    Ok(CostGradient {
        cost: cost_of(&ev),
        gradient: (jac.transpose() * &ev.r * 2.0).iter().copied().collect(),
    })
}
