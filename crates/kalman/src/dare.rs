//! The discrete algebraic Riccati equation (feature `std`).
//!
//! See [`dare`] for the equation and the method.

use crate::KalmanError;
use nalgebra::{Complex, DMatrix, DVector};

/// Settings of [`dare_with`]; `Default` gives the values documented per field.
#[derive(Clone, Debug, PartialEq)]
pub struct DareSettings {
    /// Maximum number of doubling steps (each squares the convergence factor). Default 64.
    pub max_iterations: usize,
    /// The doubling stops when `||H_{k+1} - H_k||_F <= tolerance ||H_{k+1}||_F`,
    /// or when the quadratic convergence predicts that the next relative
    /// increment (`delta_k^3 / delta_{k-1}^2`) is below it; a solve stopped
    /// by the prediction that then fails (residual, stability) is redone
    /// without it. Default 1e-15.
    pub tolerance: f64,
    /// Newton refinement runs when the relative residual exceeds this. Default 1e-13.
    pub refine_above: f64,
    /// Maximum Newton–Kleinman refinement steps. Default 8.
    pub max_refinements: usize,
    /// A solution whose relative residual exceeds this is refused with
    /// [`KalmanError::NotConverged`]. Default 1e-9.
    pub accept_residual: f64,
    /// When to run the PBH detectability test of `(Ã, Q̃)` after a
    /// successful doubling. Default [`DetectabilityCheck::OnGrowth`].
    pub detectability: DetectabilityCheck,
    /// `||G_k||_F / ||G_0||_F` above which [`DetectabilityCheck::OnGrowth`]
    /// runs the PBH test. Default 1e8.
    pub growth_limit: f64,
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
            detectability: DetectabilityCheck::OnGrowth,
            growth_limit: 1e8,
            pbh_tolerance: 1e-10,
            symmetry_tolerance: 1e-10,
        }
    }
}

/// When [`dare_with`] runs the PBH detectability test after a successful solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DetectabilityCheck {
    /// On every solve.
    Always,
    /// When the dual iterate `G_k` has grown by more than
    /// [`DareSettings::growth_limit`] (the symptom of an unobservable
    /// unstable mode; see [`dare`]).
    #[default]
    OnGrowth,
    /// Never (failures of the doubling are still diagnosed).
    Never,
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

/// Solves the DARE with default [`DareSettings`].
///
/// Solves, for the stabilising symmetric `X`,
///
/// ```text
/// X = A'XA - (A'XB + S)(R + B'XB)^-1 (B'XA + S') + Q
/// ```
///
/// (SciPy's `solve_discrete_are` and python-control's `dare` with the cross
/// term `S`). This is (5.15c) of the thesis with `A -> A'`, `B -> C'`, and
/// (7.18) as corrected in the errata.
///
/// # Method
/// 1. The cross term is removed: `Ã = A - B R^-1 S'`, `Q̃ = Q - S R^-1 S'`,
///    `G = B R^-1 B'` (R must be positive definite; a Cholesky solve, so a
///    condition number of 1e8 costs nothing).
/// 2. The structure-preserving doubling algorithm (SDA, Chu, Fan and Lin
///    2005): `A_{k+1} = A_k W^-1 A_k`, `G_{k+1} = G_k + A_k W^-1 G_k A_k'`,
///    `H_{k+1} = H_k + A_k' H_k W^-1 A_k` with `W = I + G_k H_k`, starting
///    from `(Ã, G, Q̃)`. `H_k -> X` quadratically; only one LU per
///    iteration, no inverse of `A` (singular `A` is fine), all buffers
///    allocated once before the loop.
/// 3. The relative residual is checked; above
///    [`DareSettings::refine_above`] Newton–Kleinman steps
///    (`Ac' N Ac - N = -Res`, Stein equation solved by Smith doubling)
///    refine `X`, keeping the best iterate.
/// 4. The closed loop `A - B K` must be stable. If the doubling fails,
///    the PBH tests on the unstable eigenvalues of `Ã` name the culprit
///    ([`KalmanError::NotStabilizable`], [`KalmanError::NotDetectable`]).
///    A non-detectable `(Ã, Q̃)` is refused even when a stabilising
///    solution exists: in the doubling `G_k` converges to the solution of
///    the dual equation, which exists only for a detectable pair, so an
///    unobservable unstable mode `lambda` makes `G_k` grow like
///    `|lambda|^(2^k)` and overflow or, by the time `H_k` has converged,
///    grow by orders of magnitude. [`DetectabilityCheck::OnGrowth`]
///    (default) runs the PBH test when `||G_k|| / ||G_0||` exceeds
///    [`DareSettings::growth_limit`]; [`DetectabilityCheck::Always`] runs
///    it on every solve (an eigenvalue decomposition of `A` and an SVD per
///    unstable eigenvalue: it triples the time at n = 60).
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
    // `q_t` is tested up to the size of what formed it: with perfectly
    // correlated noise (an innovations model, `Q = S = R`) it is zero up to
    // the rounding of `S R^-1 S'`, which must not read as indefinite.
    let (a_t, q_t, scale) = match s {
        Some(s) => {
            let rinv_st = r_chol.solve(&s.transpose()); // m x n
            let a_t = a - b * &rinv_st;
            let removed = s * &rinv_st;
            let mut q_t = &q - &removed;
            symmetrize(&mut q_t);
            let scale = q.norm() + removed.norm();
            (a_t, q_t, scale)
        }
        None => (a.clone(), q.clone(), q.norm()),
    };
    check_psd(
        if s.is_some() { "[Q S; S' R]" } else { "Q" },
        &q_t,
        settings.symmetry_tolerance,
        scale,
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

    let problem = Problem {
        a,
        b,
        q: &q,
        r: &r,
        s,
    };
    let reduced = Reduced {
        a_t: &a_t,
        q_t: &q_t,
    };
    // The doubling may stop one step early where its quadratic convergence
    // predicts the next increment below the tolerance. Before a mode close
    // to the unit circle takes hold the increments can pause (1e-6 at the
    // third step, then grow a hundredfold), and the prediction then stops
    // at an `X` that does not stabilise: that solve is redone to the end.
    let mut sda_result = sda(&a_t, &g, &q_t, settings, true);
    loop {
        let Some((x, iterations, growth, predicted)) = sda_result else {
            return Err(diagnose(
                &a_t,
                b,
                &q_t,
                settings,
                "the doubling iteration diverged or stagnated",
            ));
        };
        match finish(&problem, &reduced, x, iterations, growth, settings) {
            Err(_) if predicted => sda_result = sda(&a_t, &g, &q_t, settings, false),
            done => return done,
        }
    }
}

/// `Ã` and `Q̃` of the problem without its cross term (the PBH tests').
struct Reduced<'a> {
    a_t: &'a DMatrix<f64>,
    q_t: &'a DMatrix<f64>,
}

/// Steps 3 and 4 of [`dare_with`] on the doubling's `x`: Newton refinement,
/// the residual, the closed loop's stability and the detectability test.
fn finish(
    problem: &Problem<'_>,
    reduced: &Reduced<'_>,
    x: DMatrix<f64>,
    iterations: usize,
    growth: f64,
    settings: &DareSettings,
) -> Result<DareSolution, KalmanError> {
    let (a, b) = (problem.a, problem.b);
    let (a_t, q_t) = (reduced.a_t, reduced.q_t);
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
                a_t,
                b,
                q_t,
                settings,
                "the solution is not finite",
            ));
        }
        // A residual far from zero usually has a structural cause (a mode
        // the input cannot move or the weight cannot see): name it if the
        // PBH tests find one, else report the convergence failure.
        if let Some(e) = pbh(a_t, b, q_t, settings.pbh_tolerance, true, true) {
            return Err(e);
        }
        return Err(KalmanError::NotConverged {
            iterations: iterations + refinements,
            residual: best.residual,
        });
    }
    let ac = best.closed_loop().unwrap_or_else(|| a.clone());
    let Some(eig) = eigenvalues(&ac) else {
        return Err(KalmanError::NoStabilizingSolution {
            reason: "the eigenvalues of the closed loop A - BK could not be computed (Schur iteration limit)".into(),
        });
    };
    let rho = eig.iter().map(|z| z.norm()).fold(0.0, f64::max);
    if rho.is_nan() || rho >= 1.0 {
        return Err(diagnose(
            a_t,
            b,
            q_t,
            settings,
            &format!(
                "the closed loop A - BK has spectral radius {} >= 1",
                crate::error::Num(rho)
            ),
        ));
    }
    let run_pbh = match settings.detectability {
        DetectabilityCheck::Always => true,
        DetectabilityCheck::OnGrowth => growth.is_nan() || growth > settings.growth_limit,
        DetectabilityCheck::Never => false,
    };
    if run_pbh && let Some(e) = pbh(a_t, b, q_t, settings.pbh_tolerance, false, true) {
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

/// The doubling iteration: `H_k`, the iterations, the growth of `G_k` and
/// whether it stopped by the predicted increment (only when `predict`);
/// `None` when it breaks down or does not converge.
fn sda(
    a0: &DMatrix<f64>,
    g0: &DMatrix<f64>,
    h0: &DMatrix<f64>,
    settings: &DareSettings,
    predict: bool,
) -> Option<(DMatrix<f64>, usize, f64, bool)> {
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
    let mut tmp = vec![0.0; n];
    let mut previous_delta = 0.0f64;
    for it in 1..=settings.max_iterations {
        a.transpose_to(&mut at);
        // W = I + G H
        g.mul_to(&h, &mut w);
        for i in 0..n {
            w[(i, i)] += 1.0;
        }
        // W^-1 explicitly: the products below are then plain matrix products.
        if !invert_in_place(&mut w, &mut piv, &mut tmp) {
            return None;
        }
        // Y1 = W^-1 A;  H += A' H W^-1 A
        w.mul_to(&a, &mut y1);
        h.mul_to(&y1, &mut t);
        at.mul_to(&t, &mut d);
        h += &d;
        symmetrize(&mut h);
        let dn = d.norm();
        let hn = h.norm();
        if !(dn.is_finite() && hn.is_finite()) {
            return None;
        }
        // Stop when the increment is below the tolerance, or when the
        // quadratic convergence of the doubling predicts that the next one
        // would be: increments behave like `delta_{k+1} = c delta_k^2`, with
        // `c` estimated from the last two as `delta_k / delta_{k-1}^2`. This
        // saves the last doubling step (the residual is checked afterwards
        // and refined by Newton steps if it is not small enough).
        let delta = dn / hn.max(f64::MIN_POSITIVE);
        let predicted = if predict && previous_delta > 0.0 && delta < 1e-3 {
            delta * delta * (delta / (previous_delta * previous_delta))
        } else {
            f64::INFINITY
        };
        previous_delta = delta;
        if dn <= settings.tolerance * hn || predicted <= settings.tolerance {
            // (G and A of the last step are not needed: stop before them.)
            let g0 = g0.norm();
            let growth = if g0 > 0.0 { g.norm() / g0 } else { 0.0 };
            return Some((h, it, growth, dn > settings.tolerance * hn));
        }
        // Y3 = W^-1 G A';  G += A W^-1 G A'
        g.mul_to(&at, &mut t);
        w.mul_to(&t, &mut y3);
        a.mul_to(&y3, &mut t);
        g += &t;
        symmetrize(&mut g);
        if !g.iter().all(|v| v.is_finite()) {
            return None;
        }
        // A = A W^-1 A
        a.mul_to(&y1, &mut t);
        std::mem::swap(&mut a, &mut t);
    }
    None
}

/// In-place inverse of a square column-major matrix by Gauss–Jordan
/// elimination with partial pivoting. Every inner loop is a contiguous
/// column update (vectorises well). `piv` holds `n` entries, `tmp` `n`
/// entries of scratch. Returns `false` on a zero or non-finite pivot.
fn invert_in_place(w: &mut DMatrix<f64>, piv: &mut [usize], tmp: &mut [f64]) -> bool {
    let n = w.nrows();
    let data = w.as_mut_slice();
    for k in 0..n {
        // Pivot search in column k, rows k..n.
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
        let inv = 1.0 / data[k * n + k];
        // tmp = column k with a zero in row k; column k becomes -col/pivot.
        tmp.copy_from_slice(&data[k * n..(k + 1) * n]);
        tmp[k] = 0.0;
        for j in 0..n {
            if j == k {
                continue;
            }
            let col = &mut data[j * n..(j + 1) * n];
            let f = col[k] * inv;
            if f != 0.0 {
                for (c, t) in col.iter_mut().zip(tmp.iter()) {
                    *c -= t * f;
                }
            }
            col[k] = f;
        }
        let colk = &mut data[k * n..(k + 1) * n];
        for (c, t) in colk.iter_mut().zip(tmp.iter()) {
            *c = -t * inv;
        }
        colk[k] = inv;
    }
    // Undo the row interchanges as column interchanges, in reverse order.
    for k in (0..n).rev() {
        let p = piv[k];
        if p != k {
            for i in 0..n {
                data.swap(k * n + i, p * n + i);
            }
        }
    }
    true
}

/// Eigenvalues of a real square matrix, or `None` when they cannot be
/// computed: [`kestrel_core::eig::eigenvalues`] (balancing, Hessenberg,
/// Francis double shift with an iteration limit, Schur fallbacks), which
/// replaced nalgebra's `complex_eigenvalues` after it cycled for ever on a
/// Kalman closed loop with repeated decoupled modes (see
/// `dare_tests::repeated_decoupled_modes_do_not_hang`).
pub(crate) fn eigenvalues(m: &DMatrix<f64>) -> Option<DVector<Complex<f64>>> {
    kestrel_core::eig::eigenvalues(m).ok()
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

/// Positive semidefiniteness up to `tol max(||M||, scale)` (`scale`: the
/// size of the matrices `M` was computed from), by a Cholesky attempt of
/// the shifted matrix (cheap); the eigenvalue is computed only for the message.
pub(crate) fn check_psd(
    name: &'static str,
    m: &DMatrix<f64>,
    tol: f64,
    scale: f64,
) -> Result<(), KalmanError> {
    let n = m.nrows();
    let norm = m.norm().max(scale);
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
    let Some(eig) = eigenvalues(a) else {
        return Some(KalmanError::NoStabilizingSolution {
            reason: "the eigenvalues of A could not be computed for the PBH tests (Schur iteration limit)".into(),
        });
    };
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
    fn gauss_jordan_inverse() {
        for n in [1usize, 2, 5, 17, 40] {
            let w0 = DMatrix::from_fn(n, n, |i, j| {
                ((i * 7 + j * 3) % 11) as f64 - 5.0 + if i == j { 0.5 } else { 0.0 }
            });
            let mut w = w0.clone();
            let (mut piv, mut tmp) = (vec![0; n], vec![0.0; n]);
            assert!(invert_in_place(&mut w, &mut piv, &mut tmp));
            let err = (&w0 * &w - DMatrix::identity(n, n)).norm();
            assert!(err < 1e-10, "n={n}: {err:e}");
        }
        let mut z = DMatrix::<f64>::zeros(3, 3);
        assert!(!invert_in_place(&mut z, &mut [0; 3], &mut [0.0; 3]));
    }
}
