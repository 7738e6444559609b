//! [`TreeMethod::Lp`](crate::tree::TreeMethod::Lp): the best few candidates (after a ranking without
//! LPs) scored exactly, per straddling region and side an LP in the cell.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::eval::WIDE_LEAF;
use crate::lp::LpStatus;
use crate::tree::search::state::{Ball, Builder, meets_lp};
use std::collections::HashMap;

/// The key of a split ([`Builder::score`]): whether it separates only in
/// the cell (no side with fewer laws), then the counts; smaller is better.
type SplitKey = (bool, (usize, usize));

/// Candidates per node scored exactly (with LPs in the cell), after a cheap ranking.
const EXACT_CANDIDATES: usize = 12;

/// The largest ball inside the ball `wit` and the half-space
/// `sign (a'x - b) <= 0` (unit `a`) that shares its boundary point; radius
/// zero or less if the half-space misses the ball.
fn half_ball(wit: &Ball, a: &[f64], b: f64, sign: f64) -> Ball {
    let (w, rho) = wit;
    // Signed slack of the centre into the half-space.
    let into = -sign * (a.iter().zip(w).map(|(u, v)| u * v).sum::<f64>() - b);
    let t = ((rho - into) / 2.0).max(0.0);
    let c = w.iter().zip(a).map(|(x, y)| x - sign * t * y).collect();
    (c, rho - t)
}

impl Builder<'_> {
    /// -1: region inside a'x <= b; +1: inside a'x >= b; 0: straddles.
    fn side(&mut self, r: usize, h: usize) -> i8 {
        if let Some(&(_, s)) = self.reg_facets[r].iter().find(|f| f.0 == h) {
            return if s { -1 } else { 1 };
        }
        if let Some(&v) = self.side_cache.get(&(r, h)) {
            return v;
        }
        let (a, b) = self.hp[h].clone();
        let tol = 1e-9 * self.scale;
        let ra = &self.reg_a[r];
        let rb = &self.reg_b[r];
        let x0 = &self.reg_center[r];
        // The ball around the centre (unit `a`): max a'x >= a'c + rho and
        // min a'x <= a'c - rho, so a side the ball reaches past the
        // tolerance needs no LP (the LP could only confirm it).
        if let Some(v) = self.side_without_lp(r, h) {
            self.side_cache.insert((r, h), v);
            return v;
        }
        let ac: f64 = a.iter().zip(x0).map(|(u, v)| u * v).sum();
        let rho = self.reg_radius[r];
        let maybe_left = ac + rho <= b + tol;
        let maybe_right = ac - rho >= b - tol;
        let mut v = 0;

        if maybe_left {
            let (st, hi) = self.lp.maximize_from(&a, ra, rb, x0);
            if st == LpStatus::Optimal && hi <= b + tol {
                v = -1;
            }
        }
        if v == 0 && maybe_right {
            let na: Vec<f64> = a.iter().map(|v| -v).collect();
            let (st, lo) = self.lp.maximize_from(&na, ra, rb, x0);
            if st == LpStatus::Optimal && -lo >= b - tol {
                v = 1;
            }
        }
        self.side_cache.insert((r, h), v);
        v
    }

    /// [`Builder::side`] where it needs no LP: a cached answer, the
    /// bounding box on one side (max a'x <= sum max(a_j lo_j, a_j hi_j)),
    /// or the region's ball on both sides; `None` otherwise.
    fn side_without_lp(&self, r: usize, h: usize) -> Option<i8> {
        if let Some(&(_, s)) = self.reg_facets[r].iter().find(|f| f.0 == h) {
            return Some(if s { -1 } else { 1 });
        }
        if let Some(&v) = self.side_cache.get(&(r, h)) {
            return Some(v);
        }
        let (a, b) = (&self.hp[h].0, self.hp[h].1);
        let tol = 1e-9 * self.scale;
        let (bmin, bmax) = self.box_range(r, h);
        if bmax <= b + tol {
            return Some(-1);
        }
        if bmin >= b - tol {
            return Some(1);
        }
        let ac: f64 = a.iter().zip(&self.reg_center[r]).map(|(u, v)| u * v).sum();
        let rho = self.reg_radius[r];
        (ac + rho > b + tol && ac - rho < b - tol).then_some(0)
    }

    /// Whether region r meets the cell (rows) in a full-dimensional set,
    /// with the largest ball of the intersection when the LP found it.
    fn meets(&mut self, r: usize, cell: &[(Vec<f64>, f64)]) -> (bool, Option<Ball>) {
        meets_lp(
            &mut self.lp,
            self.p,
            self.scale,
            &self.reg_a[r],
            &self.reg_b[r],
            &self.reg_center[r],
            cell,
            None,
        )
    }

    /// Whether region `r` (with the ball `wit` inside it and the cell)
    /// meets both sides of hyperplane `h` within the cell, and a ball
    /// inside each side it meets. The ball answers when it reaches a side
    /// with a radius the LP would accept (a smaller LP optimum is
    /// impossible), otherwise the LP of [`Builder::meets`] decides.
    fn split_sides(
        &mut self,
        r: usize,
        h: usize,
        wit: &Ball,
        cell: &mut Vec<(Vec<f64>, f64)>,
    ) -> [(bool, Option<Ball>); 2] {
        let (a, b) = self.hp[h].clone();
        let enough = 2e-9 * self.scale;
        let mut out = [(false, None), (false, None)];
        for (side, sign) in [(0usize, 1.0f64), (1, -1.0)] {
            let half = half_ball(wit, &a, b, sign);
            if half.1 > enough {
                out[side] = (true, Some(half));
                continue;
            }
            let row: Vec<f64> = a.iter().map(|v| sign * v).collect();
            cell.push((row, sign * b));
            out[side] = self.meets(r, cell);
            cell.pop();
        }
        out
    }

    /// The split key of hyperplane `h`: first whether it leaves all the
    /// set's laws on one side (`true`, a worse key), then the distinct laws
    /// on the larger side and on both; `None` if it makes no progress. With
    /// `exact`, a straddling region counts on a side only if it meets that
    /// side of the cell in a full-dimensional set, and a split that keeps
    /// every law on one side counts as progress only if both sides keep
    /// regions and one loses some (the key is then the regions on the
    /// larger side and on both): the cell shrinks and `h` is not chosen
    /// again below, so repeated such splits end in leaves of one law.
    fn score(
        &mut self,
        h: usize,
        set: &[usize],
        wits: &[Ball],
        cell: &mut Vec<(Vec<f64>, f64)>,
        exact: bool,
        n_laws: usize,
    ) -> Option<SplitKey> {
        let mut seen_l: Vec<u16> = Vec::new();
        let mut seen_r: Vec<u16> = Vec::new();
        let (mut nl, mut nr) = (0, 0);
        for (i, &r) in set.iter().enumerate() {
            // The cheap ranking takes a region it cannot place without an
            // LP as a straddler (on both sides).
            let side = if exact {
                self.side(r, h)
            } else {
                self.side_without_lp(r, h).unwrap_or(0)
            };
            let (inl, inr) = match side {
                -1 => (true, false),
                1 => (false, true),
                _ if exact => {
                    let [l, rr] = self.split_sides(r, h, &wits[i], cell);
                    (l.0, rr.0)
                }
                _ => (true, true),
            };
            let law = self.law[r];
            nl += usize::from(inl);
            nr += usize::from(inr);
            if inl && !seen_l.contains(&law) {
                seen_l.push(law);
            }
            if inr && !seen_r.contains(&law) {
                seen_r.push(law);
            }
        }
        if nl == set.len() && nr == set.len() {
            return None;
        }
        let (ll, lr) = (seen_l.len(), seen_r.len());
        if exact && (ll >= n_laws || lr >= n_laws) {
            // No fewer laws on one side: progress only in the cell.
            return (nl > 0 && nr > 0).then_some((true, (nl.max(nr), nl + nr)));
        }
        Some((false, (ll.max(lr), ll + lr)))
    }

    pub(in crate::tree) fn build(
        &mut self,
        set: Vec<usize>,
        wits: Vec<Ball>,
        cell: &mut Vec<(Vec<f64>, f64)>,
        depth: usize,
    ) -> u32 {
        self.depth = self.depth.max(depth);
        let first_law = set.first().map_or(0, |&r| self.law[r]);
        if set.iter().all(|&r| self.law[r] == first_law) || depth > 60 {
            if depth > 60 {
                self.ambiguous += 1;
            }
            return WIDE_LEAF | u32::from(first_law);
        }
        if self.clipping
            && let Some(l) = self.serving_law(&set, cell)
        {
            return WIDE_LEAF | u32::from(l);
        }
        // Candidates: the most frequent facets of the regions in the set.
        let mut freq: HashMap<usize, usize> = HashMap::new();
        for &r in &set {
            for &(h, _) in &self.reg_facets[r] {
                *freq.entry(h).or_default() += 1;
            }
        }
        let mut cands: Vec<(usize, usize)> = freq.into_iter().collect();
        cands.sort_by(|x, y| y.1.cmp(&x.1).then(x.0.cmp(&y.0)));
        // Small sets: score every facet exactly within the cell; large sets:
        // the most frequent facets, scored with the cell-free sides.
        let exact = set.len() * cands.len() <= self.exact_budget;
        if !exact {
            cands.truncate(self.max_candidates);
        }
        let n_laws = {
            let mut v: Vec<u16> = set.iter().map(|&r| self.law[r]).collect();
            v.sort_unstable();
            v.dedup();
            v.len()
        };
        // Cheap scores (cell-free sides, straddlers on both sides) for all
        // candidates; the best few are then scored exactly within the cell.
        let mut scored: Vec<(SplitKey, usize)> = cands
            .iter()
            .filter_map(|&(h, _)| {
                self.score(h, &set, &wits, cell, false, n_laws)
                    .map(|k| (k, h))
            })
            .collect();
        scored.sort_unstable();
        let mut best: Option<(SplitKey, usize)> = None;
        if exact {
            for round in 0..2 {
                // The rest is scored when the best few leave every law on
                // one side (or make no progress at all).
                let range = if round == 0 {
                    0..scored.len().min(EXACT_CANDIDATES)
                } else if best.is_none_or(|((cell_only, _), _)| cell_only) {
                    scored.len().min(EXACT_CANDIDATES)..scored.len()
                } else {
                    break;
                };
                for i in range {
                    let h = scored[i].1;
                    if let Some(key) = self.score(h, &set, &wits, cell, true, n_laws)
                        && best.is_none_or(|(k, _)| key < k)
                    {
                        best = Some((key, h));
                    }
                }
            }
        } else {
            best = scored.first().copied();
        }
        let Some((_, h)) = best else {
            // No facet separates the laws: majority law.
            self.ambiguous += 1;
            return WIDE_LEAF | u32::from(first_law);
        };
        let (a, b) = self.hp[h].clone();
        let na: Vec<f64> = a.iter().map(|v| -v).collect();
        let (mut left, mut lw) = (Vec::new(), Vec::new());
        let (mut right, mut rw) = (Vec::new(), Vec::new());
        for (i, &r) in set.iter().enumerate() {
            match self.side(r, h) {
                // The region lies on one side up to the tolerance: its
                // ball, cut to that side, stays inside the child's cell.
                -1 => {
                    left.push(r);
                    lw.push(half_ball(&wits[i], &a, b, 1.0));
                }
                1 => {
                    right.push(r);
                    rw.push(half_ball(&wits[i], &a, b, -1.0));
                }
                _ => {
                    let [l, rr] = self.split_sides(r, h, &wits[i], cell);
                    // Without a ball (an unfinished LP) the region stays
                    // with a zero radius: its tests then fall back to LPs.
                    let keep = |o: Option<Ball>| o.unwrap_or_else(|| (wits[i].0.clone(), 0.0));
                    if l.0 {
                        left.push(r);
                        lw.push(keep(l.1));
                    }
                    if rr.0 {
                        right.push(r);
                        rw.push(keep(rr.1));
                    }
                }
            }
        }
        if left.is_empty() {
            left.push(set[0]);
            lw.push((wits[0].0.clone(), 0.0));
        }
        if right.is_empty() {
            right.push(set[0]);
            rw.push((wits[0].0.clone(), 0.0));
        }
        let hid = self.hyperplane_id(h);
        let me = self.nodes.len();

        self.nodes.push([hid, 0, 0, 0]);
        cell.push((a.clone(), b));
        let l = self.build(left, lw, cell, depth + 1);
        cell.pop();
        cell.push((na, -b));
        let rgt = self.build(right, rw, cell, depth + 1);
        cell.pop();
        self.nodes[me][2] = l;
        self.nodes[me][3] = rgt;
        me as u32
    }
}
