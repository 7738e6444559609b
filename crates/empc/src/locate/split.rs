//! The tree of the candidate lists: cells split by facet hyperplanes until
//! few regions with other laws than the cell's most expensive law are left.
//!
//! A region stays in a child cell when an LP finds a point of the region
//! within the parent cell beyond the hyperplane by more than a tolerance
//! (or when it cannot decide): the regions a leaf keeps are all those that
//! meet its cell, so the leaf's list plus its final law answer exactly.
//! The hyperplane is chosen without LPs: among the most frequent facets of
//! the cell's regions, the one that leaves the fewest regions on its larger
//! side, a region counting on both sides when its inscribed ball crosses
//! the hyperplane and on its centre's side otherwise.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::lp::{LpStatus, LpWorkspace};
use std::collections::HashMap;

/// A region inside a cell: its index and a point of it in the cell
/// (`None` when an LP failed: it is then kept on both sides).
type Member = (u32, Option<Vec<f64>>);

/// The members below and above a hyperplane.
type Sides = (Vec<Member>, Vec<Member>);

/// A split: (larger side, both sides, hyperplane, members below, above).
type Split = (usize, usize, u32, Vec<Member>, Vec<Member>);

/// The builder's inputs and outputs.
pub(super) struct Splitter<'a> {
    /// Parameters.
    pub(super) p: usize,
    /// Hyperplanes `(a, b)`, `a` unit.
    pub(super) planes: &'a [(Vec<f64>, f64)],
    /// Per region: `(hyperplane, below)`.
    pub(super) facets: &'a [Vec<(u32, bool)>],
    /// Per region: all half-spaces (row-major `a`, then `b`), for the LPs.
    pub(super) reg_a: Vec<Vec<f64>>,
    /// Offsets of the half-spaces.
    pub(super) reg_b: Vec<Vec<f64>>,
    /// Centres of the inscribed balls.
    pub(super) center: Vec<Vec<f64>>,
    /// Radii of the inscribed balls.
    pub(super) radius: Vec<f64>,
    /// Bounding boxes of the regions (lower, upper corner).
    pub(super) boxes: Vec<(Vec<f64>, Vec<f64>)>,
    /// The law of every region.
    pub(super) law: &'a [u32],
    /// Most regions a leaf lists.
    pub(super) leaf_regions: usize,
    /// Most nodes on a path.
    pub(super) max_depth: usize,
    /// Candidate hyperplanes ranked per node (without LPs).
    pub(super) candidates: usize,
    /// Of those, how many are split with LPs (the best is taken).
    pub(super) tries: usize,
    /// A split must leave at most this fraction of the regions on each side.
    pub(super) shrink: f64,
    /// A region meets a side when it reaches this far beyond the hyperplane.
    pub(super) tol: f64,
    /// The LP solvers' workspaces, one per try.
    pub(super) lp: Vec<LpWorkspace>,
    /// Run the tries on several threads (the `parallel` feature).
    pub(super) parallel: bool,
    /// LPs solved.
    pub(super) lps: usize,
    /// Nodes `[hyperplane, child below, child above]`.
    pub(super) nodes: Vec<[u32; 3]>,
    /// Leaves `[first, end, final law]`.
    pub(super) leaves: Vec<[u32; 3]>,
    /// The leaves' lists.
    pub(super) entries: Vec<u32>,
    /// Deepest path (nodes).
    pub(super) depth: usize,
    /// Fraction of the tree finished.
    pub(super) done: f64,
}

/// Leaf bit of a child code.
const LEAF: u32 = crate::eval::WIDE_LEAF;

impl Splitter<'_> {
    /// Builds the subtree of the cell `cell` (hyperplanes and sides) that
    /// the regions `members` meet, returning its child code.
    pub(super) fn build(
        &mut self,
        members: Vec<Member>,
        cell: &mut Vec<(u32, bool)>,
        depth: usize,
        weight: f64,
        progress: &mut dyn FnMut(usize),
    ) -> u32 {
        self.depth = self.depth.max(depth);
        // The final law: the one whose regions cost the most to test.
        let mut cost: HashMap<u32, usize> = HashMap::new();
        for (r, _) in &members {
            *cost.entry(self.law[*r as usize]).or_default() += self.facets[*r as usize].len();
        }
        let last = cost
            .iter()
            .max_by_key(|&(l, c)| (*c, std::cmp::Reverse(*l)))
            .map_or(0, |(l, _)| *l);
        let listed = members
            .iter()
            .filter(|(r, _)| self.law[*r as usize] != last)
            .count();
        if listed <= self.leaf_regions || depth >= self.max_depth {
            return self.leaf(&members, last, weight, progress);
        }
        // The best of the ranked candidates, by the LPs' counts; a split
        // that keeps more than `shrink` of the regions on a side is no
        // better than a longer list.
        let tries = self.ranked(&members, cell);
        let splits = self.refine_all(&members, cell, &tries);
        let mut best: Option<Split> = None;
        for (h, (below, above)) in tries.into_iter().zip(splits) {
            let (big, sum) = (below.len().max(above.len()), below.len() + above.len());
            if best.as_ref().is_none_or(|b| (big, sum) < (b.0, b.1)) {
                best = Some((big, sum, h, below, above));
            }
        }
        if let Some((big, _, h, below, above)) = best
            && (big as f64) <= self.shrink * members.len() as f64
        {
            let at = self.nodes.len();
            self.nodes.push([h, 0, 0]);
            cell.push((h, true));
            let lo = self.build(below, cell, depth + 1, weight / 2.0, progress);
            cell.pop();
            cell.push((h, false));
            let hi = self.build(above, cell, depth + 1, weight / 2.0, progress);
            cell.pop();
            self.nodes[at] = [h, lo, hi];
            return at as u32;
        }
        self.leaf(&members, last, weight, progress)
    }

    /// A leaf listing the regions of `members` without the law `last`,
    /// larger inscribed balls first.
    fn leaf(
        &mut self,
        members: &[Member],
        last: u32,
        weight: f64,
        progress: &mut dyn FnMut(usize),
    ) -> u32 {
        let mut list: Vec<u32> = members
            .iter()
            .map(|m| m.0)
            .filter(|&r| self.law[r as usize] != last)
            .collect();
        list.sort_by(|&x, &y| {
            self.radius[y as usize]
                .total_cmp(&self.radius[x as usize])
                .then(x.cmp(&y))
        });
        let first = self.entries.len() as u32;
        self.entries.extend_from_slice(&list);
        self.leaves.push([first, self.entries.len() as u32, last]);
        let before = (self.done * 1000.0) as usize;
        self.done += weight;
        let after = (self.done * 1000.0) as usize;
        if after != before {
            progress(after);
        }
        LEAF | (self.leaves.len() - 1) as u32
    }

    /// The candidate hyperplanes (the most frequent facets of the members
    /// not yet in the cell), best estimated split first.
    fn ranked(&self, members: &[Member], cell: &[(u32, bool)]) -> Vec<u32> {
        let mut freq: HashMap<u32, usize> = HashMap::new();
        for (r, _) in members {
            for &(h, _) in &self.facets[*r as usize] {
                *freq.entry(h).or_default() += 1;
            }
        }
        let mut cands: Vec<(u32, usize)> = freq
            .into_iter()
            .filter(|(h, _)| !cell.iter().any(|c| c.0 == *h))
            .collect();
        cands.sort_by_key(|&(h, n)| (std::cmp::Reverse(n), h));
        cands.truncate(self.candidates);
        let mut scored: Vec<((usize, usize), u32)> = cands
            .into_iter()
            .map(|(h, _)| (self.estimate(members, h), h))
            .collect();
        scored.sort();
        scored.into_iter().take(self.tries).map(|x| x.1).collect()
    }

    /// Estimated (larger side, both sides) of splitting at `h`, without LPs.
    fn estimate(&self, members: &[Member], h: u32) -> (usize, usize) {
        let (a, b) = &self.planes[h as usize];
        let (mut lo, mut hi) = (0, 0);
        for (r, _) in members {
            let r = *r as usize;
            if let Some(&(_, below)) = self.facets[r].iter().find(|f| f.0 == h) {
                if below {
                    lo += 1;
                } else {
                    hi += 1;
                }
                continue;
            }
            let d: f64 = a
                .iter()
                .zip(&self.center[r])
                .map(|(x, y)| x * y)
                .sum::<f64>()
                - b;
            if d.abs() < self.radius[r] {
                lo += 1;
                hi += 1;
            } else if d < 0.0 {
                lo += 1;
            } else {
                hi += 1;
            }
        }
        (lo.max(hi), lo + hi)
    }

    /// [`Self::refine`] for each hyperplane of `tries`, on several
    /// threads when asked (the same answer either way).
    fn refine_all(
        &mut self,
        members: &[Member],
        cell: &[(u32, bool)],
        tries: &[u32],
    ) -> Vec<Sides> {
        let mut lp = std::mem::take(&mut self.lp);
        lp.resize_with(tries.len().max(lp.len()), LpWorkspace::default);
        let this = &*self;
        let out: Vec<(Sides, usize)> = {
            #[cfg(feature = "parallel")]
            {
                use rayon::prelude::*;
                if this.parallel && members.len() > 64 {
                    tries
                        .par_iter()
                        .zip(lp.par_iter_mut())
                        .map(|(&h, ws)| this.refine(members, cell, h, ws))
                        .collect()
                } else {
                    tries
                        .iter()
                        .zip(lp.iter_mut())
                        .map(|(&h, ws)| this.refine(members, cell, h, ws))
                        .collect()
                }
            }
            #[cfg(not(feature = "parallel"))]
            {
                let _ = this.parallel;
                tries
                    .iter()
                    .zip(lp.iter_mut())
                    .map(|(&h, ws)| this.refine(members, cell, h, ws))
                    .collect()
            }
        };
        self.lp = lp;
        out.into_iter()
            .map(|(split, n)| {
                self.lps += n;
                split
            })
            .collect()
    }

    /// The members meeting each side of `h` within the cell, each with a
    /// point there, and the LPs solved. A region whose bounding box lies
    /// on one side needs no LP.
    fn refine(
        &self,
        members: &[Member],
        cell: &[(u32, bool)],
        h: u32,
        lp: &mut LpWorkspace,
    ) -> (Sides, usize) {
        let mut lps = 0;
        let p = self.p;
        let (a, b) = self.planes[h as usize].clone();
        let (mut below, mut above) = (Vec::new(), Vec::new());
        let mut rows_a = Vec::new();
        let mut rows_b = Vec::new();
        let mut c = vec![0.0; p];
        for (r, wit) in members {
            let ri = *r as usize;
            if let Some(&(_, bl)) = self.facets[ri].iter().find(|f| f.0 == h) {
                if bl {
                    below.push((*r, wit.clone()));
                } else {
                    above.push((*r, wit.clone()));
                }
                continue;
            }
            let Some(w) = wit else {
                below.push((*r, None));
                above.push((*r, None));
                continue;
            };
            let d: f64 = a.iter().zip(w).map(|(x, y)| x * y).sum::<f64>() - b;
            // The side the point is on is met; an LP decides the other.
            let (sign, here, there) = if d <= 0.0 {
                (1.0, &mut below, &mut above)
            } else {
                (-1.0, &mut above, &mut below)
            };
            here.push((*r, Some(w.clone())));
            // The box's extent beyond the hyperplane on the other side.
            let (lo, up) = &self.boxes[ri];
            let reach: f64 = (0..p)
                .map(|j| {
                    let v = sign * a[j];
                    if v > 0.0 { v * up[j] } else { v * lo[j] }
                })
                .sum();
            if reach <= sign * b + self.tol {
                continue;
            }
            rows_a.clear();
            rows_b.clear();
            rows_a.extend_from_slice(&self.reg_a[ri]);
            rows_b.extend_from_slice(&self.reg_b[ri]);
            for &(g, bl) in cell {
                let (ga, gb) = &self.planes[g as usize];
                let s = if bl { 1.0 } else { -1.0 };
                rows_a.extend(ga.iter().map(|v| v * s));
                rows_b.push(gb * s);
            }
            for j in 0..p {
                c[j] = sign * a[j];
            }
            lps += 1;
            // Stops at the first vertex beyond the level.
            let level = sign * b + self.tol;
            let (st, v) = lp.maximize_until(&c, &rows_a, &rows_b, w, level);
            if st != LpStatus::Optimal {
                there.push((*r, None));
            } else if v > level {
                there.push((*r, Some(lp.x.clone())));
            }
        }
        ((below, above), lps)
    }
}
