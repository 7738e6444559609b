//! The merged (over-approximating) certification: an upper bound on the
//! iterations and flops of every parameter in the box, without the
//! partition by paths.
//!
//! After a full dual step (nothing blocks) the solver's multipliers are
//! `mu*_A(theta)`, those of the equality-constrained optimum of its active
//! set `A`: everything it does next depends on `A` and `theta` only (the
//! order of `A` only through ties between identical functions and through
//! the flop count of a removal, both taken at their worst in merged mode,
//! [`Model::merge`]). Every parameter at that canonical state lies in `D_A
//! = {theta in the box : s_p mu*_A,p(theta) >= -dual_tol}`.
//!
//! A *segment* is what the solver does from one canonical state to the
//! next (one addition, then the removals of its blocking constraints), or
//! to the end. Splitting `D_A` by the exact rules (`step.rs`) gives the
//! pieces `T(A, s)`: the parameters of `D_A` whose next segment from `A`
//! is `s`, ending at the canonical state `B`. The bound `R(A, s)` of the
//! iterations after `s` is certified once over `T(A, s)` and memoised:
//! `T(A, s)` is split by the next segment `s'` from `B`, and each piece
//! takes at most `|s'| + R(B, s')` (its parameters lie in `T(B, s')`). A
//! chain of the bound thus has a common parameter for every two
//! consecutive segments (merging on the state alone, `R_A` over `D_A`,
//! lets chains switch parameter at every state and gave 22 iterations
//! against the exact 4 on a small box, and merging the arrivals' bounding
//! boxes let them cycle). A memo entry met again while it is being
//! computed (a cycle through different parameters) is continued exactly
//! instead, so the recursion ends. The cold bound is `max_s |s| + R(0, s)`
//! from the empty set over the box.

use super::error::CertifyError;
use super::explore::Ctx;
use super::flops;
use super::geometry::{Geometry, Half, Poly, half, size};
use super::model::{EQUALITY, Model, UPPER, sign};
use super::report::{self, Certificate, Certification, RegionReport};
use super::settings::{CertifySettings, Progress};
use super::step::{Change, Node, Outcome, Status, add_step, expand};
use super::warm::{warm_region, warm_root};
use kestrel_qp::parametric::ParametricQp;
use std::collections::{BTreeSet, HashMap, HashSet};
use std::rc::Rc;
use std::time::Instant;

/// The most nested bounds followed (each a few hundred bytes of stack);
/// a deeper chain is bounded by the solver's iteration cap.
const MAX_LEVELS: usize = 2_000;

/// The most numbers the stored pieces may hold (4 GB of `f64`) before
/// [`CertifyError::Limit`].
const MAX_STORED: usize = 500_000_000;

/// An active set sorted by constraint (constraint, side code).
type Key = Vec<(usize, u8)>;
/// The changes of a segment.
type Seg = Vec<Change>;

/// A piece `T(A, s)` of a canonical state's domain.
#[derive(Debug)]
struct Piece {
    poly: Poly,
    /// The segment's iterations and flops (from the canonical state).
    iterations: usize,
    flops: u64,
    /// The canonical state it reaches (sorted), or how the solve ends.
    end: Result<Key, Status>,
}

/// The pieces of one canonical state: every segment's, and those ending
/// at a canonical state by segment (unique: each is a branch of the split).
#[derive(Debug, Default)]
struct Pieces {
    all: Vec<(Seg, Piece)>,
    canonical: HashMap<Seg, usize>,
}

/// A bound after a segment: iterations, flops, how its worst chain ends,
/// and the segment that chain takes next.
#[derive(Debug, Clone)]
struct Bound {
    iterations: usize,
    flops: u64,
    status: Status,
    next: Option<(Key, Seg)>,
    next_flops: Option<(Key, Seg)>,
}

impl Bound {
    fn zero() -> Self {
        Bound {
            iterations: 0,
            flops: 0,
            status: Status::Optimal,
            next: None,
            next_flops: None,
        }
    }

    /// Takes `it`, `fl` if larger (with `next` as the continuation).
    fn offer(&mut self, it: usize, fl: u64, status: Status, next: Option<(Key, Seg)>) {
        if it > self.iterations {
            self.iterations = it;
            self.status = status;
            self.next = next.clone();
        }
        if fl > self.flops {
            self.flops = fl;
            self.next_flops = next;
        }
    }
}

/// The memoised exploration.
struct Merger<'m, 'x, 'c> {
    cold: &'m Model,
    geo: &'x mut Geometry,
    ctx: &'x mut Ctx<'c>,
    /// `T(A, s)` of every canonical state met.
    pieces: HashMap<Key, Rc<Pieces>>,
    /// `R(A, s)`.
    bounds: HashMap<(Key, Seg), Bound>,
    open: HashSet<(Key, Seg)>,
    /// Segments of history in a memo key.
    depth: usize,
    /// Nested bounds being computed, the most so far, and how often the
    /// limit [`MAX_LEVELS`] cut a chain.
    level: usize,
    deepest: usize,
    capped: usize,
    /// Numbers held by the stored pieces' polyhedra (limited by
    /// [`MAX_STORED`]).
    stored: usize,
    nodes: usize,
    inline: usize,
    infeasible: usize,
    limited: usize,
    worst_seen: usize,
    finals: BTreeSet<Key>,
}

/// The additions in a path (one per segment).
fn adds(path: &[Change]) -> usize {
    path.iter()
        .filter(|c| matches!(c, Change::Add { .. }))
        .count()
}

/// The length of a history's first segment (up to its second addition).
fn first_segment(path: &[Change]) -> usize {
    path.iter()
        .skip(1)
        .position(|c| matches!(c, Change::Add { .. }))
        .map_or(path.len(), |i| i + 1)
}

fn sorted(active: &[(usize, u8)]) -> Key {
    let mut k = active.to_vec();
    k.sort_unstable();
    k
}

impl Merger<'_, '_, '_> {
    /// The canonical state of `key` over `poly` (counters from zero).
    fn canonical(&self, key: &Key, poly: Poly) -> Result<Node, CertifyError> {
        let mu = self
            .cold
            .mustar(key)
            .ok_or_else(|| CertifyError::Numerical("M of an active set is singular".into()))?;
        Ok(Node {
            poly,
            fwd: key.len(),
            active: key.clone(),
            mu,
            dual: true,
            singular: false,
            iterations: 0,
            flops: 0,
            path: Vec::new(),
            start: 0,
            mixed: false,
        })
    }

    /// `D_A`: the parameter set where the multipliers of `key` have their
    /// signs (the solver's `star_p >= -dual_tol`).
    fn domain(&mut self, node: &Node) -> Option<Poly> {
        let model = self.cold;
        let mut hs: Vec<Half> = node
            .active
            .iter()
            .zip(&node.mu)
            .filter(|((_, code), _)| code & EQUALITY == 0)
            .map(|(&(_, code), m)| {
                let mut f: Vec<f64> = m.iter().map(|v| -sign(code) * v).collect();
                f[model.d] -= model.settings.dual_tol;
                half(&f, false, size(m))
            })
            .collect();
        hs.extend(model.param_halfs(0, model.d));
        self.geo.restrict(&Poly::cube(model.d), &hs)
    }

    /// The segments from the canonical state `start` (with `model`):
    /// every piece at its next canonical state or end.
    fn segments(
        &mut self,
        model: &Model,
        start: Node,
    ) -> Result<Vec<(Node, Option<Status>)>, CertifyError> {
        let mut pending = Vec::new();
        add_step(model, self.geo, start, &mut pending);
        let mut stack: Vec<Node> = Vec::new();
        let mut ends = Vec::new();
        loop {
            while let Some(o) = pending.pop() {
                match o {
                    Outcome::Node(n) => stack.push(n),
                    Outcome::Leaf(n, s) => {
                        match s {
                            Status::Optimal => {
                                self.finals.insert(sorted(&n.active));
                            }
                            Status::Infeasible => self.infeasible += 1,
                            Status::IterationLimit => self.limited += 1,
                        }
                        ends.push((n, Some(s)));
                    }
                    Outcome::Canonical(n) => ends.push((n, None)),
                }
            }
            let Some(node) = stack.pop() else {
                return Ok(ends);
            };
            self.nodes += 1;
            self.check(stack.len())?;
            expand(model, self.geo, node, &mut pending)?;
        }
    }

    /// `T(A, h)` for every history `h` of `depth` segments from `key` (or
    /// fewer, to the end of the solve): the exact split of `D_A`.
    fn pieces(&mut self, key: &Key) -> Result<Rc<Pieces>, CertifyError> {
        if let Some(p) = self.pieces.get(key) {
            return Ok(p.clone());
        }
        let mut node = self.canonical(key, Poly::cube(self.cold.d))?;
        let mut out = Pieces::default();
        if let Some(poly) = self.domain(&node) {
            node.poly = poly;
            let model = self.cold;
            let mut frontier = vec![node];
            while let Some(start) = frontier.pop() {
                for (n, status) in self.segments(model, start)? {
                    let end = match status {
                        Some(s) => Err(s),
                        None if adds(&n.path) < self.depth => {
                            frontier.push(n);
                            continue;
                        }
                        None => Ok(sorted(&n.active)),
                    };
                    if end.is_ok()
                        && out
                            .canonical
                            .insert(n.path.clone(), out.all.len())
                            .is_some()
                    {
                        return Err(CertifyError::Numerical(
                            "two pieces of one state with the same history".into(),
                        ));
                    }
                    self.stored += n.poly.a.len() + n.poly.b.len();
                    let piece = Piece {
                        iterations: n.iterations,
                        flops: n.flops,
                        end,
                        poly: n.poly,
                    };
                    out.all.push((n.path, piece));
                }
            }
        }
        let rc = Rc::new(out);
        self.pieces.insert(key.clone(), rc.clone());
        Ok(rc)
    }

    /// The set after `seg`'s changes from `key`.
    fn apply(&self, key: &Key, seg: &[Change]) -> Key {
        let mut set = key.clone();
        for c in seg {
            match *c {
                Change::Add { constraint, upper } => {
                    let eq = if self.cold.equality[constraint] {
                        EQUALITY
                    } else {
                        0
                    };
                    set.push((constraint, u8::from(upper) * UPPER + eq));
                }
                Change::Remove { constraint } | Change::Singular { constraint } => {
                    set.retain(|a| a.0 != constraint);
                }
            }
        }
        sorted(&set)
    }

    /// The bound after the canonical state `node`, reached from `hist.0`
    /// through the history `hist.1` (its region lies in `T(hist)`): the
    /// most over its next segments `s` of `|s| + R(hist')`, `hist'` the
    /// history shifted by one segment.
    fn after(&mut self, hist: &(Key, Seg), node: Node) -> Result<Bound, CertifyError> {
        if self.level >= MAX_LEVELS {
            // Too deep a chain of bounds to follow: the solver's cap.
            self.capped += 1;
            return Ok(Bound {
                iterations: self.cold.settings.max_iterations,
                flops: u64::MAX / 4,
                status: Status::IterationLimit,
                next: None,
                next_flops: None,
            });
        }
        self.level += 1;
        self.deepest = self.deepest.max(self.level);
        let b = self.after_inner(hist, node);
        self.level -= 1;
        b
    }

    fn after_inner(&mut self, hist: &(Key, Seg), node: Node) -> Result<Bound, CertifyError> {
        let model = self.cold;
        let first = first_segment(&hist.1);
        let from = self.apply(&hist.0, &hist.1[..first]);
        let mut b = Bound::zero();
        for (n, status) in self.segments(model, node)? {
            if let Some(s) = status {
                b.offer(n.iterations, n.flops, s, None);
                continue;
            }
            let mut path = hist.1[first..].to_vec();
            path.extend_from_slice(&n.path);
            let key = (from.clone(), path);
            let r = match self.bound(&key)? {
                Some(r) => r,
                None => {
                    // Continue exactly from this piece.
                    self.inline += 1;
                    let mut start = n.clone();
                    start.iterations = 0;
                    start.flops = 0;
                    start.path.clear();
                    self.after(&key, start)?
                }
            };
            self.worst_seen = self.worst_seen.max(n.iterations + r.iterations);
            b.offer(
                n.iterations + r.iterations,
                n.flops.saturating_add(r.flops),
                r.status,
                Some(key),
            );
        }
        Ok(b)
    }

    /// The bound over all of `D_A` from the canonical state `key`.
    fn state(&mut self, key: &Key) -> Result<Bound, CertifyError> {
        let pieces = self.pieces(key)?;
        let mut b = Bound::zero();
        for (path, piece) in pieces.all.iter() {
            let hist = (key.clone(), path.clone());
            let (r, status, next) = match &piece.end {
                Err(s) => (Bound::zero(), *s, None),
                Ok(_) => match self.bound(&hist)? {
                    Some(r) => {
                        let s = r.status;
                        (r, s, Some(hist))
                    }
                    None => {
                        let node = self.canonical(&self.apply(key, path), piece.poly.clone())?;
                        let r = self.after(&hist, node)?;
                        let s = r.status;
                        (r, s, Some(hist))
                    }
                },
            };
            b.offer(
                piece.iterations + r.iterations,
                piece.flops.saturating_add(r.flops),
                status,
                next,
            );
        }
        Ok(b)
    }

    /// `R(hist)`: `None` while it is being computed or if the history has
    /// no piece (the caller continues exactly).
    fn bound(&mut self, key: &(Key, Seg)) -> Result<Option<Bound>, CertifyError> {
        if let Some(b) = self.bounds.get(key) {
            return Ok(Some(b.clone()));
        }
        if self.open.contains(key) {
            return Ok(None);
        }
        let pieces = self.pieces(&key.0)?;
        let Some(piece) = pieces.canonical.get(&key.1).map(|&i| &pieces.all[i].1) else {
            return Ok(None);
        };
        let b = match &piece.end {
            Err(_) => Bound::zero(),
            Ok(next) => {
                self.open.insert(key.clone());
                let node = self.canonical(next, piece.poly.clone())?;
                let b = self.after(key, node)?;
                self.open.remove(key);
                b
            }
        };
        self.bounds.insert(key.clone(), b.clone());
        Ok(Some(b))
    }

    /// Limits and progress.
    fn check(&mut self, open: usize) -> Result<(), CertifyError> {
        let ctx = &mut *self.ctx;
        let states = self.bounds.len();
        let what = if states > ctx.settings.max_regions || self.stored > MAX_STORED {
            Some("region")
        } else if ctx
            .settings
            .time_limit
            .is_some_and(|t| ctx.started.elapsed() > t)
        {
            Some("time")
        } else {
            None
        };
        if let Some(what) = what {
            return Err(CertifyError::Limit {
                what,
                phase: ctx.phase,
                regions: states,
                open,
                nodes: self.nodes,
                deepest: self.deepest,
                worst_so_far: self.worst_seen,
                start_sets_done: ctx.sets_done,
                start_sets: ctx.sets_total,
                elapsed: ctx.started.elapsed(),
            });
        }
        if self.nodes.is_multiple_of(512) {
            let report = Progress {
                phase: ctx.phase,
                regions: states,
                open: self.level,
                nodes: self.nodes,
                lps: self.geo.lps,
                worst_iterations: self.worst_seen,
                start_sets_done: ctx.sets_done,
                start_sets: ctx.sets_total,
                elapsed: ctx.started.elapsed(),
                estimate: None,
                states,
            };
            (ctx.progress)(&report);
        }
        Ok(())
    }

    /// The changes of a bound's worst chain from the history `first` (in
    /// full), then the last segment of each next history (those before it
    /// are the previous history's); it stops where a bound was continued
    /// exactly (not memoised).
    fn chain(&self, first: Option<(Key, Seg)>, by_flops: bool) -> Vec<Change> {
        let mut path = Vec::new();
        let mut next = first;
        let mut seen = HashSet::new();
        while let Some(key) = next {
            if !seen.insert(key.clone()) {
                break;
            }
            if path.is_empty() {
                path.extend_from_slice(&key.1);
            } else {
                let last = key
                    .1
                    .iter()
                    .rposition(|c| matches!(c, Change::Add { .. }))
                    .unwrap_or(0);
                path.extend_from_slice(&key.1[last..]);
            }
            let Some(b) = self.bounds.get(&key) else {
                break;
            };
            next = if by_flops {
                b.next_flops.clone()
            } else {
                b.next.clone()
            };
        }
        path
    }
}

/// Certifies `par` in merged mode (cold, and warm if asked for).
pub(super) fn certify_merged(
    par: &ParametricQp,
    settings: &CertifySettings,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Certification, CertifyError> {
    let p = par.p();
    let mut cold = Model::new(par, p, settings.qp).ok_or(CertifyError::NotPositiveDefinite)?;
    cold.merge = true;
    cold.canonical = true;
    let mut ctx = Ctx::new(settings, progress);
    let started = ctx.started;
    let mut geo = Geometry::new(settings.min_radius);
    let n = par.n() as u64;
    let mut m = Merger {
        cold: &cold,
        geo: &mut geo,
        ctx: &mut ctx,
        pieces: HashMap::new(),
        bounds: HashMap::new(),
        open: HashSet::new(),
        depth: settings.merge.unwrap_or(1).max(1),
        level: 0,
        deepest: 0,
        capped: 0,
        stored: 0,
        nodes: 0,
        inline: 0,
        infeasible: 0,
        limited: 0,
        worst_seen: 0,
        finals: BTreeSet::new(),
    };
    // The empty set is canonical at once (mu* of no constraint).
    let root = m.state(&Vec::new())?;
    let pre = flops::preamble(n);
    let cap = settings.qp.max_iterations;
    let cold_cert = finish(&m, par, &root, pre, None, &[], (m.geo.lps, started));
    let warm = match settings.warm_step {
        None => None,
        Some(step) => {
            let t0 = Instant::now();
            let lps0 = m.geo.lps;
            let mut wm =
                Model::new(par, 2 * p, settings.qp).ok_or(CertifyError::NotPositiveDefinite)?;
            wm.merge = true;
            wm.canonical = true;
            let sets: Vec<Key> = m.finals.iter().cloned().collect();
            // A cut chain left the cold solves below it unexplored: their
            // optimal sets may be missing from the start sets.
            let cold_cut = m.capped > 0;
            m.capped = 0;
            m.ctx.phase = "warm";
            m.ctx.sets_total = sets.len();
            (m.infeasible, m.limited) = (0, 0);
            let mut all = Bound::zero();
            let mut worst_start = 0;
            for (id, set) in sets.iter().enumerate() {
                m.ctx.sets_done = id;
                let Some(poly) = warm_region(&cold, m.geo, set, step) else {
                    continue;
                };
                let root = warm_root(&wm, set, poly, id, n);
                let mut out = Vec::new();
                expand(&wm, m.geo, root, &mut out)?;
                // Up to the first canonical state in (theta, theta_prev).
                let mut stack = out;
                while let Some(o) = stack.pop() {
                    match o {
                        Outcome::Node(x) => {
                            m.nodes += 1;
                            m.check(stack.len())?;
                            expand(&wm, m.geo, x, &mut stack)?;
                        }
                        Outcome::Leaf(x, s) => {
                            if x.iterations > all.iterations || x.flops > all.flops {
                                worst_start = id;
                            }
                            all.offer(x.iterations, x.flops, s, None);
                        }
                        Outcome::Canonical(x) => {
                            let r = m.state(&sorted(&x.active))?;
                            let (it, fl) = (x.iterations + r.iterations, x.flops + r.flops);
                            if it > all.iterations || fl > all.flops {
                                worst_start = id;
                            }
                            all.offer(it, fl, r.status, None);
                        }
                    }
                }
            }
            if cold_cut {
                all.offer(cap + 1, u64::MAX / 4, Status::IterationLimit, None);
                m.capped += 1;
            }
            let mut c = finish(&m, par, &all, 0, Some(step), &sets, (m.geo.lps - lps0, t0));
            c.start_sets = sets.len();
            if let Some(w) = c.worst.as_mut() {
                w.start_set = report::active(&sets[worst_start]);
            }
            Some(c)
        }
    };
    Ok(Certification {
        cold: cold_cert,
        warm,
    })
}

/// The certificate of one phase from its bound (`pre` flops before it).
fn finish(
    m: &Merger<'_, '_, '_>,
    par: &ParametricQp,
    b: &Bound,
    pre: u64,
    warm_step: Option<f64>,
    sets: &[Key],
    (lps, t0): (usize, Instant),
) -> Certificate {
    let model = m.cold;
    let cap = model.settings.max_iterations;
    let report = |iterations: usize, flops: u64, path: Vec<Change>| RegionReport {
        iterations,
        flops,
        status: b.status,
        theta: Vec::new(),
        theta_prev: None,
        radius: 0.0,
        halfspaces: Vec::new(),
        path,
        start_set: Vec::new(),
    };
    let it = b.iterations.min(cap);
    let worst = report(it, b.flops + pre, m.chain(b.next.clone(), false));
    let fl_path = m.chain(b.next_flops.clone(), true);
    let worst_flops_region = report(fl_path.len(), b.flops + pre, fl_path);
    Certificate {
        warm_step,
        exact: false,
        n: par.n(),
        m: par.m(),
        p: par.p(),
        worst_iterations: it,
        worst_flops: b.flops + pre,
        worst: Some(worst),
        worst_flops_region: Some(worst_flops_region),
        regions: m.bounds.len(),
        histogram: Vec::new(),
        infeasible_regions: m.infeasible,
        iteration_limit_regions: m.limited + m.capped + usize::from(b.iterations > cap),
        start_sets: sets.len(),
        any_order: false,
        lps,
        canonical_states: m.pieces.len(),
        union: None,
        elapsed: t0.elapsed(),
        finals: m.finals.iter().cloned().collect(),
        leaves: Vec::new(),
        start_regions: Vec::new(),
        centre: model.centre.clone(),
        half: model.half.clone(),
    }
}
