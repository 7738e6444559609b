//! Prediction-error identification of innovation-form models with a
//! Levenberg-Marquardt search on exact gradients.

use crate::data::IoData;
use crate::error::{Result, SysidError};
use crate::linalg::spectral_radius;
use crate::model::InnovationModel;
use crate::n4sid::{N4sidResult, N4sidSettings, Scaling, n4sid};
use crate::validate::{estimate_x0_predictor, estimate_x0_simulation};
use nalgebra::{DMatrix, DVector};

/// What the criterion measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Focus {
    /// One-step prediction errors of the innovation form; `K` is estimated.
    #[default]
    Prediction,
    /// Simulation (output) errors: `K = 0` is fixed (output-error model).
    Simulation,
}

/// How the prediction errors of several outputs are weighed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Criterion {
    /// `det` of the residual covariance (maximum likelihood for Gaussian
    /// innovations, MATLAB's default): minimised by Gauss-Newton on
    /// `trace(W E E')` with `W` the inverse residual covariance, updated
    /// at every iteration.
    Determinant,
    /// `trace` of the residual covariance of the outputs scaled to unit variance.
    #[default]
    Trace,
    /// The sum of the root-mean-square errors of every output (of the
    /// outputs scaled to unit variance) and, with
    /// [`PemSettings::horizon`] `h > 1`, of every prediction step
    /// `1..=h`: up to the normalisation, the mean fit (4.11)/(4.12) over
    /// outputs and steps that the validation tables report. The trace
    /// weighs squared errors, so the outputs and steps the model predicts
    /// worst dominate it; a fit criterion values the same relative gain on
    /// every output and step alike. Minimised by iteratively reweighted
    /// Gauss-Newton on `sum_g w_g |e_g|^2` with `w_g = 1 / rms(e_g)`
    /// renewed every iteration, a majorise-minimise scheme (`sqrt` is
    /// concave), so every accepted step lowers the sum of the RMS errors.
    Fit,
}

/// Settings of [`pem`].
#[derive(Clone, Debug, PartialEq)]
pub struct PemSettings {
    /// Prediction or simulation focus.
    pub focus: Focus,
    /// How outputs are weighed.
    pub criterion: Criterion,
    /// Estimate a feed-through `D` (otherwise `D` stays as in the start model).
    pub feedthrough: bool,
    /// Largest number of Levenberg-Marquardt iterations.
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub cost_tolerance: f64,
    /// Stop when the largest gradient entry (relative to the cost) is below this.
    pub gradient_tolerance: f64,
    /// Stop when the step is shorter than this relative to the parameters.
    pub step_tolerance: f64,
    /// Required stability margin: spectral radii of `A` and `A - KC` at
    /// most `1 - stability_margin`.
    pub stability_margin: f64,
    /// Keep `A, B, C, D` of the start model and estimate only the noise
    /// model `K` (and the initial states) by one-step prediction: the
    /// second stage after a [`Focus::Simulation`] fit. Needs
    /// [`Focus::Prediction`].
    pub fixed_dynamics: bool,
    /// Prediction horizon `h` of [`Focus::Prediction`]: the criterion is
    /// the mean squared error of the `1, 2, ..., h`-step-ahead
    /// predictions together (multi-step focus; `1`: the one-step
    /// criterion, MATLAB's default). The Jacobian stays exact (look-ahead
    /// sensitivities); the work grows about `h`-fold. Must be at least 1,
    /// and 1 with [`Focus::Simulation`].
    pub horizon: usize,
    /// The prediction steps (each in `1..=horizon`) whose errors enter
    /// the criterion; empty: all of `1..=horizon`. For example
    /// `horizon: 5, steps: vec![1, 5]` with [`Criterion::Fit`] fits the
    /// sum of the one-step and five-step fits. The work is that of the
    /// whole horizon.
    pub steps: Vec<usize>,
    /// Weight of the simulation term (`0`: off, the default). With a
    /// positive weight the criterion is the validation tables' shape in
    /// one objective: the prediction errors of the steps above (of the
    /// innovation model with its `K`) together with the simulation
    /// errors of the same `A, B, C, D` (`K = 0`, from an initial state of
    /// its own per experiment, estimated as a parameter and started by
    /// least squares like [`compare`](crate::compare)), the simulation
    /// term weighted by this factor. With [`Criterion::Trace`] the
    /// criterion is `(|e_pred|^2 + w |e_sim|^2) / M` (simulation errors
    /// are usually much larger than one-step errors, so even `w = 1`
    /// leans the fit towards simulation); with [`Criterion::Fit`] it is
    /// the sum of the RMS errors per output and prediction step plus `w`
    /// times the RMS simulation error per output, so `w = 1` counts the
    /// simulation fit like one more prediction step. The simulation
    /// term's Jacobian is the exact one of [`Focus::Simulation`] (`K`
    /// does not enter it). Needs [`Focus::Prediction`], estimated
    /// dynamics (not [`PemSettings::fixed_dynamics`]) and the trace or
    /// fit criterion; must be finite and not negative.
    pub simulation_weight: f64,
}

impl Default for PemSettings {
    fn default() -> Self {
        PemSettings {
            focus: Focus::Prediction,
            criterion: Criterion::Trace,
            feedthrough: false,
            max_iterations: 30,
            cost_tolerance: 1e-5,
            gradient_tolerance: 1e-7,
            step_tolerance: 1e-8,
            stability_margin: 1e-4,
            fixed_dynamics: false,
            horizon: 1,
            steps: Vec::new(),
            simulation_weight: 0.0,
        }
    }
}

/// Why the search stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// The relative cost decrease fell below `cost_tolerance`.
    CostTolerance,
    /// The gradient fell below `gradient_tolerance`.
    GradientTolerance,
    /// The step fell below `step_tolerance`.
    StepTolerance,
    /// `max_iterations` reached.
    MaxIterations,
    /// No step lowering the cost (while keeping stability) was found even
    /// with very large damping: a local minimum within numerical precision.
    NoProgress,
}

/// Result of [`pem`].
#[derive(Clone, Debug, PartialEq)]
pub struct PemResult {
    /// The estimated model, in the units of the data.
    pub model: InnovationModel,
    /// Estimated initial state of every experiment (of the predictor).
    pub x0: Vec<DVector<f64>>,
    /// Estimated initial state of the simulation term of every
    /// experiment (empty unless [`PemSettings::simulation_weight`] is
    /// positive).
    pub simulation_x0: Vec<DVector<f64>>,
    /// Mean squared prediction error of the outputs scaled to unit
    /// variance (over the steps `1..=horizon`, or [`PemSettings::steps`],
    /// and, with a simulation term, over the simulation errors too,
    /// unweighted), at the start.
    pub initial_cost: f64,
    /// The same at the end.
    pub cost: f64,
    /// `det` of the residual covariance (of the scaled outputs; prediction
    /// errors only) at the end.
    pub det_cost: f64,
    /// The weighted criterion after every accepted iteration (the first
    /// entry is the start; with [`Criterion::Determinant`] and [`Criterion::Fit`] the weight is
    /// renewed every iteration, so only consecutive entries compare).
    pub history: Vec<f64>,
    /// Iterations (Jacobian evaluations) done.
    pub iterations: usize,
    /// Cost evaluations done (including rejected trial steps).
    pub evaluations: usize,
    /// Free parameters after removing the similarity directions.
    pub free_parameters: usize,
    /// Why the search stopped.
    pub stop: StopReason,
}

/// Parameter layout: `vec(A), vec(B), vec(C), [vec(D)], [vec(K)], x0 per
/// experiment, [simulation x0 per experiment]` (row-major inside every
/// matrix).
#[derive(Clone, Copy, Debug)]
struct Layout {
    n: usize,
    nu: usize,
    ny: usize,
    ne: usize,
    has_d: bool,
    has_k: bool,
    ob: usize,
    oc: usize,
    od: usize,
    ok: usize,
    ox: usize,
    /// Offset of the simulation term's initial states (`p` without one).
    osx: usize,
    p: usize,
}

impl Layout {
    fn new(n: usize, nu: usize, ny: usize, ne: usize, has_d: bool, has_k: bool) -> Self {
        let ob = n * n;
        let oc = ob + n * nu;
        let od = oc + ny * n;
        let ok = od + if has_d { ny * nu } else { 0 };
        let ox = ok + if has_k { n * ny } else { 0 };
        let p = ox + n * ne;
        Layout {
            osx: p,
            n,
            nu,
            ny,
            ne,
            has_d,
            has_k,
            ob,
            oc,
            od,
            ok,
            ox,
            p,
        }
    }
    /// The layout with the simulation term's initial states appended.
    fn with_simulation(mut self) -> Self {
        self.osx = self.ox + self.n * self.ne;
        self.p = self.osx + self.n * self.ne;
        self
    }

    fn has_simulation(&self) -> bool {
        self.p > self.osx
    }

    /// Writes the simulation term's initial states into `th`.
    fn pack_simulation(&self, th: &mut DVector<f64>, xs: &[DVector<f64>]) {
        for (e, x) in xs.iter().enumerate() {
            th.rows_mut(self.osx + e * self.n, self.n).copy_from(x);
        }
    }

    /// The simulation term's initial states (empty without one).
    fn simulation_x0(&self, th: &DVector<f64>) -> Vec<DVector<f64>> {
        if !self.has_simulation() {
            return Vec::new();
        }
        (0..self.ne)
            .map(|e| th.rows(self.osx + e * self.n, self.n).into_owned())
            .collect()
    }

    /// Parameters shared by all experiments.
    fn shared(&self) -> usize {
        self.ox
    }

    fn pack(&self, m: &InnovationModel, x0: &[DVector<f64>]) -> DVector<f64> {
        let mut th = DVector::zeros(self.p);
        let (n, nu, ny) = (self.n, self.nu, self.ny);
        for a in 0..n {
            for b in 0..n {
                th[a * n + b] = m.a[(a, b)];
            }
            for b in 0..nu {
                th[self.ob + a * nu + b] = m.b[(a, b)];
            }
            if self.has_k {
                for b in 0..ny {
                    th[self.ok + a * ny + b] = m.k[(a, b)];
                }
            }
        }
        for a in 0..ny {
            for b in 0..n {
                th[self.oc + a * n + b] = m.c[(a, b)];
            }
            if self.has_d {
                for b in 0..nu {
                    th[self.od + a * nu + b] = m.d[(a, b)];
                }
            }
        }
        for (e, x) in x0.iter().enumerate() {
            for a in 0..n {
                th[self.ox + e * n + a] = x[a];
            }
        }
        th
    }

    /// Model from parameters; `base` supplies the fixed parts (D without
    /// feed-through, K = 0 with simulation focus).
    fn unpack(
        &self,
        th: &DVector<f64>,
        base: &InnovationModel,
    ) -> (InnovationModel, Vec<DVector<f64>>) {
        let (n, nu, ny) = (self.n, self.nu, self.ny);
        let mut m = base.clone();
        for a in 0..n {
            for b in 0..n {
                m.a[(a, b)] = th[a * n + b];
            }
            for b in 0..nu {
                m.b[(a, b)] = th[self.ob + a * nu + b];
            }
            if self.has_k {
                for b in 0..ny {
                    m.k[(a, b)] = th[self.ok + a * ny + b];
                }
            }
        }
        for a in 0..ny {
            for b in 0..n {
                m.c[(a, b)] = th[self.oc + a * n + b];
            }
            if self.has_d {
                for b in 0..nu {
                    m.d[(a, b)] = th[self.od + a * nu + b];
                }
            }
        }
        let x0 = (0..self.ne)
            .map(|e| DVector::from_fn(n, |a, _| th[self.ox + e * n + a]))
            .collect();
        (m, x0)
    }

    /// Basis of the complement of the similarity directions (data-driven
    /// local coordinates): the tangent of `T -> (T^-1 A T, T^-1 B, C T, D,
    /// T^-1 K, T^-1 x0)` at `T = I` is projected out of every step.
    fn ddlc(&self, m: &InnovationModel, x0: &[DVector<f64>], xs: &[DVector<f64>]) -> DMatrix<f64> {
        let (n, nu, ny) = (self.n, self.nu, self.ny);
        let mut tg = DMatrix::<f64>::zeros(self.p, n * n);
        for i in 0..n {
            for j in 0..n {
                let col = i * n + j;
                // dA = E A - A E with E = e_i e_j'.
                for b in 0..n {
                    tg[(i * n + b, col)] += m.a[(j, b)];
                    tg[(b * n + j, col)] -= m.a[(b, i)];
                }
                for b in 0..nu {
                    tg[(self.ob + i * nu + b, col)] += m.b[(j, b)];
                }
                for a in 0..ny {
                    tg[(self.oc + a * n + j, col)] -= m.c[(a, i)];
                }
                if self.has_k {
                    for b in 0..ny {
                        tg[(self.ok + i * ny + b, col)] += m.k[(j, b)];
                    }
                }
                for (e, x) in x0.iter().enumerate() {
                    tg[(self.ox + e * n + i, col)] += x[j];
                }
                for (e, x) in xs.iter().enumerate() {
                    tg[(self.osx + e * n + i, col)] += x[j];
                }
            }
        }
        let q = tg.qr().q();
        let proj = DMatrix::<f64>::identity(self.p, self.p) - &q * q.transpose();
        let eig = proj.symmetric_eigen();
        let keep: Vec<usize> = (0..self.p).filter(|&i| eig.eigenvalues[i] > 0.5).collect();
        DMatrix::from_fn(self.p, keep.len(), |r, c| eig.eigenvectors[(r, keep[c])])
    }
}

/// Experiments as row-major sample arrays (scaled).
struct Series {
    n: usize,
    u: Vec<f64>,
    y: Vec<f64>,
}

fn series_of(data: &IoData) -> Vec<Series> {
    data.experiments()
        .iter()
        .map(|e| Series {
            n: e.len(),
            u: (0..e.len())
                .flat_map(|t| e.u.row(t).iter().copied().collect::<Vec<_>>())
                .collect(),
            y: (0..e.len())
                .flat_map(|t| e.y.row(t).iter().copied().collect::<Vec<_>>())
                .collect(),
        })
        .collect()
}

/// Cholesky factor inverse `L^-1` of the residual covariance (`ny x ny`).
fn whitener(res: &DVector<f64>, ny: usize) -> DMatrix<f64> {
    let m = res.len() / ny;
    let e = DMatrix::from_column_slice(ny, m, res.as_slice());
    let mut cov = &e * e.transpose() / m.max(1) as f64;
    let ridge = 1e-12 * cov.trace().max(1e-300);
    for i in 0..ny {
        cov[(i, i)] += ridge;
    }
    match cov.cholesky() {
        Some(ch) => ch
            .l()
            .try_inverse()
            .unwrap_or_else(|| DMatrix::identity(ny, ny)),
        None => DMatrix::identity(ny, ny),
    }
}

/// Group of every residual for [`Criterion::Fit`]: `step * ny + output`,
/// in the `[t][step][output]` order of [`residuals_and_jacobian`].
fn fit_groups(data: &[Series], ny: usize, h: usize) -> Vec<usize> {
    let mut g = Vec::new();
    for s in data {
        for t in 0..s.n {
            for j in 0..h.min(s.n - t) {
                g.extend((0..ny).map(|o| j * ny + o));
            }
        }
    }
    g
}

/// Weights `1 / rms(e_g)` of the groups of [`fit_groups`] (`ng` groups).
fn fit_weights(res: &DVector<f64>, groups: &[usize], ng: usize) -> Vec<f64> {
    let mut sum = vec![0.0; ng];
    let mut count = vec![0usize; ng];
    for (e, &g) in res.iter().zip(groups) {
        sum[g] += e * e;
        count[g] += 1;
    }
    let rms: Vec<f64> = sum
        .iter()
        .zip(&count)
        .map(|(s, &c)| (s / c.max(1) as f64).sqrt())
        .collect();
    let floor = 1e-12 * rms.iter().copied().fold(0.0, f64::max).max(1e-300);
    rms.iter().map(|r| 1.0 / r.max(floor)).collect()
}

/// Multiplies every residual (and its Jacobian column) by the square root
/// of its group's weight.
fn weigh_groups(
    w: &[f64],
    groups: &[usize],
    res: &mut DVector<f64>,
    jt: Option<&mut DMatrix<f64>>,
) {
    let sw: Vec<f64> = w.iter().map(|v| v.sqrt()).collect();
    for (e, &g) in res.iter_mut().zip(groups) {
        *e *= sw[g];
    }
    if let Some(jt) = jt {
        for (i, &g) in groups.iter().enumerate() {
            jt.column_mut(i).scale_mut(sw[g]);
        }
    }
}

/// The weighting of the residuals in force during one iteration.
enum ResidualWeights {
    /// Plain trace.
    None,
    /// `L^-1` of the residual covariance ([`Criterion::Determinant`]).
    Whiten(DMatrix<f64>),
    /// Group weights `1 / rms` ([`Criterion::Fit`]).
    Groups(Vec<f64>),
}

impl ResidualWeights {
    /// The weighting of `criterion` at the residuals `res`.
    fn at(
        criterion: Criterion,
        res: &DVector<f64>,
        ny: usize,
        groups: &[usize],
        ng: usize,
    ) -> Self {
        match criterion {
            Criterion::Trace => ResidualWeights::None,
            Criterion::Determinant => ResidualWeights::Whiten(whitener(res, ny)),
            Criterion::Fit => ResidualWeights::Groups(fit_weights(res, groups, ng)),
        }
    }
    fn apply(&self, groups: &[usize], res: &mut DVector<f64>, jt: Option<&mut DMatrix<f64>>) {
        match self {
            ResidualWeights::None => {}
            ResidualWeights::Whiten(w) => weigh(w, res, jt),
            ResidualWeights::Groups(w) => weigh_groups(w, groups, res, jt),
        }
    }
}

/// Applies `L^-1` to every sample's block of residuals (and Jacobian columns).
fn weigh(w: &DMatrix<f64>, res: &mut DVector<f64>, jt: Option<&mut DMatrix<f64>>) {
    let ny = w.nrows();
    let m = res.len() / ny;
    let mut e = DMatrix::from_column_slice(ny, m, res.as_slice());
    e = w * e;
    res.copy_from_slice(e.as_slice());
    if let Some(jt) = jt {
        for t in 0..m {
            let blk = jt.columns(t * ny, ny).into_owned();
            let wb = blk * w.transpose();
            jt.columns_mut(t * ny, ny).copy_from(&wb);
        }
    }
}

/// Prediction errors of the model (all experiments stacked, sample-major).
fn residuals(m: &InnovationModel, x0: &[DVector<f64>], data: &[Series]) -> DVector<f64> {
    let (n, nu, ny) = (m.nx(), m.nu(), m.ny());
    let total: usize = data.iter().map(|s| s.n * ny).sum();
    let mut out = DVector::zeros(total);
    let mut row = 0;
    let mut x = vec![0.0; n];
    let mut xn = vec![0.0; n];
    let mut e = vec![0.0; ny];
    for (s, x0e) in data.iter().zip(x0) {
        x.copy_from_slice(x0e.as_slice());
        for t in 0..s.n {
            let u = &s.u[t * nu..(t + 1) * nu];
            let y = &s.y[t * ny..(t + 1) * ny];
            output_error(m, &x, (u, y), &mut e);
            out.rows_mut(row, ny).copy_from_slice(&e);
            predictor_state_step(m, &x, u, &e, &mut xn);
            std::mem::swap(&mut x, &mut xn);
            row += ny;
        }
    }
    out
}

/// The predictor's output error `e = y - C x - D u`.
fn output_error(m: &InnovationModel, x: &[f64], (u, y): (&[f64], &[f64]), e: &mut [f64]) {
    for (o, eo) in e.iter_mut().enumerate() {
        let mut v = y[o];
        for (i, xi) in x.iter().enumerate() {
            v -= m.c[(o, i)] * xi;
        }
        for (j, uj) in u.iter().enumerate() {
            v -= m.d[(o, j)] * uj;
        }
        *eo = v;
    }
}

/// The predictor's state step `xn = A x + B u + K e` (with `e` empty the
/// look-ahead step `A x + B u`).
fn predictor_state_step(m: &InnovationModel, x: &[f64], u: &[f64], e: &[f64], xn: &mut [f64]) {
    for (i, xi) in xn.iter_mut().enumerate() {
        let mut v = 0.0;
        for (j, xj) in x.iter().enumerate() {
            v += m.a[(i, j)] * xj;
        }
        for (j, uj) in u.iter().enumerate() {
            v += m.b[(i, j)] * uj;
        }
        for (o, eo) in e.iter().enumerate() {
            v += m.k[(i, o)] * eo;
        }
        *xi = v;
    }
}

/// Where one sample's errors go: the first of their `ny` columns of the
/// residual vector and Jacobian, and the experiment (whose own `x0`
/// parameters they depend on).
#[derive(Clone, Copy)]
struct Column {
    col: usize,
    experiment: usize,
}

/// One sample's output error `e = y - C z - D u` (into `e` and the
/// residuals) and its sensitivity `de = -(C dz) - dC z - dD u` (into the
/// Jacobian columns; `cpsi` is scratch), for the state `z` with
/// sensitivity `dz`.
#[allow(clippy::too_many_arguments)]
fn error_and_sensitivity(
    lay: &Layout,
    m: &InnovationModel,
    (z, dz): (&[f64], &DMatrix<f64>),
    (u, y): (&[f64], &[f64]),
    at: Column,
    e: &mut [f64],
    (res, jt): (&mut DVector<f64>, &mut DMatrix<f64>),
    cpsi: &mut DMatrix<f64>,
) {
    let (n, nu, ny) = (lay.n, lay.nu, lay.ny);
    let ps = lay.shared();
    output_error(m, z, (u, y), e);
    res.rows_mut(at.col, ny).copy_from_slice(e);
    cpsi.gemm(-1.0, &m.c, dz, 0.0);
    for o in 0..ny {
        for b in 0..n {
            cpsi[(o, lay.oc + o * n + b)] -= z[b];
        }
        if lay.has_d {
            for b in 0..nu {
                cpsi[(o, lay.od + o * nu + b)] -= u[b];
            }
        }
    }
    for o in 0..ny {
        let mut jc = jt.column_mut(at.col + o);
        for q in 0..ps {
            jc[q] = cpsi[(o, q)];
        }
        for a in 0..n {
            jc[lay.ox + at.experiment * n + a] = cpsi[(o, ps + a)];
        }
    }
}

/// One predictor step with its sensitivity:
/// `Psi+ = Abar Psi + dA x + dB u + dK e - K (dC x + dD u)` and
/// `x+ = A x + B u + K e` (`xn`, `psin` are scratch; the results are
/// swapped into `x`, `psi`).
fn advance_predictor(
    lay: &Layout,
    m: &InnovationModel,
    abar: &DMatrix<f64>,
    (u, e): (&[f64], &[f64]),
    (x, xn): (&mut Vec<f64>, &mut Vec<f64>),
    (psi, psin): (&mut DMatrix<f64>, &mut DMatrix<f64>),
) {
    let (n, nu, ny) = (lay.n, lay.nu, lay.ny);
    psin.gemm(1.0, abar, psi, 0.0);
    for a in 0..n {
        for b in 0..n {
            psin[(a, a * n + b)] += x[b];
        }
        for b in 0..nu {
            psin[(a, lay.ob + a * nu + b)] += u[b];
        }
        if lay.has_k {
            for b in 0..ny {
                psin[(a, lay.ok + a * ny + b)] += e[b];
            }
        }
    }
    for o in 0..ny {
        for b in 0..n {
            let c = lay.oc + o * n + b;
            let xb = x[b];
            for a in 0..n {
                psin[(a, c)] -= m.k[(a, o)] * xb;
            }
        }
        if lay.has_d {
            for b in 0..nu {
                let c = lay.od + o * nu + b;
                for a in 0..n {
                    psin[(a, c)] -= m.k[(a, o)] * u[b];
                }
            }
        }
    }
    std::mem::swap(psi, psin);
    predictor_state_step(m, x, u, e, xn);
    std::mem::swap(x, xn);
}

/// Prediction errors and the transposed Jacobian `d e / d theta` (`p x M`)
/// by forward sensitivity recursions of the predictor:
/// `Psi+ = (A - KC) Psi + dA x + dB u + dK e - K (dC x + dD u)`,
/// `de = -(C Psi + dC x + dD u)`.
///
/// With horizon `h > 1` (multi-step focus): for every `t` the errors of
/// the `1..=h`-step-ahead predictions made from the predictor state
/// `x(t|t-1)` (`z0 = x, z+ = A z + B u`, error `y - C z - D u`), stacked
/// `[t][step][output]` (steps that run past the end of an experiment are
/// left out), and their exact Jacobian: the look-ahead sensitivities
/// `dz0 = Psi`, `dz+ = A dz + dA z + dB u`, `de = -(C dz + dC z + dD u)`.
/// `h = 1` gives the one-step errors.
fn residuals_and_jacobian(
    lay: &Layout,
    m: &InnovationModel,
    x0: &[DVector<f64>],
    data: &[Series],
    h: usize,
) -> (DVector<f64>, DMatrix<f64>) {
    let (n, nu, ny) = (lay.n, lay.nu, lay.ny);
    let total: usize = data.iter().map(|s| multistep_count(s.n, h) * ny).sum();
    let mut z = vec![0.0; n];
    let mut zn = vec![0.0; n];
    let mut dz = DMatrix::<f64>::zeros(n, 0);
    let mut dzn = DMatrix::<f64>::zeros(n, 0);
    let mut res = DVector::zeros(total);
    let mut jt = DMatrix::<f64>::zeros(lay.p, total);
    let ps = lay.shared();
    let pl = ps + n; // shared + own x0
    let abar = &m.a - &m.k * &m.c;
    let mut psi = DMatrix::<f64>::zeros(n, pl);
    let mut psin = DMatrix::<f64>::zeros(n, pl);
    let mut cpsi = DMatrix::<f64>::zeros(ny, pl);
    let mut col = 0;
    let mut x = vec![0.0; n];
    let mut xn = vec![0.0; n];
    let mut e = vec![0.0; ny];
    let mut ej = vec![0.0; ny];
    for (ei, (s, x0e)) in data.iter().zip(x0).enumerate() {
        x.copy_from_slice(x0e.as_slice());
        psi.fill(0.0);
        for a in 0..n {
            psi[(a, ps + a)] = 1.0;
        }
        for t in 0..s.n {
            let u = &s.u[t * nu..(t + 1) * nu];
            let y = &s.y[t * ny..(t + 1) * ny];
            let at = Column {
                col,
                experiment: ei,
            };
            error_and_sensitivity(
                lay,
                m,
                (&x, &psi),
                (u, y),
                at,
                &mut e,
                (&mut res, &mut jt),
                &mut cpsi,
            );
            // Look ahead: steps 2..=h from z0 = x, dz0 = Psi.
            if h > 1 {
                z.copy_from_slice(&x);
                dz.clone_from(&psi);
                dzn.clone_from(&psi);
            }
            for j in 1..h.min(s.n - t) {
                let up = &s.u[(t + j - 1) * nu..(t + j) * nu];
                dzn.gemm(1.0, &m.a, &dz, 0.0);
                for a in 0..n {
                    for b in 0..n {
                        dzn[(a, a * n + b)] += z[b];
                    }
                    for b in 0..nu {
                        dzn[(a, lay.ob + a * nu + b)] += up[b];
                    }
                }
                std::mem::swap(&mut dz, &mut dzn);
                predictor_state_step(m, &z, up, &[], &mut zn);
                std::mem::swap(&mut z, &mut zn);
                let uj = &s.u[(t + j) * nu..(t + j + 1) * nu];
                let yj = &s.y[(t + j) * ny..(t + j + 1) * ny];
                let at = Column {
                    col: col + j * ny,
                    experiment: ei,
                };
                error_and_sensitivity(
                    lay,
                    m,
                    (&z, &dz),
                    (uj, yj),
                    at,
                    &mut ej,
                    (&mut res, &mut jt),
                    &mut cpsi,
                );
            }
            advance_predictor(
                lay,
                m,
                &abar,
                (u, &e),
                (&mut x, &mut xn),
                (&mut psi, &mut psin),
            );
            col += ny * h.min(s.n - t);
        }
    }
    (res, jt)
}

/// Number of multi-step errors per output of an experiment of `len`
/// samples with horizon `h` (steps past the end left out).
fn multistep_count(len: usize, h: usize) -> usize {
    (0..len).map(|t| h.min(len - t)).sum()
}

/// Multi-step prediction errors (cost evaluation of
/// [`residuals_and_jacobian`]).
fn multistep_residuals(
    m: &InnovationModel,
    x0: &[DVector<f64>],
    data: &[Series],
    h: usize,
) -> DVector<f64> {
    let (nu, ny) = (m.nu(), m.ny());
    let total: usize = data.iter().map(|s| multistep_count(s.n, h) * ny).sum();
    let mut out = DVector::zeros(total);
    let mut row = 0;
    for (s, x0e) in data.iter().zip(x0) {
        let mut x = x0e.clone();
        for t in 0..s.n {
            let u = DVector::from_column_slice(&s.u[t * nu..(t + 1) * nu]);
            let y = DVector::from_column_slice(&s.y[t * ny..(t + 1) * ny]);
            let e = &y - &m.c * &x - &m.d * &u;
            let mut z = x.clone();
            for j in 0..h.min(s.n - t) {
                let uj = DVector::from_column_slice(&s.u[(t + j) * nu..(t + j + 1) * nu]);
                let yj = DVector::from_column_slice(&s.y[(t + j) * ny..(t + j + 1) * ny]);
                if j > 0 {
                    let up = DVector::from_column_slice(&s.u[(t + j - 1) * nu..(t + j) * nu]);
                    z = &m.a * &z + &m.b * up;
                }
                let ej = yj - &m.c * &z - &m.d * uj;
                out.rows_mut(row, ny).copy_from(&ej);
                row += ny;
            }
            x = &m.a * &x + &m.b * &u + &m.k * &e;
        }
    }
    out
}

/// The model with `K = 0`: the simulation (output-error) model of the
/// same `A, B, C, D`.
fn without_k(m: &InnovationModel) -> InnovationModel {
    let mut m0 = m.clone();
    m0.k.fill(0.0);
    m0
}

/// The simulation term of [`PemSettings::simulation_weight`]: the errors
/// `y - C x - D u` of `x+ = A x + B u` from the initial states `xs`
/// (sample-major like [`residuals`]) and their transposed Jacobian in the
/// layout `lay` (rows of `A, B, C, D` and of the simulation initial
/// states; `K` and the predictor's initial states do not enter). The
/// sensitivities are those of [`Focus::Simulation`]: the one-step
/// recursion with `K = 0`.
fn simulation_residuals_and_jacobian(
    lay: &Layout,
    m: &InnovationModel,
    xs: &[DVector<f64>],
    data: &[Series],
) -> (DVector<f64>, DMatrix<f64>) {
    let sl = Layout::new(lay.n, lay.nu, lay.ny, lay.ne, lay.has_d, false);
    let (r, js) = residuals_and_jacobian(&sl, &without_k(m), xs, data, 1);
    let mut jt = DMatrix::zeros(lay.p, r.len());
    // A, B, C, [D] come first in both layouts (sl.ox == lay.ok).
    jt.rows_mut(0, sl.ox).copy_from(&js.rows(0, sl.ox));
    let nx0 = lay.n * lay.ne;
    jt.rows_mut(lay.osx, nx0).copy_from(&js.rows(sl.ox, nx0));
    (r, jt)
}

/// Residuals `[a; b]` and transposed Jacobians `[ja, jb]` side by side.
fn stack(
    (a, ja): (DVector<f64>, DMatrix<f64>),
    (b, jb): (DVector<f64>, DMatrix<f64>),
) -> (DVector<f64>, DMatrix<f64>) {
    let (na, nb) = (a.len(), b.len());
    let r = stack_residuals(a, &b);
    let mut j = ja.resize_horizontally(na + nb, 0.0);
    j.columns_mut(na, nb).copy_from(&jb);
    (r, j)
}

/// Residuals `[a; b]`.
fn stack_residuals(a: DVector<f64>, b: &DVector<f64>) -> DVector<f64> {
    let na = a.len();
    let mut r = a.resize_vertically(na + b.len(), 0.0);
    r.rows_mut(na, b.len()).copy_from(b);
    r
}

/// Prediction-error identification of an innovation model (4.4)-(4.10):
/// minimises the mean squared one-step prediction error (of the outputs
/// scaled to unit variance) over `A, B, C, K`, optionally `D`, and one
/// initial state per experiment, starting from `start` (with
/// [`PemSettings::horizon`] `h > 1`: the mean squared error of the
/// `1..=h`-step-ahead predictions, a multi-step focus).
///
/// The search is Levenberg-Marquardt on the Gauss-Newton Hessian `J'J`
/// with the exact Jacobian from forward sensitivity recursions of the
/// predictor (no finite differences). Every step is taken in data-driven
/// local coordinates: the `nx^2` directions that only change the state
/// basis are projected out, which makes the problem well posed. A trial
/// step that makes `A` or `A - KC` unstable (spectral radius above
/// `1 - stability_margin`) is rejected like one that raises the cost.
/// With [`Focus::Simulation`] `K` is fixed at zero, so the criterion is
/// the simulation error.
///
/// ```
/// use kestrel_sysid::{n4sid, pem, synthetic, N4sidSettings, PemSettings};
/// let truth = synthetic::random_model(2, 1, 1, 3, 0.8);
/// let data = synthetic::simulate(&truth, 1000, 0.1, 1).unwrap();
/// let start = n4sid(&data, &N4sidSettings { order: Some(2), ..Default::default() }).unwrap();
/// let r = pem(&data, &start.model, &PemSettings::default()).unwrap();
/// assert!(r.cost <= r.initial_cost);
/// assert!(r.model.radius_a() < 1.0 && r.model.radius_predictor() < 1.0);
/// ```
pub fn pem(data: &IoData, start: &InnovationModel, settings: &PemSettings) -> Result<PemResult> {
    if start.nu() != data.nu() {
        return Err(SysidError::dim("start model inputs", data.nu(), start.nu()));
    }
    if start.ny() != data.ny() {
        return Err(SysidError::dim(
            "start model outputs",
            data.ny(),
            start.ny(),
        ));
    }
    start.validate()?;
    let scaling = Scaling::of(data)?;
    let sdata = data.scaled(&scaling.su, &scaling.sy);
    let (n, nu, ny) = (start.nx(), data.nu(), data.ny());
    let ne = data.experiments().len();
    let has_k = settings.focus == Focus::Prediction;
    if settings.fixed_dynamics && !has_k {
        return Err(SysidError::invalid(
            "fixed_dynamics estimates K only and needs the prediction focus",
        ));
    }
    let h = settings.horizon;
    if h == 0 || (h > 1 && !has_k) {
        return Err(SysidError::invalid(format!(
            "PEM horizon {h}: must be at least 1, and 1 with the simulation focus"
        )));
    }
    if let Some(bad) = settings.steps.iter().find(|&&k| k == 0 || k > h) {
        return Err(SysidError::invalid(format!(
            "PEM step {bad}: the selected steps must lie in 1..={h} (the horizon)"
        )));
    }
    let ws = settings.simulation_weight;
    if !ws.is_finite() || ws < 0.0 {
        return Err(SysidError::invalid(format!(
            "PEM simulation weight {ws}: must be finite and not negative"
        )));
    }
    let sim = ws > 0.0;
    if sim && (!has_k || settings.fixed_dynamics || settings.criterion == Criterion::Determinant) {
        return Err(SysidError::invalid(
            "a simulation term (simulation_weight > 0) needs the prediction focus, \
             estimated dynamics (not fixed_dynamics) and the trace or fit criterion",
        ));
    }
    let mut lay = Layout::new(n, nu, ny, ne, settings.feedthrough, has_k);
    if sim {
        lay = lay.with_simulation();
    }
    let shortest = data
        .experiments()
        .iter()
        .map(|e| e.len())
        .min()
        .unwrap_or(0);
    let m_total = data.n_samples() * ny;
    if m_total < 2 * lay.p || shortest < n + 1 {
        return Err(SysidError::TooFewSamples {
            what: format!("PEM with {} parameters (order {n})", lay.p),
            needed: (2 * lay.p).div_ceil(ny).max(n + 1),
            found: data.n_samples(),
        });
    }
    let limit = 1.0 - settings.stability_margin;
    let mut base = scaling.scale(start);
    if !has_k {
        base.k.fill(0.0);
    }
    if base.radius_a() > limit {
        return Err(SysidError::Unstable {
            what: "A of the start model".into(),
            radius: base.radius_a(),
        });
    }
    if has_k && base.radius_predictor() > limit {
        base.k = crate::n4sid::stabilise_k(&base.a, &base.c, base.k.clone());
    }
    let x0: Vec<DVector<f64>> = sdata
        .experiments()
        .iter()
        .map(|e| estimate_x0_predictor(&base, &e.u, &e.y))
        .collect::<Result<_>>()?;
    let xs0: Vec<DVector<f64>> = if sim {
        let m0 = without_k(&base);
        sdata
            .experiments()
            .iter()
            .map(|e| estimate_x0_simulation(&m0, &e.u, &e.y))
            .collect::<Result<_>>()?
    } else {
        Vec::new()
    };
    let series = series_of(&sdata);
    let selected = !settings.steps.is_empty();
    let mut groups = if settings.criterion == Criterion::Fit || selected || sim {
        fit_groups(&series, ny, h)
    } else {
        Vec::new()
    };
    // The simulation errors form groups `h * ny + output`.
    let ng = h * ny + if sim { ny } else { 0 };
    if sim {
        for s in &series {
            for _ in 0..s.n {
                groups.extend((0..ny).map(|o| h * ny + o));
            }
        }
    }
    // Weight of every group's squared errors besides 1 / rms (fit).
    let group_weight: Vec<f64> = (0..ng)
        .map(|g| if g >= h * ny { ws } else { 1.0 })
        .collect();
    // Errors of the steps left out are zeroed (with their Jacobian columns).
    let keep: Vec<bool> = (0..ng)
        .map(|g| !selected || g >= h * ny || settings.steps.contains(&(g / ny + 1)))
        .collect();
    let mask = |res: &mut DVector<f64>, jt: Option<&mut DMatrix<f64>>| {
        if !selected {
            return;
        }
        for (e, &g) in res.iter_mut().zip(&groups) {
            if !keep[g] {
                *e = 0.0;
            }
        }
        if let Some(jt) = jt {
            for (i, &g) in groups.iter().enumerate() {
                if !keep[g] {
                    jt.column_mut(i).fill(0.0);
                }
            }
        }
    };
    let res_jac = |m: &InnovationModel, x: &[DVector<f64>], xs: &[DVector<f64>]| {
        let mut rj = residuals_and_jacobian(&lay, m, x, &series, h);
        if sim {
            rj = stack(rj, simulation_residuals_and_jacobian(&lay, m, xs, &series));
        }
        let (mut r, mut j) = rj;
        mask(&mut r, Some(&mut j));
        (r, j)
    };
    let res_only = |m: &InnovationModel, x: &[DVector<f64>], xs: &[DVector<f64>]| {
        let mut r = if h > 1 {
            multistep_residuals(m, x, &series, h)
        } else {
            residuals(m, x, &series)
        };
        if sim {
            r = stack_residuals(r, &residuals(&without_k(m), xs, &series));
        }
        mask(&mut r, None);
        r
    };
    // The weighting of the criterion at the residuals `res`.
    let weights_at = |res: &DVector<f64>| match (settings.criterion, sim) {
        (Criterion::Trace, true) => ResidualWeights::Groups(group_weight.clone()),
        (Criterion::Fit, true) => {
            let w = fit_weights(res, &groups, ng);
            ResidualWeights::Groups(w.iter().zip(&group_weight).map(|(a, b)| a * b).collect())
        }
        (criterion, _) => ResidualWeights::at(criterion, res, ny, &groups, ng),
    };
    let mut theta = lay.pack(&base, &x0);
    lay.pack_simulation(&mut theta, &xs0);
    let (mut res, mut jt) = res_jac(&base, &x0, &xs0);
    let mf = if selected || sim {
        groups.iter().filter(|&&g| keep[g]).count().max(1) as f64
    } else {
        res.len().max(1) as f64
    };
    let initial_cost = res.norm_squared() / mf;
    let mut plain_cost = initial_cost;
    let mut w = weights_at(&res);
    w.apply(&groups, &mut res, Some(&mut jt));
    let mut cost = res.norm_squared() / mf;
    let mut history = vec![cost];
    let mut mu = 1e-3;
    let mut iterations = 0;
    let mut evaluations = 1;
    let mut stop = StopReason::MaxIterations;
    let mut free = 0;
    let (mut model, mut x0s) = lay.unpack(&theta, &base);
    let mut xss = lay.simulation_x0(&theta);
    while iterations < settings.max_iterations {
        iterations += 1;
        let qp = if settings.fixed_dynamics {
            // Only K and the initial states move: no similarity freedom left.
            let idx: Vec<usize> = (lay.ok..lay.p).collect();
            DMatrix::from_fn(lay.p, idx.len(), |r, c| if r == idx[c] { 1.0 } else { 0.0 })
        } else {
            lay.ddlc(&model, &x0s, &xss)
        };
        free = qp.ncols();
        let h = &jt * jt.transpose();
        let g = &jt * &res;
        let hr = qp.transpose() * &h * &qp;
        let gr = qp.transpose() * &g;
        if gr.amax() / mf <= settings.gradient_tolerance * cost.max(f64::MIN_POSITIVE) {
            stop = StopReason::GradientTolerance;
            break;
        }
        let dscale: Vec<f64> = (0..free)
            .map(|i| hr[(i, i)].max(1e-12 * hr.diagonal().amax()).max(1e-300))
            .collect();
        let mut accepted = None;
        while mu < 1e12 {
            let mut lhs = hr.clone();
            for i in 0..free {
                lhs[(i, i)] += mu * dscale[i];
            }
            let Some(ch) = lhs.cholesky() else {
                mu *= 10.0;
                continue;
            };
            let d = ch.solve(&(-&gr));
            let step = &qp * d;
            let th_try = &theta + &step;
            let (m_try, x0_try) = lay.unpack(&th_try, &base);
            let xs_try = lay.simulation_x0(&th_try);
            evaluations += 1;
            let stable = spectral_radius(&m_try.a) <= limit
                && (!has_k || spectral_radius(&(&m_try.a - &m_try.k * &m_try.c)) <= limit);
            let (c_try, p_try) = if stable {
                let mut r = res_only(&m_try, &x0_try, &xs_try);
                let plain = r.norm_squared() / mf;
                w.apply(&groups, &mut r, None);
                (r.norm_squared() / mf, plain)
            } else {
                (f64::INFINITY, f64::INFINITY)
            };
            if c_try.is_finite() && c_try < cost {
                mu = (mu / 5.0).max(1e-12);
                accepted = Some((th_try, step.norm(), c_try, p_try));
                break;
            }
            mu *= 5.0;
        }
        let Some((th_new, step_norm, c_new, p_new)) = accepted else {
            stop = StopReason::NoProgress;
            break;
        };
        let rel = (cost - c_new) / cost;
        theta = th_new;
        cost = c_new;
        plain_cost = p_new;
        history.push(cost);
        (model, x0s) = lay.unpack(&theta, &base);
        xss = lay.simulation_x0(&theta);
        if rel < settings.cost_tolerance {
            stop = StopReason::CostTolerance;
            break;
        }
        if step_norm < settings.step_tolerance * (1.0 + theta.norm()) {
            stop = StopReason::StepTolerance;
            break;
        }
        (res, jt) = res_jac(&model, &x0s, &xss);
        evaluations += 1;
        if settings.criterion != Criterion::Trace {
            w = weights_at(&res);
        }
        w.apply(&groups, &mut res, Some(&mut jt));
        cost = res.norm_squared() / mf;
    }
    let final_res = res_only(&model, &x0s, &xss);
    // The prediction errors only (the simulation errors come last).
    let n_sim = if sim {
        series.iter().map(|s| s.n * ny).sum::<usize>()
    } else {
        0
    };
    let n_pred = final_res.len() - n_sim;
    let em = DMatrix::from_column_slice(ny, n_pred / ny, &final_res.as_slice()[..n_pred]);
    let det_cost = (&em * em.transpose() / (mf - n_sim as f64).max(1.0) * ny as f64).determinant();
    Ok(PemResult {
        model: scaling.unscale(&model),
        x0: x0s,
        simulation_x0: xss,
        initial_cost,
        cost: plain_cost,
        det_cost,
        history,
        iterations,
        evaluations,
        free_parameters: free,
        stop,
    })
}

/// Result of [`pem_n4sid`]: the subspace start and the refined model.
#[derive(Clone, Debug, PartialEq)]
pub struct Identified {
    /// The N4SID start.
    pub start: N4sidResult,
    /// The prediction-error refinement.
    pub pem: PemResult,
}

/// N4SID followed by PEM from the N4SID model (MATLAB's `ssest`).
pub fn pem_n4sid(
    data: &IoData,
    start: &N4sidSettings,
    settings: &PemSettings,
) -> Result<Identified> {
    let mut s = start.clone();
    s.feedthrough = settings.feedthrough;
    let st = n4sid(data, &s)?;
    let p = pem(data, &st.model, settings)?;
    Ok(Identified { start: st, pem: p })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic;

    /// The set-up of the Jacobian checks: a random stable 3-state,
    /// 2-input, 2-output model `m`, `samples` samples of its data (noise
    /// seed `noise_seed`) merged twice into two experiments, `m` with a
    /// feed-through `D` (`base`) and two predictor initial states.
    struct JacobianFixture {
        m: InnovationModel,
        data: IoData,
        series: Vec<Series>,
        base: InnovationModel,
        x0: Vec<DVector<f64>>,
    }

    fn jacobian_fixture(seed: u64, samples: usize, noise_seed: u64) -> JacobianFixture {
        let m = synthetic::random_model(3, 2, 2, seed, 0.8);
        let data = synthetic::simulate(&m, samples, 0.3, noise_seed).unwrap();
        let sdata = IoData::merge(&[data.clone(), data.clone()]).unwrap();
        let series = series_of(&sdata);
        let mut base = m.clone();
        base.d = DMatrix::from_fn(2, 2, |i, j| 0.1 * (i + 2 * j) as f64);
        let x0 = vec![
            DVector::from_vec(vec![0.3, -0.2, 0.1]),
            DVector::from_vec(vec![0.0, 0.5, -0.4]),
        ];
        JacobianFixture {
            m,
            data,
            series,
            base,
            x0,
        }
    }

    /// The transposed Jacobian of `f` at `th` (a row per parameter) by
    /// central differences of step `1e-6`.
    fn central_differences(
        th: &DVector<f64>,
        f: impl Fn(&DVector<f64>) -> DVector<f64>,
    ) -> DMatrix<f64> {
        let eps = 1e-6;
        let rows: Vec<_> = (0..th.len())
            .map(|j| {
                let mut tp = th.clone();
                tp[j] += eps;
                let mut tm = th.clone();
                tm[j] -= eps;
                ((f(&tp) - f(&tm)) / (2.0 * eps)).transpose()
            })
            .collect();
        DMatrix::from_rows(&rows)
    }

    /// Every row of the exact transposed Jacobian `jt` agrees with that
    /// of `fd` within `1e-6 (1 + |row|)`.
    fn assert_rows_agree(jt: &DMatrix<f64>, fd: &DMatrix<f64>, label: &str) {
        assert_eq!(jt.shape(), fd.shape(), "{label}");
        for j in 0..jt.nrows() {
            let an = jt.row(j);
            let err = (fd.row(j) - an).norm();
            assert!(err < 1e-6 * (1.0 + an.norm()), "{label}param {j}: {err}");
        }
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let JacobianFixture {
            series, base, x0, ..
        } = jacobian_fixture(21, 60, 5);
        for (has_d, has_k) in [(true, true), (false, false)] {
            let lay = Layout::new(3, 2, 2, 2, has_d, has_k);
            let th = lay.pack(&base, &x0);
            let (mm, xx) = lay.unpack(&th, &base);
            let (r0, jt) = residuals_and_jacobian(&lay, &mm, &xx, &series, 1);
            let res = |th: &DVector<f64>| {
                let (mm, xx) = lay.unpack(th, &base);
                residuals(&mm, &xx, &series)
            };
            assert!((&r0 - res(&th)).norm() < 1e-12);
            assert_rows_agree(&jt, &central_differences(&th, res), "");
        }
    }

    /// The multi-step errors and their Jacobian: horizon 1 is the one-step
    /// predictor, the errors agree with an independent k-step prediction
    /// ([`InnovationModel::predict_k_step`]), and the Jacobian with central
    /// differences.
    #[test]
    fn multistep_jacobian_matches_central_differences() {
        let JacobianFixture {
            m,
            data,
            series,
            base,
            x0,
        } = jacobian_fixture(23, 40, 6);
        let one = residuals(&base, &x0, &series);
        assert!((multistep_residuals(&base, &x0, &series, 1) - &one).norm() < 1e-12);
        // Step k of sample t against predict_k_step (the k-step
        // prediction of y(t + k - 1) made at t - 1), first experiment.
        let h = 3;
        let ms = multistep_residuals(&base, &x0, &series, h);
        let e0 = &data.experiments()[0];
        for k in 1..=h {
            let p = base.predict_k_step(&e0.u, &e0.y, &x0[0], k).unwrap();
            for t in 1..(40 - h) {
                for o in 0..2 {
                    let want = e0.y[(t + k - 1, o)] - p[(t + k - 1, o)];
                    let got = ms[(t * h + (k - 1)) * 2 + o];
                    assert!((want - got).abs() < 1e-10, "t {t} k {k}: {want} vs {got}");
                }
            }
        }
        for (has_d, has_k) in [(true, true), (false, true)] {
            let lay = Layout::new(3, 2, 2, 2, has_d, has_k);
            let th = lay.pack(&base, &x0);
            let (mm, xx) = lay.unpack(&th, &base);
            let (r0, jt) = residuals_and_jacobian(&lay, &mm, &xx, &series, h);
            let res = |th: &DVector<f64>| {
                let (mm, xx) = lay.unpack(th, &base);
                multistep_residuals(&mm, &xx, &series, h)
            };
            assert!((&r0 - res(&th)).norm() < 1e-12);
            assert_rows_agree(&jt, &central_differences(&th, res), "");
        }
        // The horizon is checked.
        for (focus, horizon) in [(Focus::Prediction, 0), (Focus::Simulation, 2)] {
            let s = PemSettings {
                focus,
                horizon,
                ..Default::default()
            };
            assert!(matches!(
                pem(&data, &m, &s),
                Err(SysidError::InvalidArgument(_))
            ));
        }
    }

    #[test]
    fn similarity_directions_leave_the_predictor_unchanged() {
        let m = synthetic::random_model(3, 2, 2, 4, 0.8);
        let lay = Layout::new(3, 2, 2, 1, false, true);
        let x0 = vec![DVector::from_vec(vec![0.1, 0.2, 0.3])];
        let qp = lay.ddlc(&m, &x0, &[]);
        assert_eq!(qp.ncols(), lay.p - 9);
        // With a simulation term its initial states move along too.
        let ls = lay.with_simulation();
        let xs = vec![DVector::from_vec(vec![-0.3, 0.1, 0.2])];
        let qs = ls.ddlc(&m, &x0, &xs);
        assert_eq!(qs.ncols(), ls.p - 9);
        let mut th0 = ls.pack(&m, &x0);
        ls.pack_simulation(&mut th0, &xs);
        let ti = DMatrix::<f64>::identity(3, 3)
            + DMatrix::from_fn(3, 3, |i, j| 0.01 * ((i + 2 * j) as f64).cos());
        let tinv = ti.clone().try_inverse().unwrap();
        let mut th1 = ls.pack(&m.transform(&ti).unwrap(), &[&tinv * &x0[0]]);
        ls.pack_simulation(&mut th1, &[&tinv * &xs[0]]);
        let d = th1 - th0;
        assert!((qs.transpose() * &d).norm() < 0.05 * d.norm());
        // The complement is orthogonal to the tangent of a similarity.
        let t = DMatrix::from_fn(3, 3, |i, j| 0.01 * ((i * 3 + j) as f64).sin());
        let ti = DMatrix::<f64>::identity(3, 3) + &t;
        let mt = m.transform(&ti).unwrap();
        let x0t = vec![ti.clone().try_inverse().unwrap() * &x0[0]];
        let d = lay.pack(&mt, &x0t) - lay.pack(&m, &x0);
        let inplane = qp.transpose() * &d;
        assert!(
            inplane.norm() < 0.05 * d.norm(),
            "{} vs {}",
            inplane.norm(),
            d.norm()
        );
    }

    /// With the true dynamics fixed and `K = 0` at the start, the
    /// noise-model stage moves only `K`, reaches the true one-step fit
    /// within 0.2 points and recovers the true `K` (it is the optimum).
    #[test]
    fn fixed_dynamics_estimates_the_true_kalman_gain() {
        // A Kalman-like gain K = A C' (C C' + I)^-1 (P = I, R = I).
        let mut truth = synthetic::random_model(3, 2, 2, 77, 0.9);
        let cct = &truth.c * truth.c.transpose() + DMatrix::identity(2, 2);
        truth.k = &truth.a * truth.c.transpose() * cct.try_inverse().unwrap();
        assert!(truth.radius_predictor() < 0.95 && truth.k.amax() > 0.1);
        let est = synthetic::simulate(&truth, 4000, 0.5, 3).unwrap();
        let val = synthetic::simulate(&truth, 3000, 0.5, 4).unwrap();
        let mut start = truth.clone();
        start.k.fill(0.0);
        let settings = PemSettings {
            fixed_dynamics: true,
            ..Default::default()
        };
        let r = pem(&est, &start, &settings).unwrap();
        // Unchanged up to the scaling round trip.
        assert!((&r.model.a - &truth.a).amax() < 1e-12);
        assert!((&r.model.b - &truth.b).amax() < 1e-12);
        assert!((&r.model.c - &truth.c).amax() < 1e-12);
        assert!(r.cost < r.initial_cost);
        let k_err = (&r.model.k - &truth.k).norm() / truth.k.norm();
        assert!(k_err < 0.1, "relative K error {k_err}");
        let ft = crate::predict_fit(&truth, &val, 1).unwrap();
        let fm = crate::predict_fit(&r.model, &val, 1).unwrap();
        for (t, m) in ft.iter().zip(&fm) {
            assert!(t - m < 0.2, "one-step fit {m} vs true {t}");
        }
        // It needs the prediction focus.
        let bad = PemSettings {
            focus: Focus::Simulation,
            ..settings
        };
        assert!(matches!(
            pem(&est, &start, &bad),
            Err(SysidError::InvalidArgument(_))
        ));
    }

    /// The issue's synthetic check: a random stable 5th-order, 4-input,
    /// 3-output innovation model; PEM from N4SID reaches the true model's
    /// one-step fit on fresh data within 0.2 points and recovers `G` and `H`.
    #[test]
    fn synthetic_fifth_order_model_is_recovered() {
        let truth = synthetic::random_model(5, 4, 3, 2024, 0.9);
        let est = synthetic::simulate(&truth, 5000, 0.5, 1).unwrap();
        let val = synthetic::simulate(&truth, 5000, 0.5, 2).unwrap();
        let r = pem_n4sid(
            &est,
            &N4sidSettings {
                order: Some(5),
                ..Default::default()
            },
            &PemSettings::default(),
        )
        .unwrap();
        let m = &r.pem.model;
        assert!(r.pem.cost < r.pem.initial_cost);
        let fit_true = crate::predict_fit(&truth, &val, 1).unwrap();
        let fit_pem = crate::predict_fit(m, &val, 1).unwrap();
        for (t, p) in fit_true.iter().zip(&fit_pem) {
            assert!(t - p < 0.2, "one-step fit {p} vs true {t}");
        }
        let mut worst_g: f64 = 0.0;
        let mut worst_h: f64 = 0.0;
        for i in 0..64 {
            let w = std::f64::consts::PI * i as f64 / 64.0;
            let gt = truth.frequency_response(w).unwrap();
            let gm = m.frequency_response(w).unwrap();
            worst_g = worst_g.max((&gm - &gt).norm() / gt.norm());
            let ht = truth.noise_response(w).unwrap();
            let hm = m.noise_response(w).unwrap();
            worst_h = worst_h.max((&hm - &ht).norm() / ht.norm());
        }
        eprintln!(
            "synthetic: one-step fit true {fit_true:.3?} pem {fit_pem:.3?}; max rel. error G {worst_g:.4}, H {worst_h:.4}; {} iterations, stop {:?}",
            r.pem.iterations, r.pem.stop
        );
        assert!(worst_g < 0.03, "relative error of G: {worst_g}");
        assert!(worst_h < 0.1, "relative error of H: {worst_h}");
        let (pt, pm) = (truth.poles().unwrap(), m.poles().unwrap());
        for p in &pt {
            let d = pm
                .iter()
                .map(|q| (q - p).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(d < 0.03, "pole {p} not recovered ({d})");
        }
    }

    /// Sum over outputs of the RMS one-step error of the outputs scaled
    /// to unit variance, from an independent predictor run
    /// ([`InnovationModel::predict_one_step`] from the least-squares `x0`).
    fn sum_rms_and_trace(m: &InnovationModel, data: &IoData) -> (f64, f64) {
        let e = &data.experiments()[0];
        let x0 = estimate_x0_predictor(m, &e.u, &e.y).unwrap();
        let r = m.predict_one_step(&e.u, &e.y, &x0).unwrap().residuals;
        let (mut sum_rms, mut trace) = (0.0, 0.0);
        for o in 0..r.ncols() {
            let y = e.y.column(o);
            let var = y.map(|v| v - y.mean()).norm_squared() / y.len() as f64;
            let ms = r.column(o).norm_squared() / r.nrows() as f64 / var;
            sum_rms += ms.sqrt();
            trace += ms;
        }
        (sum_rms, trace)
    }

    /// The fit criterion against the trace on a model of too low order
    /// (3 for 4) with one well and one poorly predictable output: each criterion
    /// wins its own figure (checked by an independent predictor run), the
    /// fit criterion raises the mean one-step fit, and it works with a
    /// multi-step horizon.
    #[test]
    fn fit_criterion_trades_squared_error_for_mean_fit() {
        let mut truth = synthetic::random_model(4, 2, 2, 31, 0.9);
        truth.k.fill(0.0);
        for j in 0..4 {
            truth.c[(0, j)] *= 10.0;
            truth.c[(1, j)] *= 0.2;
        }
        let data = synthetic::simulate(&truth, 1500, 0.5, 8).unwrap();
        let (data, _) = data.remove_means().unwrap();
        let start = crate::n4sid::n4sid_of_order(&data, 3);
        let fit_of = |criterion: Criterion, horizon: usize| {
            let s = PemSettings {
                criterion,
                horizon,
                max_iterations: 60,
                ..Default::default()
            };
            pem(&data, &start.model, &s).unwrap()
        };
        let tr = fit_of(Criterion::Trace, 1);
        let fi = fit_of(Criterion::Fit, 1);
        let (rms_tr, trace_tr) = sum_rms_and_trace(&tr.model, &data);
        let (rms_fi, trace_fi) = sum_rms_and_trace(&fi.model, &data);
        eprintln!(
            "sum of RMS: trace {rms_tr:.5}, fit {rms_fi:.5}; trace: trace {trace_tr:.5}, fit {trace_fi:.5}"
        );
        assert!(rms_fi < rms_tr - 0.01, "{rms_fi} vs {rms_tr}");
        assert!(trace_tr < trace_fi - 0.004, "{trace_tr} vs {trace_fi}");
        assert!((tr.cost - trace_tr / 2.0).abs() < 0.02 * tr.cost);
        let mean_fit = |m: &InnovationModel| mean_one_step_fit(m, &data);
        assert!(mean_fit(&fi.model) > mean_fit(&tr.model) + 0.5);
        // With a horizon the groups are (step, output) and the search
        // still lowers the (reweighted) criterion from the start.
        let ms = fit_of(Criterion::Fit, 3);
        assert!(ms.history.len() > 1);
        assert!(ms.history[1] < ms.history[0]);
        assert!(ms.model.radius_a() < 1.0 && ms.model.radius_predictor() < 1.0);
    }

    /// Selected steps: `steps: [1]` with horizon 3 is the one-step
    /// criterion (the same first step), `[1, 3]` a different one from all of
    /// `1..=3`, and steps outside `1..=horizon` are refused.
    #[test]
    fn selected_steps_mask_the_others() {
        let truth = synthetic::random_model(3, 2, 2, 12, 0.85);
        let data = synthetic::simulate(&truth, 600, 0.3, 4).unwrap();
        let start = crate::n4sid::n4sid_of_order(&data, 2);
        let run = |horizon: usize, steps: Vec<usize>, max_iterations: usize| {
            let s = PemSettings {
                horizon,
                steps,
                max_iterations,
                ..Default::default()
            };
            pem(&data, &start.model, &s)
        };
        // One iteration: later ones may part because the local
        // coordinates' basis is arbitrary within a degenerate eigenspace
        // (rounding picks it) and the Marquardt scaling depends on it.
        let one = run(1, vec![], 1).unwrap();
        let masked = run(3, vec![1], 1).unwrap();
        assert!((&one.model.a - &masked.model.a).amax() < 1e-10);
        assert!((one.cost - masked.cost).abs() < 1e-12 * one.cost);
        assert!(masked.cost < masked.initial_cost);
        let all = run(3, vec![], 8).unwrap();
        let ends = run(3, vec![1, 3], 8).unwrap();
        assert!((&all.model.a - &ends.model.a).amax() > 1e-6);
        for steps in [vec![0], vec![1, 4]] {
            assert!(matches!(
                run(3, steps, 8),
                Err(SysidError::InvalidArgument(_))
            ));
        }
    }

    /// The fit criterion's groups follow the residual layout of the
    /// multi-step criterion (steps past an experiment's end left out).
    #[test]
    fn fit_groups_follow_the_multistep_layout() {
        let m = synthetic::random_model(2, 1, 2, 5, 0.8);
        let a = synthetic::simulate(&m, 7, 0.1, 1).unwrap();
        let b = synthetic::simulate(&m, 4, 0.1, 2).unwrap();
        let series = series_of(&IoData::merge(&[a, b]).unwrap());
        let x0 = vec![DVector::zeros(2), DVector::zeros(2)];
        for h in [1, 3, 5] {
            let g = fit_groups(&series, 2, h);
            assert_eq!(g.len(), multistep_residuals(&m, &x0, &series, h).len());
            // The second experiment (4 samples), h = 3: steps 1,2,3 | 1,2,3 | 1,2 | 1.
            let tail: Vec<usize> = g[g.len() - 2 * multistep_count(4, h)..]
                .iter()
                .step_by(2)
                .copied()
                .collect();
            let want: Vec<usize> = (0..4)
                .flat_map(|t: usize| (0..h.min(4 - t)).map(|j| 2 * j))
                .collect();
            assert_eq!(tail, want, "h = {h}");
        }
        // Weights are 1 / rms per group.
        let res = DVector::from_vec(vec![3.0, 1.0, -3.0, 2.0]);
        let w = fit_weights(&res, &[0, 1, 0, 1], 2);
        assert!((w[0] - 1.0 / 3.0).abs() < 1e-15);
        assert!((w[1] - 1.0 / 2.5f64.sqrt()).abs() < 1e-15);
    }

    /// The combined criterion's residuals: the prediction errors, then
    /// the simulation errors, which agree with an independent simulation
    /// ([`InnovationModel::simulate`], `K` unused) from the simulation
    /// term's own initial states; the stacked Jacobian agrees with central
    /// differences (`K` and the predictor's `x0` do not move the
    /// simulation errors, the simulation `x0` does not move the
    /// prediction errors).
    #[test]
    fn simulation_term_jacobian_matches_central_differences() {
        let JacobianFixture {
            data,
            series,
            base,
            x0,
            ..
        } = jacobian_fixture(41, 30, 7);
        let xs = vec![
            DVector::from_vec(vec![-0.1, 0.4, 0.2]),
            DVector::from_vec(vec![0.6, -0.3, 0.0]),
        ];
        let e0 = &data.experiments()[0];
        let want = &e0.y - base.simulate(&e0.u, &xs[0]).unwrap();
        let got = residuals(&without_k(&base), &xs, &series);
        for t in 0..30 {
            for o in 0..2 {
                assert!((want[(t, o)] - got[t * 2 + o]).abs() < 1e-12);
            }
        }
        for (has_d, h) in [(true, 1), (false, 3)] {
            let lay = Layout::new(3, 2, 2, 2, has_d, true).with_simulation();
            let mut th = lay.pack(&base, &x0);
            lay.pack_simulation(&mut th, &xs);
            let all = |th: &DVector<f64>| {
                let (mm, xx) = lay.unpack(th, &base);
                let ss = lay.simulation_x0(th);
                stack_residuals(
                    multistep_residuals(&mm, &xx, &series, h),
                    &residuals(&without_k(&mm), &ss, &series),
                )
            };
            let (mm, xx) = lay.unpack(&th, &base);
            assert_eq!(lay.simulation_x0(&th), xs);
            let (r0, jt) = stack(
                residuals_and_jacobian(&lay, &mm, &xx, &series, h),
                simulation_residuals_and_jacobian(&lay, &mm, &xs, &series),
            );
            assert_eq!(jt.nrows(), lay.p);
            assert!((&r0 - all(&th)).norm() < 1e-12);
            let n_pred = r0.len() - 2 * 60;
            let fd = central_differences(&th, all);
            assert_rows_agree(&jt, &fd, &format!("h {h} "));
            for j in 0..lay.p {
                let (an, fd) = (jt.row(j), fd.row(j));
                // K and the predictor's x0 leave the simulation alone; the
                // simulation x0 leaves the prediction alone.
                if (lay.ok..lay.osx).contains(&j) {
                    assert!(an.columns(n_pred, 120).amax() == 0.0);
                    assert!(fd.columns(n_pred, 120).amax() < 1e-9);
                }
                if j >= lay.osx {
                    assert!(an.columns(0, n_pred).amax() == 0.0);
                    assert!(fd.columns(0, n_pred).amax() < 1e-9);
                }
            }
        }
    }

    /// The combined criterion of `settings` evaluated from the model and
    /// initial states in the scaled data's units: `(|e_pred|^2 + w
    /// |e_sim|^2) / M` (trace) or the sum of the RMS errors per output and
    /// step plus `w` times those of the simulation (fit).
    fn combined_criterion(
        data: &IoData,
        m: &InnovationModel,
        (x0, xs): (&[DVector<f64>], &[DVector<f64>]),
        settings: &PemSettings,
    ) -> f64 {
        let scaling = Scaling::of(data).unwrap();
        let series = series_of(&data.scaled(&scaling.su, &scaling.sy));
        let m = scaling.scale(m);
        let (h, ny, w) = (settings.horizon, m.ny(), settings.simulation_weight);
        let pred = multistep_residuals(&m, x0, &series, h);
        let simr = residuals(&without_k(&m), xs, &series);
        match settings.criterion {
            Criterion::Trace => {
                (pred.norm_squared() + w * simr.norm_squared()) / (pred.len() + simr.len()) as f64
            }
            _ => {
                let rms = |r: &DVector<f64>, groups: &[usize], ng: usize| {
                    let mut sum = vec![0.0; ng];
                    let mut count = vec![0.0; ng];
                    for (e, &g) in r.iter().zip(groups) {
                        sum[g] += e * e;
                        count[g] += 1.0;
                    }
                    (0..ng).map(|g| (sum[g] / count[g]).sqrt()).sum::<f64>()
                };
                let sim_groups: Vec<usize> = (0..simr.len()).map(|i| i % ny).collect();
                rms(&pred, &fit_groups(&series, ny, h), h * ny) + w * rms(&simr, &sim_groups, ny)
            }
        }
    }

    /// PEM with a simulation term, trace and fit, from an N4SID start of
    /// too low an order: the search ends lower in its own criterion
    /// (evaluated independently of the search's weights) than it started,
    /// and the result is stable with its simulation `x0` reported.
    /// Mean-free data of a random stable 4-state, 2-input, 2-output
    /// model (`samples` samples, noise `noise` with seed `noise_seed`) and
    /// the N4SID model of too low an order (3) from them.
    fn low_order_start(
        seed: u64,
        samples: usize,
        noise: f64,
        noise_seed: u64,
    ) -> (IoData, InnovationModel) {
        let truth = synthetic::random_model(4, 2, 2, seed, 0.9);
        let data = synthetic::simulate(&truth, samples, noise, noise_seed).unwrap();
        let (data, _) = data.remove_means().unwrap();
        let start = crate::n4sid::n4sid_of_order(&data, 3).model;
        (data, start)
    }

    #[test]
    fn simulation_term_never_ends_worse_than_its_start() {
        let (data, start) = low_order_start(33, 800, 0.4, 9);
        for criterion in [Criterion::Trace, Criterion::Fit] {
            let settings = PemSettings {
                criterion,
                horizon: 2,
                simulation_weight: 1.0,
                max_iterations: 10,
                ..Default::default()
            };
            let r = pem(&data, &start, &settings).unwrap();
            assert_eq!(r.simulation_x0.len(), 1);
            // The search's start: the least-squares x0 of the predictor
            // and of the simulation (as compare estimates it).
            let sc = Scaling::of(&data).unwrap();
            let sd = data.scaled(&sc.su, &sc.sy);
            let e = &sd.experiments()[0];
            let s0 = sc.scale(&start);
            let x0 = vec![estimate_x0_predictor(&s0, &e.u, &e.y).unwrap()];
            let xs = vec![estimate_x0_simulation(&without_k(&s0), &e.u, &e.y).unwrap()];
            let before = combined_criterion(&data, &start, (&x0, &xs), &settings);
            let after = combined_criterion(&data, &r.model, (&r.x0, &r.simulation_x0), &settings);
            eprintln!("{criterion:?}: {before:.5} -> {after:.5} ({:?})", r.stop);
            assert!(after < before, "{criterion:?}: {after} vs {before}");
            assert!(r.model.radius_a() < 1.0 && r.model.radius_predictor() < 1.0);
        }
        // The plain PEM reports no simulation x0.
        let plain = pem(
            &data,
            &start,
            &PemSettings {
                max_iterations: 2,
                ..Default::default()
            },
        );
        assert!(plain.unwrap().simulation_x0.is_empty());
    }

    /// Mean one-step prediction fit.
    fn mean_one_step_fit(m: &InnovationModel, data: &IoData) -> f64 {
        let f = crate::predict_fit(m, data, 1).unwrap();
        f.iter().sum::<f64>() / f.len() as f64
    }

    /// Mean simulation fit (compare, its own least-squares x0).
    fn mean_sim_fit(m: &InnovationModel, data: &IoData) -> f64 {
        let f = crate::compare(m, data).unwrap().fit;
        f.iter().sum::<f64>() / f.len() as f64
    }

    /// With a large simulation weight the combined criterion approaches
    /// the simulation focus: its simulation fit comes within 0.05 points
    /// of [`Focus::Simulation`]'s from the same start, above the plain
    /// multi-step fit's, while `K` is still estimated (the one-step fit
    /// beats that of the simulation-focus model, whose `K` is 0).
    #[test]
    fn large_simulation_weight_approaches_the_simulation_focus() {
        let (data, start) = low_order_start(35, 1000, 0.5, 11);
        let run = |focus: Focus, simulation_weight: f64| {
            let s = PemSettings {
                focus,
                simulation_weight,
                max_iterations: 40,
                ..Default::default()
            };
            pem(&data, &start, &s).unwrap().model
        };
        let sim = run(Focus::Simulation, 0.0);
        let heavy = run(Focus::Prediction, 1e4);
        let plain = run(Focus::Prediction, 0.0);
        let (fs, fh, fp) = (
            mean_sim_fit(&sim, &data),
            mean_sim_fit(&heavy, &data),
            mean_sim_fit(&plain, &data),
        );
        let one = |m: &InnovationModel| mean_one_step_fit(m, &data);
        eprintln!(
            "simulation fit: focus {fs:.3}, weight 1e4 {fh:.3}, plain {fp:.3}; one-step: focus {:.3}, weight 1e4 {:.3}",
            one(&sim),
            one(&heavy)
        );
        assert!(
            fs > fp + 0.5,
            "the test needs the two foci apart: {fs} vs {fp}"
        );
        assert!((fh - fs).abs() < 0.05, "{fh} vs {fs}");
        assert!(one(&heavy) > one(&sim) + 0.5);
    }

    /// The simulation weight is checked: negative or not finite, with the
    /// simulation focus, fixed dynamics or the determinant criterion.
    #[test]
    fn bad_simulation_weights_are_errors() {
        let m = synthetic::random_model(2, 1, 1, 3, 0.8);
        let data = synthetic::simulate(&m, 300, 0.1, 1).unwrap();
        let bad = [
            PemSettings {
                simulation_weight: -1.0,
                ..Default::default()
            },
            PemSettings {
                simulation_weight: f64::NAN,
                ..Default::default()
            },
            PemSettings {
                simulation_weight: f64::INFINITY,
                ..Default::default()
            },
            PemSettings {
                simulation_weight: 1.0,
                focus: Focus::Simulation,
                ..Default::default()
            },
            PemSettings {
                simulation_weight: 1.0,
                fixed_dynamics: true,
                ..Default::default()
            },
            PemSettings {
                simulation_weight: 1.0,
                criterion: Criterion::Determinant,
                ..Default::default()
            },
        ];
        for s in &bad {
            assert!(
                matches!(pem(&data, &m, s), Err(SysidError::InvalidArgument(_))),
                "{s:?}"
            );
        }
    }

    #[test]
    fn too_few_samples_and_unstable_start_are_errors() {
        let m = synthetic::random_model(4, 2, 2, 4, 0.8);
        let data = synthetic::simulate(&m, 20, 0.3, 5).unwrap();
        assert!(matches!(
            pem(&data, &m, &PemSettings::default()),
            Err(SysidError::TooFewSamples { .. })
        ));
        let data = synthetic::simulate(&m, 500, 0.3, 5).unwrap();
        let mut bad = m.clone();
        bad.a *= 2.0;
        assert!(matches!(
            pem(&data, &bad, &PemSettings::default()),
            Err(SysidError::Unstable { .. })
        ));
    }
}
