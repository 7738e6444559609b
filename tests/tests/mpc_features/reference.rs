//! The independent reference: the MPC problem written out uncondensed, in
//! the variables `v = [x_0, ..., x_N, u_0, ..., u_{N-1}, slacks]`, from the
//! model and a plain statement of the settings ([`Plain`]) only. Nothing
//! here uses kestrel-mpc's condensing; the LQ terminal weight is a Riccati
//! iteration of its own.

use nalgebra::{DMatrix, DVector};

/// Affine bounds `lower + lower_shift p <= v <= upper + upper_shift p`
/// (infinite entries: no row), optionally soft (one slack per bounded
/// component, shared by the horizon and both sides).
#[derive(Clone, Debug)]
pub struct PlainBounds {
    pub lower: DVector<f64>,
    pub upper: DVector<f64>,
    /// `k x np`.
    pub lower_shift: DMatrix<f64>,
    /// `k x np`.
    pub upper_shift: DMatrix<f64>,
    /// `(quadratic, linear)` slack penalty, or hard.
    pub soft: Option<(f64, f64)>,
}

impl PlainBounds {
    fn bounded(&self, i: usize) -> bool {
        self.lower[i].is_finite() || self.upper[i].is_finite()
    }
}

/// The terminal cost on `x_N`.
#[derive(Clone, Debug)]
pub enum PlainTerminal {
    /// No terminal cost.
    Zero,
    /// `1/2 |C x_N - r_P|^2_W`.
    Output(DMatrix<f64>),
    /// `1/2 |x_N - C^+ r_P|^2_P`.
    State(DMatrix<f64>),
}

/// The input target `u_t` of the `Q2` term.
#[derive(Clone, Debug)]
pub enum PlainTarget {
    Zero,
    Fixed(DVector<f64>),
    Parameter,
}

/// The MPC problem in plain matrices (weights resolved, bounds with explicit
/// shifts), everything the uncondensed reference reads.
#[derive(Clone, Debug)]
pub struct Plain {
    pub a: DMatrix<f64>,
    pub b: DMatrix<f64>,
    pub c: DMatrix<f64>,
    pub blocks: Vec<usize>,
    pub q1: DMatrix<f64>,
    pub q2: DMatrix<f64>,
    pub du_weight: Option<DMatrix<f64>>,
    pub terminal: PlainTerminal,
    pub preview: usize,
    pub target: PlainTarget,
    pub input: Option<PlainBounds>,
    pub du: Option<PlainBounds>,
    pub output: Option<PlainBounds>,
    pub state: Option<PlainBounds>,
    /// `A x_N <= b`.
    pub terminal_set: Option<(DMatrix<f64>, DVector<f64>)>,
    /// Number of extra parameters.
    pub np: usize,
    /// Offset-free design: a constant disturbance `d` (in `theta` after
    /// `x`) with `x+ = A x + B u + Bd d`, `y = C x + Cd d`; the inputs are
    /// weighed against `u_s` and the terminal state against `x_s`, the
    /// least-norm solution of `[A - I, B; C, 0] [x_s; u_s] = [-Bd d; r_P - Cd d]`.
    /// `(Bd, Cd)`.
    pub disturbance: Option<(DMatrix<f64>, DMatrix<f64>)>,
}

/// Which constraint a row of the uncondensed problem comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Family {
    Input,
    Du,
    Output,
    State,
    TerminalSet,
    SlackSign,
}

/// What an inequality row of the uncondensed problem states.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RowKey {
    pub family: Family,
    /// `v <= upper` (terminal-set rows too); `false`: `v >= lower` (slack signs too).
    pub upper: bool,
    /// The component (input, output, state, terminal-set row, slack number).
    pub index: usize,
    /// The step of the horizon (0 for slack signs).
    pub step: usize,
    /// Whether the row is softened by a slack.
    pub soft: bool,
    /// `false` for an input or input-move row inside a block (implied by
    /// the block's first row, so a condensed problem leaves it out).
    pub canonical: bool,
}

/// A dense QP `min 1/2 v'Pv + q'v + c0` s.t. `A_eq v = b_eq`, `A_in v <= b_in`.
#[derive(Clone, Debug)]
pub struct DenseQp {
    pub p: DMatrix<f64>,
    pub q: DVector<f64>,
    pub c0: f64,
    pub a_eq: DMatrix<f64>,
    pub b_eq: DVector<f64>,
    pub a_in: DMatrix<f64>,
    pub b_in: DVector<f64>,
    /// The family of each inequality row.
    pub family: Vec<Family>,
    /// What each inequality row states.
    pub keys: Vec<RowKey>,
    /// The family and component of each slack variable.
    pub slack_of: Vec<(Family, usize)>,
}

/// `theta` split by the reference's own reading of the layout.
#[derive(Clone, Debug)]
pub struct ThetaParts {
    pub x: DVector<f64>,
    /// The disturbance (empty without one).
    pub d: DVector<f64>,
    pub u_prev: DVector<f64>,
    /// `r_1, ..., r_P`.
    pub refs: Vec<DVector<f64>>,
    pub u_target: DVector<f64>,
    pub params: DVector<f64>,
}

impl Plain {
    pub fn nx(&self) -> usize {
        self.a.nrows()
    }
    pub fn nu(&self) -> usize {
        self.b.ncols()
    }
    pub fn ny(&self) -> usize {
        self.c.nrows()
    }
    /// Number of disturbance entries in `theta`.
    pub fn nd(&self) -> usize {
        self.disturbance.as_ref().map_or(0, |(bd, _)| bd.ncols())
    }
    pub fn horizon(&self) -> usize {
        self.blocks.iter().sum()
    }
    /// Whether `theta` carries the previous input.
    pub fn has_prev(&self) -> bool {
        self.du_weight.is_some() || self.du.is_some()
    }
    /// Length of `theta`: `[x; u_prev; r_1..r_P; u_target; params]`.
    pub fn theta_len(&self) -> usize {
        self.nx()
            + self.nd()
            + if self.has_prev() { self.nu() } else { 0 }
            + self.preview * self.ny()
            + if matches!(self.target, PlainTarget::Parameter) {
                self.nu()
            } else {
                0
            }
            + self.np
    }

    /// `theta` from its parts, in the reference's reading of the layout
    /// (the previous input and the target only where the layout has them).
    pub fn assemble(
        &self,
        x: &DVector<f64>,
        u_prev: &DVector<f64>,
        refs: &[f64],
        u_target: &DVector<f64>,
        params: &[f64],
    ) -> DVector<f64> {
        // `x` holds the disturbance after the states in an offset-free design.
        let mut v: Vec<f64> = x.iter().copied().collect();
        if self.has_prev() {
            v.extend(u_prev.iter());
        }
        v.extend_from_slice(refs);
        if matches!(self.target, PlainTarget::Parameter) {
            v.extend(u_target.iter());
        }
        v.extend_from_slice(params);
        assert_eq!(v.len(), self.theta_len(), "theta length");
        DVector::from_vec(v)
    }

    /// Splits `theta` into its parts.
    pub fn split(&self, theta: &DVector<f64>) -> ThetaParts {
        assert_eq!(theta.len(), self.theta_len(), "theta length");
        let (nx, nu, ny) = (self.nx(), self.nu(), self.ny());
        let mut at = 0;
        let mut take = |k: usize| {
            let v = theta.rows(at, k).into_owned();
            at += k;
            v
        };
        let x = take(nx);
        let d = take(self.nd());
        let u_prev = if self.has_prev() {
            take(nu)
        } else {
            DVector::zeros(nu)
        };
        let refs = (0..self.preview).map(|_| take(ny)).collect();
        let u_target = match &self.target {
            PlainTarget::Zero => DVector::zeros(nu),
            PlainTarget::Fixed(t) => t.clone(),
            PlainTarget::Parameter => take(nu),
        };
        let params = take(self.np);
        ThetaParts {
            x,
            d,
            u_prev,
            refs,
            u_target,
            params,
        }
    }

    /// Index of `x_j` in `v`.
    pub fn xi(&self, j: usize) -> usize {
        j * self.nx()
    }
    /// Index of `u_j` in `v`.
    pub fn ui(&self, j: usize) -> usize {
        (self.horizon() + 1) * self.nx() + j * self.nu()
    }
    /// Index of the first slack in `v`.
    pub fn si(&self) -> usize {
        self.ui(self.horizon())
    }

    /// The families with bounds, in order, with their selection of `v`
    /// rows: `(family, bounds, steps, component map)`.
    fn bounded_families(&self) -> Vec<(Family, &PlainBounds)> {
        let mut out = Vec::new();
        for (f, b) in [
            (Family::Input, &self.input),
            (Family::Du, &self.du),
            (Family::Output, &self.output),
            (Family::State, &self.state),
        ] {
            if let Some(b) = b {
                out.push((f, b));
            }
        }
        out
    }

    /// Number of slack variables (one per bounded component of each soft family).
    pub fn n_slack(&self) -> usize {
        self.bounded_families()
            .iter()
            .filter(|(_, b)| b.soft.is_some())
            .map(|(_, b)| (0..b.lower.len()).filter(|&i| b.bounded(i)).count())
            .sum()
    }

    /// The uncondensed QP at `theta`.
    pub fn qp(&self, theta: &DVector<f64>) -> DenseQp {
        let t = self.split(theta);
        let (nx, nu) = (self.nx(), self.nu());
        let n_h = self.horizon();
        let ns = self.n_slack();
        let nv = self.si() + ns;
        let mut p = DMatrix::zeros(nv, nv);
        let mut q = DVector::zeros(nv);
        let mut c0 = 0.0;
        // The disturbance's effect on the states and the outputs, and the
        // steady-state target it asks for.
        let (bd_d, cd_d) = match &self.disturbance {
            Some((bd, cd)) => (bd * &t.d, cd * &t.d),
            None => (DVector::zeros(nx), DVector::zeros(self.ny())),
        };
        let r_last = &t.refs[self.preview - 1];
        let steady = self.disturbance.as_ref().map(|_| {
            let mut k = DMatrix::zeros(nx + self.ny(), nx + nu);
            k.view_mut((0, 0), (nx, nx))
                .copy_from(&(&self.a - DMatrix::identity(nx, nx)));
            k.view_mut((0, nx), (nx, nu)).copy_from(&self.b);
            k.view_mut((nx, 0), (self.ny(), nx)).copy_from(&self.c);
            let mut rhs = DVector::zeros(nx + self.ny());
            rhs.rows_mut(0, nx).copy_from(&(-&bd_d));
            rhs.rows_mut(nx, self.ny()).copy_from(&(r_last - &cd_d));
            // Least norm: the SVD's solve with tiny singular values dropped.
            let xu = k.svd(true, true).solve(&rhs, 1e-10).unwrap();
            (xu.rows(0, nx).into_owned(), xu.rows(nx, nu).into_owned())
        });
        let u_target = steady.as_ref().map_or(&t.u_target, |s| &s.1);
        // The output references net of the disturbance: r_min(j, P) - Cd d,
        // step 0 with r_1.
        let refs: Vec<DVector<f64>> = t.refs.iter().map(|r| r - &cd_d).collect();
        let r_of = |j: usize| &refs[j.clamp(1, self.preview) - 1];

        let mut quad = |at: usize, m: &DMatrix<f64>, r: &DVector<f64>, w: &DMatrix<f64>| {
            add_quad(&mut p, &mut q, &mut c0, at, m, r, w)
        };
        let eye_u = DMatrix::identity(nu, nu);
        let eye_x = DMatrix::identity(nx, nx);
        for j in 0..n_h {
            quad(self.xi(j), &self.c, r_of(j), &self.q1);
            quad(self.ui(j), &eye_u, u_target, &self.q2);
        }
        if let Some(rw) = &self.du_weight {
            quad(self.ui(0), &eye_u, &t.u_prev, rw);
            for j in 1..n_h {
                // 1/2 (u_j - u_{j-1})' R (u_j - u_{j-1}).
                let (a, b) = (self.ui(j - 1), self.ui(j));
                let stacked = DMatrix::from_fn(nu, 2 * nu, |i, k| {
                    if k < nu {
                        -f64::from(u8::from(i == k))
                    } else {
                        f64::from(u8::from(i + nu == k))
                    }
                });
                // [u_{j-1}; u_j] are adjacent in v.
                debug_assert_eq!(b, a + nu);
                quad(a, &stacked, &DVector::zeros(nu), rw);
            }
        }
        match &self.terminal {
            PlainTerminal::Zero => {}
            PlainTerminal::Output(w) => quad(self.xi(n_h), &self.c, r_of(n_h), w),
            PlainTerminal::State(pm) => {
                let x_ref = match &steady {
                    Some((x_s, _)) => x_s.clone(),
                    None => self.c.clone().pseudo_inverse(1e-13).unwrap() * r_last,
                };
                quad(self.xi(n_h), &eye_x, &x_ref, pm);
            }
        }

        // Equalities: x_0 = x, x_{j+1} = A x_j + B u_j (+ Bd d), u_j = u_{j-1}
        // inside a block.
        let mut eq_rows: Vec<(DVector<f64>, f64)> = Vec::new();
        let unit = |i: usize| {
            let mut r = DVector::zeros(nv);
            r[i] = 1.0;
            r
        };
        for i in 0..nx {
            eq_rows.push((unit(self.xi(0) + i), t.x[i]));
        }
        for j in 0..n_h {
            for i in 0..nx {
                let mut r = unit(self.xi(j + 1) + i);
                for k in 0..nx {
                    r[self.xi(j) + k] -= self.a[(i, k)];
                }
                for k in 0..nu {
                    r[self.ui(j) + k] -= self.b[(i, k)];
                }
                eq_rows.push((r, bd_d[i]));
            }
        }
        let mut block_start = vec![false; n_h];
        let mut s = 0;
        for &l in &self.blocks {
            block_start[s] = true;
            s += l;
        }
        for j in 1..n_h {
            if !block_start[j] {
                for i in 0..nu {
                    let mut r = unit(self.ui(j) + i);
                    r[self.ui(j - 1) + i] = -1.0;
                    eq_rows.push((r, 0.0));
                }
            }
        }

        // Inequalities.
        let mut in_rows: Vec<(DVector<f64>, f64, RowKey)> = Vec::new();
        let mut slack_of = Vec::new();
        let mut slack = self.si();
        for (fam, bnd) in self.bounded_families() {
            let lo = &bnd.lower + &bnd.lower_shift * &t.params;
            let hi = &bnd.upper + &bnd.upper_shift * &t.params;
            let steps: Vec<usize> = match fam {
                Family::Input | Family::Du => (0..n_h).collect(),
                _ => (1..=n_h).collect(),
            };
            for i in 0..bnd.lower.len() {
                if !bnd.bounded(i) {
                    continue;
                }
                let s_idx = bnd.soft.map(|(qs, ls)| {
                    p[(slack, slack)] += qs;
                    q[slack] += ls;
                    slack_of.push((fam, i));
                    slack += 1;
                    slack - 1
                });
                for &j in &steps {
                    // The row of component i at step j: (coefficients, constant)
                    // with value = coef'v + constant.
                    let mut r = DVector::zeros(nv);
                    let mut cst = 0.0;
                    match fam {
                        Family::Input => r[self.ui(j) + i] = 1.0,
                        Family::Du => {
                            r[self.ui(j) + i] = 1.0;
                            if j == 0 {
                                cst = -t.u_prev[i];
                            } else {
                                r[self.ui(j - 1) + i] = -1.0;
                            }
                        }
                        Family::Output => {
                            cst = cd_d[i];
                            for k in 0..nx {
                                r[self.xi(j) + k] = self.c[(i, k)];
                            }
                        }
                        Family::State => r[self.xi(j) + i] = 1.0,
                        _ => unreachable!(),
                    }
                    for (sign, bound) in [(1.0, hi[i]), (-1.0, lo[i])] {
                        if !bound.is_finite() {
                            continue;
                        }
                        // sign (coef'v + cst) <= sign bound (+ s)
                        let mut row = &r * sign;
                        if let Some(k) = s_idx {
                            row[k] = -1.0;
                        }
                        let key = RowKey {
                            family: fam,
                            upper: sign > 0.0,
                            index: i,
                            step: j,
                            soft: s_idx.is_some(),
                            canonical: !matches!(fam, Family::Input | Family::Du) || block_start[j],
                        };
                        in_rows.push((row, sign * (bound - cst), key));
                    }
                }
            }
        }
        if let Some((at, bt)) = &self.terminal_set {
            for i in 0..at.nrows() {
                let mut r = DVector::zeros(nv);
                for k in 0..nx {
                    r[self.xi(n_h) + k] = at[(i, k)];
                }
                let key = RowKey {
                    family: Family::TerminalSet,
                    upper: true,
                    index: i,
                    step: n_h,
                    soft: false,
                    canonical: true,
                };
                in_rows.push((r, bt[i], key));
            }
        }
        for k in self.si()..nv {
            let key = RowKey {
                family: Family::SlackSign,
                upper: false,
                index: k - self.si(),
                step: 0,
                soft: false,
                canonical: true,
            };
            in_rows.push((-unit(k), 0.0, key));
        }
        let stack = |rows: Vec<DVector<f64>>| DMatrix::from_fn(rows.len(), nv, |i, k| rows[i][k]);
        let b_eq = DVector::from_iterator(eq_rows.len(), eq_rows.iter().map(|r| r.1));
        let b_in = DVector::from_iterator(in_rows.len(), in_rows.iter().map(|r| r.1));
        let keys: Vec<RowKey> = in_rows.iter().map(|r| r.2).collect();
        let family = keys.iter().map(|k| k.family).collect();
        DenseQp {
            p: (&p + p.transpose()) * 0.5,
            q,
            c0,
            a_eq: stack(eq_rows.into_iter().map(|r| r.0).collect()),
            b_eq,
            a_in: stack(in_rows.into_iter().map(|r| r.0).collect()),
            b_in,
            family,
            keys,
            slack_of,
        }
    }

    /// The inputs of each block's first step (`nb * nu`) of a solution `v`.
    pub fn moves(&self, v: &DVector<f64>) -> DVector<f64> {
        let nu = self.nu();
        let mut out = Vec::new();
        let mut j = 0;
        for &l in &self.blocks {
            out.extend(v.rows(self.ui(j), nu).iter().copied());
            j += l;
        }
        DVector::from_vec(out)
    }
}

/// Adds `1/2 |M w - r|^2_W` to the cost, `w` the block of `v` at `at`.
fn add_quad(
    p: &mut DMatrix<f64>,
    q: &mut DVector<f64>,
    c0: &mut f64,
    at: usize,
    m: &DMatrix<f64>,
    r: &DVector<f64>,
    w: &DMatrix<f64>,
) {
    let k = m.ncols();
    let mtw = m.transpose() * w;
    let mut blk = p.view_mut((at, at), (k, k));
    blk += &mtw * m;
    let mut lin = q.rows_mut(at, k);
    lin -= &mtw * r;
    *c0 += 0.5 * r.dot(&(w * r));
}

/// The stabilising solution of `A'SA - S - A'SB (R + B'SB)^-1 B'SA + Q = 0`
/// by iterating the Riccati difference equation from `S = Q` to a fixed
/// point (independent of kestrel-kalman's solver).
pub fn riccati_by_iteration(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> DMatrix<f64> {
    let mut s = q.clone();
    let mut settled = 0;
    for _ in 0..200_000 {
        let bsb = r + b.transpose() * &s * b;
        let k = bsb.lu().solve(&(b.transpose() * &s * a)).unwrap();
        let next = q + a.transpose() * &s * a - a.transpose() * &s * b * k;
        let next = (&next + next.transpose()) * 0.5;
        let change = (&next - &s).amax();
        s = next;
        // Converged to rounding: a few more steps once the change is tiny.
        if change <= 1e-14 * s.amax().max(1.0) {
            settled += 1;
            if settled > 20 {
                return s;
            }
        }
    }
    panic!("Riccati iteration did not converge");
}
