//! The condensed parametric QP (6.19)-(6.26) with the errata applied,
//! generalised: input-move terms, output and state bounds (hard or soft),
//! reference preview, an input target, parameter-dependent bounds and a
//! terminal set.

use crate::constraints::{Bounds, InputTarget};
use crate::design::{MpcSettings, Terminal, check_hessian, check_psd};
use crate::error::MpcError;
use crate::layout::ThetaLayout;
use crate::rows::{ConstraintKind, RowLabel, RowSet, Side};
use kestrel_core::formats::MpqpProblem;
use kestrel_core::{DiscreteLinearModel, Scalar};
use nalgebra::{DMatrix, DVector};

/// A condensed MPC problem: the plain matrices of (6.26) with the errata
/// applied, the parameter box, and what is needed to evaluate the cost.
///
/// minimise over `z = [input moves (one per block, nu each); slacks]`:
/// `1/2 z'Hz + theta'F z + q'z`, subject to `G z <= W + E theta`, where
/// `theta` is laid out as [`ThetaLayout`] says (the thesis's problems:
/// `[x; r; throttle]` with the throttle an extra parameter).
///
/// The full cost (6.3a) including the part that does not depend on `z` is
/// `J = 1/2 z'Hz + theta'F z + q'z + 1/2 theta'Y theta + c'theta + c0`
/// ([`MpcProblem::cost`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MpcProblem {
    /// Hessian `H` (`n x n`, symmetric positive definite).
    pub h: DMatrix<f64>,
    /// Linear-term map `F` (`p x n`): the linear term is `F' theta + q`.
    pub f: DMatrix<f64>,
    /// Constant linear term `q` (`n`; non-zero for a fixed input target
    /// or a soft bound's linear penalty).
    pub q: DVector<f64>,
    /// Constraint matrix `G` (`m x n`); [`MpcProblem::rows`] names each row.
    pub g: DMatrix<f64>,
    /// Constraint offsets `W` (`m`).
    pub w: DVector<f64>,
    /// Constraint parameter map `E` (`m x p`).
    pub e: DMatrix<f64>,
    /// Constant cost term `Y` (`p x p`): `J = ... + 1/2 theta'Y theta`.
    pub y: DMatrix<f64>,
    /// Constant cost term `c` (`p`): `J = ... + c'theta`.
    pub c: DVector<f64>,
    /// Constant cost term `c0`.
    pub c0: f64,
    /// Lower corner of the parameter box (`p`).
    pub theta_lb: DVector<f64>,
    /// Upper corner of the parameter box (`p`).
    pub theta_ub: DVector<f64>,
    /// The layout of `theta`.
    pub layout: ThetaLayout,
    /// Number of model inputs.
    pub nu: usize,
    /// Prediction horizon `N`.
    pub horizon: usize,
    /// Move-blocking lengths (sum `N`).
    pub blocks: Vec<usize>,
    /// Number of slack variables (the last entries of `z`).
    pub n_slack: usize,
    /// The terminal state weight in use (`C'Q1N C` for an output terminal
    /// weight, the Riccati solution for the LQ weight, zero for none).
    pub terminal_weight: DMatrix<f64>,
    /// What each row of `G` states.
    pub rows: Vec<RowLabel>,
    /// The settings the problem was built with.
    pub settings: MpcSettings,
}

/// The prediction model and the maps from `theta` to the references of
/// each cost term (affine in `theta`).
pub(crate) struct Prediction {
    pub a: DMatrix<f64>,
    pub b: DMatrix<f64>,
    pub c: DMatrix<f64>,
    /// Selects the states the terminal weight, the state bounds and the
    /// terminal set apply to (`nt x nx`).
    pub terminal_sel: DMatrix<f64>,
    /// Terminal state reference (`nt x p`).
    pub x_ref: DMatrix<f64>,
    /// Input reference (`nu x p`) ...
    pub u_ref: DMatrix<f64>,
    /// ... plus this constant (`nu`).
    pub u_ref_const: DVector<f64>,
    /// Physical model used for the LQ terminal weight: `(A, B, C)`.
    pub lq_model: (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>),
}

/// An affine residual `Mz z + Mt theta + m0` with its weight, summed into
/// the cost.
struct CostSum {
    h: DMatrix<f64>,
    f: DMatrix<f64>,
    q: DVector<f64>,
    y: DMatrix<f64>,
    c: DVector<f64>,
    c0: f64,
}

impl CostSum {
    fn new(n: usize, p: usize) -> Self {
        CostSum {
            h: DMatrix::zeros(n, n),
            f: DMatrix::zeros(p, n),
            q: DVector::zeros(n),
            y: DMatrix::zeros(p, p),
            c: DVector::zeros(p),
            c0: 0.0,
        }
    }
    /// Adds `1/2 |Mz z + Mt theta + m0|^2_W`.
    fn add(&mut self, mz: &DMatrix<f64>, mt: &DMatrix<f64>, m0: &DVector<f64>, w: &DMatrix<f64>) {
        let wmz = w * mz;
        let wm0 = w * m0;
        self.h += mz.transpose() * &wmz;
        self.f += mt.transpose() * &wmz;
        self.q += mz.transpose() * &wm0;
        self.y += mt.transpose() * w * mt;
        self.c += mt.transpose() * &wm0;
        self.c0 += 0.5 * m0.dot(&wm0);
    }
}

/// The matrices of a [`DiscreteLinearModel`] as nalgebra matrices, checked
/// for finiteness and a zero feed-through.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelMatrices {
    /// `A`.
    pub a: DMatrix<f64>,
    /// `B`.
    pub b: DMatrix<f64>,
    /// `C`.
    pub c: DMatrix<f64>,
}

impl ModelMatrices {
    /// Reads and checks a model.
    pub fn from_model<M: DiscreteLinearModel>(model: &M) -> Result<Self, MpcError> {
        let (nx, nu, ny) = (model.nx(), model.nu(), model.ny());
        if nx == 0 || nu == 0 || ny == 0 {
            return Err(MpcError::dim(
                "model",
                "at least one state, input and output",
                format!("nx = {nx}, nu = {nu}, ny = {ny}"),
            ));
        }
        if !(model.sample_time().is_finite() && model.sample_time() > 0.0) {
            return Err(MpcError::setting(
                "model sample time",
                format!(
                    "the MPC needs a discrete-time model (ts > 0), found ts = {}",
                    model.sample_time()
                ),
            ));
        }
        let a = DMatrix::from_fn(nx, nx, |i, j| model.a(i, j).to_f64());
        let b = DMatrix::from_fn(nx, nu, |i, j| model.b(i, j).to_f64());
        let c = DMatrix::from_fn(ny, nx, |i, j| model.c(i, j).to_f64());
        let d = DMatrix::from_fn(ny, nu, |i, j| model.d(i, j).to_f64());
        for (what, m) in [
            ("model A", &a),
            ("model B", &b),
            ("model C", &c),
            ("model D", &d),
        ] {
            if m.iter().any(|v| !v.is_finite()) {
                return Err(MpcError::NonFinite(what.into()));
            }
        }
        let dmax = d.amax();
        if dmax > 1e-12 * c.amax().max(1.0) {
            return Err(MpcError::FeedThrough { max_abs: dmax });
        }
        Ok(ModelMatrices { a, b, c })
    }
}

impl MpcProblem {
    /// Builds the condensed problem of a model (inputs in deviations from
    /// the trim) with these settings.
    ///
    /// Settings are checked first ([`MpcSettings::validate`]); a size whose
    /// condensing would exceed a documented limit
    /// ([`MAX_DECISION_VARIABLES`](crate::MAX_DECISION_VARIABLES) decision
    /// variables, or the memory and time of [`CondensingCost`](crate::CondensingCost))
    /// is refused with [`MpcError::TooLarge`] before anything is allocated.
    ///
    /// ```
    /// use kestrel_core::{Matrix, StateSpace};
    /// use kestrel_mpc::{Bounds, MpcProblem, MpcSettings, Terminal, Weight};
    /// use nalgebra::dvector;
    /// // A double integrator sampled at 0.1 s, |u| <= 1.
    /// let m = StateSpace::new(
    ///     Matrix::from_rows([[1.0, 0.1], [0.0, 1.0]]), Matrix::from_rows([[0.005], [0.1]]),
    ///     Matrix::from_rows([[1.0, 0.0]]), Matrix::from_rows([[0.0]]), 0.1);
    /// let settings = MpcSettings { horizon: 5, terminal: Terminal::StageWeight,
    ///     q2: Weight::Scalar(0.1), input_bounds: Some(Bounds::new(dvector![-1.0], dvector![1.0])),
    ///     ..MpcSettings::default() };
    /// let p = MpcProblem::build(&m, &settings).unwrap();
    /// assert_eq!((p.n(), p.m(), p.p()), (5, 10, 3)); // theta = [x1, x2, r]
    /// assert_eq!(p.row_label(7), "input 0 lower bound at step 2");
    /// let mpqp = p.to_mpqp();
    /// assert_eq!(mpqp.h, p.h);
    /// ```
    pub fn build<M: DiscreteLinearModel>(
        model: &M,
        settings: &MpcSettings,
    ) -> Result<Self, MpcError> {
        let mm = ModelMatrices::from_model(model)?;
        let (nx, nu, ny) = (mm.a.nrows(), mm.b.ncols(), mm.c.nrows());
        settings.validate(nu, ny, nx)?;
        let layout = ThetaLayout {
            nx,
            nu_prev: if settings.uses_previous_input() {
                nu
            } else {
                0
            },
            ny,
            preview: settings.preview,
            nu_target: if settings.input_target == InputTarget::Parameter {
                nu
            } else {
                0
            },
            np: settings.parameters.len(),
        };
        let p = layout.len();
        // Terminal reference map C^+ r_P (7.19).
        let pinv =
            mm.c.clone()
                .pseudo_inverse(1e-12)
                .map_err(|e| MpcError::setting("C", format!("pseudo-inverse failed: {e}")))?;
        let mut x_ref = DMatrix::zeros(nx, p);
        x_ref
            .view_mut((0, layout.reference(layout.preview - 1).start), (nx, ny))
            .copy_from(&pinv);
        let (u_ref, u_ref_const) = input_target_maps(settings, layout, nu);
        let pred = Prediction {
            a: mm.a.clone(),
            b: mm.b.clone(),
            c: mm.c.clone(),
            terminal_sel: DMatrix::identity(nx, nx),
            x_ref,
            u_ref,
            u_ref_const,
            lq_model: (mm.a, mm.b, mm.c),
        };
        Self::condense(&pred, layout, settings)
    }

    /// The general condensing, shared by the plain and the offset-free builds.
    pub(crate) fn condense(
        pred: &Prediction,
        layout: ThetaLayout,
        settings: &MpcSettings,
    ) -> Result<Self, MpcError> {
        let (nx, nu, ny) = (pred.a.nrows(), pred.b.ncols(), pred.c.nrows());
        let nt = pred.terminal_sel.nrows();
        let p = layout.len();
        let n_h = settings.horizon;
        // The size is checked before the blocking (N ones) is allocated.
        let nb = settings.blocking.as_ref().map_or(n_h, |b| b.count());
        crate::limits::CondensingCost::of(nx, nu, ny, p, n_h, nb).check(n_h, nb)?;
        let blocking = settings.blocking();
        if blocking.total() != n_h {
            return Err(MpcError::setting(
                "blocks",
                format!(
                    "block lengths {:?} sum to {}, but the horizon is N = {n_h}",
                    blocking.lengths(),
                    blocking.total()
                ),
            ));
        }
        let q1 = settings.q1.resolve(ny, "Q1")?;
        let q2 = settings.q2.resolve(nu, "Q2")?;
        let qdu = match &settings.du_weight {
            Some(w) => Some(w.resolve(nu, "du_weight")?),
            None => None,
        };
        // Terminal weight on the state error T x_N - x_ref, or on the output error.
        enum Term {
            Output(DMatrix<f64>),
            State(DMatrix<f64>),
            None,
        }
        let term = match &settings.terminal {
            Terminal::StageWeight => Term::Output(q1.clone()),
            Terminal::Output(w) => Term::Output(w.resolve(ny, "Q1N")?),
            Terminal::State(pm) => {
                if pm.shape() != (nt, nt) {
                    return Err(MpcError::dim(
                        "terminal state weight P",
                        format!("a {nt} x {nt} matrix"),
                        format!("a {} x {} matrix", pm.nrows(), pm.ncols()),
                    ));
                }
                check_psd(pm, "terminal state weight P")?;
                Term::State(pm.clone())
            }
            Terminal::Lq => {
                let (a, b, c) = &pred.lq_model;
                Term::State(crate::lq::lq_terminal_weight(a, b, c, &q1, &q2)?)
            }
            Terminal::None => Term::None,
        };

        // Slack variables: one per bounded entry of each soft family.
        let nb = blocking.count();
        let nm = nb * nu;
        let families = [
            (ConstraintKind::Input, &settings.input_bounds),
            (ConstraintKind::InputMove, &settings.du_bounds),
            (ConstraintKind::Output, &settings.output_bounds),
            (ConstraintKind::State, &settings.state_bounds),
        ];
        let mut n_slack = 0;
        let mut slack_of: Vec<Vec<Option<usize>>> = Vec::new();
        for (_, b) in &families {
            let mut map = Vec::new();
            if let Some(b) = b {
                for i in 0..b.len() {
                    if b.soft.is_some() && b.is_bounded(i) {
                        map.push(Some(nm + n_slack));
                        n_slack += 1;
                    } else {
                        map.push(None);
                    }
                }
            }
            slack_of.push(map);
        }
        let n = nm + n_slack;

        // Prediction x_j = A^j x0 + sum_{i<j} A^(j-1-i) B u_i, with
        // u_i = z_{block(i)} and x0 = theta[0..nx]. The first block column
        // of S_u is [0; B; AB; ...] (errata for (6.13)).
        let block_of = blocking.block_of_step();
        let mut xz: Vec<DMatrix<f64>> = Vec::with_capacity(n_h + 1); // nx x n
        let mut xt: Vec<DMatrix<f64>> = Vec::with_capacity(n_h + 1); // nx x p
        let mut x0t = DMatrix::zeros(nx, p);
        x0t.view_mut((0, 0), (nx, nx))
            .copy_from(&DMatrix::identity(nx, nx));
        xz.push(DMatrix::zeros(nx, n));
        xt.push(x0t);
        for (j, &bj) in block_of.iter().enumerate() {
            let mut next_z = &pred.a * &xz[j];
            let mut col = next_z.view_mut((0, bj * nu), (nx, nu));
            col += &pred.b;
            let next_t = &pred.a * &xt[j];
            xz.push(next_z);
            xt.push(next_t);
        }
        // Reference of step j: r_min(max(j, 1), P).
        let r_sel = |j: usize| {
            let k = j.clamp(1, layout.preview) - 1;
            let mut s = DMatrix::zeros(ny, p);
            s.view_mut((0, layout.reference(k).start), (ny, ny))
                .copy_from(&DMatrix::identity(ny, ny));
            s
        };
        // The input of step j as a map of z, and the previous input's
        // selection in theta.
        let u_of = |j: usize| {
            let mut uz = DMatrix::zeros(nu, n);
            uz.view_mut((0, block_of[j] * nu), (nu, nu))
                .copy_from(&DMatrix::identity(nu, nu));
            uz
        };
        let mut uprev_sel = DMatrix::zeros(nu, p);
        if layout.nu_prev > 0 {
            uprev_sel
                .view_mut((0, layout.previous_input().start), (nu, nu))
                .copy_from(&DMatrix::identity(nu, nu));
        }

        let mut sum = CostSum::new(n, p);
        let zero_ny = DVector::zeros(ny);
        let zero_nu = DVector::zeros(nu);
        for j in 0..n_h {
            // Output error C x_j - r_j (j = 0 is constant in z but part of J).
            sum.add(
                &(&pred.c * &xz[j]),
                &(&pred.c * &xt[j] - r_sel(j)),
                &zero_ny,
                &q1,
            );
            // Input u_j - u_ref.
            sum.add(&u_of(j), &(-&pred.u_ref), &(-&pred.u_ref_const), &q2);
            // Input move u_j - u_{j-1}: non-zero at the start of a block.
            if let Some(qdu) = &qdu {
                if j == 0 {
                    sum.add(&u_of(0), &(-&uprev_sel), &zero_nu, qdu);
                } else if block_of[j] != block_of[j - 1] {
                    sum.add(
                        &(u_of(j) - u_of(j - 1)),
                        &DMatrix::zeros(nu, p),
                        &zero_nu,
                        qdu,
                    );
                }
            }
        }
        let terminal_weight = match &term {
            Term::Output(q1n) => {
                sum.add(
                    &(&pred.c * &xz[n_h]),
                    &(&pred.c * &xt[n_h] - r_sel(n_h)),
                    &zero_ny,
                    q1n,
                );
                pred.c.transpose() * q1n * &pred.c
            }
            Term::State(pm) => {
                sum.add(
                    &(&pred.terminal_sel * &xz[n_h]),
                    &(&pred.terminal_sel * &xt[n_h] - &pred.x_ref),
                    &DVector::zeros(nt),
                    pm,
                );
                pm.clone()
            }
            Term::None => DMatrix::zeros(nt, nt),
        };
        // Slack penalties.
        for ((_, b), map) in families.iter().zip(&slack_of) {
            if let Some(Some(sp)) = b.as_ref().map(|b| b.soft) {
                for s in map.iter().flatten() {
                    sum.h[(*s, *s)] += sp.quadratic;
                    sum.q[*s] += sp.linear;
                }
            }
        }
        let h = (&sum.h + sum.h.transpose()) * 0.5;
        let y = (&sum.y + sum.y.transpose()) * 0.5;
        check_hessian(&h)?;

        // Constraints.
        let step_x = |j: usize| (&pred.terminal_sel * &xz[j], &pred.terminal_sel * &xt[j]);
        let mut rows = RowSet::new();
        let params = layout.parameters();
        let block_start = blocking_starts(blocking.lengths());
        if let Some(b) = &settings.input_bounds {
            bound_rows(
                &mut rows,
                params.clone(),
                b,
                &slack_of[0],
                ConstraintKind::Input,
                |blk| {
                    (
                        u_of(block_start[blk]),
                        DMatrix::zeros(nu, p),
                        block_start[blk],
                    )
                },
                nb,
            );
        }
        if let Some(b) = &settings.du_bounds {
            bound_rows(
                &mut rows,
                params.clone(),
                b,
                &slack_of[1],
                ConstraintKind::InputMove,
                |blk| {
                    let j = block_start[blk];
                    if blk == 0 {
                        (u_of(0), -&uprev_sel, 0)
                    } else {
                        (u_of(j) - u_of(j - 1), DMatrix::zeros(nu, p), j)
                    }
                },
                nb,
            );
        }
        if let Some(b) = &settings.output_bounds {
            bound_rows(
                &mut rows,
                params.clone(),
                b,
                &slack_of[2],
                ConstraintKind::Output,
                |k| (&pred.c * &xz[k + 1], &pred.c * &xt[k + 1], k + 1),
                n_h,
            );
        }
        if let Some(b) = &settings.state_bounds {
            bound_rows(
                &mut rows,
                params.clone(),
                b,
                &slack_of[3],
                ConstraintKind::State,
                |k| {
                    let (vz, vt) = step_x(k + 1);
                    (vz, vt, k + 1)
                },
                n_h,
            );
        }
        if let Some(ts) = &settings.terminal_set {
            let (vz, vt) = step_x(n_h);
            let (az, at) = (&ts.a * vz, &ts.a * vt);
            for i in 0..ts.a.nrows() {
                let label = RowLabel {
                    kind: ConstraintKind::TerminalSet,
                    side: Side::Upper,
                    index: i,
                    step: n_h,
                    soft: false,
                };
                rows.push(
                    az.row(i).transpose(),
                    ts.b[i],
                    -at.row(i).transpose(),
                    label,
                );
            }
        }
        for s in 0..n_slack {
            let mut g = DVector::zeros(n);
            g[nm + s] = -1.0;
            let label = RowLabel {
                kind: ConstraintKind::Slack,
                side: Side::Lower,
                index: s,
                step: 0,
                soft: false,
            };
            rows.push(g, 0.0, DVector::zeros(p), label);
        }
        let (g, w, e) = rows.matrices(n, p);
        let (theta_lb, theta_ub) = theta_box(layout, settings);
        Ok(MpcProblem {
            h,
            f: sum.f,
            q: sum.q,
            g,
            w,
            e,
            y,
            c: sum.c,
            c0: sum.c0,
            theta_lb,
            theta_ub,
            layout,
            nu,
            horizon: n_h,
            blocks: blocking.lengths().to_vec(),
            n_slack,
            terminal_weight,
            rows: rows.labels,
            settings: settings.clone(),
        })
    }

    /// Number of decision variables `n` (blocks times inputs, plus slacks).
    pub fn n(&self) -> usize {
        self.h.nrows()
    }
    /// Number of parameters `p`.
    pub fn p(&self) -> usize {
        self.f.nrows()
    }
    /// Number of constraints `m`.
    pub fn m(&self) -> usize {
        self.g.nrows()
    }

    /// What row `i` of `G` states, e.g. `"output 1 upper bound at step 3
    /// (soft)"` (empty past the last row).
    pub fn row_label(&self, i: usize) -> String {
        self.rows.get(i).map_or_else(String::new, |l| l.to_string())
    }

    /// `theta = [x; r]` for a problem without the previous input in it
    /// (`r` is the law's reference vector: references, input target,
    /// parameters); a problem with input-move terms needs
    /// [`MpcProblem::theta_with_previous`].
    pub fn theta(&self, x: &[f64], r: &[f64]) -> Result<DVector<f64>, MpcError> {
        if self.layout.nu_prev > 0 {
            return Err(MpcError::setting(
                "theta",
                "this problem has the previous input in theta (input-move weight or bounds): use theta_with_previous",
            ));
        }
        self.theta_with_previous(x, &[], r)
    }

    /// `theta = [x; u_prev; r]` ([`ThetaLayout`]).
    pub fn theta_with_previous(
        &self,
        x: &[f64],
        u_prev: &[f64],
        r: &[f64],
    ) -> Result<DVector<f64>, MpcError> {
        let mut t = DVector::zeros(self.p());
        self.layout.assemble_into(x, u_prev, r, t.as_mut_slice())?;
        Ok(t)
    }

    /// The full cost `J(z, theta)` of (6.3a), constant part included.
    pub fn cost(&self, z: &DVector<f64>, theta: &DVector<f64>) -> f64 {
        0.5 * z.dot(&(&self.h * z))
            + theta.dot(&(&self.f * z))
            + self.q.dot(z)
            + 0.5 * theta.dot(&(&self.y * theta))
            + self.c.dot(theta)
            + self.c0
    }

    /// The first input move (the `nu` inputs applied now) of a solution `z`.
    pub fn first_move<'a>(&self, z: &'a [f64]) -> &'a [f64] {
        &z[..self.nu.min(z.len())]
    }

    /// The problem in the interchange form `kestrel.mpqp.v1`.
    pub fn to_mpqp(&self) -> MpqpProblem {
        MpqpProblem {
            h: self.h.clone(),
            f_theta: self.f.clone(),
            f: self.q.clone(),
            g: self.g.clone(),
            w: self.w.clone(),
            e: self.e.clone(),
            theta_lb: self.theta_lb.clone(),
            theta_ub: self.theta_ub.clone(),
            theta_poly: None,
        }
    }
}

/// The input target as `u_ref = U theta + u0`.
pub(crate) fn input_target_maps(
    settings: &MpcSettings,
    layout: ThetaLayout,
    nu: usize,
) -> (DMatrix<f64>, DVector<f64>) {
    let mut u_ref = DMatrix::zeros(nu, layout.len());
    let mut u_const = DVector::zeros(nu);
    match &settings.input_target {
        InputTarget::Zero => {}
        InputTarget::Fixed(t) => u_const.copy_from(t),
        InputTarget::Parameter => {
            u_ref
                .view_mut((0, layout.input_target().start), (nu, nu))
                .copy_from(&DMatrix::identity(nu, nu));
        }
    }
    (u_ref, u_const)
}

/// The first step of each block.
fn blocking_starts(lengths: &[usize]) -> Vec<usize> {
    lengths
        .iter()
        .scan(0, |s, &l| {
            let start = *s;
            *s += l;
            Some(start)
        })
        .collect()
}

/// The parameter box: states, previous input, references, input target,
/// parameters.
fn theta_box(layout: ThetaLayout, settings: &MpcSettings) -> (DVector<f64>, DVector<f64>) {
    let p = layout.len();
    let mut lb = DVector::zeros(p);
    let mut ub = DVector::zeros(p);
    for i in layout.state() {
        lb[i] = -settings.state_bound;
        ub[i] = settings.state_bound;
    }
    for i in layout.references() {
        lb[i] = -settings.reference_bound;
        ub[i] = settings.reference_bound;
    }
    let input_range = settings
        .input_bounds
        .as_ref()
        .map(|b| b.range_over(&settings.parameters));
    for range in [layout.previous_input(), layout.input_target()] {
        for (k, i) in range.enumerate() {
            let fallback = settings.input_parameter_bound;
            let (lo, hi) = input_range.as_ref().map_or((-fallback, fallback), |r| {
                let lo = if r.lower[k].is_finite() {
                    r.lower[k]
                } else {
                    -fallback
                };
                let hi = if r.upper[k].is_finite() {
                    r.upper[k]
                } else {
                    fallback
                };
                (lo, hi)
            });
            lb[i] = lo;
            ub[i] = hi;
        }
    }
    for (k, i) in layout.parameters().enumerate() {
        lb[i] = settings.parameters[k].min;
        ub[i] = settings.parameters[k].max;
    }
    (lb, ub)
}

/// `sign * v` with every zero a positive zero.
fn signed(v: &DVector<f64>, sign: f64) -> DVector<f64> {
    v.map(|x| if x == 0.0 { 0.0 } else { sign * x })
}

/// The rows of one bound family over `count` items (blocks or steps):
/// `at(item)` gives the bounded vector as `Vz z + Vt theta` and the step it
/// belongs to; `params` are the extra parameters' entries of `theta` (the
/// columns the shifts go to). All upper rows first, then all lower rows.
fn bound_rows(
    rows: &mut RowSet,
    params: core::ops::Range<usize>,
    b: &Bounds,
    slack: &[Option<usize>],
    kind: ConstraintKind,
    at: impl Fn(usize) -> (DMatrix<f64>, DMatrix<f64>, usize),
    count: usize,
) {
    let items: Vec<_> = (0..count).map(&at).collect();
    for side in [Side::Upper, Side::Lower] {
        let (base, shift, sign) = match side {
            Side::Upper => (&b.upper, &b.upper_shift, 1.0),
            Side::Lower => (&b.lower, &b.lower_shift, -1.0),
        };
        for (vz, vt, step) in &items {
            for i in 0..b.len() {
                if !base[i].is_finite() {
                    continue;
                }
                // sign (Vz z + Vt theta) <= sign (base + shift p) (+ s).
                // Zeros stay +0 and a shift is stored as given, so the
                // thesis's problems come out bit for bit as before.
                let mut g = signed(&vz.row(i).transpose(), sign);
                let mut e = signed(&vt.row(i).transpose(), -sign);
                if let Some(s) = shift {
                    for (k, col) in params.clone().enumerate() {
                        let v = sign * s[(i, k)];
                        e[col] = if e[col] == 0.0 { v } else { e[col] + v };
                    }
                }
                if let Some(s) = slack[i] {
                    g[s] = -1.0;
                }
                let label = RowLabel {
                    kind,
                    side,
                    index: i,
                    step: *step,
                    soft: slack[i].is_some(),
                };
                rows.push(g, sign * base[i], e, label);
            }
        }
    }
}

#[cfg(test)]
mod feature_tests;
#[cfg(test)]
pub(crate) mod tests;
