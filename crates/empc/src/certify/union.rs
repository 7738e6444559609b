//! The union-merge certification: the exact partition explored breadth
//! first by iteration count, with the regions that reach the same
//! canonical solver state after the same count merged wherever their
//! union is convex.
//!
//! After a full dual step the solver's multipliers are `mu*_A(theta)`
//! and its future depends on the active set `A` and `theta` only (the
//! order of `A` matters only for ties between identical functions and for
//! the flops of a removal). Two regions at that state with the same
//! iteration count (and warm start set) therefore take the same further
//! path at every parameter: where their union is a polyhedron they can go
//! on as one region, and the certificate stays exact (same counts, same
//! paths from there; the regions are still disjoint and cover what they
//! covered). The union of two polyhedra is convex iff it equals their
//! envelope (Bemporad, Fukuda and Torrisi 2001: the rows of each valid on
//! the other), decided by LPs.
//!
//! Orders: a merged region keeps one member's list and is marked
//! [`Node::mixed`] if its members' orders differ; from there on a removal
//! is charged its most flops (the flops become an upper bound) and an
//! order-decided tie (two identical functions compared) is counted in
//! [`Geometry::order_ties`], which makes the certification fail rather
//! than guess. (Keying the groups by the ordered list and the flops too,
//! for exact flops, merged nothing on the larger problem: one ordered
//! list at one count is one path, so one region.)

use super::error::CertifyError;
use super::explore::{Ctx, Tally, limit, progress};
use super::geometry::{Geometry, Poly, range};
use super::model::Model;
use super::step::{Node, Outcome, add_step, expand};
use std::collections::{BTreeMap, HashMap, VecDeque};

/// One iteration count's canonical regions before and after merging.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct UnionLevel {
    /// The iteration count.
    pub iterations: usize,
    /// Regions at a canonical state with this count (before merging).
    pub canonical: usize,
    /// Distinct groups (active set and warm start set).
    pub groups: usize,
    /// Regions left after merging.
    pub merged: usize,
}

/// What the union merging did ([`crate::certify::CertifySettings::union_merge`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UnionStats {
    /// Per iteration count (warm: summed over the start sets).
    pub levels: Vec<UnionLevel>,
    /// Pairs whose union was tested for convexity (LPs).
    pub pairs_tested: usize,
    /// Pairs merged.
    pub merges: usize,
    /// Merges whose members' flops differed (the larger is kept).
    pub flops_differed: usize,
    /// Merges whose members' list orders differed.
    pub orders_differed: usize,
}

impl UnionStats {
    /// Whether the flops are exact: no merged regions had different flops
    /// or list orders (else the larger flops were kept and later removals
    /// charged their most: an upper bound).
    pub fn flops_exact(&self) -> bool {
        self.flops_differed == 0 && self.orders_differed == 0
    }
}

/// A group's key: warm start set and sorted active set.
type GroupKey = (usize, Vec<(usize, u8)>);

/// Quantised row (unit normal and offset) for finding shared facets.
fn qkey(row: &[f64], b: f64, sign: f64) -> Vec<i64> {
    row.iter()
        .chain(std::iter::once(&b))
        .map(|v| (sign * v * 1e6).round() as i64)
        .collect()
}

/// Whether the bounding boxes of two polyhedra meet.
fn boxes_meet(p: &Poly, q: &Poly) -> bool {
    p.lo.iter()
        .zip(&p.hi)
        .zip(q.lo.iter().zip(&q.hi))
        .all(|((pl, ph), (ql, qh))| *pl <= qh + 1e-9 && *ql <= ph + 1e-9)
}

/// Whether `row` is (to 1e-9) the hyperplane `(h, c)` times `sign`.
fn same_plane(row: &[f64], bi: f64, h: &[f64], c: f64, sign: f64) -> bool {
    row.iter().zip(h).all(|(x, y)| (x - sign * y).abs() < 1e-9) && (bi - sign * c).abs() < 1e-9
}

/// The rows of `p` other than the facet `h` of the shared plane, if each
/// holds on `q`: first the bounding-box tests (a row failing on all of
/// `q`'s box fails), then one LP per row, stopping at the first that
/// fails. `p` is irredundant (reduced), so a failing row is a facet.
fn rows_valid_except(
    geo: &mut Geometry,
    p: &Poly,
    q: &Poly,
    (h, c, sign): (&[f64], f64, f64),
    out: &mut (Vec<f64>, Vec<f64>),
) -> bool {
    let d = p.centre.len();
    let mut need_lp = Vec::new();
    for (row, &bi) in p.a.chunks_exact(d).zip(&p.b) {
        if same_plane(row, bi, h, c, sign) {
            continue;
        }
        let (mn, mx) = range(row, &q.lo, &q.hi);
        if mn > bi + 1e-9 {
            return false;
        }
        if mx > bi + 1e-9 {
            need_lp.push((row, bi));
        }
        out.0.extend_from_slice(row);
        out.1.push(bi);
    }
    need_lp.into_iter().all(|(row, bi)| {
        geo.max_until(row, &q.a, &q.b, &q.centre, bi + 1e-9)
            .is_some_and(|v| v <= bi + 1e-9)
    })
}

/// The union of `p` and `q` as one polyhedron's rows, if it is convex.
/// Two polyhedra with disjoint interiors and a convex union meet in one
/// hyperplane `h` (a separating one); every other facet of either is a
/// facet of the union, so its row holds on the other. Conversely if every
/// row but `h`'s holds on the other, a point of the rows' intersection lies
/// in `p` where `h x <= c` and in `q` where not: the union is that
/// intersection (Bemporad, Fukuda and Torrisi's envelope).
fn convex_union(
    geo: &mut Geometry,
    p: &Poly,
    q: &Poly,
    h: (&[f64], f64),
) -> Option<(Vec<f64>, Vec<f64>)> {
    let mut out = (Vec::new(), Vec::new());
    if !rows_valid_except(geo, p, q, (h.0, h.1, 1.0), &mut out)
        || !rows_valid_except(geo, q, p, (h.0, h.1, -1.0), &mut out)
    {
        return None;
    }
    Some(out)
}

/// Merges the members of one group pairwise while a union is convex.
fn merge_group(geo: &mut Geometry, members: Vec<Node>, stats: &mut UnionStats) -> Vec<Node> {
    if members.len() < 2 {
        return members;
    }
    let d = members[0].poly.centre.len();
    let mut nodes: Vec<Option<Node>> = members
        .into_iter()
        .map(|mut n| {
            n.poly = geo.reduce(&n.poly);
            Some(n)
        })
        .collect();
    let mut index: HashMap<Vec<i64>, Vec<usize>> = HashMap::new();
    let add_rows = |index: &mut HashMap<Vec<i64>, Vec<usize>>, i: usize, p: &Poly| {
        for (row, &bi) in p.a.chunks_exact(d).zip(&p.b) {
            index.entry(qkey(row, bi, 1.0)).or_default().push(i);
        }
    };
    for (i, n) in nodes.iter().enumerate() {
        if let Some(n) = n {
            add_rows(&mut index, i, &n.poly);
        }
    }
    let mut work: VecDeque<usize> = (0..nodes.len()).collect();
    while let Some(i) = work.pop_front() {
        let Some(pi) = nodes[i].as_ref().map(|n| n.poly.clone()) else {
            continue;
        };
        let mut cands: Vec<(usize, usize)> = Vec::new();
        for (r, (row, &bi)) in pi.a.chunks_exact(d).zip(&pi.b).enumerate() {
            if let Some(v) = index.get(&qkey(row, bi, -1.0)) {
                cands.extend(v.iter().copied().filter(|&j| j != i).map(|j| (j, r)));
            }
        }
        cands.sort_unstable();
        cands.dedup_by_key(|c| c.0);
        for (j, r) in cands {
            let Some(pj) = nodes[j].as_ref().map(|n| &n.poly) else {
                continue;
            };
            if !boxes_meet(&pi, pj) {
                continue;
            }
            stats.pairs_tested += 1;
            let pj = pj.clone();
            let h = (&pi.a[r * d..(r + 1) * d], pi.b[r]);
            let Some((a, b)) = convex_union(geo, &pi, &pj, h) else {
                continue;
            };
            let Some(poly) = geo.poly_of(a, b, &pi.centre) else {
                continue;
            };
            let poly = geo.reduce(&poly);
            let other = nodes[j].take().expect("a live member");
            let mut keep = nodes[i].take().expect("a live member");
            stats.merges += 1;
            if keep.flops != other.flops {
                stats.flops_differed += 1;
            }
            if keep.active != other.active {
                stats.orders_differed += 1;
            }
            keep.mixed |= other.mixed || keep.active != other.active;
            keep.flops = keep.flops.max(other.flops);
            keep.poly = poly;
            add_rows(&mut index, i, &keep.poly);
            nodes[i] = Some(keep);
            work.push_back(i);
            break;
        }
    }
    nodes.into_iter().flatten().collect()
}

/// The most numbers the open regions may hold (4 GB of `f64`, the limit of
/// the merged mode's stored pieces) before [`CertifyError::Limit`]: the
/// breadth-first frontier keeps every region of a count in memory.
const MAX_OPEN_NUMBERS: usize = 500_000_000;

/// The numbers a region keeps: its rows, box and ball, its multipliers.
fn numbers(n: &Node) -> usize {
    let p = &n.poly;
    p.a.len()
        + p.b.len()
        + p.centre.len()
        + 2 * p.lo.len()
        + n.mu.iter().map(Vec::len).sum::<usize>()
}

/// Explores every region below `root` breadth first by iteration count,
/// merging each count's canonical regions by group.
pub(super) fn run_union(
    model: &Model,
    geo: &mut Geometry,
    root: Node,
    ctx: &mut Ctx<'_>,
    tally: &mut Tally,
    collect_finals: bool,
    stats: &mut UnionStats,
) -> Result<(), CertifyError> {
    let mut levels: BTreeMap<usize, Vec<Node>> = BTreeMap::new();
    let mut open = 1usize;
    let mut stored = numbers(&root);
    levels.entry(root.iterations).or_default().push(root);
    let mut out = Vec::new();
    let keep = ctx.settings.keep_regions;
    while let Some((t, mut stack)) = levels.pop_first() {
        let mut groups: BTreeMap<GroupKey, Vec<Node>> = BTreeMap::new();
        let mut canonical = 0usize;
        while let Some(node) = stack.pop() {
            open -= 1;
            stored = stored.saturating_sub(numbers(&node));
            tally.nodes += 1;
            tally.deepest = tally.deepest.max(node.iterations);
            if tally.regions + open + canonical > ctx.settings.max_regions
                || stored > MAX_OPEN_NUMBERS
            {
                return Err(limit(ctx, tally, open + canonical, "region"));
            }
            if ctx
                .settings
                .time_limit
                .is_some_and(|l| ctx.started.elapsed() > l)
            {
                return Err(limit(ctx, tally, open + canonical, "time"));
            }
            if tally.nodes.is_multiple_of(512) {
                let report = progress(ctx, tally, geo, open + canonical);
                (ctx.progress)(&report);
            }
            out.clear();
            expand(model, geo, node, &mut out)?;
            for o in out.drain(..) {
                match o {
                    Outcome::Node(n) if n.iterations == t => {
                        open += 1;
                        stored += numbers(&n);
                        stack.push(n);
                    }
                    Outcome::Node(n) => {
                        open += 1;
                        stored += numbers(&n);
                        levels.entry(n.iterations).or_default().push(n);
                    }
                    Outcome::Leaf(n, s) => tally.record(n, s, keep, collect_finals),
                    Outcome::Canonical(n) => {
                        canonical += 1;
                        stored += numbers(&n);
                        let mut set = n.active.clone();
                        set.sort_unstable();
                        groups.entry((n.start, set)).or_default().push(n);
                    }
                }
            }
        }
        let mut level = UnionLevel {
            iterations: t,
            canonical,
            groups: groups.len(),
            merged: 0,
        };
        for (_, members) in groups {
            stored = stored.saturating_sub(members.iter().map(numbers).sum());
            for node in merge_group(geo, members, stats) {
                level.merged += 1;
                out.clear();
                add_step(model, geo, node, &mut out);
                for o in out.drain(..) {
                    match o {
                        Outcome::Node(n) => {
                            open += 1;
                            stored += numbers(&n);
                            levels.entry(n.iterations).or_default().push(n);
                        }
                        Outcome::Leaf(n, s) => tally.record(n, s, keep, collect_finals),
                        Outcome::Canonical(_) => {
                            return Err(CertifyError::Numerical(
                                "an addition reached a canonical state".into(),
                            ));
                        }
                    }
                }
            }
        }
        // Warm: one run per start set, the counts added up.
        match stats.levels.iter_mut().find(|l| l.iterations == t) {
            Some(l) => {
                l.canonical += level.canonical;
                l.groups += level.groups;
                l.merged += level.merged;
            }
            None if level.canonical > 0 => {
                stats.levels.push(level);
                stats.levels.sort_by_key(|l| l.iterations);
            }
            None => {}
        }
        if geo.order_ties > 0 {
            return Err(CertifyError::Numerical(format!(
                "{} comparisons of identical functions decided by the list order on merged \
                 regions of different orders (use the exact mode)",
                geo.order_ties
            )));
        }
    }
    Ok(())
}
