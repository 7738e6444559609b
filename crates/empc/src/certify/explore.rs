//! The depth-first exploration of the region tree: limits, progress and
//! the tally of the leaves (the certificate's regions).

use super::error::CertifyError;
use super::geometry::Geometry;
use super::model::Model;
use super::settings::{CertifySettings, Progress};
use super::step::{Change, Node, Outcome, Status, expand};
use std::time::Instant;

/// A stored leaf region (normalised coordinates).
#[derive(Debug, Clone)]
pub(super) struct Leaf {
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub iterations: usize,
    pub flops: u64,
    pub start: usize,
}

/// A leaf with everything its report needs.
#[derive(Debug, Clone)]
pub(super) struct Worst {
    pub node: Node,
    pub status: Status,
}

/// What the exploration found.
#[derive(Debug, Default)]
pub(super) struct Tally {
    pub leaves: Vec<Leaf>,
    pub regions: usize,
    pub nodes: usize,
    pub histogram: Vec<usize>,
    pub infeasible: usize,
    pub limited: usize,
    pub worst_iterations: Option<Worst>,
    pub worst_flops: Option<Worst>,
    /// Final active sets (sorted by constraint) of the optimal leaves.
    pub finals: std::collections::BTreeSet<Vec<(usize, u8)>>,
    pub deepest: usize,
}

/// The exploration's context: settings, clock, progress callback.
pub(super) struct Ctx<'a> {
    pub settings: &'a CertifySettings,
    pub started: Instant,
    pub progress: &'a mut dyn FnMut(&Progress),
    pub phase: &'static str,
    pub sets_done: usize,
    pub sets_total: usize,
}

impl<'a> Ctx<'a> {
    /// The context of a run starting now, in its cold phase.
    pub fn new(settings: &'a CertifySettings, progress: &'a mut dyn FnMut(&Progress)) -> Self {
        Ctx {
            settings,
            started: Instant::now(),
            progress,
            phase: "cold",
            sets_done: 0,
            sets_total: 0,
        }
    }
}

fn better(a: &Node, b: &Node, key: impl Fn(&Node) -> u64) -> bool {
    (key(a), a.poly.radius) > (key(b), b.poly.radius)
}

impl Tally {
    pub(super) fn record(&mut self, node: Node, status: Status, keep: bool, collect_finals: bool) {
        self.regions += 1;
        let it = node.iterations;
        if self.histogram.len() <= it {
            self.histogram.resize(it + 1, 0);
        }
        self.histogram[it] += 1;
        match status {
            Status::Optimal => {
                if collect_finals {
                    let mut set = node.active.clone();
                    set.sort_unstable();
                    self.finals.insert(set);
                }
            }
            Status::Infeasible => self.infeasible += 1,
            Status::IterationLimit => self.limited += 1,
        }
        if keep {
            self.leaves.push(Leaf {
                a: node.poly.a.clone(),
                b: node.poly.b.clone(),
                iterations: it,
                flops: node.flops,
                start: node.start,
            });
        }
        let by_it = |n: &Node| n.iterations as u64;
        if self
            .worst_iterations
            .as_ref()
            .is_none_or(|w| better(&node, &w.node, by_it))
        {
            self.worst_iterations = Some(Worst {
                node: node.clone(),
                status,
            });
        }
        let by_fl = |n: &Node| n.flops;
        if self
            .worst_flops
            .as_ref()
            .is_none_or(|w| better(&node, &w.node, by_fl))
        {
            self.worst_flops = Some(Worst { node, status });
        }
    }
}

/// Explores every region below `root`.
pub(super) fn run(
    model: &Model,
    geo: &mut Geometry,
    root: Node,
    ctx: &mut Ctx<'_>,
    tally: &mut Tally,
    collect_finals: bool,
) -> Result<(), CertifyError> {
    let mut stack = vec![root];
    let mut out = Vec::new();
    while let Some(node) = stack.pop() {
        tally.nodes += 1;
        tally.deepest = tally.deepest.max(node.iterations);
        let open = stack.len();
        if tally.regions + open > ctx.settings.max_regions {
            return Err(limit(ctx, tally, open, "region"));
        }
        if ctx
            .settings
            .time_limit
            .is_some_and(|t| ctx.started.elapsed() > t)
        {
            return Err(limit(ctx, tally, open, "time"));
        }
        if tally.nodes.is_multiple_of(512) {
            let report = progress(ctx, tally, geo, open);
            (ctx.progress)(&report);
        }
        out.clear();
        expand(model, geo, node, &mut out)?;
        for o in out.drain(..) {
            match o {
                Outcome::Node(n) => stack.push(n),
                Outcome::Leaf(n, s) => {
                    tally.record(n, s, ctx.settings.keep_regions, collect_finals)
                }
                Outcome::Canonical(_) => return Err(merged_model()),
            }
        }
    }
    Ok(())
}

/// A merged-mode outcome where the exact exploration runs.
pub(super) fn merged_model() -> CertifyError {
    CertifyError::Numerical("a merged-mode model in the exact exploration".to_string())
}

pub(super) fn progress(ctx: &Ctx<'_>, tally: &Tally, geo: &Geometry, open: usize) -> Progress {
    Progress {
        phase: ctx.phase,
        regions: tally.regions,
        open,
        nodes: tally.nodes,
        lps: geo.lps,
        worst_iterations: tally
            .worst_iterations
            .as_ref()
            .map_or(0, |w| w.node.iterations),
        start_sets_done: ctx.sets_done,
        start_sets: ctx.sets_total,
        elapsed: ctx.started.elapsed(),
        estimate: None,
        states: 0,
    }
}

pub(super) fn limit(ctx: &Ctx<'_>, tally: &Tally, open: usize, what: &'static str) -> CertifyError {
    CertifyError::Limit {
        what,
        phase: ctx.phase,
        regions: tally.regions,
        open,
        nodes: tally.nodes,
        deepest: tally.deepest,
        worst_so_far: tally
            .worst_iterations
            .as_ref()
            .map_or(0, |w| w.node.iterations),
        start_sets_done: ctx.sets_done,
        start_sets: ctx.sets_total,
        elapsed: ctx.started.elapsed(),
    }
}

/// A node's path as text (`+b3u` added bound 3 upper, `-r1` removed row 1,
/// `~b2` removed by a singular step), constraint names as in
/// [`super::model::constraint_name`].
pub(super) fn path_text(path: &[Change], m: usize) -> String {
    let mut s = String::new();
    for c in path {
        if !s.is_empty() {
            s.push(' ');
        }
        match *c {
            Change::Add { constraint, upper } => {
                s.push('+');
                s.push_str(&super::model::constraint_name(constraint, m));
                s.push(if upper { 'u' } else { 'l' });
            }
            Change::Remove { constraint } => {
                s.push('-');
                s.push_str(&super::model::constraint_name(constraint, m));
            }
            Change::Singular { constraint } => {
                s.push('~');
                s.push_str(&super::model::constraint_name(constraint, m));
            }
        }
    }
    s
}
