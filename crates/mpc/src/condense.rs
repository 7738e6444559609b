//! The condensed parametric QP (6.19)-(6.26) with the errata applied.

use crate::design::{InputBounds, MpcSettings, Terminal, check_hessian, check_psd};
use crate::error::MpcError;
use kestrel_core::formats::MpqpProblem;
use kestrel_core::{DiscreteLinearModel, Scalar};
use nalgebra::{DMatrix, DVector};

/// Where each part of the parameter vector `theta` sits:
/// `theta = [x (nx); r (nr); throttle (0 or 1)]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ThetaLayout {
    /// Number of states (the estimate the law reads).
    pub nx: usize,
    /// Number of references (one per output).
    pub nr: usize,
    /// Whether the last entry is the throttle.
    pub throttle: bool,
}

impl ThetaLayout {
    /// Length of `theta`.
    pub fn len(&self) -> usize {
        self.nx + self.nr + usize::from(self.throttle)
    }
    /// Whether `theta` is empty (never for a built problem).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Number of entries after the state: the references plus the
    /// throttle, i.e. the `r` a [`kestrel_core::ControlLaw`] reads.
    pub fn n_law_reference(&self) -> usize {
        self.nr + usize::from(self.throttle)
    }
    /// Index of the throttle entry, if any.
    pub fn throttle_index(&self) -> Option<usize> {
        self.throttle.then_some(self.nx + self.nr)
    }
    /// Writes `theta = [x; r]` where `r` holds the references and, if the
    /// layout has one, the throttle last; lengths are checked.
    pub fn assemble_into(
        &self,
        x: &[f64],
        r: &[f64],
        theta: &mut [f64],
    ) -> Result<(), kestrel_core::Error> {
        kestrel_core::check_len(x, self.nx)?;
        kestrel_core::check_len(r, self.n_law_reference())?;
        kestrel_core::check_len(theta, self.len())?;
        theta[..self.nx].copy_from_slice(x);
        theta[self.nx..].copy_from_slice(r);
        Ok(())
    }
}

/// A condensed MPC problem: the plain matrices of (6.26) with the errata
/// applied, the parameter box, and what is needed to evaluate the cost.
///
/// minimise over `z` (the blocked input moves, deviations from the trim):
/// `1/2 z'Hz + theta'F z`, subject to `G z <= W + E theta`, where
/// `theta = [x; r; throttle]` ([`ThetaLayout`]).
///
/// The full cost (6.3a) including the part that does not depend on `z` is
/// `J = 1/2 z'Hz + theta'F z + 1/2 theta'Y theta` ([`MpcProblem::cost`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MpcProblem {
    /// Hessian `H` (`n x n`, symmetric positive definite).
    pub h: DMatrix<f64>,
    /// Linear-term map `F` (`p x n`): the linear term is `F' theta`.
    pub f: DMatrix<f64>,
    /// Constraint matrix `G = [I; -I]` over the blocked inputs (`m x n`).
    pub g: DMatrix<f64>,
    /// Constraint offsets `W = [upper; -lower]` stacked over the blocks (`m`).
    pub w: DVector<f64>,
    /// Constraint parameter map `E` (`m x p`), non-zero only in the throttle column (6.23).
    pub e: DMatrix<f64>,
    /// Constant cost term `Y` (`p x p`): `J = ... + 1/2 theta'Y theta`.
    pub y: DMatrix<f64>,
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
    /// The terminal state weight in use (`C'Q1N C` for an output terminal
    /// weight, the Riccati solution for the LQ weight).
    pub terminal_weight: DMatrix<f64>,
    /// The input bounds the problem was built with.
    pub bounds: InputBounds,
}

/// The prediction model and the maps from `theta` to the references of
/// each cost term (all linear in `theta`).
pub(crate) struct Prediction {
    pub a: DMatrix<f64>,
    pub b: DMatrix<f64>,
    pub c: DMatrix<f64>,
    /// Selects the states the terminal weight applies to (`nt x nx`).
    pub terminal_sel: DMatrix<f64>,
    /// Terminal state reference (`nt x p`).
    pub x_ref: DMatrix<f64>,
    /// Input reference (`nu x p`).
    pub u_ref: DMatrix<f64>,
    /// Physical model used for the LQ terminal weight: `(A, B, C)`.
    pub lq_model: (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>),
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
    /// Builds the condensed problem for a model (inputs in deviations from
    /// the trim), input bounds and settings.
    ///
    /// A size whose condensing would exceed a documented limit
    /// ([`MAX_DECISION_VARIABLES`](crate::MAX_DECISION_VARIABLES) decision
    /// variables, or the memory and time of [`CondensingCost`](crate::CondensingCost))
    /// is refused with [`MpcError::TooLarge`] before anything is allocated.
    ///
    /// ```
    /// use kestrel_core::{Matrix, StateSpace};
    /// use kestrel_mpc::{InputBounds, MpcProblem, MpcSettings, Terminal, Weight};
    /// use nalgebra::dvector;
    /// // A double integrator sampled at 0.1 s, |u| <= 1.
    /// let m = StateSpace::new(
    ///     Matrix::from_rows([[1.0, 0.1], [0.0, 1.0]]), Matrix::from_rows([[0.005], [0.1]]),
    ///     Matrix::from_rows([[1.0, 0.0]]), Matrix::from_rows([[0.0]]), 0.1);
    /// let settings = MpcSettings { horizon: 5, terminal: Terminal::StageWeight,
    ///     q2: Weight::Scalar(0.1), ..MpcSettings::default() };
    /// let p = MpcProblem::build(&m, &InputBounds::new(dvector![-1.0], dvector![1.0]), &settings).unwrap();
    /// assert_eq!((p.n(), p.m(), p.p()), (5, 10, 3)); // theta = [x1, x2, r]
    /// let mpqp = p.to_mpqp();
    /// assert_eq!(mpqp.h, p.h);
    /// ```
    pub fn build<M: DiscreteLinearModel>(
        model: &M,
        bounds: &InputBounds,
        settings: &MpcSettings,
    ) -> Result<Self, MpcError> {
        let mm = ModelMatrices::from_model(model)?;
        let (nx, ny) = (mm.a.nrows(), mm.c.nrows());
        let layout = ThetaLayout {
            nx,
            nr: ny,
            throttle: bounds.throttle.is_some(),
        };
        let p = layout.len();
        // Terminal reference map C^+ r (7.19); u_ref = 0 (the thesis weighs
        // the deviation from the trim).
        let pinv =
            mm.c.clone()
                .pseudo_inverse(1e-12)
                .map_err(|e| MpcError::setting("C", format!("pseudo-inverse failed: {e}")))?;
        let mut x_ref = DMatrix::zeros(nx, p);
        x_ref.view_mut((0, nx), (nx, ny)).copy_from(&pinv);
        let pred = Prediction {
            a: mm.a.clone(),
            b: mm.b.clone(),
            c: mm.c.clone(),
            terminal_sel: DMatrix::identity(nx, nx),
            x_ref,
            u_ref: DMatrix::zeros(mm.b.ncols(), p),
            lq_model: (mm.a, mm.b, mm.c),
        };
        Self::condense(&pred, layout, bounds, settings)
    }

    /// The general condensing, shared by the plain and the offset-free builds.
    pub(crate) fn condense(
        pred: &Prediction,
        layout: ThetaLayout,
        bounds: &InputBounds,
        settings: &MpcSettings,
    ) -> Result<Self, MpcError> {
        let (nx, nu, ny) = (pred.a.nrows(), pred.b.ncols(), pred.c.nrows());
        let p = layout.len();
        let n_h = settings.horizon;
        if n_h == 0 {
            return Err(MpcError::setting("horizon", "must be at least 1"));
        }
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
        bounds.validate(nu)?;
        for (what, v) in [
            ("state_bound", settings.state_bound),
            ("reference_bound", settings.reference_bound),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(MpcError::setting(
                    what,
                    format!("must be finite and > 0, found {v}"),
                ));
            }
        }
        let q1 = settings.q1.resolve(ny, "Q1")?;
        let q2 = settings.q2.resolve(nu, "Q2")?;
        let nt = pred.terminal_sel.nrows();
        // Terminal weight on the state error T x_N - x_ref, or on the output error.
        enum Term {
            Output(DMatrix<f64>),
            State(DMatrix<f64>),
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
        };

        // Prediction x_j = A^j x0 + sum_{i<j} A^(j-1-i) B u_i, with
        // u_i = z_{block(i)} and x0 = theta[0..nx]. The first block column
        // of S_u is [0; B; AB; ...] (errata for (6.13)).
        let nb = blocking.count();
        let n = nb * nu;
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
        // Reference selection r = theta[nx..nx+ny].
        let mut r_sel = DMatrix::zeros(ny, p);
        r_sel
            .view_mut((0, layout.nx), (ny, ny))
            .copy_from(&DMatrix::identity(ny, ny));

        // Accumulate residual terms e = Mz z + Mt theta with weight Q:
        // H += Mz'Q Mz, F += Mt'Q Mz, Y += Mt'Q Mt.
        let mut h = DMatrix::zeros(n, n);
        let mut f = DMatrix::zeros(p, n);
        let mut y = DMatrix::zeros(p, p);
        let mut add = |mz: &DMatrix<f64>, mt: &DMatrix<f64>, q: &DMatrix<f64>| {
            let qmz = q * mz;
            h += mz.transpose() * &qmz;
            f += mt.transpose() * &qmz;
            y += mt.transpose() * q * mt;
        };
        for j in 0..n_h {
            // Output error C x_j - r (j = 0 is constant in z but part of J).
            add(&(&pred.c * &xz[j]), &(&pred.c * &xt[j] - &r_sel), &q1);
            // Input u_j - u_ref.
            let mut uz = DMatrix::zeros(nu, n);
            uz.view_mut((0, block_of[j] * nu), (nu, nu))
                .copy_from(&DMatrix::identity(nu, nu));
            add(&uz, &(-&pred.u_ref), &q2);
        }
        let terminal_weight = match &term {
            Term::Output(q1n) => {
                add(&(&pred.c * &xz[n_h]), &(&pred.c * &xt[n_h] - &r_sel), q1n);
                pred.c.transpose() * q1n * &pred.c
            }
            Term::State(pm) => {
                add(
                    &(&pred.terminal_sel * &xz[n_h]),
                    &(&pred.terminal_sel * &xt[n_h] - &pred.x_ref),
                    pm,
                );
                pm.clone()
            }
        };
        let h = (&h + h.transpose()) * 0.5;
        let y = (&y + y.transpose()) * 0.5;
        check_hessian(&h)?;

        // Constraints (6.22d/e), (6.23) with the errata: G = [I; -I] over the
        // blocked inputs, W = [upper...; -lower...], E = [c; -c] in the
        // throttle column.
        let m = 2 * n;
        let mut g = DMatrix::zeros(m, n);
        let mut w = DVector::zeros(m);
        let mut e = DMatrix::zeros(m, p);
        for b in 0..nb {
            for i in 0..nu {
                let k = b * nu + i;
                g[(k, k)] = 1.0;
                g[(n + k, k)] = -1.0;
                w[k] = bounds.upper[i];
                w[n + k] = -bounds.lower[i];
                if let (Some(t), Some(ti)) = (&bounds.throttle, layout.throttle_index()) {
                    e[(k, ti)] = t.coupling[i];
                    e[(n + k, ti)] = -t.coupling[i];
                }
            }
        }

        let mut theta_lb = DVector::zeros(p);
        let mut theta_ub = DVector::zeros(p);
        for i in 0..layout.nx {
            theta_lb[i] = -settings.state_bound;
            theta_ub[i] = settings.state_bound;
        }
        for i in layout.nx..layout.nx + layout.nr {
            theta_lb[i] = -settings.reference_bound;
            theta_ub[i] = settings.reference_bound;
        }
        if let (Some(t), Some(ti)) = (&bounds.throttle, layout.throttle_index()) {
            theta_lb[ti] = t.min;
            theta_ub[ti] = t.max;
        }
        Ok(MpcProblem {
            h,
            f,
            g,
            w,
            e,
            y,
            theta_lb,
            theta_ub,
            layout,
            nu,
            horizon: n_h,
            blocks: blocking.lengths().to_vec(),
            terminal_weight,
            bounds: bounds.clone(),
        })
    }

    /// Number of decision variables `n` (blocks times inputs).
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

    /// `theta = [x; r; throttle]` from its parts (`r` holds the references
    /// and, if the problem has a throttle parameter, the throttle last).
    pub fn theta(&self, x: &[f64], r: &[f64]) -> Result<DVector<f64>, MpcError> {
        let mut t = DVector::zeros(self.p());
        self.layout.assemble_into(x, r, t.as_mut_slice())?;
        Ok(t)
    }

    /// The full cost `J(z, theta)` of (6.3a), constant part included.
    pub fn cost(&self, z: &DVector<f64>, theta: &DVector<f64>) -> f64 {
        0.5 * z.dot(&(&self.h * z))
            + theta.dot(&(&self.f * z))
            + 0.5 * theta.dot(&(&self.y * theta))
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
            f: DVector::zeros(self.n()),
            g: self.g.clone(),
            w: self.w.clone(),
            e: self.e.clone(),
            theta_lb: self.theta_lb.clone(),
            theta_ub: self.theta_ub.clone(),
            theta_poly: None,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::design::{Blocking, Weight};
    use crate::qp::{QpSettings, ReferenceSolver, kkt_residuals, solve_dense};
    use kestrel_core::formats::SsModel;
    use proptest::prelude::*;
    use rand::{RngExt, SeedableRng};
    use rand_xoshiro::SplitMix64;

    /// Reproducible random data from the workspace's seeded generator,
    /// `rand_xoshiro::SplitMix64`.
    pub(crate) struct Rng(SplitMix64);
    impl Rng {
        pub(crate) fn new(seed: u64) -> Self {
            Rng(SplitMix64::seed_from_u64(seed))
        }
        /// Uniform in [-1, 1).
        pub(crate) fn next(&mut self) -> f64 {
            self.0.random::<f64>() * 2.0 - 1.0
        }
        pub(crate) fn mat(&mut self, r: usize, c: usize) -> DMatrix<f64> {
            DMatrix::from_fn(r, c, |_, _| self.next())
        }
        pub(crate) fn psd(&mut self, n: usize, floor: f64) -> DMatrix<f64> {
            let l = self.mat(n, n);
            &l * l.transpose() + DMatrix::identity(n, n) * floor
        }
    }

    /// A random discrete model with spectral radius about 0.95.
    pub(crate) fn random_model(rng: &mut Rng, nx: usize, nu: usize, ny: usize) -> SsModel {
        let a0 = rng.mat(nx, nx);
        let rho = kestrel_core::eig::spectral_radius(&a0).unwrap();
        let a = a0 * (0.95 / rho.max(1e-3));
        SsModel::new(
            0.02,
            a,
            rng.mat(nx, nu),
            rng.mat(ny, nx),
            DMatrix::zeros(ny, nu),
        )
        .unwrap()
    }

    /// The direct (uncondensed) problem in the variables
    /// `v = [x_0, ..., x_N, u_0, ..., u_{N-1}]`, built from the model and
    /// weights only, and solved with clarabel. Returns the inputs of each
    /// block and the optimal cost (constant included).
    #[allow(clippy::too_many_arguments)]
    fn solve_uncondensed(
        m: &SsModel,
        q1: &DMatrix<f64>,
        q2: &DMatrix<f64>,
        term_state: &DMatrix<f64>,
        term_lin: &DVector<f64>,
        term_const: f64,
        blocks: &[usize],
        bounds: &InputBounds,
        x0: &DVector<f64>,
        r: &DVector<f64>,
        throttle: f64,
    ) -> (DVector<f64>, f64) {
        let (nx, nu) = (m.nx(), m.nu());
        let n_h: usize = blocks.iter().sum();
        let nv = (n_h + 1) * nx + n_h * nu;
        let xi = |j: usize| j * nx;
        let ui = |j: usize| (n_h + 1) * nx + j * nu;
        let mut p = DMatrix::zeros(nv, nv);
        let mut q = DVector::zeros(nv);
        let mut cst = term_const;
        let cqc = m.c.transpose() * q1 * &m.c;
        let cqr = m.c.transpose() * q1 * r;
        for j in 0..n_h {
            p.view_mut((xi(j), xi(j)), (nx, nx)).copy_from(&cqc);
            q.rows_mut(xi(j), nx).copy_from(&(-&cqr));
            cst += 0.5 * r.dot(&(q1 * r));
            p.view_mut((ui(j), ui(j)), (nu, nu)).copy_from(q2);
        }
        p.view_mut((xi(n_h), xi(n_h)), (nx, nx))
            .copy_from(term_state);
        q.rows_mut(xi(n_h), nx).copy_from(term_lin);
        let block_of = Blocking::new(blocks.to_vec()).unwrap().block_of_step();
        let n_eq =
            nx + n_h * nx + (1..n_h).filter(|&j| block_of[j] == block_of[j - 1]).count() * nu;
        let mut a_eq = DMatrix::zeros(n_eq, nv);
        let mut b_eq = DVector::zeros(n_eq);
        a_eq.view_mut((0, 0), (nx, nx))
            .copy_from(&DMatrix::identity(nx, nx));
        b_eq.rows_mut(0, nx).copy_from(x0);
        let mut row = nx;
        for j in 0..n_h {
            a_eq.view_mut((row, xi(j + 1)), (nx, nx))
                .copy_from(&DMatrix::identity(nx, nx));
            a_eq.view_mut((row, xi(j)), (nx, nx)).copy_from(&(-&m.a));
            a_eq.view_mut((row, ui(j)), (nx, nu)).copy_from(&(-&m.b));
            row += nx;
        }
        for j in 1..n_h {
            if block_of[j] == block_of[j - 1] {
                a_eq.view_mut((row, ui(j)), (nu, nu))
                    .copy_from(&DMatrix::identity(nu, nu));
                a_eq.view_mut((row, ui(j - 1)), (nu, nu))
                    .copy_from(&(-DMatrix::identity(nu, nu)));
                row += nu;
            }
        }
        let at = bounds.at(throttle);
        let mut a_in = DMatrix::zeros(2 * n_h * nu, nv);
        let mut b_in = DVector::zeros(2 * n_h * nu);
        for j in 0..n_h {
            for i in 0..nu {
                a_in[(j * nu + i, ui(j) + i)] = 1.0;
                b_in[j * nu + i] = at.upper[i];
                a_in[(n_h * nu + j * nu + i, ui(j) + i)] = -1.0;
                b_in[n_h * nu + j * nu + i] = -at.lower[i];
            }
        }
        let v = solve_dense(&p, &q, &a_eq, &b_eq, &a_in, &b_in).unwrap();
        let obj = 0.5 * v.dot(&(&p * &v)) + q.dot(&v) + cst;
        let mut starts = Vec::new();
        let mut s = 0;
        for &l in blocks {
            starts.push(s);
            s += l;
        }
        let z = DVector::from_iterator(
            starts.len() * nu,
            starts
                .iter()
                .flat_map(|&j| v.rows(ui(j), nu).iter().copied().collect::<Vec<_>>()),
        );
        (z, obj)
    }

    #[test]
    fn condensed_matches_uncondensed_clarabel() {
        let mut rng = Rng::new(7);
        let cases: &[(usize, &[usize])] = &[
            (1, &[1]),
            (2, &[2]),
            (2, &[1, 1]),
            (4, &[1, 3]),
            (5, &[1, 1, 1, 1, 1]),
            (10, &[1, 1, 2, 6]),
        ];
        let (mut checked, mut active) = (0, 0);
        for (case, &(n_h, blocks)) in cases.iter().enumerate() {
            for terminal_kind in 0..3 {
                let (nx, nu, ny) = (3 + case % 2, 2, 2);
                let m = random_model(&mut rng, nx, nu, ny);
                let q1 = rng.psd(ny, 0.5) * 10.0;
                let q2 = rng.psd(nu, 0.1) * 0.1;
                let pinv = m.c.clone().pseudo_inverse(1e-12).unwrap();
                let (terminal, pt) = match terminal_kind {
                    0 => (Terminal::StageWeight, None),
                    1 => {
                        let q1n = rng.psd(ny, 0.2);
                        (Terminal::Output(Weight::Matrix(q1n.clone())), Some(q1n))
                    }
                    _ => {
                        let pm = rng.psd(nx, 0.1);
                        (Terminal::State(pm.clone()), None)
                    }
                };
                // Tight, loose and medium bounds, so both regimes occur.
                let wide = [1.0, 30.0, 4.0][terminal_kind];
                let mut bounds = InputBounds::new(
                    DVector::from_fn(nu, |_, _| wide * (-0.5 - 0.3 * rng.next().abs())),
                    DVector::from_fn(nu, |_, _| wide * (0.4 + 0.3 * rng.next().abs())),
                );
                if case % 2 == 0 {
                    bounds = bounds.with_throttle(
                        DVector::from_fn(nu, |i, _| -0.2 * i as f64),
                        -1.0,
                        1.0,
                    );
                }
                let settings = MpcSettings {
                    horizon: n_h,
                    blocking: Some(Blocking::new(blocks.to_vec()).unwrap()),
                    q1: Weight::Matrix(q1.clone()),
                    q2: Weight::Matrix(q2.clone()),
                    terminal: terminal.clone(),
                    state_bound: 3.0,
                    reference_bound: 2.0,
                };
                let prob = MpcProblem::build(&m, &bounds, &settings).unwrap();
                let mpqp = prob.to_mpqp();
                let mut solver = ReferenceSolver::new(&mpqp, QpSettings::default()).unwrap();
                for _ in 0..4 {
                    let x0 = DVector::from_fn(nx, |_, _| 3.0 * rng.next());
                    let r = DVector::from_fn(ny, |_, _| 2.0 * rng.next());
                    let th = rng.next();
                    let mut rr: Vec<f64> = r.iter().copied().collect();
                    if bounds.throttle.is_some() {
                        rr.push(th);
                    }
                    let theta = prob.theta(x0.as_slice(), &rr).unwrap();
                    let sol = solver.solve(&theta).unwrap();
                    let kkt = kkt_residuals(&mpqp, &theta, &sol.z, &sol.lambda);
                    assert!(kkt.max() < 1e-6, "KKT residuals {kkt:?}");
                    active += usize::from(sol.lambda.amax() > 1e-6);
                    let (pterm, lin, cst) = match (&terminal, &pt) {
                        (Terminal::StageWeight, _) => (
                            m.c.transpose() * &q1 * &m.c,
                            -(m.c.transpose() * &q1 * &r),
                            0.5 * r.dot(&(&q1 * &r)),
                        ),
                        (Terminal::Output(_), Some(q1n)) => (
                            m.c.transpose() * q1n * &m.c,
                            -(m.c.transpose() * q1n * &r),
                            0.5 * r.dot(&(q1n * &r)),
                        ),
                        (Terminal::State(pm), _) => {
                            let xr = &pinv * &r;
                            (pm.clone(), -(pm * &xr), 0.5 * xr.dot(&(pm * &xr)))
                        }
                        _ => unreachable!(),
                    };
                    let (z_ref, j_ref) = solve_uncondensed(
                        &m, &q1, &q2, &pterm, &lin, cst, blocks, &bounds, &x0, &r, th,
                    );
                    let scale = z_ref.amax().max(1.0);
                    assert!(
                        (&sol.z - &z_ref).amax() < 1e-5 * scale,
                        "N = {n_h}, blocks {blocks:?}, terminal {terminal_kind}: condensed {} vs direct {}",
                        sol.z,
                        z_ref
                    );
                    let j = prob.cost(&sol.z, &theta);
                    assert!(
                        (j - j_ref).abs() < 1e-6 * j_ref.abs().max(1.0),
                        "cost {j} vs direct {j_ref}"
                    );
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 6 * 3 * 4);
        // Both regimes are exercised: some solutions with active bounds, some without.
        assert!(
            active > 10 && active < checked - 10,
            "{active} of {checked} active"
        );
    }

    #[test]
    fn lq_terminal_weight_solves_riccati_and_gives_lqr_law() {
        let mut rng = Rng::new(21);
        for n_h in [1, 2, 5] {
            let m = random_model(&mut rng, 4, 2, 2);
            let q1 = rng.psd(2, 0.5);
            let q2 = rng.psd(2, 0.2);
            let settings = MpcSettings {
                horizon: n_h,
                q1: Weight::Matrix(q1.clone()),
                q2: Weight::Matrix(q2.clone()),
                terminal: Terminal::Lq,
                ..MpcSettings::default()
            };
            let wide = InputBounds::new(
                DVector::from_element(2, -1e3),
                DVector::from_element(2, 1e3),
            );
            let p = MpcProblem::build(&m, &wide, &settings).unwrap();
            // (7.18) corrected: A'SA - S - A'SB (Q2 + B'SB)^-1 B'SA + C'Q1C = 0.
            let (a, b, s) = (&m.a, &m.b, &p.terminal_weight);
            let bsb = q2 + b.transpose() * s * b;
            let k = bsb
                .clone()
                .cholesky()
                .unwrap()
                .solve(&(b.transpose() * s * a));
            let res = a.transpose() * s * a - s - a.transpose() * s * b * &k
                + m.c.transpose() * &q1 * &m.c;
            assert!(
                res.amax() < 1e-9 * s.amax().max(1.0),
                "Riccati residual {}",
                res.amax()
            );
            // With the cost-to-go as terminal weight and no active bound, the
            // MPC's first move is the LQ law u = -K x (principle of optimality).
            let mut solver = ReferenceSolver::new(&p.to_mpqp(), QpSettings::default()).unwrap();
            for _ in 0..3 {
                let x = DVector::from_fn(4, |_, _| rng.next());
                let sol = solver
                    .solve(&p.theta(x.as_slice(), &[0.0, 0.0]).unwrap())
                    .unwrap();
                let u_lq = -(&k * &x);
                assert!((sol.z.rows(0, 2) - &u_lq).amax() < 1e-6, "N = {n_h}");
            }
        }
    }

    /// Direct rollout of the cost (6.3a) for the output terminal weight.
    fn rollout_cost(
        m: &SsModel,
        q1: &DMatrix<f64>,
        q2: &DMatrix<f64>,
        blocks: &[usize],
        x0: &DVector<f64>,
        r: &DVector<f64>,
        z: &DVector<f64>,
    ) -> f64 {
        let nu = m.nu();
        let mut x = x0.clone();
        let mut j = 0.0;
        for (b, &l) in blocks.iter().enumerate() {
            let u = z.rows(b * nu, nu).into_owned();
            for _ in 0..l {
                let e = &m.c * &x - r;
                j += 0.5 * e.dot(&(q1 * &e)) + 0.5 * u.dot(&(q2 * &u));
                x = &m.a * &x + &m.b * &u;
            }
        }
        let e = &m.c * &x - r;
        j + 0.5 * e.dot(&(q1 * &e))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// J(z, theta) from H, F, Y equals the cost of simulating the model,
        /// for every z and theta (the condensing is exact, not just at the optimum).
        #[test]
        fn cost_equals_rollout(seed in 0u64..1000, n_h in 1usize..6, split in 0usize..3) {
            let mut rng = Rng::new(seed);
            let m = random_model(&mut rng, 3, 2, 2);
            let blocks = match split.min(n_h - 1) {
                0 => vec![n_h],
                k => { let mut v = vec![1; k]; v.push(n_h - k); v }
            };
            let q1 = rng.psd(2, 0.1);
            let q2 = rng.psd(2, 0.1);
            let settings = MpcSettings {
                horizon: n_h,
                blocking: Some(Blocking::new(blocks.clone()).unwrap()),
                q1: Weight::Matrix(q1.clone()),
                q2: Weight::Matrix(q2.clone()),
                terminal: Terminal::StageWeight,
                ..MpcSettings::default()
            };
            let bounds = InputBounds::new(DVector::from_element(2, -1.0), DVector::from_element(2, 1.0));
            let prob = MpcProblem::build(&m, &bounds, &settings).unwrap();
            let x0 = DVector::from_fn(3, |_, _| rng.next());
            let r = DVector::from_fn(2, |_, _| rng.next());
            let z = DVector::from_fn(prob.n(), |_, _| rng.next());
            let theta = prob.theta(x0.as_slice(), r.as_slice()).unwrap();
            let j = prob.cost(&z, &theta);
            let want = rollout_cost(&m, &q1, &q2, &blocks, &x0, &r, &z);
            prop_assert!((j - want).abs() < 1e-10 * want.abs().max(1.0), "{} vs {}", j, want);
        }
    }

    #[test]
    fn thesis_bound_structure_6_23() {
        // Tricopter bounds: E has -1 in the motor rows of the upper block and
        // +1 in the lower block, 0 for the servo; W holds the PWM limits
        // minus the trim.
        let mut rng = Rng::new(3);
        let m = random_model(&mut rng, 5, 4, 3);
        let u0 = [15.63, 0.85, -16.01, -32.3];
        let bounds = InputBounds::new(
            DVector::from_fn(4, |i, _| if i < 3 { 1000.0 } else { -300.0 } - u0[i]),
            DVector::from_fn(4, |i, _| if i < 3 { 2000.0 } else { 300.0 } - u0[i]),
        )
        .with_throttle(
            DVector::from_column_slice(&[-1.0, -1.0, -1.0, 0.0]),
            1000.0,
            2000.0,
        );
        let settings = MpcSettings {
            horizon: 3,
            blocking: Some(Blocking::new(vec![1, 2]).unwrap()),
            terminal: Terminal::StageWeight,
            ..MpcSettings::default()
        };
        let p = MpcProblem::build(&m, &bounds, &settings).unwrap();
        assert_eq!((p.n(), p.m(), p.p()), (8, 16, 9));
        let ti = 8;
        for b in 0..2 {
            for (i, u0i) in u0.iter().enumerate() {
                let k = b * 4 + i;
                let c = if i < 3 { -1.0 } else { 0.0 };
                assert_eq!(p.e[(k, ti)], c);
                assert_eq!(p.e[(8 + k, ti)], -c);
                let (lo, hi) = if i < 3 {
                    (1000.0, 2000.0)
                } else {
                    (-300.0, 300.0)
                };
                assert_eq!(p.w[k], hi - u0i);
                assert_eq!(p.w[8 + k], -(lo - u0i));
            }
        }
        // Only the throttle column of E is non-zero, and F's throttle row is zero.
        assert_eq!(p.e.columns(0, 8).amax(), 0.0);
        assert_eq!(p.f.row(ti).amax(), 0.0);
        // Feasible point at throttle 1500: motors 1000 - 1500 - u0 <= z <= 2000 - 1500 - u0.
        let theta = p.theta(&[0.0; 5], &[0.0, 0.0, 0.0, 1500.0]).unwrap();
        let rhs = &p.w + &p.e * &theta;
        assert!((rhs[0] - (500.0 - 15.63)).abs() < 1e-12);
        assert!((rhs[8] - (500.0 + 15.63)).abs() < 1e-12);
    }

    #[test]
    fn bad_designs_are_clear_errors() {
        let mut rng = Rng::new(11);
        let m = random_model(&mut rng, 3, 2, 2);
        let ok = InputBounds::new(
            DVector::from_element(2, -1.0),
            DVector::from_element(2, 1.0),
        );
        let base = MpcSettings {
            horizon: 3,
            terminal: Terminal::StageWeight,
            ..MpcSettings::default()
        };
        let err = |b: &InputBounds, s: &MpcSettings| MpcProblem::build(&m, b, s).unwrap_err();
        // Infeasible bounds.
        let bad = InputBounds::new(
            DVector::from_vec(vec![-1.0, 2.0]),
            DVector::from_element(2, 1.0),
        );
        let e = err(&bad, &base);
        assert!(
            matches!(e, MpcError::InfeasibleBounds { input: 1, .. }),
            "{e}"
        );
        assert!(e.to_string().contains("infeasible input bounds"));
        // Wrong bound length.
        let short = InputBounds::new(
            DVector::from_element(1, -1.0),
            DVector::from_element(1, 1.0),
        );
        assert!(matches!(err(&short, &base), MpcError::Dimension { .. }));
        // NaN bound.
        let nan = InputBounds::new(
            DVector::from_vec(vec![-1.0, f64::NAN]),
            DVector::from_element(2, 1.0),
        );
        assert!(matches!(err(&nan, &base), MpcError::NonFinite(_)));
        // Mismatched weight dimensions.
        let s = MpcSettings {
            q1: Weight::Matrix(DMatrix::identity(3, 3)),
            ..base.clone()
        };
        let e = err(&ok, &s);
        assert!(
            e.to_string().starts_with("Q1: expected a 2 x 2 matrix"),
            "{e}"
        );
        let s = MpcSettings {
            q2: Weight::Diagonal(vec![1.0]),
            ..base.clone()
        };
        assert!(matches!(err(&ok, &s), MpcError::Dimension { .. }));
        let s = MpcSettings {
            terminal: Terminal::State(DMatrix::identity(2, 2)),
            ..base.clone()
        };
        assert!(matches!(err(&ok, &s), MpcError::Dimension { .. }));
        // Indefinite weight.
        let s = MpcSettings {
            q1: Weight::Diagonal(vec![1.0, -1.0]),
            ..base.clone()
        };
        assert!(matches!(err(&ok, &s), MpcError::NotPositiveDefinite { .. }));
        // Non-positive-definite H: no input weight and an output weight that
        // does not see every input direction.
        let s = MpcSettings {
            q2: Weight::Scalar(0.0),
            q1: Weight::Diagonal(vec![1.0, 0.0]),
            horizon: 1,
            ..base.clone()
        };
        let e = err(&ok, &s);
        assert!(
            matches!(e, MpcError::NotPositiveDefinite { kind: "", .. }),
            "{e}"
        );
        assert!(e.to_string().contains("Hessian H"));
        // Blocking that does not fit the horizon; zero horizon.
        let s = MpcSettings {
            blocking: Some(Blocking::new(vec![1, 1]).unwrap()),
            ..base.clone()
        };
        assert!(
            err(&ok, &s)
                .to_string()
                .contains("sum to 2, but the horizon is N = 3")
        );
        let s = MpcSettings {
            horizon: 0,
            ..base.clone()
        };
        assert!(matches!(err(&ok, &s), MpcError::InvalidSetting { .. }));
        // Feed-through and non-finite models.
        let mut md = m.clone();
        md.d[(0, 0)] = 0.5;
        assert!(matches!(
            MpcProblem::build(&md, &ok, &base),
            Err(MpcError::FeedThrough { .. })
        ));
        let mut mn = m.clone();
        mn.a[(1, 1)] = f64::INFINITY;
        assert!(matches!(
            MpcProblem::build(&mn, &ok, &base),
            Err(MpcError::NonFinite(_))
        ));
    }
}
