//! The state of the tree construction ([`Builder`]) and the helpers both
//! scoring methods share.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::lp::{LpStatus, LpWorkspace, slack_start};
use std::collections::HashMap;

/// A polytope `a x <= b` (rows of `p`) with an interior point.
pub(super) type Piece = (Vec<f64>, Vec<f64>, Vec<f64>);

/// A ball (centre, radius) inside a region intersected with the current
/// cell: a cheap certificate that the region meets a side of a hyperplane
/// (the LP is needed only when the ball cannot tell).
pub(in crate::tree) type Ball = (Vec<f64>, f64);

/// The tree construction: the regions, their laws and the nodes built so far.
pub(in crate::tree) struct Builder<'a> {
    pub(in crate::tree) p: usize,
    pub(in crate::tree) scale: f64,
    /// Region facets (hyperplane id, side: true = region has a'x <= b).
    pub(in crate::tree) reg_facets: Vec<Vec<(usize, bool)>>,
    pub(in crate::tree) reg_a: Vec<Vec<f64>>,
    pub(in crate::tree) reg_b: Vec<Vec<f64>>,
    /// An interior point of every region (the LPs' feasible start).
    pub(in crate::tree) reg_center: Vec<Vec<f64>>,
    /// The radius of a ball around `reg_center` inside the region.
    pub(in crate::tree) reg_radius: Vec<f64>,
    /// The bounding box of every region (lower and upper corner).
    pub(in crate::tree) reg_box: Vec<(Vec<f64>, Vec<f64>)>,
    pub(in crate::tree) law: &'a [u16],
    /// Row indices of every law (`k` each), the affine rows and the output bounds.
    pub(in crate::tree) law_rows: Vec<Vec<usize>>,
    pub(in crate::tree) rows: Vec<f64>,
    pub(in crate::tree) bounds: Vec<[u16; 2]>,
    pub(in crate::tree) clipping: bool,
    /// Clamping tolerance of the clipping test.
    pub(in crate::tree) clip_tol: f64,
    pub(in crate::tree) serve_cache: HashMap<(u16, usize), bool>,
    pub(in crate::tree) hp: Vec<(Vec<f64>, f64)>,
    pub(in crate::tree) side_cache: HashMap<(usize, usize), i8>,
    pub(in crate::tree) lp: LpWorkspace,
    /// Nodes as built: `[hyperplane id, 0, child, child]`, child codes
    /// with [`WIDE_LEAF`](crate::eval::WIDE_LEAF) (narrowed to `u16` when the tree fits).
    pub(in crate::tree) nodes: Vec<[u32; 4]>,
    pub(in crate::tree) used_hp: HashMap<usize, u32>,
    pub(in crate::tree) ambiguous: usize,
    pub(in crate::tree) depth: usize,
    pub(in crate::tree) max_candidates: usize,
    pub(in crate::tree) exact_budget: usize,
    /// Sample points of every region (`p` numbers each), all inside the
    /// region: its centre, bounding-box vertices pulled towards it, and
    /// interior points of region and cell found by the split LPs
    /// ([`TreeMethod::Sampled`](crate::tree::TreeMethod::Sampled)).
    pub(in crate::tree) pool: Vec<Vec<f64>>,
    #[cfg_attr(not(feature = "parallel"), allow(dead_code))]
    pub(in crate::tree) parallel: bool,
    /// Number of distinct laws (for the law counters of the scoring).
    pub(in crate::tree) n_laws_total: usize,
    pub(in crate::tree) max_nodes: usize,
}

/// The LP of [`Builder::meets`] with a caller-owned workspace: whether the
/// polytope `ra x <= rb` meets the cell (and the extra half-space
/// `sign (a'x - b) <= 0`, if given) in a ball of radius above `1e-9 scale`,
/// and the ball's centre and radius when the LP finished.
#[allow(clippy::too_many_arguments)]
pub(super) fn meets_lp(
    lp: &mut LpWorkspace,
    p: usize,
    scale: f64,
    ra: &[f64],
    rb: &[f64],
    center: &[f64],
    cell: &[(Vec<f64>, f64)],
    extra: Option<(&[f64], f64, f64)>,
) -> (bool, Option<Ball>) {
    let mut a = Vec::with_capacity((rb.len() + cell.len() + 2) * (p + 1));
    let mut b = Vec::with_capacity(rb.len() + cell.len() + 2);
    for (i, bi) in rb.iter().enumerate() {
        a.extend_from_slice(&ra[i * p..(i + 1) * p]);
        a.push(1.0);
        b.push(*bi);
    }
    for (ca, cb) in cell {
        a.extend_from_slice(ca);
        a.push(1.0);
        b.push(*cb);
    }
    if let Some((ea, eb, sign)) = extra {
        a.extend(ea.iter().map(|v| sign * v));
        a.push(1.0);
        b.push(sign * eb);
    }
    a.extend(std::iter::repeat_n(0.0, p));
    a.push(1.0);
    b.push(scale);
    let mut c = vec![0.0; p + 1];
    c[p] = 1.0;
    let mut x0: Vec<f64> = center.iter().copied().chain([0.0]).collect();
    slack_start(&a, &b, &mut x0, p);
    let (st, rad) = lp.maximize_from(&c, &a, &b, &x0);
    match st {
        LpStatus::Optimal => (rad > 1e-9 * scale, Some((lp.x[..p].to_vec(), rad))),
        // An LP that did not finish proves nothing: keep the region.
        _ => (true, None),
    }
}

impl Builder<'_> {
    /// The node code of candidate hyperplane `h`: its index among the
    /// hyperplanes the tree uses, numbered in order of first use.
    pub(super) fn hyperplane_id(&mut self, h: usize) -> u32 {
        let next = self.used_hp.len() as u32;
        *self.used_hp.entry(h).or_insert(next)
    }

    /// The least and the greatest value of `a_h theta` over the bounding
    /// box of region `r`.
    pub(super) fn box_range(&self, r: usize, h: usize) -> (f64, f64) {
        let a = &self.hp[h].0;
        let (lo, up) = &self.reg_box[r];
        let (mut bmax, mut bmin) = (0.0, 0.0);
        for j in 0..a.len() {
            let (u, v) = (a[j] * lo[j], a[j] * up[j]);
            bmax += u.max(v);
            bmin += u.min(v);
        }
        (bmin, bmax)
    }

    /// The bounding box of region `r` (2p LPs); the parameter box in a
    /// direction whose LP fails (the region lies inside it).
    pub(in crate::tree) fn bounding_box(
        &mut self,
        r: usize,
        lb: &[f64],
        ub: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let p = self.p;
        let (mut lo, mut up) = (lb.to_vec(), ub.to_vec());
        let mut c = vec![0.0; p];
        for j in 0..p {
            for sign in [1.0, -1.0] {
                c[j] = sign;
                let (st, v) =
                    self.lp
                        .maximize_from(&c, &self.reg_a[r], &self.reg_b[r], &self.reg_center[r]);
                if st == LpStatus::Optimal {
                    if sign > 0.0 {
                        up[j] = up[j].min(v);
                    } else {
                        lo[j] = lo[j].max(-v);
                    }
                }
            }
            c[j] = 0.0;
        }
        (lo, up)
    }
}
