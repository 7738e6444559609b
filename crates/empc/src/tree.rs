//! Complexity reduction and the binary search tree (design time).
//!
//! - Only the first `k` outputs of `z` are kept ([`Outputs`]); their affine
//!   rows are shared between laws and identical laws are stored once, so
//!   regions with the same law are merged in storage (the tree never
//!   distinguishes them: a leaf is reached as soon as one law is left).
//! - The tree follows Tøndel, Johansen and Bemporad (2003): the hyperplanes
//!   are the regions' facets; each node takes the candidate hyperplane that
//!   minimises the larger number of regions left on either side (then their
//!   sum), regions straddling it are kept on a side only if they meet that
//!   side of the node's cell in a full-dimensional set (an LP).
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::error::EmpcError;
use crate::eval::{
    CompactNode, ForestTables, LEAF, NO_ROW, NO_ROW8, SliceTables, TreeIndex, WIDE_LEAF,
    WIDE_NO_ROW,
};
use crate::lp::{LpStatus, LpWorkspace, slack_start};
use crate::mpqp::MpqpSolution;
use kestrel_core::Scalar;
use kestrel_core::formats::MpqpProblem;
use std::collections::HashMap;

/// Which part of `z` the controller outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Outputs {
    /// All of `z`.
    #[default]
    All,
    /// The first `k` entries (the first move of a condensed MPC).
    First(usize),
}

/// Settings of the reduction and the tree construction.
#[derive(Clone, Debug)]
pub struct TreeSettings {
    /// The outputs to keep.
    pub outputs: Outputs,
    /// Two affine rows are the same law row if they differ by at most this
    /// (relative to their size).
    pub law_tol: f64,
    /// Candidate hyperplanes scored per node (the most frequent facets)
    /// when the node has too many regions for exact scoring.
    pub max_candidates: usize,
    /// A node scores every facet of its regions exactly (one LP per
    /// straddling region and side) when regions x facets is at most this.
    pub exact_budget: usize,
    /// Clipping: a leaf may hold one law for regions with other laws when,
    /// after the evaluation clamps the outputs to their bounds, it gives
    /// the same `z` on all of them (each differing output of a region is
    /// saturated there, and the leaf's law lies beyond that bound on the
    /// whole region; checked with one LP per output). Fewer leaves, the
    /// same answers.
    pub clipping: bool,
    /// How candidate hyperplanes are scored ([`TreeMethod::Auto`] by default).
    pub method: TreeMethod,
    /// Score candidates and split regions on several threads (needs the
    /// `parallel` feature; ignored otherwise). The tree is the same.
    pub parallel: bool,
    /// Stop with [`EmpcError::TooLarge`] once the tree has this many nodes
    /// ([`TreeMethod::Sampled`]), instead of running on for hours. The
    /// default, [`DEFAULT_MAX_NODES`], allows wide trees; the `u16` layout
    /// ([`build_controller`], [`TreeLayout::Narrow`]) stops at
    /// [`MAX_NODES`] whatever this says, the wide layout at
    /// [`WIDE_MAX_NODES`].
    pub max_nodes: usize,
    /// The table layout [`build_any`] returns ([`TreeLayout::Auto`]: `u16`
    /// when the tree fits, else `u32`). [`build_controller`] always builds
    /// the `u16` layout.
    pub layout: TreeLayout,
}

/// The index width of the tables ([`build_any`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TreeLayout {
    /// `u16` when the tree fits ([`MAX_NODES`] nodes, 65534 rows), else `u32`.
    #[default]
    Auto,
    /// Always `u16` ([`OwnedTables`]): [`EmpcError::TooLarge`] beyond
    /// [`MAX_NODES`] nodes.
    Narrow,
    /// Always `u32` ([`WideTables`]), even when the tree would fit `u16`
    /// (the same tree, node for node).
    Wide,
}

/// How the tree construction scores candidate hyperplanes at a node.
///
/// Both are exact: a region is dropped from a side only when an LP (or its
/// own facet, or its bounding box) proves it does not meet that side of
/// the cell in a full-dimensional set. They differ in how the split is
/// chosen, which changes the tree's size and the build time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TreeMethod {
    /// [`TreeMethod::Lp`] up to [`AUTO_SAMPLED_REGIONS`] regions,
    /// [`TreeMethod::Sampled`] above.
    #[default]
    Auto,
    /// The best few candidates (after a ranking without LPs) are scored
    /// exactly: per straddling region and side an LP within the cell. Small
    /// trees, but slow beyond a few hundred regions.
    Lp,
    /// Candidates are scored without LPs, from sample points kept inside
    /// every region and cell (interior points found by the LPs along the
    /// way); only the chosen split runs LPs, at most one per region whose
    /// points lie on one side. Builds trees over thousands of regions in
    /// seconds (thesis problem with `Ns = 2`: 1545 regions).
    Sampled,
}

/// Above this many regions [`TreeMethod::Auto`] uses [`TreeMethod::Sampled`].
pub const AUTO_SAMPLED_REGIONS: usize = 400;

/// Exact splits tried per node by [`TreeMethod::Sampled`].
const SAMPLED_ATTEMPTS: usize = 6;

/// Most nodes the `u16` child codes address (the [`LEAF`] bit marks leaves).
pub const MAX_NODES: usize = LEAF as usize - 1;

/// Most nodes the wide layout's `u32` child codes address ([`WIDE_LEAF`]).
pub const WIDE_MAX_NODES: usize = WIDE_LEAF as usize - 1;

/// The default [`TreeSettings::max_nodes`]: room for the wide trees of
/// the Ns = 2 class problems (about 10^5 to 10^6 nodes) while a build
/// that runs away still stops in reasonable time.
pub const DEFAULT_MAX_NODES: usize = 2_000_000;

impl Default for TreeSettings {
    fn default() -> Self {
        TreeSettings {
            outputs: Outputs::All,
            law_tol: 1e-9,
            max_candidates: 40,
            exact_budget: 60_000,
            clipping: true,
            method: TreeMethod::Auto,
            parallel: true,
            max_nodes: DEFAULT_MAX_NODES,
            layout: TreeLayout::Auto,
        }
    }
}

/// Size and shape of the tree and tables.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TreeStats {
    /// Regions of the solution.
    pub regions: usize,
    /// Distinct laws (on the kept outputs).
    pub distinct_laws: usize,
    /// Distinct affine rows shared by the laws and bounds.
    pub distinct_rows: usize,
    /// Largest number of nodes on a root-to-leaf path.
    pub depth: usize,
    /// Tree nodes.
    pub nodes: usize,
    /// Distinct hyperplanes used by the nodes (each stored as a pair of
    /// affine rows; only those that are no difference of law and bound
    /// rows add a row).
    pub hyperplanes: usize,
    /// Leaves where the construction could not separate different laws
    /// (numerically degenerate cases); 0 in an exact tree.
    pub ambiguous_leaves: usize,
    /// Seconds spent building.
    pub build_seconds: f64,
}

/// Owned tables of an explicit controller, in scalar `S`, with index type
/// `X`: `u16` (the default, [`LEAF`] child codes, [`NO_ROW`]) or `u32`
/// ([`WideTables`]).
#[derive(Clone, Debug, PartialEq)]
pub struct OwnedTables<S, X = u16> {
    /// Number of parameters `p`.
    pub n_params: usize,
    /// Number of outputs `k`.
    pub n_outputs: usize,
    /// The root child code.
    pub root: X,
    /// Tree nodes `[row a, row b, child if a <= b, child otherwise]`.
    pub nodes: Vec<[X; 4]>,
    /// Laws, `k` row indices each.
    pub laws: Vec<X>,
    /// Affine rows, `p + 1` entries each.
    pub rows: Vec<S>,
    /// Explored set rows, `p + 1` entries each.
    pub hull: Vec<S>,
    /// Parameter lower bounds.
    pub theta_lb: Vec<S>,
    /// Parameter upper bounds.
    pub theta_ub: Vec<S>,
    /// Per output: rows of the lower and upper bound (`X::NO_ROW`: none).
    pub bounds: Vec<[X; 2]>,
}

impl<S: Scalar, X: TreeIndex> OwnedTables<S, X> {
    /// Borrowed tables for [`crate::evaluate`].
    pub fn tables(&self) -> SliceTables<'_, S, X> {
        SliceTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: self.root,
            nodes: &self.nodes,
            laws: &self.laws,
            rows: &self.rows,
            hull: &self.hull,
            theta_lb: &self.theta_lb,
            theta_ub: &self.theta_ub,
            bounds: &self.bounds,
        }
    }
    /// The same tables in another scalar (rounded through `f64`).
    pub fn cast<T: Scalar>(&self) -> OwnedTables<T, X> {
        let c = |v: &Vec<S>| v.iter().map(|x| T::from_f64(x.to_f64())).collect();
        OwnedTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: self.root,
            nodes: self.nodes.clone(),
            laws: self.laws.clone(),
            rows: c(&self.rows),
            hull: c(&self.hull),
            theta_lb: c(&self.theta_lb),
            theta_ub: c(&self.theta_ub),
            bounds: self.bounds.clone(),
        }
    }
    /// Storage in bytes with `scalar_bytes` per number and the index
    /// type's size per index (2 for `u16`, 4 for `u32`).
    pub fn bytes(&self, scalar_bytes: usize) -> usize {
        let numbers = self.rows.len() + self.hull.len() + self.theta_lb.len() + self.theta_ub.len();
        numbers * scalar_bytes
            + core::mem::size_of::<X>()
                * (4 * self.nodes.len() + self.laws.len() + 2 * self.bounds.len())
    }
}

/// An explicit controller: the tables and what building them found.
#[derive(Clone, Debug)]
pub struct ExplicitController {
    /// The tables in `f64`.
    pub tables: OwnedTables<f64>,
    /// Law index of every region of the solution.
    pub region_law: Vec<u16>,
    /// Tree statistics.
    pub stats: TreeStats,
}

/// Owned tables of the wide layout (`u32` indices, [`WIDE_LEAF`] child
/// codes, [`WIDE_NO_ROW`]) in scalar `S`: the layout of trees beyond the
/// [`MAX_NODES`] the `u16` codes address, otherwise as [`OwnedTables`]
/// (the same struct with index type `u32`). Evaluated by
/// [`crate::evaluate`] through [`OwnedTables::tables`].
pub type WideTables<S> = OwnedTables<S, u32>;

/// A `u16` child code in the wide layout.
fn widen_code(c: u16) -> u32 {
    if c & LEAF != 0 {
        WIDE_LEAF | u32::from(c & !LEAF)
    } else {
        u32::from(c)
    }
}

/// A `u16` row index in the wide layout.
fn widen_row(r: u16) -> u32 {
    if r == NO_ROW {
        WIDE_NO_ROW
    } else {
        u32::from(r)
    }
}

/// A wide child code as `u16`, if it fits.
fn narrow_code(c: u32) -> Option<u16> {
    if c & WIDE_LEAF != 0 {
        let v = u16::try_from(c & !WIDE_LEAF).ok()?;
        (v & LEAF == 0).then_some(LEAF | v)
    } else {
        u16::try_from(c).ok().filter(|v| v & LEAF == 0)
    }
}

/// A wide row index as `u16`, if it fits.
fn narrow_row(r: u32) -> Option<u16> {
    if r == WIDE_NO_ROW {
        Some(NO_ROW)
    } else {
        u16::try_from(r).ok().filter(|&v| v != NO_ROW)
    }
}

impl<S: Scalar> WideTables<S> {
    /// The same tree in the `u16` layout, if every index fits (at most
    /// [`MAX_NODES`] nodes, 32767 laws, 65534 rows); `None` otherwise.
    pub fn narrow(&self) -> Option<OwnedTables<S>> {
        let nodes = self
            .nodes
            .iter()
            .map(|n| {
                Some([
                    narrow_row(n[0])?,
                    narrow_row(n[1])?,
                    narrow_code(n[2])?,
                    narrow_code(n[3])?,
                ])
            })
            .collect::<Option<Vec<_>>>()?;
        let laws = self
            .laws
            .iter()
            .map(|&r| narrow_row(r).filter(|&v| v != NO_ROW))
            .collect::<Option<Vec<_>>>()?;
        let bounds = self
            .bounds
            .iter()
            .map(|b| Some([narrow_row(b[0])?, narrow_row(b[1])?]))
            .collect::<Option<Vec<_>>>()?;
        if nodes.len() > MAX_NODES || self.rows.len() / (self.n_params + 1) >= NO_ROW as usize {
            return None;
        }
        Some(OwnedTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: narrow_code(self.root)?,
            nodes,
            laws,
            rows: self.rows.clone(),
            hull: self.hull.clone(),
            theta_lb: self.theta_lb.clone(),
            theta_ub: self.theta_ub.clone(),
            bounds,
        })
    }
}

impl<S: Scalar> OwnedTables<S> {
    /// The same tree in the wide layout (`u32` indices).
    pub fn widen(&self) -> WideTables<S> {
        WideTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: widen_code(self.root),
            nodes: self
                .nodes
                .iter()
                .map(|n| {
                    [
                        widen_row(n[0]),
                        widen_row(n[1]),
                        widen_code(n[2]),
                        widen_code(n[3]),
                    ]
                })
                .collect(),
            laws: self.laws.iter().map(|&r| u32::from(r)).collect(),
            rows: self.rows.clone(),
            hull: self.hull.clone(),
            theta_lb: self.theta_lb.clone(),
            theta_ub: self.theta_ub.clone(),
            bounds: self
                .bounds
                .iter()
                .map(|b| [widen_row(b[0]), widen_row(b[1])])
                .collect(),
        }
    }
}

/// The tables of [`build_any`]: the `u16` layout when the tree fits (or
/// was asked for), else the wide `u32` layout.
#[derive(Clone, Debug, PartialEq)]
pub enum AnyTables {
    /// `u16` indices, flash-ready ([`OwnedTables`]).
    Narrow(OwnedTables<f64>),
    /// `u32` indices ([`WideTables`]).
    Wide(WideTables<f64>),
}

impl AnyTables {
    /// Whether these are the wide (`u32`) tables.
    pub fn is_wide(&self) -> bool {
        matches!(self, AnyTables::Wide(_))
    }
    /// Storage in bytes with `scalar_bytes` per number (2 or 4 per index).
    pub fn bytes(&self, scalar_bytes: usize) -> usize {
        match self {
            AnyTables::Narrow(t) => t.bytes(scalar_bytes),
            AnyTables::Wide(t) => t.bytes(scalar_bytes),
        }
    }
    /// Tree nodes.
    pub fn n_nodes(&self) -> usize {
        match self {
            AnyTables::Narrow(t) => t.nodes.len(),
            AnyTables::Wide(t) => t.nodes.len(),
        }
    }
    /// Evaluates either layout in `f64`, the law index as `u32`
    /// (allocates a scratch vector: in a loop, borrow the tables and call
    /// [`crate::evaluate`]).
    pub fn evaluate_f64(
        &self,
        theta: &[f64],
        z: &mut [f64],
    ) -> Result<crate::Evaluation<u32>, kestrel_core::Error> {
        let mut scratch = vec![0.0; theta.len()];
        match self {
            AnyTables::Narrow(t) => {
                crate::evaluate_with(&t.tables(), theta, &mut scratch, z).map(|e| {
                    crate::Evaluation {
                        law: u32::from(e.law),
                        outside: e.outside,
                        steps: e.steps,
                    }
                })
            }
            AnyTables::Wide(t) => crate::evaluate_with(&t.tables(), theta, &mut scratch, z),
        }
    }
}

/// An explicit controller in either layout ([`build_any`]).
#[derive(Clone, Debug)]
pub struct AnyController {
    /// The tables in `f64`.
    pub tables: AnyTables,
    /// Law index of every region of the solution.
    pub region_law: Vec<u16>,
    /// Tree statistics.
    pub stats: TreeStats,
}

/// A polytope `a x <= b` (rows of `p`) with an interior point.
type Piece = (Vec<f64>, Vec<f64>, Vec<f64>);

/// A ball (centre, radius) inside a region intersected with the current
/// cell: a cheap certificate that the region meets a side of a hyperplane
/// (the LP is needed only when the ball cannot tell).
type Ball = (Vec<f64>, f64);

/// Candidates per node scored exactly (with LPs in the cell), after a cheap ranking.
const EXACT_CANDIDATES: usize = 12;

struct Builder<'a> {
    p: usize,
    scale: f64,
    /// Region facets (hyperplane id, side: true = region has a'x <= b).
    reg_facets: Vec<Vec<(usize, bool)>>,
    reg_a: Vec<Vec<f64>>,
    reg_b: Vec<Vec<f64>>,
    /// An interior point of every region (the LPs' feasible start).
    reg_center: Vec<Vec<f64>>,
    /// The radius of a ball around `reg_center` inside the region.
    reg_radius: Vec<f64>,
    /// The bounding box of every region (lower and upper corner).
    reg_box: Vec<(Vec<f64>, Vec<f64>)>,
    law: &'a [u16],
    /// Row indices of every law (`k` each), the affine rows and the output bounds.
    law_rows: Vec<Vec<usize>>,
    rows: Vec<f64>,
    bounds: Vec<[u16; 2]>,
    clipping: bool,
    /// Clamping tolerance of the clipping test.
    clip_tol: f64,
    serve_cache: HashMap<(u16, usize), bool>,
    hp: Vec<(Vec<f64>, f64)>,
    side_cache: HashMap<(usize, usize), i8>,
    lp: LpWorkspace,
    /// Nodes as built: `[hyperplane id, 0, child, child]`, child codes
    /// with [`WIDE_LEAF`] (narrowed to `u16` when the tree fits).
    nodes: Vec<[u32; 4]>,
    used_hp: HashMap<usize, u32>,
    ambiguous: usize,
    depth: usize,
    max_candidates: usize,
    exact_budget: usize,
    /// Sample points of every region (`p` numbers each), all inside the
    /// region: its centre, bounding-box vertices pulled towards it, and
    /// interior points of region and cell found by the split LPs
    /// ([`TreeMethod::Sampled`]).
    pool: Vec<Vec<f64>>,
    #[cfg_attr(not(feature = "parallel"), allow(dead_code))]
    parallel: bool,
    /// Number of distinct laws (for the law counters of the scoring).
    n_laws_total: usize,
    max_nodes: usize,
}

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

/// The LP of [`Builder::meets`] with a caller-owned workspace: whether the
/// polytope `ra x <= rb` meets the cell (and the extra half-space
/// `sign (a'x - b) <= 0`, if given) in a ball of radius above `1e-9 scale`,
/// and the ball's centre and radius when the LP finished.
#[allow(clippy::too_many_arguments)]
fn meets_lp(
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

/// A candidate split exactly: its key (larger side's laws, both sides'
/// laws, smaller side's laws), the hyperplane and every region's split.
type Tried = ((usize, usize, usize), usize, Vec<RegionSplit>);

/// The outcome of splitting one region of a node ([`TreeMethod::Sampled`]):
/// its points on each side, whether it goes left and right, and the new
/// interior points the LPs found.
struct RegionSplit {
    left: Option<Vec<u32>>,
    right: Option<Vec<u32>>,
    new_left: Option<Vec<f64>>,
    new_right: Option<Vec<f64>>,
}

impl Builder<'_> {
    /// The node code of candidate hyperplane `h`: its index among the
    /// hyperplanes the tree uses, numbered in order of first use.
    fn hyperplane_id(&mut self, h: usize) -> u32 {
        let next = self.used_hp.len() as u32;
        *self.used_hp.entry(h).or_insert(next)
    }

    /// The least and the greatest value of `a_h theta` over the bounding
    /// box of region `r`.
    fn box_range(&self, r: usize, h: usize) -> (f64, f64) {
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

    /// Sample points of every region for [`TreeMethod::Sampled`]: the
    /// centre and the vertices that maximise the coordinates, the inward
    /// facet normals and a few fixed pseudo-random directions (LPs).
    fn init_pool(&mut self) {
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

    /// The search tree with sampled scoring ([`TreeMethod::Sampled`]):
    /// `pts[i]` are the sample points of region `set[i]` inside the cell.
    ///
    /// The candidates are scored from the points; the best one is split
    /// exactly (LPs), the points the LPs find join the pools, and the
    /// candidates are scored again, until the best is one already split
    /// (its score then is exact) or [`SAMPLED_ATTEMPTS`] splits were tried.
    fn build_sampled(
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

    /// The bounding box of region `r` (2p LPs); the parameter box in a
    /// direction whose LP fails (the region lies inside it).
    fn bounding_box(&mut self, r: usize, lb: &[f64], ub: &[f64]) -> (Vec<f64>, Vec<f64>) {
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

    /// Whether law `l`, clamped to the output bounds, equals region `r`'s law on all of `r`.
    fn serves(&mut self, l: u16, r: usize) -> bool {
        let lr = self.law[r];
        if l == lr {
            return true;
        }
        if let Some(&v) = self.serve_cache.get(&(l, r)) {
            return v;
        }
        let (a, b, x0) = (
            std::mem::take(&mut self.reg_a[r]),
            std::mem::take(&mut self.reg_b[r]),
            std::mem::take(&mut self.reg_center[r]),
        );
        let ok = self.serves_on(l, lr, &a, &b, &x0);
        self.reg_a[r] = a;
        self.reg_b[r] = b;
        self.reg_center[r] = x0;
        self.serve_cache.insert((l, r), ok);
        ok
    }

    /// Whether law `l` clamped equals law `lr` on the polytope `a x <= b`
    /// (with the interior point `x0`).
    fn serves_on(&mut self, l: u16, lr: u16, a: &[f64], b: &[f64], x0: &[f64]) -> bool {
        let p = self.p;
        let w = p + 1;
        let mut ok = true;
        for o in 0..self.bounds.len() {
            let (rl, rr) = (self.law_rows[l as usize][o], self.law_rows[lr as usize][o]);
            if rl == rr {
                continue;
            }
            // Region r saturates output o at a bound; law l must lie beyond it on r.
            let sign = if rr == self.bounds[o][1] as usize {
                1.0 // upper: max over r of (rr - rl) <= tol
            } else if rr == self.bounds[o][0] as usize {
                -1.0 // lower: max over r of (rl - rr) <= tol
            } else {
                ok = false;
                break;
            };
            let c: Vec<f64> = (0..p)
                .map(|j| sign * (self.rows[rr * w + j] - self.rows[rl * w + j]))
                .collect();
            let c0 = sign * (self.rows[rr * w + p] - self.rows[rl * w + p]);
            let (st, v) = self.lp.maximize_from(&c, a, b, x0);
            if st != LpStatus::Optimal || v + c0 > self.clip_tol {
                ok = false;
                break;
            }
        }
        ok
    }

    /// Region `r` intersected with the cell (rows, offsets) and an interior
    /// point of it, if it is full-dimensional.
    fn in_cell(&mut self, r: usize, cell: &[(Vec<f64>, f64)]) -> Option<Piece> {
        let p = self.p;
        let mut a = self.reg_a[r].clone();
        let mut b = self.reg_b[r].clone();
        for (ca, cb) in cell {
            a.extend_from_slice(ca);
            b.push(*cb);
        }
        let rows = b.len();
        let mut la = Vec::with_capacity((rows + 1) * (p + 1));
        for i in 0..rows {
            la.extend_from_slice(&a[i * p..(i + 1) * p]);
            la.push(1.0);
        }
        la.extend(std::iter::repeat_n(0.0, p));
        la.push(1.0);
        let mut lb = b.clone();
        lb.push(self.scale);
        let mut c = vec![0.0; p + 1];
        c[p] = 1.0;
        let mut x0: Vec<f64> = self.reg_center[r].iter().copied().chain([0.0]).collect();
        slack_start(&la, &lb, &mut x0, p);
        let (st, rad) = self.lp.maximize_from(&c, &la, &lb, &x0);
        (st == LpStatus::Optimal && rad > 1e-9 * self.scale)
            .then(|| (a, b, self.lp.x[..p].to_vec()))
    }

    /// A law that serves every region of the set within the cell (clipping), if any.
    fn serving_law(&mut self, set: &[usize], cell: &[(Vec<f64>, f64)]) -> Option<u16> {
        let mut laws: Vec<(usize, u16)> = Vec::new();
        for &r in set {
            let l = self.law[r];
            match laws.iter_mut().find(|x| x.1 == l) {
                Some(x) => x.0 += 1,
                None => laws.push((1, l)),
            }
        }
        laws.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut pieces: Vec<Option<Option<Piece>>> = vec![None; set.len()];
        'law: for (_, l) in laws {
            // Without an LP: every differing output of every region must
            // be saturated in that region's law (else `serves` fails too).
            let saturated = |o: usize, lr: u16| {
                let rr = self.law_rows[lr as usize][o];
                rr == self.bounds[o][0] as usize || rr == self.bounds[o][1] as usize
            };
            for &r in set {
                let lr = self.law[r];
                if lr != l
                    && (0..self.bounds.len()).any(|o| {
                        self.law_rows[l as usize][o] != self.law_rows[lr as usize][o]
                            && !saturated(o, lr)
                    })
                {
                    continue 'law;
                }
            }
            for (i, &r) in set.iter().enumerate() {
                if self.serves(l, r) {
                    continue;
                }
                if cell.is_empty() {
                    continue 'law;
                }
                if pieces[i].is_none() {
                    pieces[i] = Some(self.in_cell(r, cell));
                }
                let Some(Some((a, b, x0))) = &pieces[i] else {
                    continue 'law;
                };
                let (a, b, x0) = (a.clone(), b.clone(), x0.clone());
                if !self.serves_on(l, self.law[r], &a, &b, &x0) {
                    continue 'law;
                }
            }
            return Some(l);
        }
        None
    }

    /// The split key of hyperplane `h` (distinct laws on the larger side,
    /// then on both), `None` if it makes no progress. With `exact`, a
    /// straddling region counts on a side only if it meets that side of the
    /// cell in a full-dimensional set.
    fn score(
        &mut self,
        h: usize,
        set: &[usize],
        wits: &[Ball],
        cell: &mut Vec<(Vec<f64>, f64)>,
        exact: bool,
        n_laws: usize,
    ) -> Option<(usize, usize)> {
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
            return None; // no progress on one side
        }
        Some((ll.max(lr), ll + lr))
    }

    fn build(
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
        let mut scored: Vec<((usize, usize), usize)> = cands
            .iter()
            .filter_map(|&(h, _)| {
                self.score(h, &set, &wits, cell, false, n_laws)
                    .map(|k| (k, h))
            })
            .collect();
        scored.sort_unstable();
        let mut best: Option<((usize, usize), usize)> = None;
        if exact {
            for round in 0..2 {
                let range = if round == 0 {
                    0..scored.len().min(EXACT_CANDIDATES)
                } else if best.is_none() {
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
        let best = best.map(|(k, h)| (h, k.0, k.1));
        let Some((h, _, _)) = best else {
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

/// Dedupes `row` into `rows` (width p + 1) and returns its index.
fn intern(
    rows: &mut Vec<f64>,
    index: &mut HashMap<Vec<i64>, usize>,
    row: &[f64],
    tol: f64,
) -> usize {
    let scale = row.iter().fold(1.0_f64, |s, v| s.max(v.abs()));
    let q = |v: f64| (v / (scale * tol * 10.0)).round() as i64;
    let key: Vec<i64> = row.iter().map(|&v| q(v)).collect();
    if let Some(&i) = index.get(&key) {
        return i;
    }
    let width = row.len();
    let i = rows.len() / width;
    rows.extend_from_slice(row);
    index.insert(key, i);
    i
}

/// Builds the explicit controller: law sharing, the search tree and the tables.
///
/// `problem` supplies the output bounds (rows of `G` that bound a single
/// kept output) used to clamp outside the explored set.
pub fn build_controller(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
) -> Result<ExplicitController, EmpcError> {
    let k = kept_outputs(problem, solution, settings)?;
    let outs: Vec<usize> = (0..k).collect();
    build_for(problem, solution, settings, &outs)
}

/// Builds the explicit controller in the layout [`TreeSettings::layout`]
/// asks for: as [`build_controller`] (the same tree, node for node), with
/// the wide `u32` tables ([`WideTables`]) when the tree exceeds the
/// [`MAX_NODES`] of the `u16` layout ([`TreeLayout::Auto`]) or always
/// ([`TreeLayout::Wide`]), up to [`TreeSettings::max_nodes`].
///
/// ```
/// use kestrel_empc::{solve, Settings};
/// use kestrel_empc::tree::{build_any, AnyTables, TreeLayout, TreeSettings};
/// # use kestrel_core::formats::MpqpProblem;
/// # let problem = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
/// #   "H": [[1, 0], [0, 1]], "F": [[1, 0], [0, 1]],
/// #   "G": [[1, 0], [0, 1], [-1, 0], [0, -1]], "W": [1, 1, 1, 1],
/// #   "E": [[0, 0], [0, 0], [0, 0], [0, 0]],
/// #   "theta_lb": [-3, -3], "theta_ub": [3, 3]}"#).unwrap();
/// let solution = solve(&problem, &Settings::default()).unwrap();
/// let settings = TreeSettings { layout: TreeLayout::Wide, ..TreeSettings::default() };
/// let c = build_any(&problem, &solution, &settings).unwrap();
/// let AnyTables::Wide(t) = &c.tables else { unreachable!() };
/// let mut z = [0.0; 2];
/// kestrel_empc::evaluate(&t.tables(), &[0.5, -2.0], &mut z).unwrap();
/// assert_eq!(z, [-0.5, 1.0]);
/// ```
pub fn build_any(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
) -> Result<AnyController, EmpcError> {
    let k = kept_outputs(problem, solution, settings)?;
    let outs: Vec<usize> = (0..k).collect();
    let cap = match settings.layout {
        TreeLayout::Narrow => settings.max_nodes.min(MAX_NODES),
        TreeLayout::Auto | TreeLayout::Wide => settings.max_nodes.min(WIDE_MAX_NODES),
    };
    let w = build_wide_for(problem, solution, settings, &outs, cap)?;
    let tables = match settings.layout {
        TreeLayout::Wide => AnyTables::Wide(w.tables),
        TreeLayout::Auto => match w.tables.narrow() {
            Some(t) => AnyTables::Narrow(t),
            None => AnyTables::Wide(w.tables),
        },
        TreeLayout::Narrow => {
            AnyTables::Narrow(w.tables.narrow().ok_or_else(|| narrow_error(&w.tables))?)
        }
    };
    Ok(AnyController {
        tables,
        region_law: w.region_law,
        stats: w.stats,
    })
}

/// The error for a tree that does not fit the `u16` layout.
fn narrow_error(t: &WideTables<f64>) -> EmpcError {
    EmpcError::TooLarge(format!(
        "{} nodes, {} affine rows: beyond the u16 layout ({MAX_NODES} nodes, 65534 rows); build_any with TreeLayout::Auto or Wide gives u32 tables",
        t.nodes.len(),
        t.rows.len() / (t.n_params + 1)
    ))
}

/// What [`build_wide_for`] found.
struct WideBuild {
    tables: WideTables<f64>,
    region_law: Vec<u16>,
    stats: TreeStats,
}

/// The number of kept outputs, after checking that problem and solution match.
fn kept_outputs(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
) -> Result<usize, EmpcError> {
    let p = solution.p;
    let n = solution.n;
    let k = match settings.outputs {
        Outputs::All => n,
        Outputs::First(k) if k >= 1 && k <= n => k,
        Outputs::First(k) => {
            return Err(EmpcError::InvalidArgument(format!(
                "Outputs::First({k}) needs 1 <= k <= n = {n}"
            )));
        }
    };
    if problem.n() != n || problem.p() != p {
        return Err(EmpcError::InvalidArgument(
            "the problem does not match the solution".into(),
        ));
    }
    Ok(k)
}

/// [`build_controller`] for the outputs `outs` of `z` (in that order).
fn build_for(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
    outs: &[usize],
) -> Result<ExplicitController, EmpcError> {
    let w = build_wide_for(
        problem,
        solution,
        settings,
        outs,
        settings.max_nodes.min(MAX_NODES),
    )?;
    let tables = w.tables.narrow().ok_or_else(|| narrow_error(&w.tables))?;
    Ok(ExplicitController {
        tables,
        region_law: w.region_law,
        stats: w.stats,
    })
}

/// The tree and tables in the wide layout, at most `max_nodes` nodes.
fn build_wide_for(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
    outs: &[usize],
    max_nodes: usize,
) -> Result<WideBuild, EmpcError> {
    let start = std::time::Instant::now();
    let p = solution.p;
    let n = solution.n;
    let k = outs.len();
    let w = p + 1;
    let mut rows: Vec<f64> = Vec::new();
    let mut row_index = HashMap::new();
    let mut laws: Vec<u16> = Vec::new();
    let mut law_index: HashMap<Vec<usize>, usize> = HashMap::new();
    let mut region_law = Vec::with_capacity(solution.regions.len());
    for r in &solution.regions {
        let mut ids = Vec::with_capacity(k);
        for &o in outs {
            let row: Vec<f64> = (0..p).map(|j| r.fz[(o, j)]).chain([r.gz[o]]).collect();
            ids.push(intern(&mut rows, &mut row_index, &row, settings.law_tol));
        }
        let nl = law_index.len();
        let id = *law_index.entry(ids.clone()).or_insert_with(|| {
            laws.extend(ids.iter().map(|&i| i as u16));
            nl
        });
        region_law.push(id as u16);
    }
    let distinct_laws = law_index.len();
    // Output bounds from single-variable rows of G.
    let mut bounds = vec![[NO_ROW, NO_ROW]; k];
    for i in 0..problem.m() {
        let nz: Vec<usize> = (0..n).filter(|&j| problem.g[(i, j)] != 0.0).collect();
        if nz.len() == 1
            && let Some(o) = outs.iter().position(|&x| x == nz[0])
        {
            let gc = problem.g[(i, nz[0])];
            let row: Vec<f64> = (0..p)
                .map(|j| problem.e[(i, j)] / gc)
                .chain([problem.w[i] / gc])
                .collect();
            let slot = usize::from(gc > 0.0);
            if bounds[o][slot] == NO_ROW {
                bounds[o][slot] = intern(&mut rows, &mut row_index, &row, settings.law_tol) as u16;
            }
        }
    }
    let nrows = rows.len() / w;
    // Size of the outputs over the parameter box (for the clipping tolerance).
    let zscale = 1.0
        + (0..nrows)
            .map(|i| {
                (0..p)
                    .map(|j| {
                        rows[i * w + j].abs()
                            * solution.theta_lb[j].abs().max(solution.theta_ub[j].abs())
                    })
                    .sum::<f64>()
                    + rows[i * w + p].abs()
            })
            .fold(0.0, f64::max);
    if nrows >= NO_ROW as usize || distinct_laws >= LEAF as usize {
        return Err(EmpcError::TooLarge(format!(
            "{nrows} affine rows, {distinct_laws} laws (at most 32767 laws and 65534 rows)"
        )));
    }
    // Hyperplane pool from the facets, canonically oriented.
    let scale = 1.0
        + solution
            .theta_lb
            .iter()
            .chain(solution.theta_ub.iter())
            .fold(0.0_f64, |s, v| s.max(v.abs()));
    let mut hp: Vec<(Vec<f64>, f64)> = Vec::new();
    let mut hp_index: HashMap<Vec<i64>, usize> = HashMap::new();
    let mut reg_facets = Vec::new();
    let mut reg_a = Vec::new();
    let mut reg_b = Vec::new();
    let mut reg_center = Vec::new();
    let mut reg_radius = Vec::new();
    for r in &solution.regions {
        reg_center.push(r.center.iter().copied().collect::<Vec<f64>>());
        reg_radius.push(r.radius);
        let mut fs = Vec::new();
        let mut ra = Vec::new();
        for i in 0..r.a.nrows() {
            let a: Vec<f64> = r.a.row(i).iter().copied().collect();
            ra.extend_from_slice(&a);
            let bi = r.b[i];
            let lead = a.iter().copied().find(|v| v.abs() > 1e-9).unwrap_or(1.0);
            let sgn = if lead < 0.0 { -1.0 } else { 1.0 };
            let ca: Vec<f64> = a.iter().map(|v| v * sgn).collect();
            let cb = bi * sgn;
            let key: Vec<i64> = ca
                .iter()
                .map(|v| (v * 1e8).round() as i64)
                .chain([(cb / scale * 1e8).round() as i64])
                .collect();
            let id = *hp_index.entry(key).or_insert_with(|| {
                hp.push((ca, cb));
                hp.len() - 1
            });
            fs.push((id, sgn > 0.0));
        }
        reg_facets.push(fs);
        reg_a.push(ra);
        reg_b.push(r.b.iter().copied().collect::<Vec<f64>>());
    }
    let mut builder = Builder {
        p,
        scale,
        reg_facets,
        reg_a,
        reg_b,
        reg_center,
        reg_radius,
        reg_box: Vec::new(),
        law: &region_law,
        law_rows: laws
            .chunks(k)
            .map(|c| c.iter().map(|&i| i as usize).collect())
            .collect(),
        rows: rows.clone(),
        bounds: bounds.clone(),
        clipping: settings.clipping,
        clip_tol: 1e-10 * zscale,
        serve_cache: HashMap::new(),
        hp,
        side_cache: HashMap::new(),
        lp: LpWorkspace::default(),
        nodes: Vec::new(),
        used_hp: HashMap::new(),
        ambiguous: 0,
        depth: 0,
        max_candidates: settings.max_candidates.max(1),
        exact_budget: settings.exact_budget,
        pool: Vec::new(),
        parallel: settings.parallel,
        n_laws_total: distinct_laws,
        max_nodes,
    };
    let (lb, ub) = (
        solution.theta_lb.as_slice().to_vec(),
        solution.theta_ub.as_slice().to_vec(),
    );
    builder.reg_box = (0..solution.regions.len())
        .map(|r| builder.bounding_box(r, &lb, &ub))
        .collect();
    let all: Vec<usize> = (0..solution.regions.len()).collect();
    let mut cell = Vec::new();
    let sampled = match settings.method {
        TreeMethod::Auto => all.len() > AUTO_SAMPLED_REGIONS,
        TreeMethod::Lp => false,
        TreeMethod::Sampled => true,
    };
    let root = if all.is_empty() {
        WIDE_LEAF
    } else if sampled {
        builder.init_pool();
        let pts = builder
            .pool
            .iter()
            .map(|v| (0..(v.len() / p) as u32).collect())
            .collect();
        let mut mark = vec![0u32; builder.n_laws_total];
        builder.build_sampled(all, pts, &mut cell, 0, &mut mark, &mut 0)?
    } else {
        let wits = all
            .iter()
            .map(|&r| (builder.reg_center[r].clone(), builder.reg_radius[r]))
            .collect();
        builder.build(all, wits, &mut cell, 0)
    };
    if builder.nodes.len() > WIDE_MAX_NODES {
        return Err(EmpcError::TooLarge(format!(
            "{} nodes (the wide layout addresses {WIDE_MAX_NODES})",
            builder.nodes.len(),
        )));
    }
    // Each hyperplane a'theta <= b as two affine rows: r1(theta) <= r2(theta)
    // with r1 - r2 a positive multiple of (a, -b). Facets where an output's
    // law meets its bound are differences of stored rows; others get a row.
    let mut pair_index: HashMap<Vec<i64>, (usize, usize, f64)> = HashMap::new();
    let nrows0 = rows.len() / w;
    for r1 in 0..nrows0 {
        for r2 in 0..nrows0 {
            if r1 == r2 {
                continue;
            }
            let d: Vec<f64> = (0..w)
                .map(|j| rows[r1 * w + j] - rows[r2 * w + j])
                .collect();
            let nrm = d[..p].iter().map(|v| v * v).sum::<f64>().sqrt();
            if nrm <= 1e-9 {
                continue;
            }
            let lead = d[..p]
                .iter()
                .copied()
                .find(|v| v.abs() > 1e-9 * nrm)
                .unwrap_or(1.0);
            if lead < 0.0 {
                continue; // the swapped pair has the canonical sign
            }
            let key: Vec<i64> = d
                .iter()
                .enumerate()
                .map(|(j, v)| {
                    let s = if j == p { scale } else { 1.0 };
                    (v / nrm / s * 1e7).round() as i64
                })
                .collect();
            pair_index.entry(key).or_insert((r1, r2, nrm));
        }
    }
    let mut hp_rows: Vec<[u32; 2]> = vec![[0, 0]; builder.used_hp.len()];
    let mut used: Vec<(usize, u32)> = builder.used_hp.iter().map(|(&h, &i)| (h, i)).collect();
    used.sort_by_key(|x| x.1);
    for (h, i) in used {
        let (a, b) = builder.hp[h].clone();
        // The row (a, -b): gains a, constant -b.
        let key: Vec<i64> = a
            .iter()
            .map(|v| (v * 1e7).round() as i64)
            .chain([(-b / scale * 1e7).round() as i64])
            .collect();
        let exact = pair_index.get(&key).and_then(|&(r1, r2, nrm)| {
            let ok = (0..w).all(|j| {
                let d = (rows[r1 * w + j] - rows[r2 * w + j]) / nrm;
                let want = if j == p { -b } else { a[j] };
                (d - want).abs() <= 1e-11 * if j == p { scale } else { 1.0 }
            });
            ok.then_some([r1 as u32, r2 as u32])
        });
        hp_rows[i as usize] = match exact {
            Some(pr) => pr,
            None => {
                let r = rows.len() / w;
                rows.extend_from_slice(&a);
                rows.push(-b);
                [r as u32, WIDE_NO_ROW]
            }
        };
    }
    let mut nodes = builder.nodes.clone();
    for nd in &mut nodes {
        let [r1, r2] = hp_rows[nd[0] as usize];
        nd[0] = r1;
        nd[1] = r2;
    }
    if rows.len() / w >= WIDE_NO_ROW as usize {
        return Err(EmpcError::TooLarge(format!(
            "{} affine rows",
            rows.len() / w
        )));
    }
    let mut hull = Vec::new();
    for i in 0..solution.hull_a.nrows() {
        hull.extend(solution.hull_a.row(i).iter());
        hull.push(solution.hull_b[i]);
    }
    // The depth counted in nodes on the longest path.
    let depth = if builder.nodes.is_empty() {
        0
    } else {
        builder.depth
    };
    let tables = WideTables {
        n_params: p,
        n_outputs: k,
        root,
        nodes,
        laws: laws.iter().map(|&r| u32::from(r)).collect(),
        rows,
        hull,
        theta_lb: solution.theta_lb.iter().copied().collect(),
        theta_ub: solution.theta_ub.iter().copied().collect(),
        bounds: bounds.iter().map(|b| b.map(widen_row)).collect(),
    };
    let stats = TreeStats {
        regions: solution.regions.len(),
        distinct_laws,
        distinct_rows: tables.rows.len() / w,
        depth,
        nodes: tables.nodes.len(),
        hyperplanes: builder.used_hp.len(),
        ambiguous_leaves: builder.ambiguous,
        build_seconds: start.elapsed().as_secs_f64(),
    };
    Ok(WideBuild {
        tables,
        region_law,
        stats,
    })
}

/// Owned compact tables (one tree per output, [`ForestTables`]), in scalar `S`.
#[derive(Clone, Debug, PartialEq)]
pub struct CompactTables<S> {
    /// Number of parameters `p`.
    pub n_params: usize,
    /// Number of outputs `k`.
    pub n_outputs: usize,
    /// The root child code of every output's tree.
    pub roots: Vec<u16>,
    /// Tree nodes of all trees; a leaf's payload is an affine row.
    pub nodes: Vec<CompactNode>,
    /// Affine rows, `p + 1` entries each.
    pub rows: Vec<S>,
    /// Explored set rows, `p + 1` entries each.
    pub hull: Vec<S>,
    /// Parameter lower bounds.
    pub theta_lb: Vec<S>,
    /// Parameter upper bounds.
    pub theta_ub: Vec<S>,
    /// Per output: rows of the lower and upper bound.
    pub bounds: Vec<[u16; 2]>,
}

impl<S: Scalar> CompactTables<S> {
    /// Borrowed tables for [`crate::evaluate`].
    pub fn tables(&self) -> ForestTables<'_, S> {
        ForestTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            roots: &self.roots,
            nodes: &self.nodes,
            rows: &self.rows,
            hull: &self.hull,
            theta_lb: &self.theta_lb,
            theta_ub: &self.theta_ub,
            bounds: &self.bounds,
        }
    }
    /// The same tables in another scalar (rounded through `f64`).
    pub fn cast<T: Scalar>(&self) -> CompactTables<T> {
        let c = |v: &Vec<S>| v.iter().map(|x| T::from_f64(x.to_f64())).collect();
        CompactTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            roots: self.roots.clone(),
            nodes: self.nodes.clone(),
            rows: c(&self.rows),
            hull: c(&self.hull),
            theta_lb: c(&self.theta_lb),
            theta_ub: c(&self.theta_ub),
            bounds: self.bounds.clone(),
        }
    }
    /// Storage in bytes with `scalar_bytes` per number, 6 per node and 2
    /// per other index (counted as [`OwnedTables::bytes`], with the roots
    /// instead of the law table).
    pub fn bytes(&self, scalar_bytes: usize) -> usize {
        let numbers = self.rows.len() + self.hull.len() + self.theta_lb.len() + self.theta_ub.len();
        numbers * scalar_bytes
            + 6 * self.nodes.len()
            + 2 * (self.roots.len() + 2 * self.bounds.len())
    }
}

/// An explicit controller in the compact layout: one tree per output.
#[derive(Clone, Debug)]
pub struct CompactController {
    /// The tables in `f64`.
    pub tables: CompactTables<f64>,
    /// Statistics of every output's tree (`distinct_laws`: that output's
    /// distinct laws; `distinct_rows`: rows of that tree alone).
    pub per_output: Vec<TreeStats>,
    /// Largest depth over the outputs' trees.
    pub depth: usize,
    /// Leaves where a construction could not separate different laws; 0 in an exact tree.
    pub ambiguous_leaves: usize,
    /// Distinct hyperplanes (row pairs) of all nodes.
    pub hyperplanes: usize,
    /// Seconds spent building all trees.
    pub build_seconds: f64,
}

/// Builds the explicit controller in the compact layout: one search tree
/// per kept output over that output's own distinct laws (regions that
/// differ only in other outputs are never told apart), the trees sharing
/// one deduplicated table of affine rows, leaves pointing straight at the
/// output's law row. Evaluate with [`crate::evaluate`] on
/// [`CompactTables::tables`]; the answers are those of [`build_controller`].
pub fn build_compact(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
) -> Result<CompactController, EmpcError> {
    let start = std::time::Instant::now();
    let k = kept_outputs(problem, solution, settings)?;
    let p = solution.p;
    let w = p + 1;
    let mut rows: Vec<f64> = Vec::new();
    let mut row_index = HashMap::new();
    let mut nodes: Vec<[u16; 4]> = Vec::new();
    let mut roots = Vec::with_capacity(k);
    let mut bounds = Vec::with_capacity(k);
    let mut per_output = Vec::with_capacity(k);
    let mut hull = Vec::new();
    let too_large = |what: String| EmpcError::TooLarge(what);
    for o in 0..k {
        let ctl = build_for(problem, solution, settings, &[o])?;
        let t = &ctl.tables;
        hull.clone_from(&t.hull);
        let map: Vec<u16> = t
            .rows
            .chunks(w)
            .map(|r| intern(&mut rows, &mut row_index, r, settings.law_tol) as u16)
            .collect();
        let base = nodes.len();
        let child = |c: u16| -> Option<u16> {
            if c & LEAF != 0 {
                let row = *map.get(*t.laws.get((c & !LEAF) as usize)? as usize)?;
                Some(LEAF | row)
            } else {
                u16::try_from(base + c as usize).ok()
            }
        };
        let bad = || too_large(format!("output {o}: tables exceed the u16 indices"));
        for nd in &t.nodes {
            let r = |i: u16| {
                if i == NO_ROW {
                    Some(NO_ROW)
                } else {
                    map.get(i as usize).copied()
                }
            };
            nodes.push([
                r(nd[0]).ok_or_else(bad)?,
                r(nd[1]).ok_or_else(bad)?,
                child(nd[2]).ok_or_else(bad)?,
                child(nd[3]).ok_or_else(bad)?,
            ]);
        }
        roots.push(child(t.root).ok_or_else(bad)?);
        let b = t.bounds[0].map(|i| if i == NO_ROW { NO_ROW } else { map[i as usize] });
        bounds.push(b);
        per_output.push(ctl.stats);
    }
    let scale = 1.0
        + solution
            .theta_lb
            .iter()
            .chain(solution.theta_ub.iter())
            .fold(0.0_f64, |s, v| s.max(v.abs()));
    let rows = share_hyperplane_rows(rows, p, scale, &mut nodes, &mut roots, &mut bounds);
    if rows.len() / w >= usize::from(NO_ROW8) || nodes.len() >= 0x7FFF {
        return Err(too_large(format!(
            "{} rows, {} nodes (the compact layout holds at most 254 rows and 32766 nodes; use the default layout)",
            rows.len() / w,
            nodes.len()
        )));
    }
    let r8 = |i: u16| if i == NO_ROW { NO_ROW8 } else { i as u8 };
    let nodes: Vec<CompactNode> = nodes
        .iter()
        .map(|n| CompactNode {
            rows: [r8(n[0]), r8(n[1])],
            children: [n[2], n[3]],
        })
        .collect();
    let tables = CompactTables {
        n_params: p,
        n_outputs: k,
        roots,
        nodes,
        rows,
        hull,
        theta_lb: solution.theta_lb.iter().copied().collect(),
        theta_ub: solution.theta_ub.iter().copied().collect(),
        bounds,
    };
    let hyperplanes = {
        let mut h: Vec<[u8; 2]> = tables.nodes.iter().map(|n| n.rows).collect();
        h.sort_unstable();
        h.dedup();
        h.len()
    };
    Ok(CompactController {
        tables,
        depth: per_output.iter().map(|s| s.depth).max().unwrap_or(0),
        ambiguous_leaves: per_output.iter().map(|s| s.ambiguous_leaves).sum(),
        per_output,
        hyperplanes,
        build_seconds: start.elapsed().as_secs_f64(),
    })
}

/// Stores the compact trees' hyperplanes without rows of their own where
/// possible: a node `[h, NO_ROW]` whose hyperplane `h(theta) <= 0` is a
/// positive multiple of the difference of two law or bound rows (of any
/// output's tree) becomes `[r1, r2]`, hyperplane rows equal up to a
/// positive factor are shared, and rows no longer used are dropped (the
/// indices in nodes, roots and bounds are renumbered).
fn share_hyperplane_rows(
    rows: Vec<f64>,
    p: usize,
    scale: f64,
    nodes: &mut [[u16; 4]],
    roots: &mut [u16],
    bounds: &mut [[u16; 2]],
) -> Vec<f64> {
    let w = p + 1;
    let nrows = rows.len() / w;
    let row = |i: usize| &rows[i * w..(i + 1) * w];
    // Rows holding values: leaves and bounds.
    let mut value = vec![false; nrows];
    let mark = |c: u16, value: &mut Vec<bool>| {
        if c & LEAF != 0
            && let Some(v) = value.get_mut((c & !LEAF) as usize)
        {
            *v = true;
        }
    };
    for nd in nodes.iter() {
        mark(nd[2], &mut value);
        mark(nd[3], &mut value);
        if nd[1] != NO_ROW {
            for &i in &nd[..2] {
                if let Some(v) = value.get_mut(i as usize) {
                    *v = true;
                }
            }
        }
    }
    for &r in roots.iter() {
        mark(r, &mut value);
    }
    for b in bounds.iter() {
        for &i in b {
            if let Some(v) = value.get_mut(i as usize) {
                *v = true;
            }
        }
    }
    // The direction of an affine row (unit gains, constant relative to scale).
    let key = |d: &[f64]| -> Option<Vec<i64>> {
        let nrm = d[..p].iter().map(|v| v * v).sum::<f64>().sqrt();
        (nrm > 1e-9).then(|| {
            d.iter()
                .enumerate()
                .map(|(j, v)| {
                    let s = if j == p { scale } else { 1.0 };
                    (v / nrm / s * 1e7).round() as i64
                })
                .collect()
        })
    };
    let same_direction = |x: &[f64], y: &[f64]| -> bool {
        let nx = x[..p].iter().map(|v| v * v).sum::<f64>().sqrt();
        let ny = y[..p].iter().map(|v| v * v).sum::<f64>().sqrt();
        (0..w).all(|j| {
            let s = if j == p { scale } else { 1.0 };
            (x[j] / nx - y[j] / ny).abs() <= 1e-11 * s
        })
    };
    let mut pairs: HashMap<Vec<i64>, Vec<(usize, usize)>> = HashMap::new();
    let vals: Vec<usize> = (0..nrows).filter(|&i| value[i]).collect();
    for &r1 in &vals {
        for &r2 in &vals {
            if r1 == r2 {
                continue;
            }
            let d: Vec<f64> = (0..w).map(|j| row(r1)[j] - row(r2)[j]).collect();
            if let Some(k) = key(&d) {
                pairs.entry(k).or_default().push((r1, r2));
            }
        }
    }
    let mut shared_hp: HashMap<Vec<i64>, Vec<usize>> = HashMap::new();
    for nd in nodes.iter_mut() {
        if nd[1] != NO_ROW || value.get(nd[0] as usize).is_none_or(|&v| v) {
            continue;
        }
        let h = row(nd[0] as usize);
        let Some(k) = key(h) else { continue };
        let found = pairs.get(&k).and_then(|c| {
            c.iter().copied().find(|&(r1, r2)| {
                let d: Vec<f64> = (0..w).map(|j| row(r1)[j] - row(r2)[j]).collect();
                same_direction(&d, h)
            })
        });
        if let Some((r1, r2)) = found {
            *nd = [r1 as u16, r2 as u16, nd[2], nd[3]];
            continue;
        }
        let list = shared_hp.entry(k).or_default();
        match list.iter().find(|&&o| same_direction(row(o), h)) {
            Some(&o) => nd[0] = o as u16,
            None => list.push(nd[0] as usize),
        }
    }
    // Drop unused rows and renumber.
    let mut used = value;
    for nd in nodes.iter() {
        for &i in &nd[..2] {
            if let Some(u) = used.get_mut(i as usize) {
                *u = true;
            }
        }
    }
    let mut new_index = vec![NO_ROW; nrows];
    let mut out = Vec::with_capacity(rows.len());
    for i in 0..nrows {
        if used[i] {
            new_index[i] = (out.len() / w) as u16;
            out.extend_from_slice(row(i));
        }
    }
    let re = |i: u16| {
        if i == NO_ROW {
            NO_ROW
        } else {
            new_index.get(i as usize).copied().unwrap_or(NO_ROW)
        }
    };
    let re_child = |c: u16| {
        if c & LEAF != 0 {
            LEAF | re(c & !LEAF)
        } else {
            c
        }
    };
    for nd in nodes.iter_mut() {
        *nd = [re(nd[0]), re(nd[1]), re_child(nd[2]), re_child(nd[3])];
    }
    for r in roots.iter_mut() {
        *r = re_child(*r);
    }
    for b in bounds.iter_mut() {
        *b = [re(b[0]), re(b[1])];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mpqp::{Settings, solve};
    use crate::testing;

    /// Mismatches (beyond 1e-9 relative) of the tree against the region
    /// lookup at `n` random parameters of the box; panics on an uncovered one.
    fn mismatches(sol: &MpqpSolution, t: &OwnedTables<f64>, n: usize, seed: u64) -> usize {
        let mut rng = crate::mpqp::Rng::new(seed);
        let (p, k) = (t.n_params, t.n_outputs);
        let (mut z, mut scratch) = (vec![0.0; k], vec![0.0; p]);
        let mut bad = 0;
        for _ in 0..n {
            let th: Vec<f64> = (0..p)
                .map(|j| {
                    let u = 0.5 * (rng.sym() + 1.0);
                    sol.theta_lb[j] + u * (sol.theta_ub[j] - sol.theta_lb[j])
                })
                .collect();
            let want = sol
                .first_outputs_at(&th, k)
                .expect("every parameter of the box is covered");
            let e = crate::eval::evaluate_with(&t.tables(), &th, &mut scratch, &mut z).unwrap();
            assert!(!e.outside);
            if want
                .iter()
                .zip(&z)
                .any(|(a, b)| (a - b).abs() > 1e-9 * (1.0 + a.abs()))
            {
                bad += 1;
            }
        }
        bad
    }

    fn problems() -> Vec<(&'static str, MpqpProblem)> {
        let mut blocked = testing::random_system(2, 2, 1, 0.9, 7);
        blocked.horizon = 3;
        blocked.free_moves = 2;
        vec![
            ("thesis-sized", testing::thesis_sized(1)),
            (
                "random 3x2",
                testing::random_system(3, 2, 2, 0.95, 3).condense(),
            ),
            ("blocked 2x2", blocked.condense()),
        ]
    }

    #[test]
    fn sampled_and_lp_trees_are_exact() {
        for (name, prob) in problems() {
            let sol = solve(&prob, &Settings::default()).unwrap();
            for k in [2, prob.n()] {
                let mut sizes = Vec::new();
                for method in [TreeMethod::Lp, TreeMethod::Sampled] {
                    for clipping in [true, false] {
                        let settings = TreeSettings {
                            outputs: Outputs::First(k),
                            method,
                            clipping,
                            ..TreeSettings::default()
                        };
                        let ctl = build_controller(&prob, &sol, &settings).unwrap();
                        assert_eq!(ctl.stats.ambiguous_leaves, 0, "{name} {method:?}");
                        let bad = mismatches(&sol, &ctl.tables, 2000, 11);
                        assert_eq!(bad, 0, "{name}, k = {k}, {method:?}, clipping {clipping}");
                        sizes.push(ctl.stats.nodes);
                    }
                }
                // Both methods build a tree (of comparable size).
                assert!(sizes.iter().all(|&s| s > 0), "{name}: {sizes:?}");
            }
        }
    }

    #[test]
    fn sampled_tree_is_deterministic_and_parallel_invariant() {
        let prob = testing::thesis_sized(2);
        let sol = solve(&prob, &Settings::default()).unwrap();
        let build = |parallel| {
            let settings = TreeSettings {
                outputs: Outputs::First(4),
                method: TreeMethod::Sampled,
                parallel,
                ..TreeSettings::default()
            };
            build_controller(&prob, &sol, &settings).unwrap().tables
        };
        let a = build(true);
        assert_eq!(a, build(true));
        assert_eq!(a, build(false));
    }

    #[test]
    fn node_cap_gives_too_large() {
        let prob = testing::thesis_sized(1);
        let sol = solve(&prob, &Settings::default()).unwrap();
        let settings = TreeSettings {
            outputs: Outputs::First(4),
            method: TreeMethod::Sampled,
            max_nodes: 20,
            ..TreeSettings::default()
        };
        let e = build_controller(&prob, &sol, &settings).unwrap_err();
        assert!(matches!(e, EmpcError::TooLarge(_)), "{e}");
        assert!(e.to_string().contains("max_nodes"), "{e}");
    }
}
