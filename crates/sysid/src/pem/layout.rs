//! The parameter vector of the search: where every matrix entry and
//! initial state sits, packing and unpacking, and the data-driven local
//! coordinates that remove the similarity directions.

use crate::model::InnovationModel;
use nalgebra::{DMatrix, DVector};

/// Parameter layout: `vec(A), vec(B), vec(C), [vec(D)], [vec(K)], x0 per
/// experiment, [simulation x0 per experiment]` (row-major inside every
/// matrix).
#[derive(Clone, Copy, Debug)]
pub(super) struct Layout {
    pub(super) n: usize,
    pub(super) nu: usize,
    pub(super) ny: usize,
    pub(super) ne: usize,
    pub(super) has_d: bool,
    pub(super) has_k: bool,
    pub(super) ob: usize,
    pub(super) oc: usize,
    pub(super) od: usize,
    pub(super) ok: usize,
    pub(super) ox: usize,
    /// Offset of the simulation term's initial states (`p` without one).
    pub(super) osx: usize,
    pub(super) p: usize,
}

impl Layout {
    pub(super) fn new(n: usize, nu: usize, ny: usize, ne: usize, has_d: bool, has_k: bool) -> Self {
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
    pub(super) fn with_simulation(mut self) -> Self {
        self.osx = self.ox + self.n * self.ne;
        self.p = self.osx + self.n * self.ne;
        self
    }

    pub(super) fn has_simulation(&self) -> bool {
        self.p > self.osx
    }

    /// Writes the simulation term's initial states into `th`.
    pub(super) fn pack_simulation(&self, th: &mut DVector<f64>, xs: &[DVector<f64>]) {
        for (e, x) in xs.iter().enumerate() {
            th.rows_mut(self.osx + e * self.n, self.n).copy_from(x);
        }
    }

    /// The simulation term's initial states (empty without one).
    pub(super) fn simulation_x0(&self, th: &DVector<f64>) -> Vec<DVector<f64>> {
        if !self.has_simulation() {
            return Vec::new();
        }
        (0..self.ne)
            .map(|e| th.rows(self.osx + e * self.n, self.n).into_owned())
            .collect()
    }

    /// Parameters shared by all experiments.
    pub(super) fn shared(&self) -> usize {
        self.ox
    }

    pub(super) fn pack(&self, m: &InnovationModel, x0: &[DVector<f64>]) -> DVector<f64> {
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
    pub(super) fn unpack(
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
    pub(super) fn ddlc(
        &self,
        m: &InnovationModel,
        x0: &[DVector<f64>],
        xs: &[DVector<f64>],
    ) -> DMatrix<f64> {
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
