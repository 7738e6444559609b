//! The multi-parametric QP solver: critical regions by facet-to-facet exploration.
//!
//! For an active set `A` whose rows `G_A` are linearly independent (LICQ),
//! the KKT conditions give the affine laws (ERRATA's corrected (6.27c)/(6.28),
//! with the constant linear term `f`):
//!
//! ```text
//! lambda_A(theta) = -(G_A H^-1 G_A')^-1 (W_A + E_A theta + G_A H^-1 (F'theta + f))
//! z(theta)        = -H^-1 (F'theta + f + G_A' lambda_A(theta))
//! ```
//!
//! and the critical region `{theta in Theta : lambda_A >= 0, G_i z <= W_i + E_i theta (i not in A)}`.
//! The exploration starts from the optimal active set at an interior
//! feasible parameter and crosses every facet of every region: a facet
//! where constraint `i` becomes active leads to `A + {i}`, a facet where
//! `lambda_j` reaches zero to `A - {j}`. The guess is checked at a point just
//! beyond the facet; when it fails (degeneracy: LICQ violated, weakly active
//! constraints, coincident facets), the QP is solved at that point and every
//! linearly independent subset of its active constraints that represents the
//! optimum is tried. Exact duplicate constraints (move blocking produces
//! them) are removed beforehand; constraints without `z` become parameter
//! constraints. Regions whose inscribed ball is smaller than
//! [`Settings::radius_tol`] are lower-dimensional and discarded.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::error::EmpcError;
use crate::lp::{LpStatus, LpWorkspace, slack_start};
use crate::qp;
use kestrel_core::formats::MpqpProblem;
use nalgebra::{DMatrix, DVector};
use std::collections::HashMap;

/// Settings of the mpQP solver.
#[derive(Clone, Debug)]
pub struct Settings {
    /// A region (or facet) whose largest inscribed ball has a radius below
    /// `radius_tol * max(1, |theta bounds|)` counts as lower-dimensional.
    pub radius_tol: f64,
    /// Step beyond a facet (relative to the parameter scale) to probe the neighbour.
    pub step: f64,
    /// Stop with [`EmpcError::TooManyRegions`] beyond this many regions.
    pub max_regions: usize,
    /// In degenerate points, try all subsets of at most this many active constraints.
    pub max_degenerate_set: usize,
    /// Explore in parallel (needs the `parallel` feature; ignored otherwise).
    pub parallel: bool,
    /// Show a progress bar on standard error (needs the `progress` feature).
    pub progress: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            radius_tol: 1e-8,
            step: 1e-6,
            max_regions: 200_000,
            max_degenerate_set: 12,
            parallel: true,
            progress: false,
        }
    }
}

/// One critical region: `theta` with `a theta <= b` has the optimal active
/// set `active_set` and the optimiser `z = fz theta + gz`.
#[derive(Clone, Debug, PartialEq)]
pub struct CriticalRegion {
    /// Indices of the active constraints (rows of the problem's `G`).
    pub active_set: Vec<usize>,
    /// Half-space normals, one non-redundant facet per row, unit length.
    pub a: DMatrix<f64>,
    /// Half-space offsets.
    pub b: DVector<f64>,
    /// Gain of the optimiser, `n x p`.
    pub fz: DMatrix<f64>,
    /// Offset of the optimiser, `n`.
    pub gz: DVector<f64>,
    /// Centre of the largest ball inside the region.
    pub center: DVector<f64>,
    /// Radius of that ball.
    pub radius: f64,
}

impl CriticalRegion {
    /// Whether `theta` satisfies every half-space within `tol`.
    pub fn contains(&self, theta: &[f64], tol: f64) -> bool {
        (0..self.a.nrows()).all(|i| {
            let s: f64 = (0..self.a.ncols()).map(|j| self.a[(i, j)] * theta[j]).sum();
            s <= self.b[i] + tol
        })
    }
    /// The optimiser `fz theta + gz`.
    pub fn z(&self, theta: &[f64]) -> DVector<f64> {
        &self.fz * DVector::from_column_slice(theta) + &self.gz
    }
}

/// Counters of a solve.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SolveStats {
    /// Active sets whose region was computed.
    pub active_sets_tested: usize,
    /// Of those, how many were lower-dimensional, empty or violated LICQ.
    pub discarded: usize,
    /// QP solves at probe points where the facet rule failed (degeneracy).
    pub fallback_qps: usize,
    /// LPs solved.
    pub lps: usize,
    /// Constraint rows removed as exact duplicates of another row.
    pub duplicate_rows: usize,
    /// Wall-clock seconds of the solve (measured inside [`solve`]).
    pub solve_seconds: f64,
}

/// The explicit solution: all full-dimensional critical regions.
#[derive(Clone, Debug)]
pub struct MpqpSolution {
    /// Number of decision variables.
    pub n: usize,
    /// Number of parameters.
    pub p: usize,
    /// The regions.
    pub regions: Vec<CriticalRegion>,
    /// The explored set (parameters with a feasible QP) is the parameter box
    /// intersected with `hull_a theta <= hull_b`.
    pub hull_a: DMatrix<f64>,
    /// Offsets of the explored set.
    pub hull_b: DVector<f64>,
    /// Lower corner of the parameter box.
    pub theta_lb: DVector<f64>,
    /// Upper corner of the parameter box.
    pub theta_ub: DVector<f64>,
    /// Counters and timing.
    pub stats: SolveStats,
}

impl MpqpSolution {
    /// The index of the first region containing `theta` (within `tol`).
    pub fn locate(&self, theta: &[f64], tol: f64) -> Option<usize> {
        self.regions.iter().position(|r| r.contains(theta, tol))
    }

    /// The first `k` entries of the optimiser `fz theta + gz` of the first
    /// region containing `theta`, each half-space `a_i theta <= b_i` allowed
    /// the relative slack `1e-9 (1 + |b_i|)`: the solution's own answer, the
    /// reference a search tree is checked against. `None` where no region
    /// contains `theta`, or where `theta.len() != p` or `k > n`.
    ///
    /// ```
    /// use kestrel_core::formats::MpqpProblem;
    /// use kestrel_empc::{Settings, solve};
    ///
    /// // min 1/2 z^2 + theta z on |z| <= 1: z = clamp(-theta).
    /// let prob = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
    ///   "H": [[1]], "F": [[1]], "G": [[1], [-1]], "W": [1, 1],
    ///   "E": [[0], [0]], "theta_lb": [-3], "theta_ub": [3]}"#).unwrap();
    /// let sol = solve(&prob, &Settings::default()).unwrap();
    /// assert!((sol.first_outputs_at(&[0.5], 1).unwrap()[0] + 0.5).abs() < 1e-12);
    /// assert_eq!(sol.first_outputs_at(&[2.0], 1).unwrap(), vec![-1.0]);
    /// assert!(sol.first_outputs_at(&[0.5, 0.0], 1).is_none());
    /// ```
    pub fn first_outputs_at(&self, theta: &[f64], k: usize) -> Option<Vec<f64>> {
        if theta.len() != self.p || k > self.n {
            return None;
        }
        let r = self.regions.iter().find(|r| {
            (0..r.a.nrows()).all(|i| {
                let v: f64 = (0..theta.len()).map(|j| r.a[(i, j)] * theta[j]).sum();
                v <= r.b[i] + 1e-9 * (1.0 + r.b[i].abs())
            })
        })?;
        Some(
            (0..k)
                .map(|o| {
                    r.gz[o]
                        + (0..theta.len())
                            .map(|j| r.fz[(o, j)] * theta[j])
                            .sum::<f64>()
                })
                .collect(),
        )
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Origin {
    Primal(usize),
    Dual(usize),
    Param,
}

/// The problem after validation and preprocessing.
pub(crate) struct Prepared {
    pub n: usize,
    pub p: usize,
    pub m: usize,
    pub h: DMatrix<f64>,
    pub hinv: DMatrix<f64>,
    /// `F`, `p x n`.
    pub ft: DMatrix<f64>,
    pub f: DVector<f64>,
    pub g: DMatrix<f64>,
    pub w: DVector<f64>,
    pub e: DMatrix<f64>,
    /// Reduced row -> original row.
    pub kept: Vec<usize>,
    pub param_a: DMatrix<f64>,
    pub param_b: DVector<f64>,
    pub hinv_gt: DMatrix<f64>,
    pub hinv_ft: DMatrix<f64>,
    pub hinv_f: DVector<f64>,
    pub scale: f64,
    pub radius_tol: f64,
    pub duplicates: usize,
    pub theta_lb: DVector<f64>,
    pub theta_ub: DVector<f64>,
}

pub(crate) fn prepare(prob: &MpqpProblem, settings: &Settings) -> Result<Prepared, EmpcError> {
    if let Some(j) = (0..prob.theta_lb.len().min(prob.theta_ub.len()))
        .find(|&j| !prob.theta_lb[j].is_finite() || !prob.theta_ub[j].is_finite())
    {
        return Err(EmpcError::UnboundedParameterSet(format!(
            "theta_lb[{j}] = {}, theta_ub[{j}] = {}: every parameter needs finite bounds",
            prob.theta_lb[j], prob.theta_ub[j]
        )));
    }
    prob.validate()?;
    if let Some(j) =
        (0..prob.p()).find(|&j| prob.theta_lb[j].abs().max(prob.theta_ub[j].abs()) > 1e12)
    {
        return Err(EmpcError::UnboundedParameterSet(format!(
            "theta bound {j} has magnitude above 1e12; give a realistic box"
        )));
    }
    if !(settings.radius_tol > 0.0 && settings.step > 0.0) {
        return Err(EmpcError::InvalidArgument(
            "radius_tol and step must be positive".into(),
        ));
    }
    let (n, p) = (prob.n(), prob.p());
    if n == 0 || p == 0 {
        return Err(EmpcError::InvalidArgument(
            "the problem needs at least one variable and one parameter".into(),
        ));
    }
    // H positive definite.
    let hmax = prob.h.amax().max(f64::MIN_POSITIVE);
    let chol = prob
        .h
        .clone()
        .cholesky()
        .ok_or(EmpcError::IndefiniteHessian {
            min_pivot: f64::NAN,
        })?;
    let min_pivot = (0..n)
        .map(|i| chol.l()[(i, i)].powi(2))
        .fold(f64::INFINITY, f64::min);
    if min_pivot <= 1e-12 * hmax {
        return Err(EmpcError::IndefiniteHessian { min_pivot });
    }
    let hinv = chol.inverse();
    let scale = 1.0
        + (0..p)
            .map(|j| prob.theta_lb[j].abs().max(prob.theta_ub[j].abs()))
            .fold(0.0, f64::max);
    // Parameter set: box and optional polytope.
    let mut prow: Vec<(Vec<f64>, f64)> = Vec::new();
    for j in 0..p {
        let mut a = vec![0.0; p];
        a[j] = 1.0;
        prow.push((a.clone(), prob.theta_ub[j]));
        a[j] = -1.0;
        prow.push((a, -prob.theta_lb[j]));
    }
    if let Some((pa, pb)) = &prob.theta_poly {
        for i in 0..pa.nrows() {
            let a: Vec<f64> = pa.row(i).iter().copied().collect();
            let nrm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            if nrm <= 1e-12 {
                if pb[i] < 0.0 {
                    return Err(EmpcError::EmptyFeasibleSet);
                }
                continue;
            }
            prow.push((a.iter().map(|v| v / nrm).collect(), pb[i] / nrm));
        }
    }
    // Constraint rows: normalise, move z-free rows to the parameter set, drop duplicates.
    let gmax = prob.g.amax().max(1e-300);
    let mut rows: Vec<(Vec<f64>, f64, Vec<f64>, usize)> = Vec::new();
    let mut duplicates = 0;
    for i in 0..prob.m() {
        let gi: Vec<f64> = prob.g.row(i).iter().copied().collect();
        let nrm = gi.iter().map(|v| v * v).sum::<f64>().sqrt();
        let ei: Vec<f64> = prob.e.row(i).iter().copied().collect();
        if nrm <= 1e-12 * gmax {
            // 0 <= W_i + E_i theta.
            let en = ei.iter().map(|v| v * v).sum::<f64>().sqrt();
            if en <= 1e-12 {
                if prob.w[i] < -1e-12 * scale {
                    return Err(EmpcError::EmptyFeasibleSet);
                }
                continue;
            }
            prow.push((ei.iter().map(|v| -v / en).collect(), prob.w[i] / en));
            continue;
        }
        let gn: Vec<f64> = gi.iter().map(|v| v / nrm).collect();
        let en: Vec<f64> = ei.iter().map(|v| v / nrm).collect();
        let wn = prob.w[i] / nrm;
        let tol = 1e-10;
        let dup = rows.iter().any(|(g2, w2, e2, _)| {
            g2.iter().zip(&gn).all(|(a, b)| (a - b).abs() <= tol)
                && (w2 - wn).abs() <= tol * scale
                && e2.iter().zip(&en).all(|(a, b)| (a - b).abs() <= tol)
        });
        if dup {
            duplicates += 1;
            continue;
        }
        rows.push((gn, wn, en, i));
    }
    let m = rows.len();
    let mut g = DMatrix::zeros(m, n);
    let mut w = DVector::zeros(m);
    let mut e = DMatrix::zeros(m, p);
    let mut kept = Vec::with_capacity(m);
    for (r, (gi, wi, ei, orig)) in rows.into_iter().enumerate() {
        for j in 0..n {
            g[(r, j)] = gi[j];
        }
        for j in 0..p {
            e[(r, j)] = ei[j];
        }
        w[r] = wi;
        kept.push(orig);
    }
    let mut param_a = DMatrix::zeros(prow.len(), p);
    let mut param_b = DVector::zeros(prow.len());
    for (r, (a, b)) in prow.into_iter().enumerate() {
        for j in 0..p {
            param_a[(r, j)] = a[j];
        }
        param_b[r] = b;
    }
    let hinv_gt = &hinv * g.transpose();
    let hinv_ft = &hinv * prob.f_theta.transpose();
    let hinv_f = &hinv * &prob.f;
    Ok(Prepared {
        n,
        p,
        m,
        h: prob.h.clone(),
        hinv,
        ft: prob.f_theta.clone(),
        f: prob.f.clone(),
        g,
        w,
        e,
        kept,
        param_a,
        param_b,
        hinv_gt,
        hinv_ft,
        hinv_f,
        scale,
        radius_tol: settings.radius_tol * scale,
        duplicates,
        theta_lb: prob.theta_lb.clone(),
        theta_ub: prob.theta_ub.clone(),
    })
}

/// A facet of a computed region, with a point in its relative interior.
#[derive(Clone, Debug)]
pub(crate) struct Facet {
    hs: usize,
    point: Vec<f64>,
    radius: f64,
}

/// A region while exploring (reduced row indices).
#[derive(Clone, Debug)]
pub(crate) struct RegionData {
    pub active: Vec<usize>,
    /// All distinct half-spaces (rows of length p), with origins.
    hs_a: Vec<f64>,
    hs_b: Vec<f64>,
    origins: Vec<Vec<Origin>>,
    facets: Vec<Facet>,
    pub kz: DMatrix<f64>,
    pub kzc: DVector<f64>,
    pub center: Vec<f64>,
    pub radius: f64,
    pub lps: usize,
}

impl RegionData {
    fn contains(&self, theta: &[f64], tol: f64) -> bool {
        let p = theta.len();
        self.facets.iter().all(|f| {
            let a = &self.hs_a[f.hs * p..(f.hs + 1) * p];
            a.iter().zip(theta).map(|(x, y)| x * y).sum::<f64>() <= self.hs_b[f.hs] + tol
        })
    }
}

/// A small deterministic random generator (SplitMix64), used for probe
/// perturbations and by the test problems.
#[derive(Clone, Debug)]
pub struct Rng(u64);
impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [-1, 1).
    pub fn sym(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

fn seed_of(set: &[usize]) -> u64 {
    set.iter().fold(0xCBF2_9CE4_8422_2325u64, |h, &i| {
        (h ^ i as u64).wrapping_mul(0x0100_0000_01B3)
    })
}

impl Prepared {
    /// Largest ball in `{x : a x <= b}` (unit rows, `rows x p`), optionally on the
    /// hyperplane of row `on` (which then gets no radius term).
    pub(crate) fn chebyshev(
        &self,
        a: &[f64],
        b: &[f64],
        on: Option<usize>,
        lp: &mut LpWorkspace,
        buf: &mut (Vec<f64>, Vec<f64>),
    ) -> Option<(Vec<f64>, f64)> {
        let p = self.p;
        let d = p + 1;
        let rows = b.len();
        let (la, lb) = buf;
        la.clear();
        lb.clear();
        for i in 0..rows {
            la.extend_from_slice(&a[i * p..(i + 1) * p]);
            la.push(if Some(i) == on { 0.0 } else { 1.0 });
            lb.push(b[i]);
        }
        if let Some(k) = on {
            for j in 0..p {
                la.push(-a[k * p + j]);
            }
            la.push(0.0);
            lb.push(-b[k]);
        }
        // r <= scale keeps the LP bounded.
        la.extend(std::iter::repeat_n(0.0, p));
        la.push(1.0);
        lb.push(self.scale);
        let mut c = vec![0.0; d];
        c[p] = 1.0;
        // Start: the box centre (on the hyperplane `on`), r its smallest slack.
        let mut x0: Vec<f64> = (0..p)
            .map(|j| 0.5 * (self.theta_lb[j] + self.theta_ub[j]))
            .chain([0.0])
            .collect();
        if let Some(k) = on {
            let ak = &a[k * p..(k + 1) * p];
            let s = ak.iter().zip(&x0).map(|(u, v)| u * v).sum::<f64>() - b[k];
            for j in 0..p {
                x0[j] -= s * ak[j];
            }
        }
        slack_start(la, lb, &mut x0, p);
        let (st, r) = lp.maximize_from(&c, la, lb, &x0);
        if st != LpStatus::Optimal {
            return None;
        }
        Some((lp.x[..p].to_vec(), r))
    }

    /// Computes the region of an active set (reduced indices, sorted);
    /// `None` if LICQ fails or the region is lower-dimensional or empty.
    pub(crate) fn region(&self, act: &[usize], lp: &mut LpWorkspace) -> Option<RegionData> {
        let (n, p, m) = (self.n, self.p, self.m);
        let k = act.len();
        if k > n {
            return None;
        }
        let mut lam_t = DMatrix::zeros(k, p);
        let mut lam_c = DVector::zeros(k);
        let mut kz = -self.hinv_ft.clone();
        let mut kzc = -self.hinv_f.clone();
        if k > 0 {
            let mut ga = DMatrix::zeros(k, n);
            let mut hga = DMatrix::zeros(n, k);
            for (r, &i) in act.iter().enumerate() {
                ga.row_mut(r).copy_from(&self.g.row(i));
                hga.column_mut(r).copy_from(&self.hinv_gt.column(i));
            }
            let mm = &ga * &hga;
            let mmax = (0..k).map(|i| mm[(i, i)]).fold(0.0, f64::max);
            let chol = mm.cholesky()?;
            let minp = (0..k)
                .map(|i| chol.l()[(i, i)].powi(2))
                .fold(f64::INFINITY, f64::min);
            if minp <= 1e-10 * mmax.max(1e-300) {
                return None; // LICQ violated
            }
            let mut rt = &ga * &self.hinv_ft; // k x p
            let mut rc = &ga * &self.hinv_f;
            for (r, &i) in act.iter().enumerate() {
                for j in 0..p {
                    rt[(r, j)] += self.e[(i, j)];
                }
                rc[r] += self.w[i];
            }
            lam_t = -chol.solve(&rt);
            lam_c = -chol.solve(&rc);
            kz -= &hga * &lam_t;
            kzc -= &hga * &lam_c;
        }
        // Half-spaces.
        // Raw half-spaces, one flat row-major array (no allocation per row).
        let nraw = k + (m - k) + self.param_b.len();
        let mut raw_a: Vec<f64> = Vec::with_capacity(nraw * p);
        let mut raw: Vec<(f64, Origin)> = Vec::with_capacity(nraw);
        for (r, &j) in act.iter().enumerate() {
            raw_a.extend((0..p).map(|c| -lam_t[(r, c)]));
            raw.push((lam_c[r], Origin::Dual(j)));
        }
        let gk = &self.g * &kz; // m x p
        let gkc = &self.g * &kzc;
        for i in 0..m {
            if act.binary_search(&i).is_ok() {
                continue;
            }
            raw_a.extend((0..p).map(|c| gk[(i, c)] - self.e[(i, c)]));
            raw.push((self.w[i] - gkc[i], Origin::Primal(i)));
        }
        for i in 0..self.param_b.len() {
            raw_a.extend(self.param_a.row(i).iter().copied());
            raw.push((self.param_b[i], Origin::Param));
        }
        let mut hs_a: Vec<f64> = Vec::with_capacity(raw.len() * p);
        let mut hs_b: Vec<f64> = Vec::with_capacity(raw.len());
        let mut origins: Vec<Vec<Origin>> = Vec::with_capacity(raw.len());
        let mut a = vec![0.0; p];
        for (ra, &(b, o)) in raw_a.chunks_exact(p).zip(&raw) {
            let nrm = ra.iter().map(|v| v * v).sum::<f64>().sqrt();
            if nrm <= 1e-10 {
                if b < -1e-9 * self.scale {
                    return None; // empty
                }
                continue; // always satisfied
            }
            for (x, v) in a.iter_mut().zip(ra) {
                *x = v / nrm;
            }
            let b = b / nrm;
            let cnt = hs_b.len();
            let mut merged = false;
            for q in 0..cnt {
                let aq = &hs_a[q * p..(q + 1) * p];
                if (hs_b[q] - b).abs() <= 1e-10 * self.scale
                    && aq.iter().zip(&a).all(|(x, y)| (x - y).abs() <= 1e-10)
                {
                    origins[q].push(o);
                    merged = true;
                    break;
                }
            }
            if !merged {
                hs_a.extend_from_slice(&a);
                hs_b.push(b);
                origins.push(vec![o]);
            }
        }
        let mut buf = (Vec::new(), Vec::new());
        let mut lps = 1;
        let (center, radius) = self.chebyshev(&hs_a, &hs_b, None, lp, &mut buf)?;
        if radius <= self.radius_tol {
            return None;
        }
        // Facets: half-spaces with a full-dimensional face.
        let facets = self.facets(&hs_a, &hs_b, &origins, &center, act, lp, &mut buf, &mut lps);
        Some(RegionData {
            active: act.to_vec(),
            hs_a,
            hs_b,
            origins,
            facets,
            kz,
            kzc,
            center,
            radius,
            lps,
        })
    }

    /// A box containing `{x in the parameter box : a x <= b}` (unit rows,
    /// `rows x p`): a few rounds of bound propagation, each row bounding
    /// each coordinate by the smallest value the other terms take on the
    /// current box. Every bound it gives is implied by the rows.
    fn implied_box(&self, a: &[f64], b: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let p = self.p;
        let mut lo: Vec<f64> = self.theta_lb.iter().copied().collect();
        let mut hi: Vec<f64> = self.theta_ub.iter().copied().collect();
        for _ in 0..3 {
            let mut changed = false;
            for (r, &bi) in a.chunks_exact(p).zip(b) {
                let low = |j: usize, lo: &[f64], hi: &[f64]| (r[j] * lo[j]).min(r[j] * hi[j]);
                let total: f64 = (0..p).map(|j| low(j, &lo, &hi)).sum();
                if !total.is_finite() {
                    continue;
                }
                for j in 0..p {
                    // Coefficients below 1e-6 would amplify rounding.
                    if r[j].abs() < 1e-6 {
                        continue;
                    }
                    let bound = (bi - (total - low(j, &lo, &hi))) / r[j];
                    if r[j] > 0.0 && bound < hi[j] {
                        hi[j] = bound;
                        changed = true;
                    } else if r[j] < 0.0 && bound > lo[j] {
                        lo[j] = bound;
                        changed = true;
                    }
                }
            }
            if !changed {
                break;
            }
        }
        (lo, hi)
    }

    /// Finds the facets of `{a x <= b}` (unit rows) around the interior point `c`.
    ///
    /// Rays from `c` find most facets without an LP (the first hyperplane a
    /// ray meets, if met alone, is a facet and the hit point lies inside
    /// it). Each remaining row is then decided with one small LP over the
    /// facets known so far plus the parameter rows (Clarkson's method): if
    /// the row cannot be violated it is redundant, else a ray towards the
    /// LP optimum reveals another facet.
    #[allow(clippy::too_many_arguments)]
    fn facets(
        &self,
        a: &[f64],
        b: &[f64],
        origins: &[Vec<Origin>],
        c: &[f64],
        act: &[usize],
        lp: &mut LpWorkspace,
        buf: &mut (Vec<f64>, Vec<f64>),
        lps: &mut usize,
    ) -> Vec<Facet> {
        let p = self.p;
        let nh = b.len();
        let row = |i: usize| &a[i * p..(i + 1) * p];
        let dot = crate::lp::dot;
        let slack: Vec<f64> = (0..nh).map(|i| b[i] - dot(row(i), c)).collect();
        let tol = self.radius_tol;
        // First hit of the ray c + t dir: (row, t), if one row is hit first.
        // `ads` keeps a_i'dir for the margin below.
        let mut ads = vec![0.0; nh];
        let first_hit = |dir: &[f64], ads: &mut [f64]| -> Option<(usize, f64)> {
            let mut best = (usize::MAX, f64::INFINITY);
            let mut second = f64::INFINITY;
            for i in 0..nh {
                let ad = dot(row(i), dir);
                ads[i] = ad;
                if ad > 1e-12 {
                    let t = slack[i] / ad;
                    if t < best.1 {
                        second = best.1;
                        best = (i, t);
                    } else if t < second {
                        second = t;
                    }
                }
            }
            let (j, t) = best;
            let gap_ok = matches!(
                (second - t).partial_cmp(&1e-9),
                Some(std::cmp::Ordering::Greater)
            );
            (j != usize::MAX && gap_ok).then_some((j, t))
        };
        // The hit point and its distance, inside the facet's hyperplane, to
        // the other hyperplanes (a_i'pt = b_i - slack_i + t a_i'dir needs no
        // second product); `None` if below the tolerance. `inv_sin` caches
        // 1 / sin(angle between rows j and i) per row j (0: parallel),
        // filled when row j is first hit (`sin_done`).
        let mut inv_sin = vec![0.0; nh * nh];
        let mut sin_done = vec![false; nh];
        let mut facet_at =
            |j: usize, t: f64, dir: &[f64], ads: &[f64]| -> Option<(usize, Vec<f64>, f64)> {
                let gj = &mut inv_sin[j * nh..(j + 1) * nh];
                if !sin_done[j] {
                    let aj = row(j);
                    for i in 0..nh {
                        let cosang = dot(row(i), aj);
                        let sin = (1.0 - cosang * cosang).max(0.0).sqrt();
                        gj[i] = if i != j && sin > 1e-9 { 1.0 / sin } else { 0.0 };
                    }
                    sin_done[j] = true;
                }
                let mut margin = f64::INFINITY;
                for i in 0..nh {
                    if gj[i] != 0.0 {
                        margin = margin.min((slack[i] - t * ads[i]) * gj[i]);
                    }
                }
                let margin = margin.min(self.scale);
                if margin > tol {
                    let pt: Vec<f64> = (0..p).map(|k| c[k] + t * dir[k]).collect();
                    Some((j, pt, margin))
                } else {
                    None
                }
            };
        let mut state = vec![0u8; nh]; // 0 unknown, 1 facet, 2 redundant
        let mut dir: Vec<f64> = Vec::with_capacity(p);
        let mut facets: Vec<Facet> = Vec::new();
        let mut rng = Rng::new(seed_of(act) ^ 0x5555);
        let add =
            |j: usize, pt: Vec<f64>, margin: f64, state: &mut [u8], facets: &mut Vec<Facet>| {
                if state[j] != 1 {
                    state[j] = 1;
                    facets.push(Facet {
                        hs: j,
                        point: pt,
                        radius: margin,
                    });
                }
            };
        for k in 0..nh {
            if state[k] != 0 {
                continue;
            }
            dir.clear();
            dir.extend((0..p).map(|q| row(k)[q] + 1e-3 * rng.sym()));
            if let Some((j, t)) = first_hit(&dir, &mut ads)
                && state[j] != 1
                && let Some((j, pt, mg)) = facet_at(j, t, &dir, &ads)
            {
                add(j, pt, mg, &mut state, &mut facets);
            }
        }
        // A box around the region by bound propagation (every row holds on
        // the region, so each row bounds one coordinate given the box of the
        // others); a row that stays clear of this box by a margin does not
        // touch the region, so it is not a facet: no LP for it. (A facet has
        // points of the region on its hyperplane, which lie in the box.)
        let (lo, hi) = self.implied_box(a, b);
        for k in 0..nh {
            if state[k] == 0 {
                let top: f64 = row(k)
                    .iter()
                    .zip(lo.iter().zip(&hi))
                    .map(|(&v, (&l, &u))| (v * l).max(v * u))
                    .sum();
                if top <= b[k] - 1e-9 * self.scale {
                    state[k] = 2;
                }
            }
        }
        let mut la: Vec<f64> = Vec::new();
        let mut lb: Vec<f64> = Vec::new();
        for k in 0..nh {
            let mut guard = 0;
            while state[k] == 0 {
                guard += 1;
                la.clear();
                lb.clear();
                for i in 0..nh {
                    if i != k && (state[i] == 1 || origins[i].contains(&Origin::Param)) {
                        la.extend_from_slice(row(i));
                        lb.push(b[i]);
                    }
                }
                la.extend_from_slice(row(k));
                lb.push(b[k] + self.scale);
                *lps += 1;
                let level = b[k] + 1e-9 * self.scale;
                let (st, val) = lp.maximize_until(row(k), &la, &lb, c, level);
                if st == LpStatus::Optimal && val <= level {
                    state[k] = 2;
                    break;
                }
                let mut found = None;
                if st == LpStatus::Optimal && guard < 50 {
                    dir.clear();
                    dir.extend((0..p).map(|q| lp.x[q] - c[q]));
                    found = first_hit(&dir, &mut ads)
                        .filter(|&(j, _)| state[j] != 1)
                        .and_then(|(j, t)| facet_at(j, t, &dir, &ads));
                }
                match found {
                    Some((j, pt, mg)) if state[j] != 1 => add(j, pt, mg, &mut state, &mut facets),
                    _ => {
                        // Ambiguous ray: decide row k exactly.
                        *lps += 1;
                        match self.chebyshev(a, b, Some(k), lp, buf) {
                            Some((pt, r)) if r > tol => add(k, pt, r, &mut state, &mut facets),
                            _ => state[k] = 2,
                        }
                    }
                }
            }
        }
        facets.sort_by_key(|f| f.hs);
        facets
    }

    /// All linearly independent subsets of the active constraints at the QP
    /// optimum of `theta` that represent the optimum with non-negative
    /// multipliers, and have a full-dimensional region.
    fn regions_at(
        &self,
        theta: &[f64],
        max_set: usize,
        lp: &mut LpWorkspace,
    ) -> Result<Option<Vec<RegionData>>, EmpcError> {
        let th = DVector::from_column_slice(theta);
        let q = self.ft.tr_mul(&th) + &self.f;
        let rhs = &self.w + &self.e * &th;
        let opt = match qp::solve(&self.h, &self.hinv, &q, &self.g, &rhs, lp) {
            Ok(o) => o,
            Err(qp::QpFailure::Infeasible) => return Ok(None),
            Err(qp::QpFailure::NotConverged) => {
                return Err(EmpcError::Numerical(format!(
                    "the QP at theta = {theta:?} did not converge"
                )));
            }
        };
        let z = &opt.z;
        let slack = &rhs - &self.g * z;
        let tol = 1e-8 * (1.0 + rhs.amax());
        let zset: Vec<usize> = (0..self.m).filter(|&i| slack[i] <= tol).collect();
        let grad = &self.h * z + &q;
        let mut out = Vec::new();
        let mut sets: Vec<Vec<usize>> = Vec::new();
        let mut ws = opt.working.clone();
        ws.sort_unstable();
        sets.push(ws);
        if zset.len() <= max_set {
            let kz = zset.len();
            for mask in 0u64..(1u64 << kz) {
                let sub: Vec<usize> = (0..kz)
                    .filter(|&b| mask >> b & 1 == 1)
                    .map(|b| zset[b])
                    .collect();
                if sub.len() > self.n || sets.contains(&sub) {
                    continue;
                }
                if represents(&self.g, &sub, &grad) {
                    sets.push(sub);
                }
            }
        }
        for s in sets {
            if let Some(r) = self.region(&s, lp) {
                out.push(r);
            }
        }
        Ok(Some(out))
    }
}

/// Whether `-grad = G_S' lambda` with `lambda >= 0` and independent rows `S`.
fn represents(g: &DMatrix<f64>, set: &[usize], grad: &DVector<f64>) -> bool {
    let n = g.ncols();
    let k = set.len();
    let gnorm = 1.0 + grad.amax();
    if k == 0 {
        return grad.amax() <= 1e-8 * gnorm;
    }
    let mut gs = DMatrix::zeros(n, k);
    for (c, &i) in set.iter().enumerate() {
        gs.column_mut(c).copy_from(&g.row(i).transpose());
    }
    let gtg = gs.tr_mul(&gs);
    let Some(ch) = gtg.clone().cholesky() else {
        return false;
    };
    let minp = (0..k)
        .map(|i| ch.l()[(i, i)].powi(2))
        .fold(f64::INFINITY, f64::min);
    if minp <= 1e-10 {
        return false;
    }
    let lam = ch.solve(&(-gs.tr_mul(grad)));
    let resid = &gs * &lam + grad;
    resid.amax() <= 1e-7 * gnorm && lam.iter().all(|&l| l >= -1e-9 * gnorm)
}

/// A probe point beyond a facet.
#[derive(Clone, Debug)]
struct Witness {
    theta: Vec<f64>,
    facet_a: Vec<f64>,
    facet_b: f64,
}

enum Work {
    Set(Vec<usize>, Vec<Witness>),
    Probe(Witness),
}

#[derive(Default)]
struct WorkOut {
    regions: Vec<RegionData>,
    no_region: Option<Vec<usize>>,
    hull: Vec<(Vec<f64>, f64)>,
    tested: usize,
    discarded: usize,
    fallbacks: usize,
    lps: usize,
    error: Option<EmpcError>,
}

fn process(prep: &Prepared, work: &Work, settings: &Settings, lp: &mut LpWorkspace) -> WorkOut {
    let mut out = WorkOut::default();
    let mut probes: Vec<&Witness> = Vec::new();
    match work {
        Work::Set(act, wits) => {
            out.tested += 1;
            match prep.region(act, lp) {
                Some(r) => {
                    out.lps += r.lps;
                    for w in wits {
                        if !r.contains(&w.theta, 1e-9 * prep.scale) {
                            probes.push(w);
                        }
                    }
                    out.regions.push(r);
                }
                None => {
                    out.discarded += 1;
                    out.no_region = Some(act.clone());
                    probes.extend(wits.iter());
                }
            }
        }
        Work::Probe(w) => probes.push(w),
    }
    for w in probes {
        out.fallbacks += 1;
        match prep.regions_at(&w.theta, settings.max_degenerate_set, lp) {
            Ok(None) => out.hull.push((w.facet_a.clone(), w.facet_b)),
            Ok(Some(rs)) => {
                for r in rs {
                    out.tested += 1;
                    out.lps += r.lps;
                    out.regions.push(r);
                }
            }
            Err(e) => out.error = Some(e),
        }
    }
    out
}

fn run_wave(
    prep: &Prepared,
    items: &[Work],
    settings: &Settings,
    lp: &mut LpWorkspace,
) -> Vec<WorkOut> {
    #[cfg(feature = "parallel")]
    if settings.parallel && items.len() > 1 {
        use rayon::prelude::*;
        return items
            .par_iter()
            .map_init(LpWorkspace::default, |lp, w| process(prep, w, settings, lp))
            .collect();
    }
    items
        .iter()
        .map(|w| process(prep, w, settings, lp))
        .collect()
}

/// Solves the mpQP: all full-dimensional critical regions over the parameter set.
///
/// ```
/// use kestrel_core::formats::MpqpProblem;
/// use kestrel_empc::{solve, Settings};
/// // min 1/2 z^2 + theta z  s.t. -1 <= z <= 1,  theta in [-2, 2]: z = clamp(-theta).
/// let p = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
///   "H": [[1]], "F": [[1]], "G": [[1], [-1]], "W": [1, 1], "E": [[0], [0]],
///   "theta_lb": [-2], "theta_ub": [2]}"#).unwrap();
/// let sol = solve(&p, &Settings::default()).unwrap();
/// assert_eq!(sol.regions.len(), 3);
/// let r = sol.locate(&[0.5], 1e-9).unwrap();
/// assert!((sol.regions[r].z(&[0.5])[0] + 0.5).abs() < 1e-12);
/// ```
pub fn solve(problem: &MpqpProblem, settings: &Settings) -> Result<MpqpSolution, EmpcError> {
    let start = std::time::Instant::now();
    let prep = prepare(problem, settings)?;
    let mut lp = LpWorkspace::default();
    let mut stats = SolveStats {
        duplicate_rows: prep.duplicates,
        ..Default::default()
    };
    // An interior feasible parameter: maximise the smallest slack over (z, theta).
    let (theta0, r0) = interior_parameter(&prep, &mut lp)?;
    stats.lps += 1;
    let mut regions: Vec<RegionData> = Vec::new();
    let mut status: HashMap<Vec<usize>, Option<usize>> = HashMap::new();
    let mut hull: Vec<(Vec<f64>, f64)> = Vec::new();
    // Initial regions: at theta0, perturbed if it sits on a boundary.
    let mut rng = Rng::new(1);
    let mut initial = Vec::new();
    for attempt in 0..20 {
        let th: Vec<f64> = if attempt == 0 {
            theta0.clone()
        } else {
            theta0
                .iter()
                .map(|v| v + 0.5 * r0 * rng.sym() / (prep.p as f64).sqrt())
                .collect()
        };
        stats.fallback_qps += 1;
        if let Some(rs) = prep.regions_at(&th, settings.max_degenerate_set, &mut lp)?
            && !rs.is_empty()
        {
            initial = rs;
            break;
        }
    }
    if initial.is_empty() {
        return Err(EmpcError::Numerical(
            "no full-dimensional region found around an interior feasible parameter".into(),
        ));
    }
    #[cfg(feature = "progress")]
    let bar = settings.progress.then(|| {
        let b = indicatif::ProgressBar::new_spinner();
        b.set_message("exploring critical regions");
        b
    });
    let mut fresh: Vec<usize> = Vec::new();
    let add_region = |r: RegionData,
                      regions: &mut Vec<RegionData>,
                      status: &mut HashMap<Vec<usize>, Option<usize>>,
                      fresh: &mut Vec<usize>| {
        if let Some(Some(_)) = status.get(&r.active) {
            return;
        }
        status.insert(r.active.clone(), Some(regions.len()));
        fresh.push(regions.len());
        regions.push(r);
    };
    for r in initial {
        stats.active_sets_tested += 1;
        stats.lps += r.lps;
        add_region(r, &mut regions, &mut status, &mut fresh);
    }
    let step = settings.step * prep.scale;
    let tol_in = 1e-9 * prep.scale;
    let p = prep.p;
    while !fresh.is_empty() {
        if regions.len() > settings.max_regions {
            return Err(EmpcError::TooManyRegions(settings.max_regions));
        }
        // Generate the next wave from the facets of the fresh regions.
        let mut pending: Vec<(Vec<usize>, Vec<Witness>)> = Vec::new();
        let mut pending_idx: HashMap<Vec<usize>, usize> = HashMap::new();
        let mut probes: Vec<Witness> = Vec::new();
        for &ri in &fresh {
            let r = &regions[ri];
            let mut rng = Rng::new(seed_of(&r.active));
            for fct in &r.facets {
                let orig = &r.origins[fct.hs];
                let a = &r.hs_a[fct.hs * p..(fct.hs + 1) * p];
                let b = r.hs_b[fct.hs];
                if orig.contains(&Origin::Param) {
                    continue; // boundary of the parameter set
                }
                // A point inside the facet, randomly moved within it, then stepped out.
                let mut v: Vec<f64> = (0..p).map(|_| rng.sym()).collect();
                let av: f64 = a.iter().zip(&v).map(|(x, y)| x * y).sum();
                for j in 0..p {
                    v[j] -= av * a[j];
                }
                let vn = v.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300);
                let len = 0.5 * fct.radius * rng.sym().abs();
                let theta: Vec<f64> = (0..p)
                    .map(|j| fct.point[j] + len * v[j] / vn + step * a[j])
                    .collect();
                let wit = Witness {
                    theta,
                    facet_a: a.to_vec(),
                    facet_b: b,
                };
                if orig.len() != 1 {
                    probes.push(wit);
                    continue;
                }
                let cand = match orig[0] {
                    Origin::Primal(i) => {
                        let mut c = r.active.clone();
                        let pos = c.binary_search(&i).unwrap_or_else(|e| e);
                        c.insert(pos, i);
                        c
                    }
                    Origin::Dual(j) => r.active.iter().copied().filter(|&x| x != j).collect(),
                    Origin::Param => unreachable!(),
                };
                match status.get(&cand) {
                    Some(Some(j)) => {
                        if !regions[*j].contains(&wit.theta, tol_in) {
                            probes.push(wit);
                        }
                    }
                    Some(None) => probes.push(wit),
                    None => match pending_idx.get(&cand) {
                        Some(&k) => pending[k].1.push(wit),
                        None => {
                            pending_idx.insert(cand.clone(), pending.len());
                            pending.push((cand, vec![wit]));
                        }
                    },
                }
            }
        }
        fresh.clear();
        let mut items: Vec<Work> = pending.into_iter().map(|(c, w)| Work::Set(c, w)).collect();
        items.extend(probes.into_iter().map(Work::Probe));
        let outs = run_wave(&prep, &items, settings, &mut lp);
        for o in outs {
            if let Some(e) = o.error {
                return Err(e);
            }
            stats.active_sets_tested += o.tested;
            stats.discarded += o.discarded;
            stats.fallback_qps += o.fallbacks;
            stats.lps += o.lps;
            hull.extend(o.hull);
            if let Some(s) = o.no_region {
                status.entry(s).or_insert(None);
            }
            for r in o.regions {
                add_region(r, &mut regions, &mut status, &mut fresh);
            }
        }
        #[cfg(feature = "progress")]
        if let Some(b) = &bar {
            b.set_message(format!("{} critical regions", regions.len()));
            b.tick();
        }
    }
    #[cfg(feature = "progress")]
    if let Some(b) = bar {
        b.finish_with_message(format!("{} critical regions", regions.len()));
    }
    // The explored set: the box (stored apart), extra parameter rows and the
    // facets beyond which the QP is infeasible. Box rows come first in param_a.
    let mut hrows: Vec<(Vec<f64>, f64)> = (2 * p..prep.param_b.len())
        .map(|i| {
            (
                prep.param_a.row(i).iter().copied().collect(),
                prep.param_b[i],
            )
        })
        .collect();
    for (a, b) in hull {
        let dup = hrows.iter().any(|(a2, b2)| {
            (b2 - b).abs() <= 1e-7 * prep.scale
                && a2.iter().zip(&a).all(|(x, y)| (x - y).abs() <= 1e-7)
        });
        if !dup {
            hrows.push((a, b));
        }
    }
    let hull_a = DMatrix::from_fn(hrows.len(), p, |i, j| hrows[i].0[j]);
    let hull_b = DVector::from_iterator(hrows.len(), hrows.iter().map(|r| r.1));
    let out_regions = regions.iter().map(|r| finish_region(&prep, r)).collect();
    stats.solve_seconds = start.elapsed().as_secs_f64();
    Ok(MpqpSolution {
        n: prep.n,
        p,
        regions: out_regions,
        hull_a,
        hull_b,
        theta_lb: prep.theta_lb.clone(),
        theta_ub: prep.theta_ub.clone(),
        stats,
    })
}

fn finish_region(prep: &Prepared, r: &RegionData) -> CriticalRegion {
    let p = prep.p;
    let nf = r.facets.len();
    let a = DMatrix::from_fn(nf, p, |i, j| r.hs_a[r.facets[i].hs * p + j]);
    let b = DVector::from_iterator(nf, r.facets.iter().map(|f| r.hs_b[f.hs]));
    CriticalRegion {
        active_set: r.active.iter().map(|&i| prep.kept[i]).collect(),
        a,
        b,
        fz: r.kz.clone(),
        gz: r.kzc.clone(),
        center: DVector::from_column_slice(&r.center),
        radius: r.radius,
    }
}

/// An interior point of the set of parameters with a feasible QP.
fn interior_parameter(prep: &Prepared, lp: &mut LpWorkspace) -> Result<(Vec<f64>, f64), EmpcError> {
    let (n, p, m) = (prep.n, prep.p, prep.m);
    let d = n + p + 1;
    let np = prep.param_b.len();
    let mut a = Vec::with_capacity((m + np + 1) * d);
    let mut b = Vec::with_capacity(m + np + 1);
    for i in 0..m {
        a.extend(prep.g.row(i).iter());
        a.extend(prep.e.row(i).iter().map(|v| -v));
        a.push(1.0);
        b.push(prep.w[i]);
    }
    for i in 0..np {
        a.extend(std::iter::repeat_n(0.0, n));
        a.extend(prep.param_a.row(i).iter());
        a.push(1.0);
        b.push(prep.param_b[i]);
    }
    a.extend(std::iter::repeat_n(0.0, n + p));
    a.push(1.0);
    b.push(prep.scale);
    let mut c = vec![0.0; d];
    c[d - 1] = 1.0;
    let mut x0: Vec<f64> = std::iter::repeat_n(0.0, n)
        .chain((0..p).map(|j| 0.5 * (prep.theta_lb[j] + prep.theta_ub[j])))
        .chain([0.0])
        .collect();
    slack_start(&a, &b, &mut x0, d - 1);
    let (st, r) = lp.maximize_from(&c, &a, &b, &x0);
    match st {
        LpStatus::Optimal => {}
        other => {
            return Err(EmpcError::Numerical(format!(
                "the LP for an interior feasible parameter ended with {other:?}"
            )));
        }
    }
    if r < -1e-9 * prep.scale {
        return Err(EmpcError::EmptyFeasibleSet);
    }
    if r <= prep.radius_tol {
        return Err(EmpcError::NoInterior { radius: r });
    }
    Ok((lp.x[n..n + p].to_vec(), r))
}

/// All full-dimensional critical regions by brute force: every linearly
/// independent subset of the (deduplicated) constraints, pruned only by
/// infeasibility. Exponential: for testing the explorer on small problems.
/// Returns the sorted active sets (original row indices).
pub fn brute_force_active_sets(
    problem: &MpqpProblem,
    settings: &Settings,
) -> Result<Vec<Vec<usize>>, EmpcError> {
    let prep = prepare(problem, settings)?;
    let mut lp = LpWorkspace::default();
    let mut found = Vec::new();
    let mut stack: Vec<Vec<usize>> = vec![Vec::new()];
    while let Some(set) = stack.pop() {
        if prep.region(&set, &mut lp).is_some() {
            found.push(set.iter().map(|&i| prep.kept[i]).collect::<Vec<_>>());
        }
        if set.len() == prep.n {
            continue;
        }
        let next = set.last().map_or(0, |&l| l + 1);
        for i in next..prep.m {
            if !qp::independent(&prep.g, &set, i) {
                continue;
            }
            let mut s = set.clone();
            s.push(i);
            if feasible_set(&prep, &s, &mut lp) {
                stack.push(s);
            }
        }
    }
    for s in &mut found {
        s.sort_unstable();
    }
    found.sort();
    Ok(found)
}

/// Whether some (z, theta) satisfies all constraints with those of `set` active.
fn feasible_set(prep: &Prepared, set: &[usize], lp: &mut LpWorkspace) -> bool {
    let (n, p, m) = (prep.n, prep.p, prep.m);
    // Variables (z, theta, r): maximise the smallest slack r <= 0.
    let d = n + p + 1;
    let mut a = Vec::new();
    let mut b = Vec::new();
    let tol = 1e-9 * prep.scale;
    for i in 0..m {
        a.extend(prep.g.row(i).iter());
        a.extend(prep.e.row(i).iter().map(|v| -v));
        a.push(1.0);
        b.push(prep.w[i] + tol);
        if set.contains(&i) {
            a.extend(prep.g.row(i).iter().map(|v| -v));
            a.extend(prep.e.row(i).iter());
            a.push(1.0);
            b.push(-prep.w[i] + tol);
        }
    }
    for i in 0..prep.param_b.len() {
        a.extend(std::iter::repeat_n(0.0, n));
        a.extend(prep.param_a.row(i).iter());
        a.push(1.0);
        b.push(prep.param_b[i]);
    }
    a.extend(std::iter::repeat_n(0.0, n + p));
    a.push(1.0);
    b.push(0.0);
    let mut c = vec![0.0; d];
    c[d - 1] = 1.0;
    let mut x0: Vec<f64> = std::iter::repeat_n(0.0, n)
        .chain((0..p).map(|j| 0.5 * (prep.theta_lb[j] + prep.theta_ub[j])))
        .chain([0.0])
        .collect();
    slack_start(&a, &b, &mut x0, d - 1);
    let (st, r) = lp.maximize_from(&c, &a, &b, &x0);
    st == LpStatus::Optimal && r >= -1e-12 * prep.scale
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing;

    /// The propagated box contains the polytope: for random polytopes
    /// (random unit rows around the box centre, within the thesis-sized
    /// problem's parameter box) every coordinate's maximum and minimum,
    /// from an LP, lie inside it; and it is tighter than the parameter box.
    #[test]
    fn implied_box_contains_the_polytope() {
        let prep = prepare(&testing::thesis_sized(1), &Settings::default()).unwrap();
        let p = prep.p;
        let mut rng = Rng::new(21);
        let mut lp = LpWorkspace::default();
        let mut tighter = 0;
        for _ in 0..200 {
            let rows = 2 + (rng.next_u64() % 14) as usize;
            let centre: Vec<f64> = (0..p)
                .map(|j| 0.5 * (prep.theta_lb[j] + prep.theta_ub[j]))
                .collect();
            let (mut a, mut b) = (Vec::new(), Vec::new());
            for _ in 0..rows {
                let mut r: Vec<f64> = (0..p).map(|_| rng.sym()).collect();
                if rng.next_u64().is_multiple_of(3) {
                    let keep = (rng.next_u64() % p as u64) as usize;
                    for (j, v) in r.iter_mut().enumerate() {
                        if j != keep && rng.next_u64().is_multiple_of(2) {
                            *v = 0.0;
                        }
                    }
                }
                let n = r.iter().map(|v| v * v).sum::<f64>().sqrt();
                r.iter_mut().for_each(|v| *v /= n);
                b.push(crate::lp::dot(&r, &centre) + 0.05 + 0.5 * rng.sym().abs());
                a.extend(r);
            }
            let (lo, hi) = prep.implied_box(&a, &b);
            // The LP over the rows and the box.
            let (mut la, mut lb) = (a.clone(), b.clone());
            for j in 0..p {
                for (s, v) in [(1.0, prep.theta_ub[j]), (-1.0, -prep.theta_lb[j])] {
                    la.extend((0..p).map(|t| if t == j { s } else { 0.0 }));
                    lb.push(v);
                }
            }
            for j in 0..p {
                let e: Vec<f64> = (0..p).map(|t| if t == j { 1.0 } else { 0.0 }).collect();
                let (st, top) = lp.maximize_from(&e, &la, &lb, &centre);
                assert_eq!(st, LpStatus::Optimal);
                assert!(top <= hi[j] + 1e-9, "max {top} above the box's {}", hi[j]);
                let ne: Vec<f64> = e.iter().map(|v| -v).collect();
                let (st, bot) = lp.maximize_from(&ne, &la, &lb, &centre);
                assert_eq!(st, LpStatus::Optimal);
                assert!(
                    -bot >= lo[j] - 1e-9,
                    "min {} below the box's {}",
                    -bot,
                    lo[j]
                );
                if hi[j] < prep.theta_ub[j] - 1e-6 || lo[j] > prep.theta_lb[j] + 1e-6 {
                    tighter += 1;
                }
            }
        }
        assert!(tighter > 20, "{tighter}");
    }
}
