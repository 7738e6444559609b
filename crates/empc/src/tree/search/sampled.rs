//! [`TreeMethod::Sampled`](crate::tree::TreeMethod::Sampled): candidates scored from sample points kept
//! inside every region and cell; only the chosen split runs LPs.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::error::EmpcError;
use crate::eval::WIDE_LEAF;
use crate::lp::{LpStatus, LpWorkspace};
use crate::tree::search::state::{Builder, meets_lp};
use crate::tree::settings::{MAX_NODES, WIDE_MAX_NODES};
use std::collections::HashMap;

/// Exact splits tried per node by [`TreeMethod::Sampled`](crate::tree::TreeMethod::Sampled).
const SAMPLED_ATTEMPTS: usize = 6;

/// How a region lies relative to a hyperplane within the current cell,
/// from its facets, bounding box and sample points (no LP).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Lie {
    /// Proven inside `a'x <= b` (a facet, or the bounding box).
    Left,
    /// Proven inside `a'x >= b`.
    Right,
    /// Sample points strictly on both sides: meets both in a full-dimensional set.
    Both,
    /// Sample points only strictly left (it may still reach the right side).
    PtsLeft,
    /// Sample points only strictly right.
    PtsRight,
    /// No sample point off the hyperplane.
    Unknown,
}

/// A candidate split exactly: its key (larger side's laws, both sides'
/// laws, smaller side's laws), the hyperplane and every region's split.
type Tried = ((usize, usize, usize), usize, Vec<RegionSplit>);

/// The outcome of splitting one region of a node ([`TreeMethod::Sampled`](crate::tree::TreeMethod::Sampled)):
/// its points on each side, whether it goes left and right, and the new
/// interior points the LPs found.
struct RegionSplit {
    left: Option<Vec<u32>>,
    right: Option<Vec<u32>>,
    new_left: Option<Vec<f64>>,
    new_right: Option<Vec<f64>>,
}

impl Builder<'_> {
    /// Whether hyperplane `h` is a facet of region `r`, and on which side
    /// `r` lies; else whether `r`'s bounding box lies on one side.
    fn proven_side(&self, r: usize, h: usize, tol: f64) -> Option<Lie> {
        if let Some(&(_, s)) = self.reg_facets[r].iter().find(|f| f.0 == h) {
            return Some(if s { Lie::Left } else { Lie::Right });
        }
        let b = self.hp[h].1;
        let (bmin, bmax) = self.box_range(r, h);
        if bmax <= b + tol {
            Some(Lie::Left)
        } else if bmin >= b - tol {
            Some(Lie::Right)
        } else {
            None
        }
    }

    /// How region `r` (with its sample points `pts` inside the cell) lies
    /// relative to hyperplane `h`, without an LP.
    fn lie(&self, r: usize, h: usize, pts: &[u32]) -> Lie {
        let tol = 1e-9 * self.scale;
        if let Some(l) = self.proven_side(r, h, tol) {
            return l;
        }
        let (a, b) = (&self.hp[h].0, self.hp[h].1);
        let p = self.p;
        let pool = &self.pool[r];
        let (mut l, mut rt) = (false, false);
        for &i in pts {
            let x = &pool[i as usize * p..(i as usize + 1) * p];
            let v: f64 = a.iter().zip(x).map(|(u, w)| u * w).sum::<f64>() - b;
            l |= v < -tol;
            rt |= v > tol;
            if l && rt {
                return Lie::Both;
            }
        }
        match (l, rt) {
            (true, _) => Lie::PtsLeft,
            (_, true) => Lie::PtsRight,
            _ => Lie::Unknown,
        }
    }

    /// The sampled split key of a hyperplane (distinct laws on the larger
    /// side, then on both) from how each region of the set lies
    /// ([`Builder::lie`]): a region counts on the sides its facets, box or
    /// points show, on both when nothing shows. `None` if every region
    /// would stay on both sides. `mark` is a scratch law counter.
    fn score_lies(
        &self,
        lies: &[Lie],
        set: &[usize],
        mark: &mut [u32],
        stamp: u32,
    ) -> Option<(usize, usize)> {
        let (mut nl, mut nr, mut ll, mut lr) = (0, 0, 0, 0);
        // mark bit 0: seen left, bit 1: seen right (with the stamp above).
        for (&r, &lie) in set.iter().zip(lies) {
            let (inl, inr) = match lie {
                Lie::Left | Lie::PtsLeft => (true, false),
                Lie::Right | Lie::PtsRight => (false, true),
                Lie::Both | Lie::Unknown => (true, true),
            };
            nl += usize::from(inl);
            nr += usize::from(inr);
            let m = &mut mark[self.law[r] as usize];
            if *m >> 2 != stamp {
                *m = stamp << 2;
            }
            if inl && *m & 1 == 0 {
                *m |= 1;
                ll += 1;
            }
            if inr && *m & 2 == 0 {
                *m |= 2;
                lr += 1;
            }
        }
        if (nl == set.len() && nr == set.len()) || nl == 0 || nr == 0 {
            return None; // every region on both sides, or one side empty
        }
        // A side that keeps every law ranks last (its count is the node's
        // law count), but stays a candidate: the exact split may show
        // progress the points miss.
        Some((ll.max(lr), ll + lr))
    }

    /// Splits region `r` (points `pts` in the cell) by hyperplane `h`:
    /// proven sides take no LP, points on both sides prove both, and a
    /// side without a point is decided by one LP within the cell.
    fn split_region(
        &self,
        lp: &mut LpWorkspace,
        r: usize,
        h: usize,
        pts: &[u32],
        cell: &[(Vec<f64>, f64)],
    ) -> RegionSplit {
        let (a, b) = (&self.hp[h].0, self.hp[h].1);
        let p = self.p;
        let pool = &self.pool[r];
        let val = |i: u32| -> f64 {
            let x = &pool[i as usize * p..(i as usize + 1) * p];
            a.iter().zip(x).map(|(u, w)| u * w).sum::<f64>() - b
        };
        let lie = self.lie(r, h, pts);
        // Points in each closed side (they stay inside the child's cell).
        let lpts = || pts.iter().copied().filter(|&i| val(i) <= 0.0).collect();
        let rpts = || pts.iter().copied().filter(|&i| val(i) >= 0.0).collect();
        let mut out = RegionSplit {
            left: None,
            right: None,
            new_left: None,
            new_right: None,
        };
        let mut lp_side = |sign: f64| -> (bool, Option<Vec<f64>>) {
            let (ok, ball) = meets_lp(
                lp,
                p,
                self.scale,
                &self.reg_a[r],
                &self.reg_b[r],
                &self.reg_center[r],
                cell,
                Some((a, b, sign)),
            );
            (ok, ball.filter(|_| ok).map(|bl| bl.0))
        };
        match lie {
            Lie::Left => out.left = Some(pts.to_vec()),
            Lie::Right => out.right = Some(pts.to_vec()),
            Lie::Both => {
                out.left = Some(lpts());
                out.right = Some(rpts());
            }
            Lie::PtsLeft | Lie::PtsRight | Lie::Unknown => {
                let check_left = lie != Lie::PtsLeft;
                let check_right = lie != Lie::PtsRight;
                let (mut go_l, mut go_r) = (true, true);
                if check_left {
                    let (ok, x) = lp_side(1.0);
                    go_l = ok;
                    out.new_left = x;
                }
                if check_right {
                    let (ok, x) = lp_side(-1.0);
                    go_r = ok;
                    out.new_right = x;
                }
                if go_l {
                    out.left = Some(lpts());
                }
                if go_r {
                    out.right = Some(rpts());
                }
            }
        }
        out
    }

    /// Sample points of every region for [`TreeMethod::Sampled`](crate::tree::TreeMethod::Sampled): the
    /// centre and the vertices that maximise the coordinates, the inward
    /// facet normals and a few fixed pseudo-random directions (LPs).
    pub(in crate::tree) fn init_pool(&mut self) {
        let p = self.p;
        let mut seed: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let random: Vec<f64> = (0..2 * p * p).map(|_| rnd()).collect();
        self.pool = (0..self.reg_a.len())
            .map(|r| {
                let c = &self.reg_center[r];
                let ra = &self.reg_a[r];
                let mut dirs: Vec<f64> = Vec::new();
                for j in 0..p {
                    for sign in [1.0, -1.0] {
                        dirs.extend((0..p).map(|i| if i == j { sign } else { 0.0 }));
                    }
                }
                dirs.extend(ra.iter().map(|v| -v));
                dirs.extend_from_slice(&random);
                let mut pts = c.clone();
                for d in dirs.chunks(p) {
                    let (st, _) = self.lp.maximize_from(d, ra, &self.reg_b[r], c);
                    if st == LpStatus::Optimal {
                        pts.extend_from_slice(&self.lp.x[..p]);
                    }
                }
                pts
            })
            .collect();
    }

    /// How every region of the set lies relative to every candidate
    /// (`[candidate][region]`), on several threads when the node is large.
    fn lies_all(&self, cands: &[usize], set: &[usize], pts: &[Vec<u32>]) -> Vec<Vec<Lie>> {
        let one = |h: usize| -> Vec<Lie> {
            set.iter()
                .zip(pts)
                .map(|(&r, q)| self.lie(r, h, q))
                .collect()
        };
        #[cfg(feature = "parallel")]
        if self.parallel && set.len() * cands.len() > 2000 {
            use rayon::prelude::*;
            return cands.par_iter().map(|&h| one(h)).collect();
        }
        cands.iter().map(|&h| one(h)).collect()
    }

    /// Sampled scores of the candidates (in their order) from their lies.
    fn score_all(
        &self,
        lies: &[Vec<Lie>],
        set: &[usize],
        mark: &mut [u32],
        stamp: &mut u32,
    ) -> Vec<Option<(usize, usize)>> {
        #[cfg(feature = "parallel")]
        if self.parallel && set.len() * lies.len() > 2000 {
            use rayon::prelude::*;
            let n = self.n_laws_total;
            return lies
                .par_iter()
                .map_init(
                    || (vec![0u32; n], 0u32),
                    |(m, st), l| {
                        *st += 1;
                        self.score_lies(l, set, m, *st)
                    },
                )
                .collect();
        }
        lies.iter()
            .map(|l| {
                *stamp += 1;
                self.score_lies(l, set, mark, *stamp)
            })
            .collect()
    }

    /// Splits every region of the set by hyperplane `h` (LPs only where
    /// the points cannot tell), on several threads when the set is large.
    fn split_all(
        &mut self,
        h: usize,
        set: &[usize],
        pts: &[Vec<u32>],
        cell: &[(Vec<f64>, f64)],
    ) -> Vec<RegionSplit> {
        let mut lp = std::mem::take(&mut self.lp);
        let this = &*self;
        #[cfg(feature = "parallel")]
        let out = if this.parallel && set.len() > 16 {
            use rayon::prelude::*;
            set.par_iter()
                .zip(pts.par_iter())
                .map_init(LpWorkspace::default, |lp, (&r, q)| {
                    this.split_region(lp, r, h, q, cell)
                })
                .collect()
        } else {
            set.iter()
                .zip(pts)
                .map(|(&r, q)| this.split_region(&mut lp, r, h, q, cell))
                .collect()
        };
        #[cfg(not(feature = "parallel"))]
        let out = set
            .iter()
            .zip(pts)
            .map(|(&r, q)| this.split_region(&mut lp, r, h, q, cell))
            .collect();
        self.lp = lp;
        out
    }

    /// Adds the interior points the split LPs found to the regions' pools,
    /// to the node's point lists (they lie in region and cell) and to the
    /// child lists of their side.
    /// Returns the positions in `set` of the regions that got new points.
    fn absorb(
        &mut self,
        set: &[usize],
        pts: &mut [Vec<u32>],
        splits: &mut [RegionSplit],
    ) -> Vec<usize> {
        let p = self.p;
        let mut grown = Vec::new();
        for (i, ((&r, q), sp)) in set
            .iter()
            .zip(pts.iter_mut())
            .zip(splits.iter_mut())
            .enumerate()
        {
            if sp.new_left.is_some() || sp.new_right.is_some() {
                grown.push(i);
            }
            for (new, side) in [
                (sp.new_left.take(), &mut sp.left),
                (sp.new_right.take(), &mut sp.right),
            ] {
                if let Some(x) = new {
                    let id = (self.pool[r].len() / p) as u32;
                    self.pool[r].extend(x);
                    q.push(id);
                    if let Some(s) = side {
                        s.push(id);
                    }
                }
            }
        }
        grown
    }

    /// The exact key of a split (as [`Builder::score_lies`], from the
    /// regions each side really keeps).
    fn split_key(&self, set: &[usize], splits: &[RegionSplit]) -> (usize, usize, usize) {
        let (mut l, mut r): (Vec<u16>, Vec<u16>) = (Vec::new(), Vec::new());
        for (&reg, sp) in set.iter().zip(splits) {
            if sp.left.is_some() {
                l.push(self.law[reg]);
            }
            if sp.right.is_some() {
                r.push(self.law[reg]);
            }
        }
        for v in [&mut l, &mut r] {
            v.sort_unstable();
            v.dedup();
        }
        (
            l.len().max(r.len()),
            l.len() + r.len(),
            l.len().min(r.len()),
        )
    }

    /// The search tree with sampled scoring ([`TreeMethod::Sampled`](crate::tree::TreeMethod::Sampled)):
    /// `pts[i]` are the sample points of region `set[i]` inside the cell.
    ///
    /// The candidates are scored from the points; the best one is split
    /// exactly (LPs), the points the LPs find join the pools, and the
    /// candidates are scored again, until the best is one already split
    /// (its score then is exact) or [`SAMPLED_ATTEMPTS`] splits were tried.
    pub(in crate::tree) fn build_sampled(
        &mut self,
        set: Vec<usize>,
        mut pts: Vec<Vec<u32>>,
        cell: &mut Vec<(Vec<f64>, f64)>,
        depth: usize,
        mark: &mut Vec<u32>,
        stamp: &mut u32,
    ) -> Result<u32, EmpcError> {
        self.depth = self.depth.max(depth);
        let first_law = set.first().map_or(0, |&r| self.law[r]);
        if set.iter().all(|&r| self.law[r] == first_law) || depth > 60 {
            if depth > 60 {
                self.ambiguous += 1;
            }
            return Ok(WIDE_LEAF | u32::from(first_law));
        }
        if self.clipping
            && let Some(l) = self.serving_law(&set, cell)
        {
            return Ok(WIDE_LEAF | u32::from(l));
        }
        if self.nodes.len() >= self.max_nodes {
            return Err(EmpcError::TooLarge(format!(
                "the search tree exceeds {} nodes (TreeSettings::max_nodes; the u16 layout addresses {MAX_NODES}, the wide layout up to {WIDE_MAX_NODES})",
                self.max_nodes
            )));
        }
        let mut freq: HashMap<usize, usize> = HashMap::new();
        for &r in &set {
            for &(h, _) in &self.reg_facets[r] {
                *freq.entry(h).or_default() += 1;
            }
        }
        let mut cands: Vec<(usize, usize)> = freq.into_iter().collect();
        cands.sort_by(|x, y| y.1.cmp(&x.1).then(x.0.cmp(&y.0)));
        if set.len() * cands.len() > self.exact_budget {
            cands.truncate(self.max_candidates);
        }
        let cands: Vec<usize> = cands.into_iter().map(|c| c.0).collect();
        let n_laws = {
            let mut v: Vec<u16> = set.iter().map(|&r| self.law[r]).collect();
            v.sort_unstable();
            v.dedup();
            v.len()
        };
        // (exact key, candidate, splits) of the candidates split so far.
        let mut tried: Vec<Tried> = Vec::new();
        let progress = |k: &(usize, usize, usize)| k.0 < n_laws && k.2 > 0;
        // How every region lies relative to every candidate; after a split
        // only the regions that got new points are looked at again (a lie
        // depends on the region, the hyperplane and the region's points).
        let mut lies = self.lies_all(&cands, &set, &pts);
        loop {
            let scores = self.score_all(&lies, &set, mark, stamp);
            // Candidates by key; ties go to the more frequent facet.
            let mut order: Vec<((usize, usize), usize, usize)> = cands
                .iter()
                .enumerate()
                .zip(&scores)
                .filter_map(|((i, &h), k)| k.map(|k| (k, i, h)))
                .collect();
            order.sort_unstable();
            let done = |h: usize| tried.iter().find(|t| t.1 == h);
            // The best candidate is split already and its exact key shows
            // progress: its score is exact now, take it.
            if let Some(&(_, _, h)) = order.first()
                && done(h).is_some_and(|t| progress(&t.0))
            {
                break;
            }
            if tried.len() >= SAMPLED_ATTEMPTS && tried.iter().any(|t| progress(&t.0)) {
                break;
            }
            let Some(&(_, _, h)) = order.iter().find(|c| done(c.2).is_none()) else {
                break;
            };
            let mut splits = self.split_all(h, &set, &pts, cell);
            let grown = self.absorb(&set, &mut pts, &mut splits);
            for (l, &c) in lies.iter_mut().zip(&cands) {
                for &i in &grown {
                    l[i] = self.lie(set[i], c, &pts[i]);
                }
            }
            let key = self.split_key(&set, &splits);
            tried.push((key, h, splits));
        }
        // The best exact split that makes progress on both sides.
        let Some(pos) = tried
            .iter()
            .enumerate()
            .filter(|(_, t)| progress(&t.0))
            .min_by(|x, y| (x.1.0.0, x.1.0.1).cmp(&(y.1.0.0, y.1.0.1)))
            .map(|x| x.0)
            .or_else(|| (!tried.is_empty()).then_some(0))
        else {
            self.ambiguous += 1;
            return Ok(WIDE_LEAF | u32::from(first_law));
        };
        let (_, h, splits) = tried.swap_remove(pos);
        drop(tried);
        let (mut left, mut lp_) = (Vec::new(), Vec::new());
        let (mut right, mut rp) = (Vec::new(), Vec::new());
        for (&r, sp) in set.iter().zip(splits) {
            if let Some(q) = sp.left {
                left.push(r);
                lp_.push(q);
            }
            if let Some(q) = sp.right {
                right.push(r);
                rp.push(q);
            }
        }
        if left.is_empty() {
            left.push(set[0]);
            lp_.push(Vec::new());
        }
        if right.is_empty() {
            right.push(set[0]);
            rp.push(Vec::new());
        }
        drop(set);
        drop(pts);
        let hid = self.hyperplane_id(h);
        let me = self.nodes.len();
        self.nodes.push([hid, 0, 0, 0]);
        let (a, b) = self.hp[h].clone();
        let na: Vec<f64> = a.iter().map(|v| -v).collect();
        cell.push((a, b));
        let l = self.build_sampled(left, lp_, cell, depth + 1, mark, stamp);
        cell.pop();
        let l = l?;
        cell.push((na, -b));
        let rgt = self.build_sampled(right, rp, cell, depth + 1, mark, stamp);
        cell.pop();
        let rgt = rgt?;
        self.nodes[me][2] = l;
        self.nodes[me][3] = rgt;
        Ok(me as u32)
    }
}
