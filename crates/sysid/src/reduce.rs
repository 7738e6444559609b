//! Balanced reduction (`balred`) of discrete-time models and transmission zeros.

use crate::error::{Result, SysidError};
use crate::linalg::{dlyap, eigenvalues, psd_factor, spectral_radius, stable_split};
use crate::model::InnovationModel;
use crate::synthetic::Rng;
use nalgebra::{Complex, DMatrix};

/// How the states that are dropped are treated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ReductionMethod {
    /// Plain balanced truncation (good at high frequencies).
    #[default]
    Truncate,
    /// Singular perturbation of the balanced realisation: the dropped
    /// states are set to their steady state, which keeps the DC gain exactly.
    MatchDc,
}

/// Settings of [`balred`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct BalredSettings {
    /// Truncation or DC matching.
    pub method: ReductionMethod,
    /// Balance the noise channels too (the Gramians of `[B K]`), so that
    /// the reduced model keeps the noise model; otherwise only `B` is used
    /// and `K` is carried along by the same transformation.
    pub include_noise: bool,
}

/// Result of [`balred`].
#[derive(Clone, Debug, PartialEq)]
pub struct Reduced {
    /// The reduced model.
    pub model: InnovationModel,
    /// Hankel singular values of the full model, descending.
    pub hankel_singular_values: Vec<f64>,
    /// The a-priori bound `2 sum_{i > r} sigma_i` on the largest singular
    /// value of `G - G_r` over frequency (for the balanced channels).
    pub error_bound: f64,
}

struct Balanced {
    t: DMatrix<f64>,
    ti: DMatrix<f64>,
    hsv: Vec<f64>,
}

fn balance(a: &DMatrix<f64>, b: &DMatrix<f64>, c: &DMatrix<f64>) -> Result<Balanced> {
    let p = dlyap(a, &(b * b.transpose()))?;
    let q = dlyap(&a.transpose(), &(c.transpose() * c))?;
    let lc = psd_factor(&p);
    let lo = psd_factor(&q);
    let svd = (lo.transpose() * &lc).svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(SysidError::Numerical(
            "SVD of the Gramian factors failed".into(),
        ));
    };
    let mut idx: Vec<usize> = (0..svd.singular_values.len()).collect();
    idx.sort_by(|x, y| svd.singular_values[*y].total_cmp(&svd.singular_values[*x]));
    let hsv: Vec<f64> = idx.iter().map(|&i| svd.singular_values[i]).collect();
    let n = a.nrows();
    let smax = hsv.first().copied().unwrap_or(0.0);
    let mut t = DMatrix::zeros(n, n);
    let mut ti = DMatrix::zeros(n, n);
    for (k, &i) in idx.iter().enumerate() {
        let s = hsv[k].max(smax * 1e-300).max(f64::MIN_POSITIVE);
        let f = 1.0 / s.sqrt();
        t.column_mut(k)
            .copy_from(&(&lc * vt.row(i).transpose() * f));
        ti.row_mut(k)
            .copy_from(&(u.column(i).transpose() * lo.transpose() * f));
    }
    Ok(Balanced { t, ti, hsv })
}

/// Hankel singular values of the deterministic part (`A`, `B`, `C`), descending.
/// Modes on or outside `|z| = MARGINAL` are kept whole by [`balred`].
const MARGINAL: f64 = 1.0 - 1e-6;

/// Hankel singular values of the deterministic part (`A`, `B`, `C`),
/// descending; modes on or outside the unit circle (see [`balred`]) count
/// as infinite, as in MATLAB.
pub fn hankel_singular_values(model: &InnovationModel) -> Result<Vec<f64>> {
    model.validate()?;
    if spectral_radius(&model.a) < MARGINAL {
        return Ok(balance(&model.a, &model.b, &model.c)?.hsv);
    }
    let sp = stable_split(&model.a, MARGINAL)?;
    let ns = sp.n_stable;
    let mut hsv = vec![f64::INFINITY; model.nx() - ns];
    if ns > 0 {
        let a = (&sp.ti * &model.a * &sp.t)
            .view((0, 0), (ns, ns))
            .into_owned();
        let b = (&sp.ti * &model.b).rows(0, ns).into_owned();
        let c = (&model.c * &sp.t).columns(0, ns).into_owned();
        hsv.extend(balance(&a, &b, &c)?.hsv);
    }
    Ok(hsv)
}

/// Balanced reduction of a model whose modes are all inside the unit disc.
fn balred_stable(
    model: &InnovationModel,
    order: usize,
    settings: &BalredSettings,
) -> Result<Reduced> {
    model.validate()?;
    let n = model.nx();
    if order == 0 || order > n {
        return Err(SysidError::invalid(format!(
            "reduced order must be in 1..={n}, found {order}"
        )));
    }
    let bb = if settings.include_noise {
        let mut m = DMatrix::zeros(n, model.nu() + model.ny());
        m.columns_mut(0, model.nu()).copy_from(&model.b);
        m.columns_mut(model.nu(), model.ny()).copy_from(&model.k);
        m
    } else {
        model.b.clone()
    };
    let bal = balance(&model.a, &bb, &model.c)?;
    if bal.hsv[order - 1] <= 1e-14 * bal.hsv[0] {
        return Err(SysidError::invalid(format!(
            "the model has only {} states that are both controllable and observable; reduce to fewer",
            bal.hsv.iter().filter(|s| **s > 1e-14 * bal.hsv[0]).count()
        )));
    }
    let ab = &bal.ti * &model.a * &bal.t;
    let bbm = &bal.ti * &model.b;
    let kb = &bal.ti * &model.k;
    let cb = &model.c * &bal.t;
    let r = order;
    let rest = n - r;
    let a11 = ab.view((0, 0), (r, r)).into_owned();
    let b1 = bbm.rows(0, r).into_owned();
    let k1 = kb.rows(0, r).into_owned();
    let c1 = cb.columns(0, r).into_owned();
    let reduced = match settings.method {
        ReductionMethod::Truncate => {
            InnovationModel::new(model.ts, a11, b1, c1, model.d.clone(), k1)?
        }
        ReductionMethod::MatchDc => {
            if rest == 0 {
                InnovationModel::new(model.ts, a11, b1, c1, model.d.clone(), k1)?
            } else {
                let a12 = ab.view((0, r), (r, rest)).into_owned();
                let a21 = ab.view((r, 0), (rest, r)).into_owned();
                let a22 = ab.view((r, r), (rest, rest)).into_owned();
                let b2 = bbm.rows(r, rest).into_owned();
                let k2 = kb.rows(r, rest).into_owned();
                let c2 = cb.columns(r, rest).into_owned();
                let m = (DMatrix::<f64>::identity(rest, rest) - a22)
                    .try_inverse()
                    .ok_or_else(|| {
                        SysidError::Numerical("I - A22 is singular (pole at z = 1)".into())
                    })?;
                InnovationModel::new(
                    model.ts,
                    &a11 + &a12 * &m * &a21,
                    &b1 + &a12 * &m * &b2,
                    &c1 + &c2 * &m * &a21,
                    &model.d + &c2 * &m * &b2,
                    &k1 + &a12 * &m * &k2,
                )?
            }
        }
    };
    Ok(Reduced {
        model: reduced,
        error_bound: 2.0 * bal.hsv[r..].iter().sum::<f64>(),
        hankel_singular_values: bal.hsv,
    })
}

/// Balanced reduction of a discrete-time model to `order` states
/// (MATLAB's `balred`, e.g. order 8 to 5 as in section 7.4 of the thesis).
///
/// Modes on or outside the circle `|z| = 1 - 1e-6` (integrators, unstable
/// poles) have no finite Gramians; as MATLAB does, they are separated
/// first ([`crate::linalg::stable_split`]) and kept unchanged, their Hankel
/// singular values are reported as infinite, and only the stable part is
/// balanced and reduced to `order - (number of such modes)` states.
///
/// The Gramians solve the *discrete* Lyapunov equations
/// `A P A' - P + B B' = 0` and `A' Q A - Q + C' C = 0` (python-control
/// uses the continuous ones for discrete models, which is wrong); the
/// square-root method balances `P` and `Q` to `diag(sigma)`. With
/// [`ReductionMethod::MatchDc`] the discrete singular perturbation
/// `A_r = A11 + A12 (I - A22)^-1 A21` (and likewise `B`, `C`, `D`, `K`)
/// keeps the DC gain.
///
/// ```
/// use kestrel_sysid::{balred, synthetic, BalredSettings, ReductionMethod};
/// let m = synthetic::random_model(6, 2, 2, 3, 0.9);
/// let r = balred(&m, 3, &BalredSettings { method: ReductionMethod::MatchDc, ..Default::default() }).unwrap();
/// assert_eq!(r.model.nx(), 3);
/// let (g, gr) = (m.dc_gain().unwrap(), r.model.dc_gain().unwrap());
/// assert!((&g - &gr).norm() < 1e-8 * g.norm());
/// ```
pub fn balred(model: &InnovationModel, order: usize, settings: &BalredSettings) -> Result<Reduced> {
    model.validate()?;
    let n = model.nx();
    if order == 0 || order > n {
        return Err(SysidError::invalid(format!(
            "reduced order must be in 1..={n}, found {order}"
        )));
    }
    if spectral_radius(&model.a) < MARGINAL {
        return balred_stable(model, order, settings);
    }
    let sp = stable_split(&model.a, MARGINAL)?;
    let (ns, nun) = (sp.n_stable, n - sp.n_stable);
    if order < nun {
        return Err(SysidError::invalid(format!(
            "the model has {nun} marginal or unstable modes (|z| >= {MARGINAL}), which balred keeps; reduce to at least {nun} states, not {order}"
        )));
    }
    let ab = &sp.ti * &model.a * &sp.t;
    let bb = &sp.ti * &model.b;
    let kb = &sp.ti * &model.k;
    let cb = &model.c * &sp.t;
    let ass = ab.view((0, 0), (ns, ns)).into_owned();
    let auu = ab.view((ns, ns), (nun, nun)).into_owned();
    let stable = InnovationModel {
        ts: model.ts,
        a: ass.clone(),
        b: bb.rows(0, ns).into_owned(),
        c: cb.columns(0, ns).into_owned(),
        d: model.d.clone(),
        k: kb.rows(0, ns).into_owned(),
    };
    let rs = order - nun;
    let (red_s, hsv, bound) = if ns == 0 {
        (stable, Vec::new(), 0.0)
    } else if rs == 0 {
        // The whole stable part goes: its DC contribution moves to D when
        // matching DC gains.
        let all = balred_stable(&stable, ns, settings)?;
        let mut d = model.d.clone();
        if settings.method == ReductionMethod::MatchDc {
            let m = (DMatrix::<f64>::identity(ns, ns) - &stable.a)
                .try_inverse()
                .ok_or_else(|| {
                    SysidError::Numerical("I - A of the stable part is singular".into())
                })?;
            d += &stable.c * m * &stable.b;
        }
        let empty = InnovationModel {
            ts: model.ts,
            a: DMatrix::zeros(0, 0),
            b: DMatrix::zeros(0, model.nu()),
            c: DMatrix::zeros(model.ny(), 0),
            d,
            k: DMatrix::zeros(0, model.ny()),
        };
        let bound = 2.0 * all.hankel_singular_values.iter().sum::<f64>();
        (empty, all.hankel_singular_values, bound)
    } else {
        let r = balred_stable(&stable, rs, settings)?;
        (r.model, r.hankel_singular_values, r.error_bound)
    };
    let nr = red_s.nx();
    let mut a = DMatrix::zeros(order, order);
    a.view_mut((0, 0), (nr, nr)).copy_from(&red_s.a);
    a.view_mut((nr, nr), (nun, nun)).copy_from(&auu);
    let mut b = DMatrix::zeros(order, model.nu());
    b.rows_mut(0, nr).copy_from(&red_s.b);
    b.rows_mut(nr, nun).copy_from(&bb.rows(ns, nun));
    let mut k = DMatrix::zeros(order, model.ny());
    k.rows_mut(0, nr).copy_from(&red_s.k);
    k.rows_mut(nr, nun).copy_from(&kb.rows(ns, nun));
    let mut c = DMatrix::zeros(model.ny(), order);
    c.columns_mut(0, nr).copy_from(&red_s.c);
    c.columns_mut(nr, nun).copy_from(&cb.columns(ns, nun));
    let mut all_hsv = vec![f64::INFINITY; nun];
    all_hsv.extend(hsv);
    Ok(Reduced {
        model: InnovationModel::new(model.ts, a, b, c, red_s.d, k)?,
        hankel_singular_values: all_hsv,
        error_bound: bound,
    })
}

/// A transmission zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Zero {
    /// Its location in the z-plane.
    pub z: Complex<f64>,
    /// True when `|z| > 1`: non-minimum phase (the thesis's performance limit).
    pub non_minimum_phase: bool,
}

/// Singular values of the Rosenbrock matrix `[[A - z I, B], [C, D]]`, descending.
pub fn rosenbrock_singular_values(model: &InnovationModel, z: Complex<f64>) -> Vec<f64> {
    let (n, nu, ny) = (model.nx(), model.nu(), model.ny());
    let mut m = DMatrix::<Complex<f64>>::zeros(n + ny, n + nu);
    for i in 0..n {
        for j in 0..n {
            m[(i, j)] = Complex::new(model.a[(i, j)], 0.0);
        }
        m[(i, i)] -= z;
        for j in 0..nu {
            m[(i, n + j)] = Complex::new(model.b[(i, j)], 0.0);
        }
    }
    for i in 0..ny {
        for j in 0..n {
            m[(n + i, j)] = Complex::new(model.c[(i, j)], 0.0);
        }
        for j in 0..nu {
            m[(n + i, n + j)] = Complex::new(model.d[(i, j)], 0.0);
        }
    }
    let mut s: Vec<f64> = m.singular_values().iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    s
}

fn square_zeros(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    c: &DMatrix<f64>,
    d: &DMatrix<f64>,
) -> Result<Vec<Complex<f64>>> {
    let n = a.nrows();
    let p = c.nrows();
    let scale = 1.0 + a.norm() + b.norm() + c.norm();
    // D invertible: the zeros are the eigenvalues of A - B D^-1 C.
    if d.norm() > 1e-12 * scale {
        let svd = d.clone().svd(false, false);
        if svd.singular_values.min() > 1e-10 * svd.singular_values.max() {
            let di = d
                .clone()
                .try_inverse()
                .ok_or_else(|| SysidError::Numerical("D".into()))?;
            return eigenvalues(&(a - b * di * c));
        }
    }
    // D = 0 and CB invertible (relative degree one): the zero dynamics
    // x+ = (I - B (CB)^-1 C) A x restricted to ker C.
    let cb = c * b;
    let svd = cb.clone().svd(false, false);
    if d.norm() <= 1e-12 * scale && svd.singular_values.min() > 1e-9 * svd.singular_values.max() {
        let cbi = cb
            .try_inverse()
            .ok_or_else(|| SysidError::Numerical("CB".into()))?;
        let az = (DMatrix::<f64>::identity(n, n) - b * cbi * c) * a;
        // Orthonormal basis of ker C from the eigenvectors of C'C.
        let svdc = (c.transpose() * c).symmetric_eigen();
        let cols: Vec<usize> = (0..n)
            .filter(|&i| svdc.eigenvalues[i] <= 1e-12 * svdc.eigenvalues.amax().max(1e-300))
            .collect();
        if cols.len() != n - p {
            return Err(SysidError::Numerical(
                "C does not have full row rank".into(),
            ));
        }
        let nb = DMatrix::from_fn(n, cols.len(), |r, k| svdc.eigenvectors[(r, cols[k])]);
        return eigenvalues(&(nb.transpose() * az * nb));
    }
    Err(SysidError::invalid(
        "transmission zeros are computed for a feed-through D of full rank or for relative degree one (C B of full rank); this model has neither",
    ))
}

/// The model with its inputs and outputs rescaled so that every column of
/// `[B; D]` and every row of `[C D]` has the norm of `A` (or 1): the
/// transmission zeros do not change (they do not depend on units), but the
/// rank tests on the Rosenbrock matrix stop depending on them.
fn equilibrated(model: &InnovationModel) -> InnovationModel {
    let target = model.a.norm().max(1.0);
    let mut m = model.clone();
    for j in 0..m.nu() {
        let s = (m.b.column(j).norm_squared() + m.d.column(j).norm_squared()).sqrt();
        if s > 0.0 && s.is_finite() {
            m.b.column_mut(j).scale_mut(target / s);
            m.d.column_mut(j).scale_mut(target / s);
        }
    }
    for i in 0..m.ny() {
        let s = (m.c.row(i).norm_squared() + m.d.row(i).norm_squared()).sqrt();
        if s > 0.0 && s.is_finite() {
            m.c.row_mut(i).scale_mut(target / s);
            m.d.row_mut(i).scale_mut(target / s);
        }
    }
    m
}

/// Relative tolerance of the rank test in [`is_transmission_zero`]: the
/// smallest singular value of the (equilibrated) Rosenbrock matrix at `z`
/// must be below this fraction of `||[A B; C D]|| + |z|`.
pub const ZERO_RANK_TOLERANCE: f64 = 1e-8;

/// Whether the (equilibrated) Rosenbrock matrix `[[A - zI, B], [C, D]]`
/// really loses rank at `z`, with `normal_rank` its rank at a generic point.
///
/// Two conditions, both needed because a small singular value alone
/// means nothing at a large `|z|` (there `G(z) -> D`, which for `D = 0`
/// makes the matrix nearly rank deficient everywhere):
/// - scale: the `normal_rank`-th singular value is below
///   [`ZERO_RANK_TOLERANCE`] `* (||[A B; C D]|| + |z|)`;
/// - locality: it is at most `1e-3` of its value at every one of four
///   points at distance `1e-2 (1 + |z|)` around `z` (a rank drop is a dip
///   of the singular value, not a plateau).
fn pencil_drops_rank(m: &InnovationModel, z: Complex<f64>, normal_rank: usize) -> bool {
    let smin = |w: Complex<f64>| rosenbrock_singular_values(m, w)[normal_rank - 1];
    let mut abcd = DMatrix::zeros(m.nx() + m.ny(), m.nx() + m.nu());
    abcd.view_mut((0, 0), m.a.shape()).copy_from(&m.a);
    abcd.view_mut((0, m.nx()), m.b.shape()).copy_from(&m.b);
    abcd.view_mut((m.nx(), 0), m.c.shape()).copy_from(&m.c);
    abcd.view_mut((m.nx(), m.nx()), m.d.shape()).copy_from(&m.d);
    let s0 = smin(z);
    // NaN (a non-finite model) fails too.
    let small = s0 <= ZERO_RANK_TOLERANCE * (abcd.norm() + z.norm());
    if !small {
        return false;
    }
    let r = 1e-2 * (1.0 + z.norm());
    [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]
        .iter()
        .all(|&(re, im)| s0 <= 1e-3 * smin(z + Complex::new(re * r, im * r)))
}

/// Whether `z` is a transmission zero of the deterministic part of the
/// model: the Rosenbrock matrix `[[A - zI, B], [C, D]]` (after rescaling
/// inputs and outputs, which does not move zeros) loses rank at `z`
/// relative to its normal rank `nx + min(nu, ny)`, judged by the size of
/// its smallest relevant singular value against `||[A B; C D]|| + |z|` and
/// against its values nearby (see [`ZERO_RANK_TOLERANCE`]).
///
/// ```
/// use kestrel_sysid::{InnovationModel, is_transmission_zero};
/// use nalgebra::{Complex, DMatrix};
/// // G(z) = (z - 60) / ((z - 0.5)(z - 0.2)): a zero at 60, none at 50.
/// let a = DMatrix::from_row_slice(2, 2, &[0.7, -0.1, 1.0, 0.0]);
/// let b = DMatrix::from_row_slice(2, 1, &[1.0, 0.0]);
/// let c = DMatrix::from_row_slice(1, 2, &[1.0, -60.0]);
/// let m = InnovationModel::new(1.0, a, b, c, DMatrix::zeros(1, 1), DMatrix::zeros(2, 1)).unwrap();
/// assert!(is_transmission_zero(&m, Complex::new(60.0, 0.0)));
/// assert!(!is_transmission_zero(&m, Complex::new(50.0, 0.0)));
/// ```
pub fn is_transmission_zero(model: &InnovationModel, z: Complex<f64>) -> bool {
    let normal_rank = model.nx() + model.nu().min(model.ny());
    normal_rank > 0 && z.is_finite() && pencil_drops_rank(&equilibrated(model), z, normal_rank)
}

/// Candidate zeros: those of a square system made from the model by a
/// random input or output combination `seed` (they include the true ones).
fn square_candidates(m: &InnovationModel, seed: u64) -> Result<Vec<Complex<f64>>> {
    let (nu, ny) = (m.nu(), m.ny());
    let mut rng = Rng::new(seed);
    let (b, c, d) = if nu > ny {
        let r = rng.normal_matrix(nu, ny);
        (&m.b * &r, m.c.clone(), &m.d * &r)
    } else if ny > nu {
        let l = rng.normal_matrix(nu, ny);
        (m.b.clone(), &l * &m.c, &l * &m.d)
    } else {
        (m.b.clone(), m.c.clone(), m.d.clone())
    };
    square_zeros(&m.a, &b, &c, &d)
}

/// Transmission zeros of the deterministic part of a MIMO model: the
/// values `z` where the Rosenbrock matrix `[[A - zI, B], [C, D]]` loses
/// rank, each flagged when outside the unit circle (non-minimum phase).
///
/// Inputs and outputs are first rescaled to unit-free sizes (zeros do not
/// depend on units). Square systems with `D` of full rank give the
/// eigenvalues of `A - B D^-1 C`; with `D = 0` and `C B` of full rank
/// (the generic case of an identified model without feed-through) the
/// zeros are the eigenvalues of the zero dynamics `(I - B (CB)^-1 C) A` on
/// `ker C`. Non-square systems are compressed to square ones by two
/// independent random input or output combinations, whose zeros include
/// the true ones; a candidate is kept only if both give it (to
/// `1e-6 (1 + |z|)`). Every candidate, square or not, must then pass
/// [`is_transmission_zero`]: a genuine rank drop of the full Rosenbrock
/// matrix, not merely a small singular value at a large `|z|`. Generic
/// non-square systems have no zeros.
pub fn transmission_zeros(model: &InnovationModel) -> Result<Vec<Zero>> {
    model.validate()?;
    let m = equilibrated(model);
    let (nu, ny) = (m.nu(), m.ny());
    let normal_rank = m.nx() + nu.min(ny);
    let mut cand = square_candidates(&m, 0x5EED)?;
    if nu != ny {
        let other = square_candidates(&m, 0xC0FFEE)?;
        cand.retain(|z| {
            other
                .iter()
                .any(|w| (z - w).norm() <= 1e-6 * (1.0 + z.norm()))
        });
    }
    let mut out: Vec<Zero> = cand
        .into_iter()
        .filter(|z| normal_rank > 0 && pencil_drops_rank(&m, *z, normal_rank))
        .map(|z| Zero {
            z,
            non_minimum_phase: z.norm() > 1.0,
        })
        .collect();
    out.sort_by(|a, b| b.z.norm().total_cmp(&a.z.norm()));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic;

    fn sigma_max(m: &DMatrix<Complex<f64>>) -> f64 {
        m.singular_values().max()
    }

    #[test]
    fn hankel_values_match_eigenvalues_of_pq() {
        let m = synthetic::random_model(5, 2, 3, 8, 0.9);
        let hsv = hankel_singular_values(&m).unwrap();
        let p = dlyap(&m.a, &(&m.b * m.b.transpose())).unwrap();
        let q = dlyap(&m.a.transpose(), &(m.c.transpose() * &m.c)).unwrap();
        let mut ev: Vec<f64> = eigenvalues(&(&p * &q))
            .unwrap()
            .iter()
            .map(|l| l.re.max(0.0).sqrt())
            .collect();
        ev.sort_by(|a, b| b.total_cmp(a));
        for (a, b) in hsv.iter().zip(&ev) {
            assert!((a - b).abs() < 1e-8 * hsv[0], "{hsv:?} vs {ev:?}");
        }
    }

    #[test]
    fn truncation_error_within_twice_the_tail() {
        let m = synthetic::random_model(8, 3, 3, 12, 0.95);
        for method in [ReductionMethod::Truncate, ReductionMethod::MatchDc] {
            let r = balred(
                &m,
                5,
                &BalredSettings {
                    method,
                    include_noise: false,
                },
            )
            .unwrap();
            assert_eq!(r.model.nx(), 5);
            let mut worst: f64 = 0.0;
            for i in 0..=400 {
                let w = std::f64::consts::PI * i as f64 / 400.0;
                let e = m.frequency_response(w).unwrap() - r.model.frequency_response(w).unwrap();
                worst = worst.max(sigma_max(&e));
            }
            assert!(
                worst <= r.error_bound * (1.0 + 1e-9),
                "{method:?}: {worst} > {}",
                r.error_bound
            );
            // Lower bound: no order-5 model does better than sigma_6 (checked on a grid, loosely).
            assert!(worst >= 0.5 * r.hankel_singular_values[5], "{method:?}");
            if method == ReductionMethod::MatchDc {
                let (g, gr) = (m.dc_gain().unwrap(), r.model.dc_gain().unwrap());
                assert!((&g - &gr).norm() < 1e-8 * g.norm());
            }
        }
        assert!(balred(&m, 0, &BalredSettings::default()).is_err());
        assert!(balred(&m, 9, &BalredSettings::default()).is_err());
    }

    /// A model with an integrator and an unstable pole mixed into a stable
    /// 6th-order one: `balred` keeps both exactly (infinite Hankel singular
    /// values first) and the error of the stable part stays within its bound.
    #[test]
    fn marginal_and_unstable_modes_are_kept() {
        let s = synthetic::random_model(6, 2, 2, 5, 0.9);
        let n = 8;
        let mut a = DMatrix::zeros(n, n);
        a.view_mut((0, 0), (6, 6)).copy_from(&s.a);
        a[(6, 6)] = 1.0;
        a[(7, 7)] = 1.05;
        let mut b = DMatrix::zeros(n, 2);
        b.rows_mut(0, 6).copy_from(&s.b);
        b.rows_mut(6, 2)
            .copy_from(&DMatrix::from_row_slice(2, 2, &[0.3, -0.2, 0.1, 0.4]));
        let mut c = DMatrix::zeros(2, n);
        c.columns_mut(0, 6).copy_from(&s.c);
        c.columns_mut(6, 2)
            .copy_from(&DMatrix::from_row_slice(2, 2, &[1.0, 0.5, -0.7, 0.2]));
        // Mix the coordinates so the modes are not already separated.
        let t = DMatrix::from_fn(n, n, |r, c| {
            ((r * 5 + c * 3) % 7) as f64 * 0.1 + if r == c { 1.0 } else { 0.0 }
        });
        let ti = t.clone().try_inverse().unwrap();
        let m = InnovationModel::new(
            1.0,
            &ti * a * &t,
            &ti * b,
            c * &t,
            DMatrix::zeros(2, 2),
            DMatrix::zeros(n, 2),
        )
        .unwrap();
        let hsv = hankel_singular_values(&m).unwrap();
        assert!(hsv[0].is_infinite() && hsv[1].is_infinite() && hsv[2].is_finite());
        let stable_hsv = hankel_singular_values(&s).unwrap();
        for (h, e) in hsv[2..].iter().zip(&stable_hsv) {
            assert!(
                (h - e).abs() < 1e-8 * stable_hsv[0],
                "{hsv:?} vs {stable_hsv:?}"
            );
        }
        for method in [ReductionMethod::Truncate, ReductionMethod::MatchDc] {
            let settings = BalredSettings {
                method,
                include_noise: false,
            };
            let r = balred(&m, 5, &settings).unwrap();
            assert_eq!(r.model.nx(), 5);
            let mut poles: Vec<f64> = r.model.poles().unwrap().iter().map(|z| z.norm()).collect();
            poles.sort_by(f64::total_cmp);
            assert!(
                (poles[4] - 1.05).abs() < 1e-9 && (poles[3] - 1.0).abs() < 1e-9,
                "{poles:?}"
            );
            assert!(poles[2] < 0.95);
            // G - G_r is the stable part's error: within 2 * tail (away from z = 1).
            let mut worst: f64 = 0.0;
            for i in 1..=300 {
                let w = std::f64::consts::PI * i as f64 / 300.0;
                let e = m.frequency_response(w).unwrap() - r.model.frequency_response(w).unwrap();
                worst = worst.max(sigma_max(&e));
            }
            assert!(
                worst <= r.error_bound * (1.0 + 1e-6),
                "{method:?}: {worst} > {}",
                r.error_bound
            );
            // Down to the kept modes alone, and no further.
            assert_eq!(balred(&m, 2, &settings).unwrap().model.nx(), 2);
            assert!(matches!(
                balred(&m, 1, &settings),
                Err(SysidError::InvalidArgument(_))
            ));
        }
    }

    #[test]
    fn siso_zeros_are_numerator_roots() {
        // G(z) = (z - 1.5)(z - 0.2) / ((z - 0.5)(z - 0.6)(z + 0.3)), controllable form.
        let den = [1.0, -0.8, -0.03, 0.09]; // (z-.5)(z-.6)(z+.3) = z^3 - 0.8 z^2 - 0.03 z + 0.09
        let a = DMatrix::from_row_slice(
            3,
            3,
            &[-den[1], -den[2], -den[3], 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
        );
        let b = DMatrix::from_row_slice(3, 1, &[1.0, 0.0, 0.0]);
        let c = DMatrix::from_row_slice(1, 3, &[1.0, -1.7, 0.3]); // (z-1.5)(z-0.2) = z^2 - 1.7 z + 0.3
        let m =
            InnovationModel::new(1.0, a, b, c, DMatrix::zeros(1, 1), DMatrix::zeros(3, 1)).unwrap();
        let z = transmission_zeros(&m).unwrap();
        assert_eq!(z.len(), 2);
        assert!((z[0].z - Complex::new(1.5, 0.0)).norm() < 1e-10 && z[0].non_minimum_phase);
        assert!((z[1].z - Complex::new(0.2, 0.0)).norm() < 1e-10 && !z[1].non_minimum_phase);
    }

    #[test]
    fn mimo_zeros_drop_the_rosenbrock_rank() {
        for (nu, ny, d) in [(3, 3, false), (3, 3, true), (2, 2, false)] {
            let mut m = synthetic::random_model(6, nu, ny, 40 + nu as u64, 0.9);
            if d {
                m.d = DMatrix::from_fn(ny, nu, |i, j| if i == j { 1.0 } else { 0.3 });
            }
            let z = transmission_zeros(&m).unwrap();
            assert_eq!(z.len(), if d { 6 } else { 6 - ny });
            for zz in &z {
                let s = rosenbrock_singular_values(&m, zz.z);
                assert!(s[6 + nu - 1] < 1e-8 * s[0], "{zz:?}: {s:?}");
            }
        }
        // Generic non-square (4 inputs, 3 outputs): no transmission zeros.
        let m = synthetic::random_model(5, 4, 3, 77, 0.9);
        assert!(transmission_zeros(&m).unwrap().is_empty());
        // ... unless one is built in: a common zero of every channel.
        let mut m = synthetic::random_model(4, 1, 1, 5, 0.8);
        m.b = DMatrix::from_fn(4, 2, |i, j| m.b[(i, 0)] * (1.0 + j as f64));
        m.d = DMatrix::zeros(1, 2);
        let z1 = transmission_zeros(&InnovationModel {
            b: m.b.columns(0, 1).into_owned(),
            d: DMatrix::zeros(1, 1),
            ..m.clone()
        })
        .unwrap();
        let z2 = transmission_zeros(&m).unwrap();
        assert_eq!(z1.len(), z2.len());
    }
}
