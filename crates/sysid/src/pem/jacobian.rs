//! The exact Jacobian of the prediction errors by forward sensitivity
//! recursions of the predictor, for one-step, multi-step and simulation
//! errors, handed on block by block (one sample and prediction step:
//! `ny` rows) to a [`Rows`] sink; the search accumulates the normal
//! equations from them ([`super::normal`]) and never stores the whole
//! Jacobian.
//!
//! Every row has the compact columns of one experiment: the parameters
//! shared by all experiments (`A, B, C, [D], [K]`, [`Layout::shared`])
//! followed by that experiment's own initial state (`n`); the sink maps
//! them to the full layout ([`Target`]).

use super::layout::Layout;
use super::residuals::{output_error, predictor_state_step};
use super::series::Series;
use crate::model::InnovationModel;
use nalgebra::{DMatrixView, DMatrixViewMut, DVector};

/// Above this order `(A - KC) Psi` is one `gemm` (nalgebra hands
/// products with every dimension above 5 to matrixmultiply).
const GEMM_STATES: usize = 5;

/// Receives the Jacobian rows of [`sensitivity_rows`].
pub(super) trait Rows {
    /// The rows of experiment `experiment` follow.
    fn begin(&mut self, experiment: usize);
    /// The `ny` rows (row-major, compact columns) of the errors
    /// `residual..residual + ny` (their index among the errors of the
    /// recursion, all experiments stacked), those of prediction step
    /// `step + 1`. The sink may change the rows (weigh them).
    fn block(&mut self, residual: usize, step: usize, rows: &mut [f64]);
    /// The rows of experiment `experiment` are done.
    fn end(&mut self, experiment: usize);
}

/// Where the compact columns of a row go in the full layout: the first
/// `shared` stay, the experiment's own initial state starts at
/// `x0 + experiment * n`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Target {
    /// Number of shared parameters in the rows.
    pub(super) shared: usize,
    /// Full index of the first experiment's initial state.
    pub(super) x0: usize,
    /// States.
    pub(super) n: usize,
}

impl Target {
    /// The prediction errors of `lay`.
    pub(super) fn prediction(lay: &Layout) -> Self {
        Target {
            shared: lay.shared(),
            x0: lay.ox,
            n: lay.n,
        }
    }

    /// The simulation term of `lay` (its rows in the layout of
    /// [`simulation_layout`]).
    pub(super) fn simulation(lay: &Layout) -> Self {
        Target {
            shared: simulation_layout(lay).shared(),
            x0: lay.osx,
            n: lay.n,
        }
    }

    /// Compact columns of a row.
    pub(super) fn width(&self) -> usize {
        self.shared + self.n
    }

    /// Full index of compact column `c` of experiment `experiment`.
    pub(super) fn full(&self, experiment: usize, c: usize) -> usize {
        if c < self.shared {
            c
        } else {
            self.x0 + experiment * self.n + c - self.shared
        }
    }
}

/// The layout of the simulation term's recursion: `A, B, C, [D]` (first
/// in both layouts, so at the same indices) and the simulation initial
/// states, no `K`.
pub(super) fn simulation_layout(lay: &Layout) -> Layout {
    Layout::new(lay.n, lay.nu, lay.ny, lay.ne, lay.has_d, false)
}

/// `dst += c * src`.
fn axpy(dst: &mut [f64], c: f64, src: &[f64]) {
    for (d, s) in dst.iter_mut().zip(src) {
        *d += c * s;
    }
}

/// `dst = sum_k coef[k] psi_k` over the rows `psi_k` of `psi` (row-major,
/// each `dst.len()` long): eight columns at a time with the sums in
/// registers (the same sums in the same order as a row of axpys, which
/// load and store `dst` once per `k`).
fn combine(dst: &mut [f64], coef: &[f64], psi: &[f64]) {
    const W: usize = 8;
    let pl = dst.len();
    let full = pl / W * W;
    for c0 in (0..full).step_by(W) {
        let mut acc = [0.0; W];
        for (k, &c) in coef.iter().enumerate() {
            let src = &psi[k * pl + c0..k * pl + c0 + W];
            for (a, s) in acc.iter_mut().zip(src) {
                *a += c * s;
            }
        }
        dst[c0..c0 + W].copy_from_slice(&acc);
    }
    for (c, d) in dst.iter_mut().enumerate().skip(full) {
        let mut v = 0.0;
        for (k, &cf) in coef.iter().enumerate() {
            v += cf * psi[k * pl + c];
        }
        *d = v;
    }
}

/// The rows of the errors of step `j + 1` (`rows`, `ny x pl` row-major):
/// `de = -(C dz_j + dC z_j + dD u_j)` with the look-ahead sensitivity
/// `dz_j = A^j Psi + sum_{i<j} A^{j-1-i} (dA z_i + dB u_i)`, so
/// `C dz_j = M_j Psi + sum_{i<j} M_{j-1-i} (dA z_i + dB u_i)` with
/// `M_k = C A^k` (`powers`, `ny x n` row-major each): the structured
/// terms cost `ny n (n + nu)` per earlier step instead of a dense
/// `n x n x pl` product per step.
#[allow(clippy::too_many_arguments)]
fn step_rows(
    lay: &Layout,
    pl: usize,
    j: usize,
    (powers, psi): (&[f64], &[f64]),
    z: &[f64],
    u: &[f64],
    rows: &mut [f64],
) {
    let (n, nu, ny) = (lay.n, lay.nu, lay.ny);
    for (o, row) in rows.chunks_exact_mut(pl).enumerate() {
        combine(row, &powers[(j * ny + o) * n..][..n], psi);
        row.iter_mut().for_each(|v| *v = -*v);
        for i in 0..j {
            let mm = &powers[((j - 1 - i) * ny + o) * n..][..n];
            let zi = &z[i * n..(i + 1) * n];
            let ui = &u[i * nu..(i + 1) * nu];
            for (a, &c) in mm.iter().enumerate() {
                axpy(&mut row[a * n..(a + 1) * n], -c, zi);
                axpy(&mut row[lay.ob + a * nu..][..nu], -c, ui);
            }
        }
        axpy(
            &mut row[lay.oc + o * n..][..n],
            -1.0,
            &z[j * n..(j + 1) * n],
        );
        if lay.has_d {
            axpy(
                &mut row[lay.od + o * nu..][..nu],
                -1.0,
                &u[j * nu..(j + 1) * nu],
            );
        }
    }
}

/// One predictor step of the sensitivity (`n x pl` row-major):
/// `Psi+ = Abar Psi + dA x + dB u + dK e - K (dC x + dD u)` into `psin`.
fn advance_sensitivity(
    lay: &Layout,
    m: &InnovationModel,
    (abar, pl): (&[f64], usize),
    (x, u, e): (&[f64], &[f64], &[f64]),
    psi: &[f64],
    psin: &mut [f64],
) {
    let (n, nu, ny) = (lay.n, lay.nu, lay.ny);
    if n > GEMM_STATES {
        // All rows at once through matrixmultiply's kernels (row-major
        // views: row stride first).
        let ab = DMatrixView::from_slice_with_strides(abar, n, n, n, 1);
        let ps = DMatrixView::from_slice_with_strides(psi, n, pl, pl, 1);
        DMatrixViewMut::from_slice_with_strides_mut(psin, n, pl, pl, 1).gemm(1.0, &ab, &ps, 0.0);
    }
    for (a, dst) in psin.chunks_exact_mut(pl).enumerate() {
        if n <= GEMM_STATES {
            combine(dst, &abar[a * n..(a + 1) * n], psi);
        }
        axpy(&mut dst[a * n..(a + 1) * n], 1.0, x);
        axpy(&mut dst[lay.ob + a * nu..][..nu], 1.0, u);
        if lay.has_k {
            axpy(&mut dst[lay.ok + a * ny..][..ny], 1.0, e);
        }
        for o in 0..ny {
            let kao = m.k[(a, o)];
            axpy(&mut dst[lay.oc + o * n..][..n], -kao, x);
            if lay.has_d {
                axpy(&mut dst[lay.od + o * nu..][..nu], -kao, u);
            }
        }
    }
}

/// The exact Jacobian rows of the prediction errors `d e / d theta` by
/// forward sensitivity recursions of the predictor:
/// `Psi+ = (A - KC) Psi + dA x + dB u + dK e - K (dC x + dD u)`,
/// `de = -(C Psi + dC x + dD u)`, in the compact columns of every
/// experiment ([`Target`]), handed to `sink` block by block.
///
/// With horizon `h = keep.len() > 1` (multi-step focus): for every `t`
/// the errors of the `1..=h`-step-ahead predictions made from the
/// predictor state `x(t|t-1)` (`z0 = x, z+ = A z + B u`, error
/// `y - C z - D u`), indexed `[t][step][output]` (steps that run past the
/// end of an experiment are left out), with the look-ahead sensitivities
/// `dz0 = Psi`, `dz+ = A dz + dA z + dB u`, `de = -(C dz + dC z + dD u)`;
/// only the steps `j` with `keep[j]` are handed on (the others count in
/// the indices). `h = 1` gives the one-step errors.
pub(super) fn sensitivity_rows(
    lay: &Layout,
    m: &InnovationModel,
    x0: &[DVector<f64>],
    data: &[Series],
    keep: &[bool],
    sink: &mut impl Rows,
) {
    let (n, nu, ny) = (lay.n, lay.nu, lay.ny);
    let h = keep.len();
    let ps = lay.shared();
    let pl = ps + n;
    let abar: Vec<f64> = (0..n * n)
        .map(|i| {
            let (a, b) = (i / n, i % n);
            m.a[(a, b)] - (0..ny).map(|o| m.k[(a, o)] * m.c[(o, b)]).sum::<f64>()
        })
        .collect();
    // M_j = C A^j, j < h (row-major).
    let mut powers = vec![0.0; h * ny * n];
    for o in 0..ny {
        for b in 0..n {
            powers[o * n + b] = m.c[(o, b)];
        }
    }
    for j in 1..h {
        let (prev, next) = powers.split_at_mut(j * ny * n);
        let prev = &prev[(j - 1) * ny * n..];
        for o in 0..ny {
            for b in 0..n {
                next[o * n + b] = (0..n).map(|l| prev[o * n + l] * m.a[(l, b)]).sum();
            }
        }
    }
    let mut psi = vec![0.0; n * pl];
    let mut psin = vec![0.0; n * pl];
    let mut rows = vec![0.0; ny * pl];
    let mut x = vec![0.0; n];
    let mut xn = vec![0.0; n];
    let mut e = vec![0.0; ny];
    let mut z = vec![0.0; h * n];
    let mut col = 0;
    for (ei, (s, x0e)) in data.iter().zip(x0).enumerate() {
        sink.begin(ei);
        x.copy_from_slice(x0e.as_slice());
        psi.fill(0.0);
        for a in 0..n {
            psi[a * pl + ps + a] = 1.0;
        }
        for t in 0..s.n {
            let u = &s.u[t * nu..(t + 1) * nu];
            let y = &s.y[t * ny..(t + 1) * ny];
            output_error(m, &x, (u, y), &mut e);
            let steps = h.min(s.n - t);
            if let Some(last) = (0..steps).rev().find(|&j| keep[j]) {
                // Look-ahead states z_0 = x, z_j = A z_{j-1} + B u_{t+j-1}.
                z[..n].copy_from_slice(&x);
                for j in 1..=last {
                    let (done, next) = z.split_at_mut(j * n);
                    let up = &s.u[(t + j - 1) * nu..(t + j) * nu];
                    predictor_state_step(m, &done[(j - 1) * n..], up, &[], &mut next[..n]);
                }
                for j in (0..=last).filter(|&j| keep[j]) {
                    step_rows(lay, pl, j, (&powers, &psi), &z, &s.u[t * nu..], &mut rows);
                    sink.block(col + j * ny, j, &mut rows);
                }
            }
            advance_sensitivity(lay, m, (&abar, pl), (&x, u, &e), &psi, &mut psin);
            std::mem::swap(&mut psi, &mut psin);
            predictor_state_step(m, &x, u, &e, &mut xn);
            std::mem::swap(&mut x, &mut xn);
            col += ny * steps;
        }
        sink.end(ei);
    }
}

/// A sink that stores the whole transposed Jacobian (`p x M`, a column
/// per error): the reference the tests check against finite differences.
#[cfg(test)]
struct Full<'a> {
    target: Target,
    experiment: usize,
    jt: &'a mut nalgebra::DMatrix<f64>,
}

#[cfg(test)]
impl Rows for Full<'_> {
    fn begin(&mut self, experiment: usize) {
        self.experiment = experiment;
    }
    fn block(&mut self, residual: usize, _step: usize, rows: &mut [f64]) {
        let pl = self.target.width();
        for (o, row) in rows.chunks_exact(pl).enumerate() {
            for (c, v) in row.iter().enumerate() {
                self.jt[(self.target.full(self.experiment, c), residual + o)] = *v;
            }
        }
    }
    fn end(&mut self, _experiment: usize) {}
}

/// The prediction errors of horizon `h` and their whole transposed
/// Jacobian (`p x M`) in the layout `lay`.
#[cfg(test)]
pub(super) fn residuals_and_jacobian(
    lay: &Layout,
    m: &InnovationModel,
    x0: &[DVector<f64>],
    data: &[Series],
    h: usize,
) -> (DVector<f64>, nalgebra::DMatrix<f64>) {
    let r = super::residuals::multistep_residuals(m, x0, data, h);
    let mut jt = nalgebra::DMatrix::zeros(lay.p, r.len());
    let mut sink = Full {
        target: Target::prediction(lay),
        experiment: 0,
        jt: &mut jt,
    };
    sensitivity_rows(lay, m, x0, data, &vec![true; h], &mut sink);
    (r, jt)
}

/// The simulation term of [`PemSettings::simulation_weight`]: the errors
/// `y - C x - D u` of `x+ = A x + B u` from the initial states `xs` and
/// their transposed Jacobian in the layout `lay` (rows of `A, B, C, D`
/// and of the simulation initial states; `K` and the predictor's initial
/// states do not enter). The sensitivities are those of
/// [`Focus::Simulation`]: the one-step recursion with `K = 0`.
///
/// [`PemSettings::simulation_weight`]: super::PemSettings::simulation_weight
/// [`Focus::Simulation`]: super::Focus::Simulation
#[cfg(test)]
pub(super) fn simulation_residuals_and_jacobian(
    lay: &Layout,
    m: &InnovationModel,
    xs: &[DVector<f64>],
    data: &[Series],
) -> (DVector<f64>, nalgebra::DMatrix<f64>) {
    let m0 = super::residuals::without_k(m);
    let r = super::residuals::residuals(&m0, xs, data);
    let mut jt = nalgebra::DMatrix::zeros(lay.p, r.len());
    let mut sink = Full {
        target: Target::simulation(lay),
        experiment: 0,
        jt: &mut jt,
    };
    sensitivity_rows(&simulation_layout(lay), &m0, xs, data, &[true], &mut sink);
    (r, jt)
}

/// Residuals `[a; b]` and transposed Jacobians `[ja, jb]` side by side.
#[cfg(test)]
pub(super) fn stack(
    (a, ja): (DVector<f64>, nalgebra::DMatrix<f64>),
    (b, jb): (DVector<f64>, nalgebra::DMatrix<f64>),
) -> (DVector<f64>, nalgebra::DMatrix<f64>) {
    let (na, nb) = (a.len(), b.len());
    let r = super::residuals::stack_residuals(a, &b);
    let mut j = ja.resize_horizontally(na + nb, 0.0);
    j.columns_mut(na, nb).copy_from(&jb);
    (r, j)
}
