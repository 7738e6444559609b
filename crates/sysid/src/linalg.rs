//! Small dense linear-algebra helpers on nalgebra (design time).

use crate::error::{Result, SysidError};
use nalgebra::{Complex, DMatrix, DVector};

/// The eigenvalues of a square matrix: [`kestrel_core::eig::eigenvalues`]
/// (balancing, Hessenberg, Francis double shift with an iteration limit;
/// nalgebra's `complex_eigenvalues` has none and cycled for ever on a
/// matrix with repeated decoupled modes). A matrix that is not square or
/// not finite, or an iteration that does not converge, is an error.
pub fn eigenvalues(a: &DMatrix<f64>) -> Result<Vec<Complex<f64>>> {
    Ok(kestrel_core::eig::eigenvalues(a)?.iter().copied().collect())
}

/// The spectral radius `max |lambda_i(A)|` (0 for an empty matrix).
/// Stability checks use it, so a matrix whose eigenvalues cannot be
/// computed (non-finite entries, no convergence) counts as unstable:
/// `f64::INFINITY`.
pub fn spectral_radius(a: &DMatrix<f64>) -> f64 {
    kestrel_core::eig::spectral_radius(a).unwrap_or(f64::INFINITY)
}

/// Moore-Penrose pseudo-inverse with a relative singular-value cut-off.
///
/// A matrix with a NaN or infinite entry, or one whose SVD does not converge
/// within a generous iteration limit, gives a matrix of NaN (which the
/// callers' finiteness checks turn into an error) instead of looping: the
/// plain SVD never returns on such input.
pub fn pinv(a: &DMatrix<f64>) -> DMatrix<f64> {
    let (r, c) = a.shape();
    if r == 0 || c == 0 {
        return DMatrix::zeros(c, r);
    }
    let failed = || DMatrix::from_element(c, r, f64::NAN);
    if a.iter().any(|v| !v.is_finite()) {
        return failed();
    }
    let Some(svd) = a
        .clone()
        .try_svd(true, true, f64::EPSILON, 200 * (r.max(c) + 10))
    else {
        return failed();
    };
    let smax = svd.singular_values.max();
    let tol = smax * f64::EPSILON * (r.max(c) as f64);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return DMatrix::zeros(c, r);
    };
    let mut out = DMatrix::zeros(c, r);
    for (i, s) in svd.singular_values.iter().enumerate() {
        if *s > tol {
            out += vt.row(i).transpose() * u.column(i).transpose() * (1.0 / s);
        }
    }
    out
}

/// Least-squares solution of `A X = B` (minimum norm when rank deficient).
pub fn lstsq(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    pinv(a) * b
}

/// Solves the discrete Lyapunov equation `A X A' - X + Q = 0` for a Schur
/// stable `A` by the doubling (squared Smith) iteration
/// `X <- X + A X A'`, `A <- A^2`, which sums `sum_k A^k Q A'^k` in
/// `log2` of the number of terms.
pub fn dlyap(a: &DMatrix<f64>, q: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let n = a.nrows();
    if a.ncols() != n {
        return Err(SysidError::dim("A columns (dlyap)", n, a.ncols()));
    }
    if q.shape() != (n, n) {
        return Err(SysidError::dim("Q rows (dlyap)", n, q.nrows()));
    }
    let rho = spectral_radius(a);
    if rho.is_nan() || rho >= 1.0 {
        return Err(SysidError::Unstable {
            what: "A (discrete Lyapunov equation)".into(),
            radius: rho,
            limit: 1.0,
        });
    }
    let mut x = q.clone();
    let mut ak = a.clone();
    for _ in 0..64 {
        let inc = &ak * &x * ak.transpose();
        x += &inc;
        ak = &ak * &ak;
        if inc.norm() <= 1e-15 * x.norm() || ak.norm() < 1e-300 {
            let x = (&x + x.transpose()) * 0.5;
            return Ok(x);
        }
    }
    Err(SysidError::Numerical(
        "discrete Lyapunov doubling did not converge (pole too close to the unit circle)".into(),
    ))
}

/// A block-diagonalising change of coordinates that separates the modes
/// of `A` inside the disc `|z| < radius` from those on or outside it.
#[derive(Clone, Debug, PartialEq)]
pub struct StableSplit {
    /// `x = T [x_s; x_u]`.
    pub t: DMatrix<f64>,
    /// `T^-1`.
    pub ti: DMatrix<f64>,
    /// Number of modes inside the disc (the first `n_stable` new coordinates).
    pub n_stable: usize,
}

/// Separates the modes of `a` with `|z| < radius` from the others (like
/// MATLAB's `stabsep`): the matrix sign function (Newton with determinant
/// scaling) of the Cayley transform `(A/radius + I)^-1 (A/radius - I)`,
/// whose eigenvalues have negative real part exactly for the modes inside
/// the disc, gives the spectral projector onto the stable invariant
/// subspace; its range and the range of its complement are the new
/// coordinates. `T^-1 A T` is block diagonal up to rounding.
pub fn stable_split(a: &DMatrix<f64>, radius: f64) -> Result<StableSplit> {
    let n = a.nrows();
    if a.ncols() != n {
        return Err(SysidError::dim("A columns (stable_split)", n, a.ncols()));
    }
    if !(radius.is_finite() && radius > 0.0) || a.iter().any(|v| !v.is_finite()) {
        return Err(SysidError::invalid(
            "stable_split needs a finite A and a radius > 0",
        ));
    }
    let eye = DMatrix::<f64>::identity(n, n);
    let sa = a / radius;
    let den = (&sa + &eye).try_inverse().ok_or_else(|| {
        SysidError::Numerical(format!("A has a pole at z = -{radius}; cannot split it"))
    })?;
    let mut s = den * (&sa - &eye);
    let mut converged = false;
    for _ in 0..100 {
        let Some(si) = s.clone().try_inverse() else {
            return Err(SysidError::Numerical(
                "a pole lies on the splitting circle".into(),
            ));
        };
        let det = s.determinant().abs();
        let c = if det.is_finite() && det > 0.0 {
            det.powf(-1.0 / n as f64)
        } else {
            1.0
        };
        let next = (&s * c + si / c) * 0.5;
        let diff = (&next - &s).norm();
        s = next;
        if diff <= 1e-13 * s.norm() {
            converged = true;
            break;
        }
    }
    if !converged {
        return Err(SysidError::Numerical(
            "sign iteration did not converge (a pole lies on the splitting circle)".into(),
        ));
    }
    let p_stable = (&eye - &s) * 0.5;
    let n_stable = p_stable.trace().round().clamp(0.0, n as f64) as usize;
    let basis = |p: DMatrix<f64>, k: usize| -> Result<DMatrix<f64>> {
        let svd = p.svd(true, false);
        let u = svd
            .u
            .ok_or_else(|| SysidError::Numerical("SVD of the spectral projector failed".into()))?;
        let mut idx: Vec<usize> = (0..svd.singular_values.len()).collect();
        idx.sort_by(|x, y| svd.singular_values[*y].total_cmp(&svd.singular_values[*x]));
        Ok(DMatrix::from_fn(n, k, |r, c| u[(r, idx[c])]))
    };
    let mut t = DMatrix::zeros(n, n);
    t.columns_mut(0, n_stable)
        .copy_from(&basis(p_stable.clone(), n_stable)?);
    t.columns_mut(n_stable, n - n_stable)
        .copy_from(&basis(&eye - &p_stable, n - n_stable)?);
    let ti = t.clone().try_inverse().ok_or_else(|| {
        SysidError::Numerical("the stable and unstable subspaces are not complementary".into())
    })?;
    Ok(StableSplit { t, ti, n_stable })
}

/// Symmetric positive semi-definite square-root factor `R` with `P = R R'`
/// (from the symmetric eigendecomposition, negative eigenvalues clipped).
pub fn psd_factor(p: &DMatrix<f64>) -> DMatrix<f64> {
    let sym = (p + p.transpose()) * 0.5;
    let eig = sym.symmetric_eigen();
    let mut r = eig.eigenvectors.clone();
    for (j, l) in eig.eigenvalues.iter().enumerate() {
        let s = l.max(0.0).sqrt();
        r.column_mut(j).scale_mut(s);
    }
    r
}

/// Inverse square root of a symmetric positive definite matrix.
pub fn inv_sqrt_spd(p: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let sym = (p + p.transpose()) * 0.5;
    let eig = sym.symmetric_eigen();
    let lmax = eig.eigenvalues.max();
    let mut d = DVector::zeros(eig.eigenvalues.len());
    for (i, l) in eig.eigenvalues.iter().enumerate() {
        if *l <= lmax * 1e-12 || *l <= 0.0 {
            return Err(SysidError::Numerical(
                "matrix is not positive definite (CVA weighting: outputs linearly dependent?)"
                    .into(),
            ));
        }
        d[i] = 1.0 / l.sqrt();
    }
    let v = &eig.eigenvectors;
    Ok(v * DMatrix::from_diagonal(&d) * v.transpose())
}

/// The `R` factor (upper triangular, `k x k` with `k = min(rows, cols)`) of
/// a QR factorisation, rows made to have non-negative diagonal.
pub fn r_factor(m: DMatrix<f64>) -> DMatrix<f64> {
    let qr = m.qr();
    let mut r = qr.r();
    for i in 0..r.nrows().min(r.ncols()) {
        if r[(i, i)] < 0.0 {
            r.row_mut(i).neg_mut();
        }
    }
    r
}

/// Steady-state Kalman gain of the innovation form for
/// `x+ = A x + w`, `y = C x + v` with `cov([w; v]) = [[Q, S], [S', R]]`:
/// `K = (A P C' + S)(C P C' + R)^-1` where `P` solves the filter Riccati
/// equation `P = A P A' + Q - K (C P C' + R) K'` (iterated to convergence).
pub fn kalman_gain(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    q: &DMatrix<f64>,
    s: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<DMatrix<f64>> {
    let mut p = q.clone();
    let mut k = DMatrix::zeros(a.nrows(), c.nrows());
    for it in 0..5000 {
        let sig = c * &p * c.transpose() + r;
        let sig_inv = sig
            .clone()
            .try_inverse()
            .ok_or_else(|| SysidError::Numerical("innovation covariance is singular".into()))?;
        let kn = (a * &p * c.transpose() + s) * &sig_inv;
        let pn = a * &p * a.transpose() + q - &kn * &sig * kn.transpose();
        let pn = (&pn + pn.transpose()) * 0.5;
        let done = (&pn - &p).norm() <= 1e-12 * (1.0 + p.norm()) && it > 2;
        p = pn;
        k = kn;
        if done {
            return Ok(k);
        }
        if !p.iter().all(|v| v.is_finite()) {
            break;
        }
    }
    if k.iter().all(|v| v.is_finite()) {
        Ok(k)
    } else {
        Err(SysidError::Numerical("Riccati iteration diverged".into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigenvalues_are_core_s_and_failures_are_errors_or_unstable() {
        // Companion matrix of (z - 0.5)(z + 0.25): trace 0.25, det -0.125.
        let a = DMatrix::from_row_slice(2, 2, &[0.25, 0.125, 1.0, 0.0]);
        let mut e: Vec<f64> = eigenvalues(&a).unwrap().iter().map(|z| z.re).collect();
        e.sort_by(f64::total_cmp);
        assert!((e[0] + 0.25).abs() < 1e-15 && (e[1] - 0.5).abs() < 1e-15);
        assert!((spectral_radius(&a) - 0.5).abs() < 1e-15);
        let bad = DMatrix::from_row_slice(2, 2, &[0.5, f64::NAN, 0.0, 0.1]);
        assert!(matches!(
            eigenvalues(&bad),
            Err(SysidError::Core(kestrel_core::Error::NonFinite))
        ));
        // A stability check treats it as unstable.
        assert_eq!(spectral_radius(&bad), f64::INFINITY);
        assert!(eigenvalues(&DMatrix::zeros(2, 3)).is_err());
    }

    #[test]
    fn stable_split_block_diagonalises_and_counts_modes() {
        // Modes 1 (integrator), 1.02, 0.5, 0.9 +- 0.3i, mixed by a random basis.
        let d = DMatrix::from_row_slice(
            5,
            5,
            &[
                1.0, 0.0, 0.0, 0.0, 0.0, //
                0.0, 1.02, 0.0, 0.0, 0.0, //
                0.0, 0.0, 0.5, 0.0, 0.0, //
                0.0, 0.0, 0.0, 0.9, 0.3, //
                0.0, 0.0, 0.0, -0.3, 0.9,
            ],
        );
        let v = DMatrix::from_fn(5, 5, |r, c| {
            ((r * 7 + c * 3) % 5) as f64 + if r == c { 3.0 } else { 0.0 }
        });
        let a = &v * d * v.clone().try_inverse().unwrap();
        let sp = stable_split(&a, 1.0 - 1e-6).unwrap();
        assert_eq!(sp.n_stable, 3);
        let ab = &sp.ti * &a * &sp.t;
        let ns = sp.n_stable;
        assert!(ab.view((0, ns), (ns, 5 - ns)).amax() < 1e-9 * a.norm());
        assert!(ab.view((ns, 0), (5 - ns, ns)).amax() < 1e-9 * a.norm());
        let mut stable: Vec<f64> = eigenvalues(&ab.view((0, 0), (ns, ns)).into_owned())
            .unwrap()
            .iter()
            .map(|z| z.norm())
            .collect();
        stable.sort_by(f64::total_cmp);
        assert!((stable[0] - 0.5).abs() < 1e-9 && (stable[2] - 0.9f64.hypot(0.3)).abs() < 1e-9);
        assert!(stable_split(&DMatrix::from_element(1, 1, -0.5), 0.5).is_err());
    }

    #[test]
    fn dlyap_matches_kronecker_solution() {
        let a = DMatrix::from_row_slice(3, 3, &[0.5, 0.2, 0.0, -0.1, 0.7, 0.3, 0.0, 0.1, -0.4]);
        let b = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.5, 1.0, 0.0, 2.0]);
        let q = &b * b.transpose();
        let x = dlyap(&a, &q).unwrap();
        // Independent: (I - A kron A) vec X = vec Q.
        let n = 3;
        let mut m = DMatrix::<f64>::identity(n * n, n * n);
        m -= a.kronecker(&a);
        let vx = m
            .lu()
            .solve(&DVector::from_column_slice(q.as_slice()))
            .unwrap();
        let xk = DMatrix::from_column_slice(n, n, vx.as_slice());
        assert!((&x - &xk).norm() < 1e-12 * xk.norm());
        assert!((&a * &x * a.transpose() - &x + &q).norm() < 1e-12);
    }

    #[test]
    fn dlyap_refuses_unstable() {
        let a = DMatrix::from_row_slice(1, 1, &[1.2]);
        assert!(matches!(
            dlyap(&a, &DMatrix::identity(1, 1)),
            Err(SysidError::Unstable { .. })
        ));
    }

    #[test]
    fn pinv_of_non_finite_input_is_nan_not_a_hang() {
        let mut a = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 2.0, 4.0, 3.0, 6.0]);
        a[(1, 1)] = f64::INFINITY;
        assert!(pinv(&a).iter().all(|v| v.is_nan()));
        a[(1, 1)] = f64::NAN;
        let p = pinv(&a);
        assert_eq!(p.shape(), (2, 3));
        assert!(p.iter().all(|v| v.is_nan()));
    }

    #[test]
    fn pinv_of_rank_deficient() {
        let a = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 2.0, 4.0, 3.0, 6.0]);
        let p = pinv(&a);
        assert!((&a * &p * &a - &a).norm() < 1e-12);
        assert!((&p * &a * &p - &p).norm() < 1e-12);
    }
}
