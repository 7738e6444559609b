//! The discrete algebraic Riccati equation (feature `std`).
//!
//! Solves, for the stabilising symmetric `X`,
//!
//! ```text
//! X = A'XA - (A'XB + S)(R + B'XB)^-1 (B'XA + S') + Q
//! ```
//!
//! (SciPy's `solve_discrete_are` and python-control's `dare` with the cross
//! term `S`). This is (5.15c) of the thesis with `A -> A'`, `B -> C'`, and
//! (7.18) as corrected in the errata.
//!
//! # Method
//! 1. The cross term is removed: `Ã = A - B R^-1 S'`, `Q̃ = Q - S R^-1 S'`,
//!    `G = B R^-1 B'` (R must be positive definite; a Cholesky solve, so a
//!    condition number of 1e8 costs nothing).
//! 2. The structure-preserving doubling algorithm (SDA, Chu, Fan and Lin
//!    2005): `A_{k+1} = A_k W^-1 A_k`, `G_{k+1} = G_k + A_k W^-1 G_k A_k'`,
//!    `H_{k+1} = H_k + A_k' H_k W^-1 A_k` with `W = I + G_k H_k`, starting
//!    from `(Ã, G, Q̃)`. `H_k -> X` quadratically; only one LU per
//!    iteration, no inverse of `A` (singular `A` is fine), all buffers
//!    allocated once before the loop.
//! 3. The relative residual is checked; above
//!    [`DareSettings::refine_above`] Newton–Kleinman steps
//!    (`Ac' N Ac - N = -Res`, Stein equation solved by Smith doubling)
//!    refine `X`, keeping the best iterate.
//! 4. The closed loop `A - B K` must be stable. If the doubling fails,
//!    the PBH tests on the unstable eigenvalues of `Ã` name the culprit
//!    ([`KalmanError::NotStabilizable`], [`KalmanError::NotDetectable`]).
//!    With [`DareSettings::check_detectability`] (default) the
//!    detectability of `(Ã, Q̃)` is also checked on success, so a
//!    non-detectable problem is refused even when a stabilising solution
//!    exists.

use crate::KalmanError;
use nalgebra::{Complex, DMatrix, DVector};

/// Settings of [`dare_with`]; `Default` gives the values documented per field.
#[derive(Clone, Debug, PartialEq)]
pub struct DareSettings {
    /// Maximum number of doubling steps (each squares the convergence factor). Default 64.
    pub max_iterations: usize,
    /// The doubling stops when `||H_{k+1} - H_k||_F <= tolerance ||H_{k+1}||_F`. Default 1e-15.
    pub tolerance: f64,
    /// Newton refinement runs when the relative residual exceeds this. Default 1e-13.
    pub refine_above: f64,
    /// Maximum Newton–Kleinman refinement steps. Default 8.
    pub max_refinements: usize,
    /// A solution whose relative residual exceeds this is refused with
    /// [`KalmanError::NotConverged`]. Default 1e-9.
    pub accept_residual: f64,
    /// Check the detectability of `(Ã, Q̃)` even when the solve succeeds
    /// (costs an eigenvalue decomposition of `A`). Default `true`.
    pub check_detectability: bool,
    /// Relative tolerance of the PBH rank tests (smallest singular value of
    /// the scaled PBH matrix). Default 1e-10.
    pub pbh_tolerance: f64,
    /// Relative tolerance of the symmetry and semidefiniteness checks of the
    /// weights. Default 1e-10.
    pub symmetry_tolerance: f64,
}

impl Default for DareSettings {
    fn default() -> Self {
        DareSettings {
            max_iterations: 64,
            tolerance: 1e-15,
            refine_above: 1e-13,
            max_refinements: 8,
            accept_residual: 1e-9,
            check_detectability: true,
            pbh_tolerance: 1e-10,
            symmetry_tolerance: 1e-10,
        }
    }
}

/// The stabilising solution of the DARE.
#[derive(Clone, Debug, PartialEq)]
pub struct DareSolution {
    /// The stabilising solution `X` (symmetric positive semidefinite), `n x n`.
    pub x: DMatrix<f64>,
    /// The gain `K = (R + B'XB)^-1 (B'XA + S')`, `m x n`: `u = -K x` is optimal.
    pub gain: DMatrix<f64>,
    /// Eigenvalues of `A - B K`, all strictly inside the unit circle.
    pub closed_loop_eigenvalues: DVector<Complex<f64>>,
    /// Relative residual `||Res||_F / (||A'XA||_F + ||X||_F + ||Q||_F + ||(A'XB + S) K||_F)`
    /// where `Res = A'XA - X - (A'XB + S) K + Q`.
    pub residual: f64,
    /// Doubling iterations spent.
    pub iterations: usize,
    /// Newton refinement steps spent.
    pub refinements: usize,
}

/// Solves the DARE with default [`DareSettings`]; see the [module documentation](self).
///
/// `a` is `n x n`, `b` `n x m`, `q` `n x n` symmetric, `r` `m x m` symmetric
/// positive definite, `s` (optional cross weight) `n x m`, with
/// `[Q S; S' R]` positive semidefinite.
///
/// ```
/// use kestrel_kalman::dare;
/// use nalgebra::dmatrix;
/// // Scalar case: x = a^2 x r / (r + b^2 x) + q, a quadratic in x.
/// let (a, b, q, r) = (1.2_f64, 1.0, 1.0, 1.0);
/// let sol = dare(&dmatrix![a], &dmatrix![b], &dmatrix![q], &dmatrix![r], None).unwrap();
/// let (qa, qb, qc) = (b * b, r - a * a * r - q * b * b, -q * r);
/// let x = (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
/// assert!((sol.x[(0, 0)] - x).abs() < 1e-12);
/// assert!(sol.residual < 1e-13);
/// assert!(sol.closed_loop_eigenvalues[0].norm() < 1.0);
/// ```
pub fn dare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<DareSolution, KalmanError> {
    dare_with(a, b, q, r, s, &DareSettings::default())
}

/// [`dare`] with explicit settings.
pub fn dare_with(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
    settings: &DareSettings,
) -> Result<DareSolution, KalmanError> {
    let n = a.nrows();
    let m = b.ncols();
    check_shape("A", a, n, n)?;
    check_shape("B", b, n, m)?;
    check_shape("Q", q, n, n)?;
    check_shape("R", r, m, m)?;
    if let Some(s) = s {
        check_shape("S", s, n, m)?;
    }
    let q = symmetrized("Q", q, settings.symmetry_tolerance)?;
    let r = symmetrized("R", r, settings.symmetry_tolerance)?;
    let r_chol = r
        .clone()
        .cholesky()
        .ok_or(KalmanError::NotPositiveDefinite { name: "R" })?;

    // Remove the cross term.
    let (a_t, q_t) = match s {
        Some(s) => {
            let rinv_st = r_chol.solve(&s.transpose()); // m x n
            let a_t = a - b * &rinv_st;
            let mut q_t = &q - s * &rinv_st;
            symmetrize(&mut q_t);
            (a_t, q_t)
        }
        None => (a.clone(), q.clone()),
    };
    check_psd(
        if s.is_some() { "[Q S; S' R]" } else { "Q" },
        &q_t,
        settings.symmetry_tolerance,
    )?;
    let rinv_bt = r_chol.solve(&b.transpose());
    let mut g = b * rinv_bt;
    symmetrize(&mut g);

    if n == 0 {
        return Ok(DareSolution {
            x: DMatrix::zeros(0, 0),
            gain: DMatrix::zeros(m, 0),
            closed_loop_eigenvalues: DVector::zeros(0),
            residual: 0.0,
            iterations: 0,
            refinements: 0,
        });
    }

    let sda = sda(&a_t, &g, &q_t, settings);
    let (x, iterations) = match sda {
        Some(v) => v,
        None => {
            return Err(diagnose(
                &a_t,
                b,
                &q_t,
                settings,
                "the doubling iteration diverged or stagnated",
            ));
        }
    };

    let problem = Problem {
        a,
        b,
        q: &q,
        r: &r,
        s,
    };
    let mut best = problem.evaluate(x);
    let mut refinements = 0;
    while best.residual > settings.refine_above && refinements < settings.max_refinements {
        refinements += 1;
        let Some(ac) = best.closed_loop() else { break };
        let Some(step) = stein_smith(&ac, &best.res, 64) else {
            break;
        };
        let mut x = &best.x + step;
        symmetrize(&mut x);
        let cand = problem.evaluate(x);
        if cand.residual.is_finite() && cand.residual < best.residual {
            best = cand;
        } else {
            break;
        }
    }
    if !best.residual.is_finite() || best.residual > settings.accept_residual {
        if !best.residual.is_finite() {
            return Err(diagnose(
                &a_t,
                b,
                &q_t,
                settings,
                "the solution is not finite",
            ));
        }
        return Err(KalmanError::NotConverged {
            iterations: iterations + refinements,
            residual: best.residual,
        });
    }
    let ac = best.closed_loop().unwrap_or_else(|| a.clone());
    let eig = ac.complex_eigenvalues();
    let rho = eig.iter().map(|z| z.norm()).fold(0.0, f64::max);
    if rho.is_nan() || rho >= 1.0 {
        return Err(diagnose(
            &a_t,
            b,
            &q_t,
            settings,
            &format!("the closed loop A - BK has spectral radius {rho:.6} >= 1"),
        ));
    }
    if settings.check_detectability
        && let Some(e) = pbh(&a_t, b, &q_t, settings.pbh_tolerance, false, true)
    {
        return Err(e);
    }
    Ok(DareSolution {
        x: best.x,
        gain: best.k,
        closed_loop_eigenvalues: eig,
        residual: best.residual,
        iterations,
        refinements,
    })
}

/// The original (cross-term) problem, for residual evaluation.
struct Problem<'a> {
    a: &'a DMatrix<f64>,
    b: &'a DMatrix<f64>,
    q: &'a DMatrix<f64>,
    r: &'a DMatrix<f64>,
    s: Option<&'a DMatrix<f64>>,
}

/// An iterate with its gain and residual.
struct Evaluated<'a> {
    x: DMatrix<f64>,
    k: DMatrix<f64>,
    res: DMatrix<f64>,
    residual: f64,
    a: &'a DMatrix<f64>,
    b: &'a DMatrix<f64>,
}

impl Evaluated<'_> {
    fn closed_loop(&self) -> Option<DMatrix<f64>> {
        let ac = self.a - self.b * &self.k;
        ac.iter().all(|v| v.is_finite()).then_some(ac)
    }
}

impl<'a> Problem<'a> {
    fn evaluate(&self, x: DMatrix<f64>) -> Evaluated<'a> {
        let btx = self.b.transpose() * &x; // m x n
        let mut rb = self.r + &btx * self.b;
        symmetrize(&mut rb);
        let mut rhs = &btx * self.a; // B'XA, m x n
        if let Some(s) = self.s {
            rhs += s.transpose();
        }
        let k = match rb.clone().cholesky() {
            Some(c) => c.solve(&rhs),
            None => rb
                .lu()
                .solve(&rhs)
                .unwrap_or_else(|| DMatrix::from_element(rhs.nrows(), rhs.ncols(), f64::NAN)),
        };
        let xa = &x * self.a;
        let atxa = self.a.transpose() * xa;
        let term = rhs.transpose() * &k;
        let mut res = &atxa - &x + self.q - &term;
        symmetrize(&mut res);
        let scale = atxa.norm() + x.norm() + self.q.norm() + term.norm();
        let residual = if scale > 0.0 {
            res.norm() / scale
        } else {
            res.norm()
        };
        Evaluated {
            x,
            k,
            res,
            residual: if residual.is_finite() {
                residual
            } else {
                f64::INFINITY
            },
            a: self.a,
            b: self.b,
        }
    }
}

/// Solves the Stein equation `X = Ac' X Ac + C` (stable `Ac`) by Smith doubling:
/// `X_{j+1} = X_j + M_j' X_j M_j`, `M_{j+1} = M_j^2`.
pub(crate) fn stein_smith(
    ac: &DMatrix<f64>,
    c: &DMatrix<f64>,
    max_doublings: usize,
) -> Option<DMatrix<f64>> {
    let mut x = c.clone();
    let mut mk = ac.clone();
    for _ in 0..max_doublings {
        let inc = mk.transpose() * &x * &mk;
        let done = inc.norm() <= 1e-17 * x.norm() || inc.norm() == 0.0;
        x += inc;
        if !x.iter().all(|v| v.is_finite()) {
            return None;
        }
        if done {
            symmetrize(&mut x);
            return Some(x);
        }
        mk = &mk * &mk;
    }
    None
}

/// The doubling iteration; `None` when it breaks down or does not converge.
fn sda(
    a0: &DMatrix<f64>,
    g0: &DMatrix<f64>,
    h0: &DMatrix<f64>,
    settings: &DareSettings,
) -> Option<(DMatrix<f64>, usize)> {
    let n = a0.nrows();
    let mut a = a0.clone();
    let mut g = g0.clone();
    let mut h = h0.clone();
    let mut at = DMatrix::zeros(n, n);
    let mut w = DMatrix::zeros(n, n);
    let mut y1 = DMatrix::zeros(n, n);
    let mut y3 = DMatrix::zeros(n, n);
    let mut t = DMatrix::zeros(n, n);
    let mut d = DMatrix::zeros(n, n);
    let mut piv = vec![0usize; n];
    for it in 1..=settings.max_iterations {
        a.transpose_to(&mut at);
        // W = I + G H
        w.gemm(1.0, &g, &h, 0.0);
        for i in 0..n {
            w[(i, i)] += 1.0;
        }
        if !lu_factor(&mut w, &mut piv) {
            return None;
        }
        // Y1 = W^-1 A, Y3 = W^-1 G A'
        y1.copy_from(&a);
        y3.gemm(1.0, &g, &at, 0.0);
        lu_solve(&w, &piv, &mut y1);
        lu_solve(&w, &piv, &mut y3);
        // H += A' H W^-1 A
        t.gemm(1.0, &h, &y1, 0.0);
        d.gemm(1.0, &at, &t, 0.0);
        h += &d;
        symmetrize(&mut h);
        // G += A W^-1 G A'
        g.gemm(1.0, &a, &y3, 1.0);
        symmetrize(&mut g);
        // A = A W^-1 A
        t.gemm(1.0, &a, &y1, 0.0);
        std::mem::swap(&mut a, &mut t);
        let dn = d.norm();
        let hn = h.norm();
        if !(dn.is_finite() && hn.is_finite()) {
            return None;
        }
        if dn <= settings.tolerance * hn {
            return Some((h, it));
        }
    }
    None
}

/// In-place LU with partial pivoting of a square column-major matrix.
/// Returns `false` on a zero or non-finite pivot.
fn lu_factor(w: &mut DMatrix<f64>, piv: &mut [usize]) -> bool {
    let n = w.nrows();
    let data = w.as_mut_slice();
    for k in 0..n {
        let col = &data[k * n..(k + 1) * n];
        let mut p = k;
        let mut best = col[k].abs();
        for (i, v) in col.iter().enumerate().skip(k + 1) {
            if v.abs() > best {
                best = v.abs();
                p = i;
            }
        }
        if best == 0.0 || !best.is_finite() {
            return false;
        }
        piv[k] = p;
        if p != k {
            for j in 0..n {
                data.swap(j * n + k, j * n + p);
            }
        }
        let pivot = data[k * n + k];
        let inv = 1.0 / pivot;
        for v in &mut data[k * n + k + 1..(k + 1) * n] {
            *v *= inv;
        }
        let (left, right) = data.split_at_mut((k + 1) * n);
        let lcol = &left[k * n + k + 1..(k + 1) * n];
        for j in 0..n - k - 1 {
            let col = &mut right[j * n..(j + 1) * n];
            let ukj = col[k];
            if ukj != 0.0 {
                for (c, l) in col[k + 1..].iter_mut().zip(lcol) {
                    *c -= l * ukj;
                }
            }
        }
    }
    true
}

/// Solves `W X = B` in place with the factors of [`lu_factor`].
fn lu_solve(w: &DMatrix<f64>, piv: &[usize], b: &mut DMatrix<f64>) {
    let n = w.nrows();
    let lu = w.as_slice();
    let ncols = b.ncols();
    let data = b.as_mut_slice();
    for c in 0..ncols {
        let x = &mut data[c * n..(c + 1) * n];
        for (k, &p) in piv.iter().enumerate() {
            if p != k {
                x.swap(k, p);
            }
        }
        for k in 0..n {
            let xk = x[k];
            if xk != 0.0 {
                for (xi, l) in x[k + 1..].iter_mut().zip(&lu[k * n + k + 1..(k + 1) * n]) {
                    *xi -= l * xk;
                }
            }
        }
        for k in (0..n).rev() {
            x[k] /= lu[k * n + k];
            let xk = x[k];
            if xk != 0.0 {
                for (xi, u) in x[..k].iter_mut().zip(&lu[k * n..k * n + k]) {
                    *xi -= u * xk;
                }
            }
        }
    }
}

pub(crate) fn symmetrize(m: &mut DMatrix<f64>) {
    let n = m.nrows();
    for j in 0..n {
        for i in 0..j {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}

pub(crate) fn check_shape(
    name: &'static str,
    m: &DMatrix<f64>,
    rows: usize,
    cols: usize,
) -> Result<(), KalmanError> {
    if m.shape() != (rows, cols) {
        return Err(KalmanError::DimensionMismatch {
            name,
            expected_rows: rows,
            expected_cols: cols,
            found_rows: m.nrows(),
            found_cols: m.ncols(),
        });
    }
    if let Some(i) = m.iter().position(|v| !v.is_finite()) {
        return Err(KalmanError::NonFinite {
            name,
            row: i % rows.max(1),
            col: i / rows.max(1),
        });
    }
    Ok(())
}

pub(crate) fn symmetrized(
    name: &'static str,
    m: &DMatrix<f64>,
    tol: f64,
) -> Result<DMatrix<f64>, KalmanError> {
    let norm = m.norm();
    let asym = (m - m.transpose()).norm();
    if asym > tol * norm {
        return Err(KalmanError::NotSymmetric {
            name,
            asymmetry: asym / norm,
        });
    }
    let mut s = m.clone();
    symmetrize(&mut s);
    Ok(s)
}

/// Positive semidefiniteness up to `tol ||M||`, by a Cholesky attempt of
/// the shifted matrix (cheap); the eigenvalue is computed only for the message.
pub(crate) fn check_psd(name: &'static str, m: &DMatrix<f64>, tol: f64) -> Result<(), KalmanError> {
    let n = m.nrows();
    let norm = m.norm();
    if n == 0 || norm == 0.0 {
        return Ok(());
    }
    let shifted = m + DMatrix::identity(n, n) * (tol * norm + f64::MIN_POSITIVE);
    if shifted.cholesky().is_some() {
        return Ok(());
    }
    let min_eigenvalue = m.clone().symmetric_eigenvalues().min();
    Err(KalmanError::NotPositiveSemidefinite {
        name,
        min_eigenvalue,
    })
}

/// Explains a failure with the PBH tests, or reports `reason`.
fn diagnose(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    settings: &DareSettings,
    reason: &str,
) -> KalmanError {
    pbh(a, b, q, settings.pbh_tolerance, true, true).unwrap_or_else(|| {
        KalmanError::NoStabilizingSolution {
            reason: format!(
                "{reason}; (A, B) passes the stabilisability and (A, Q) the detectability PBH tests, so a mode is probably on (or numerically at) the unit circle"
            ),
        }
    })
}

/// PBH tests on the eigenvalues of `a` with `|lambda| >= 1 - 1e-9`:
/// `rank [A - lambda I, B] < n` (not stabilisable) and
/// `rank [A - lambda I; Q] < n` (not detectable), each block scaled to unit norm.
fn pbh(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    tol: f64,
    stabilizability: bool,
    detectability: bool,
) -> Option<KalmanError> {
    let n = a.nrows();
    let an = a.norm().max(f64::MIN_POSITIVE);
    let eig = a.complex_eigenvalues();
    let mut seen: Vec<Complex<f64>> = Vec::new();
    for &lambda in eig.iter() {
        if lambda.norm() < 1.0 - 1e-9 || lambda.im < 0.0 {
            continue;
        }
        if seen.iter().any(|z| (z - lambda).norm() <= 1e-9 * an) {
            continue;
        }
        seen.push(lambda);
        let shifted = DMatrix::from_fn(n, n, |i, j| {
            Complex::new(a[(i, j)] / an, 0.0)
                - if i == j {
                    lambda / an
                } else {
                    Complex::new(0.0, 0.0)
                }
        });
        if stabilizability {
            let m = b.ncols();
            let bn = b.norm();
            let mut mat = DMatrix::<Complex<f64>>::zeros(n, n + m);
            mat.columns_mut(0, n).copy_from(&shifted);
            if bn > 0.0 {
                for j in 0..m {
                    for i in 0..n {
                        mat[(i, n + j)] = Complex::new(b[(i, j)] / bn, 0.0);
                    }
                }
            }
            let sv = mat.singular_values();
            if sv.min() <= tol {
                return Some(KalmanError::NotStabilizable { eigenvalue: lambda });
            }
        }
        if detectability {
            let qn = q.norm();
            let mut mat = DMatrix::<Complex<f64>>::zeros(2 * n, n);
            mat.rows_mut(0, n).copy_from(&shifted);
            if qn > 0.0 {
                for j in 0..n {
                    for i in 0..n {
                        mat[(n + i, j)] = Complex::new(q[(i, j)] / qn, 0.0);
                    }
                }
            }
            let sv = mat.singular_values();
            if sv.min() <= tol {
                return Some(KalmanError::NotDetectable { eigenvalue: lambda });
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lu_matches_nalgebra() {
        let n = 7;
        let w0 = DMatrix::from_fn(n, n, |i, j| {
            ((i * 7 + j * 3) % 11) as f64 - 5.0 + if i == j { 0.5 } else { 0.0 }
        });
        let b0 = DMatrix::from_fn(n, 3, |i, j| (i + 2 * j) as f64);
        let mut w = w0.clone();
        let mut piv = vec![0; n];
        assert!(lu_factor(&mut w, &mut piv));
        let mut x = b0.clone();
        lu_solve(&w, &piv, &mut x);
        assert!((&w0 * &x - &b0).norm() < 1e-10 * b0.norm());
        let mut z = DMatrix::<f64>::zeros(3, 3);
        assert!(!lu_factor(&mut z, &mut [0; 3]));
    }
}
