//! The Gauss-Newton normal equations `J'J`, `J'r` of the weighted
//! residuals, accumulated from the Jacobian rows of [`sensitivity_rows`]
//! a block of rows at a time, so the whole Jacobian is never stored
//! (memory: the residuals, `p^2` and one block of rows).
//!
//! Every block of [`BLOCK_ROWS`] rows (compact columns of one
//! experiment, [`Target`]) adds its `B'B` to the experiment's compact
//! Hessian through nalgebra's `gemm` (matrixmultiply's packed kernels);
//! the rows of a step the criterion leaves out are never formed. The
//! order of every sum is fixed (samples in order, blocks in order), so
//! the result does not depend on anything but the data.

use super::criterion::{Objective, ResidualWeights};
use super::jacobian::{Rows, Target, sensitivity_rows, simulation_layout};
use super::layout::Layout;
use super::residuals::without_k;
use super::series::Series;
use crate::model::InnovationModel;
use nalgebra::{DMatrix, DMatrixView, DVector};

/// Jacobian rows per `gemm` of the accumulation (one block of rows
/// stays in the cache: 256 x 126 columns are 250 KiB).
const BLOCK_ROWS: usize = 256;

/// Columns of the Hessian blocks of one `gemm` (40-64 measured alike on
/// the steam generator's 126 columns; the full width took 20 % longer).
const PANEL: usize = 64;

/// A [`Rows`] sink that weighs the rows (as [`ResidualWeights::apply`]
/// weighs the residuals: `L^-1` on every block of `ny` rows, or the
/// group's root weight) and accumulates `J'J`, `J'r`.
struct Accumulator<'a> {
    target: Target,
    weights: &'a ResidualWeights,
    /// Group of the first output of step 1 (the simulation term's groups
    /// follow the prediction steps').
    group0: usize,
    ny: usize,
    /// The weighted residuals of this term.
    res: &'a [f64],
    /// Rows waiting for the next `gemm` (row-major, `filled` of them).
    buf: Vec<f64>,
    filled: usize,
    /// One block before whitening.
    tmp: Vec<f64>,
    /// Compact Hessian and gradient of the current experiment.
    hc: DMatrix<f64>,
    gc: Vec<f64>,
    hessian: &'a mut DMatrix<f64>,
    gradient: &'a mut DVector<f64>,
}

impl<'a> Accumulator<'a> {
    fn new(
        target: Target,
        (weights, group0, ny): (&'a ResidualWeights, usize, usize),
        res: &'a [f64],
        (hessian, gradient): (&'a mut DMatrix<f64>, &'a mut DVector<f64>),
    ) -> Self {
        let pl = target.width();
        Accumulator {
            target,
            weights,
            group0,
            ny,
            res,
            buf: vec![0.0; BLOCK_ROWS * pl],
            filled: 0,
            tmp: vec![0.0; ny * pl],
            hc: DMatrix::zeros(pl, pl),
            gc: vec![0.0; pl],
            hessian,
            gradient,
        }
    }

    /// Adds the buffered rows' `B'B` to the lower triangle of the compact
    /// Hessian, a block of [`PANEL`] columns at a time (the blocks above
    /// the diagonal are left out: a third of the work for 126 columns).
    fn flush(&mut self) {
        let (pl, k) = (self.target.width(), self.filled);
        if k == 0 {
            return;
        }
        let rows = &self.buf[..k * pl];
        for i0 in (0..pl).step_by(PANEL) {
            let wi = PANEL.min(pl - i0);
            // Columns i0.. of the rows, transposed (wi x k).
            let bi = DMatrixView::from_slice_with_strides(&rows[i0..], wi, k, 1, pl);
            for j0 in (0..=i0).step_by(PANEL) {
                let wj = PANEL.min(pl - j0);
                // Columns j0.. of the rows (k x wj).
                let bj = DMatrixView::from_slice_with_strides(&rows[j0..], k, wj, pl, 1);
                self.hc
                    .view_mut((i0, j0), (wi, wj))
                    .gemm(1.0, &bi, &bj, 1.0);
            }
        }
        self.filled = 0;
    }
}

impl Rows for Accumulator<'_> {
    fn begin(&mut self, _experiment: usize) {
        self.hc.fill(0.0);
        self.gc.fill(0.0);
        self.filled = 0;
    }

    fn block(&mut self, residual: usize, step: usize, rows: &mut [f64]) {
        let (pl, ny) = (self.target.width(), self.ny);
        match self.weights {
            ResidualWeights::None => {}
            ResidualWeights::Groups(sw) => {
                for (o, row) in rows.chunks_exact_mut(pl).enumerate() {
                    let s = sw[self.group0 + step * ny + o];
                    row.iter_mut().for_each(|v| *v *= s);
                }
            }
            ResidualWeights::Whiten(w) => {
                self.tmp.copy_from_slice(rows);
                for (o, row) in rows.chunks_exact_mut(pl).enumerate() {
                    row.fill(0.0);
                    for k in 0..ny {
                        let c = w[(o, k)];
                        for (d, s) in row.iter_mut().zip(&self.tmp[k * pl..(k + 1) * pl]) {
                            *d += s * c;
                        }
                    }
                }
            }
        }
        for (o, row) in rows.chunks_exact(pl).enumerate() {
            let r = self.res[residual + o];
            for (g, v) in self.gc.iter_mut().zip(row) {
                *g += v * r;
            }
            self.buf[self.filled * pl..(self.filled + 1) * pl].copy_from_slice(row);
            self.filled += 1;
            if self.filled == BLOCK_ROWS {
                self.flush();
            }
        }
    }

    fn end(&mut self, experiment: usize) {
        self.flush();
        let pl = self.target.width();
        let full: Vec<usize> = (0..pl).map(|c| self.target.full(experiment, c)).collect();
        for (j, &fj) in full.iter().enumerate() {
            for (i, &fi) in full.iter().enumerate() {
                // The lower triangle holds every entry.
                self.hessian[(fi, fj)] += self.hc[(i.max(j), i.min(j))];
            }
            self.gradient[fj] += self.gc[j];
        }
    }
}

/// The normal equations `J'J`, `J'r` (`p x p`, `p`) of the residuals
/// `res` of the search in the layout `lay` (prediction errors of horizon
/// `h`, then the simulation errors of the initial states `xs` when the
/// layout has a simulation term), already masked and weighed by `w`: the
/// Jacobian rows are weighed like the residuals, those of the steps the
/// objective leaves out are skipped (the mask zeroes them).
#[allow(clippy::too_many_arguments)]
pub(super) fn normal_equations(
    lay: &Layout,
    m: &InnovationModel,
    (x0, xs): (&[DVector<f64>], &[DVector<f64>]),
    data: &[Series],
    h: usize,
    objective: &Objective,
    w: &ResidualWeights,
    res: &DVector<f64>,
) -> (DMatrix<f64>, DVector<f64>) {
    let ny = lay.ny;
    let mut hessian = DMatrix::zeros(lay.p, lay.p);
    let mut gradient = DVector::zeros(lay.p);
    let n_sim = if lay.has_simulation() {
        data.iter().map(|s| s.n * ny).sum()
    } else {
        0
    };
    let (pred, sim) = res.as_slice().split_at(res.len() - n_sim);
    let mut acc = Accumulator::new(
        Target::prediction(lay),
        (w, 0, ny),
        pred,
        (&mut hessian, &mut gradient),
    );
    sensitivity_rows(lay, m, x0, data, &objective.kept_steps(h), &mut acc);
    if lay.has_simulation() {
        let mut acc = Accumulator::new(
            Target::simulation(lay),
            (w, h * ny, ny),
            sim,
            (&mut hessian, &mut gradient),
        );
        let m0 = without_k(m);
        sensitivity_rows(&simulation_layout(lay), &m0, xs, data, &[true], &mut acc);
    }
    (hessian, gradient)
}
