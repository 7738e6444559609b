//! The entry points: [`build_lists`], [`build_locator`] (the structure the
//! settings choose) and [`estimate`] (before building).

use crate::error::EmpcError;
use crate::eval::{WIDE_LEAF, WIDE_NO_ROW};
use crate::locate::pool::{self, Pool};
use crate::locate::settings::{LocateMethod, LocateSettings, Progress, Stage};
use crate::locate::split::Splitter;
use crate::locate::stats::{Estimate, ListStats, OpCount};
use crate::locate::tables::ListTables;
use crate::lp::{LpStatus, LpWorkspace};
use crate::mpqp::{CriticalRegion, MpqpSolution};
use crate::tree::{AnyController, Outputs, SharedLaws, TreeSettings, build_any, share_laws};
use kestrel_core::formats::MpqpProblem;

/// Candidate-list tables and what building them found ([`build_lists`]).
#[derive(Clone, Debug)]
pub struct ListController {
    /// The tables in `f64` with `u32` indices ([`ListTables::narrow`] gives
    /// the `u16` ones when they fit).
    pub tables: ListTables<f64>,
    /// The law of every region of the solution.
    pub region_law: Vec<u32>,
    /// Statistics.
    pub stats: ListStats,
}

/// The point location [`build_locator`] built.
#[derive(Clone, Debug)]
pub enum Locator {
    /// The exact search tree ([`LocateMethod::Tree`]).
    Tree(Box<AnyController>),
    /// The candidate lists ([`LocateMethod::Lists`]).
    Lists(Box<ListController>),
}

impl Locator {
    /// The structure built ([`LocateMethod::Tree`] or [`LocateMethod::Lists`]).
    pub fn method(&self) -> LocateMethod {
        match self {
            Locator::Tree(_) => LocateMethod::Tree,
            Locator::Lists(_) => LocateMethod::Lists,
        }
    }
    /// Storage in bytes with `f32` numbers (`u16` indices when they fit).
    pub fn bytes_f32(&self) -> usize {
        match self {
            Locator::Tree(c) => c.tables.bytes(4),
            Locator::Lists(c) => c.stats.bytes_f32,
        }
    }
    /// Evaluates in `f64`: writes the outputs into `z` and returns the law
    /// index (allocates a scratch vector).
    pub fn evaluate_f64(&self, theta: &[f64], z: &mut [f64]) -> Result<u32, kestrel_core::Error> {
        match self {
            Locator::Tree(c) => c.tables.evaluate_f64(theta, z).map(|e| e.law),
            Locator::Lists(c) => c.tables.evaluate_f64(theta, z).map(|e| e.law),
        }
    }
}

/// The kept outputs, after checking the settings and that problem and
/// solution match.
fn kept(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &LocateSettings,
) -> Result<Vec<usize>, EmpcError> {
    settings.validate()?;
    let n = solution.n;
    let k = match settings.outputs {
        Outputs::All => n,
        Outputs::First(k) if k <= n => k,
        Outputs::First(k) => {
            return Err(EmpcError::InvalidArgument(format!(
                "Outputs::First({k}) needs 1 <= k <= n = {n}"
            )));
        }
    };
    if problem.n() != n || problem.p() != solution.p {
        return Err(EmpcError::InvalidArgument(
            "the problem does not match the solution".into(),
        ));
    }
    if solution.regions.is_empty() {
        return Err(EmpcError::InvalidArgument(
            "the solution has no regions".into(),
        ));
    }
    Ok((0..k).collect())
}

/// The structure [`LocateMethod::Auto`] resolves to.
fn resolve(settings: &LocateSettings, regions: usize) -> LocateMethod {
    match settings.method {
        LocateMethod::Auto if regions <= settings.auto_tree_regions => LocateMethod::Tree,
        LocateMethod::Auto => LocateMethod::Lists,
        m => m,
    }
}

/// Laws and hyperplanes, the part of the build without LPs.
fn shared(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    outs: &[usize],
    settings: &LocateSettings,
    progress: &mut dyn FnMut(Progress),
) -> (SharedLaws, Pool) {
    progress(Progress {
        stage: Stage::Laws,
        done: 0,
        total: 1,
    });
    let mut laws = share_laws(problem, solution, outs, settings.law_tol);
    progress(Progress {
        stage: Stage::Laws,
        done: 1,
        total: 1,
    });
    let k = outs.len();
    let law_rows: Vec<&[u32]> = laws
        .region_law
        .iter()
        .map(|&l| &laws.laws[l as usize * k..][..k])
        .collect();
    let total = solution.regions.len();
    let mut rows = laws.rows.clone();
    let pool = pool::collect(solution, &law_rows, &mut rows, &mut |done| {
        progress(Progress {
            stage: Stage::Hyperplanes,
            done,
            total,
        })
    });
    progress(Progress {
        stage: Stage::Hyperplanes,
        done: total,
        total,
    });
    laws.rows = rows;
    (laws, pool)
}

/// Builds the candidate-list point location ([`LocateMethod::Lists`]):
/// the first [`LocateSettings::outputs`] of `z`, their laws shared as in
/// [`crate::tree`], the facet hyperplanes stored once, and a shallow tree
/// whose leaves list at most [`LocateSettings::leaf_regions`] regions to
/// test. `progress` hears every stage ([`Progress`]).
///
/// ```
/// use kestrel_empc::{solve, Settings};
/// use kestrel_empc::locate::{build_lists, LocateSettings};
/// # use kestrel_core::formats::MpqpProblem;
/// # let problem = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
/// #   "H": [[1, 0], [0, 1]], "F": [[1, 0], [0, 1]],
/// #   "G": [[1, 0], [0, 1], [-1, 0], [0, -1]], "W": [1, 1, 1, 1],
/// #   "E": [[0, 0], [0, 0], [0, 0], [0, 0]],
/// #   "theta_lb": [-3, -3], "theta_ub": [3, 3]}"#).unwrap();
/// let solution = solve(&problem, &Settings::default()).unwrap();
/// let settings = LocateSettings { leaf_regions: 1, ..LocateSettings::default() };
/// let c = build_lists(&problem, &solution, &settings, &mut |_| {}).unwrap();
/// let mut z = [0.0; 2];
/// c.tables.evaluate_f64(&[0.5, -2.0], &mut z).unwrap();
/// assert_eq!(z, [-0.5, 1.0]);
/// assert!(c.stats.fits_u16 && c.stats.worst_case.mul_adds > 0);
/// ```
pub fn build_lists(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &LocateSettings,
    progress: &mut dyn FnMut(Progress),
) -> Result<ListController, EmpcError> {
    let start = std::time::Instant::now();
    let outs = kept(problem, solution, settings)?;
    let (k, p) = (outs.len(), solution.p);
    let (laws, pool) = shared(problem, solution, &outs, settings, progress);
    let scale = 1.0
        + solution
            .theta_lb
            .iter()
            .chain(solution.theta_ub.iter())
            .fold(0.0_f64, |s, v| s.max(v.abs()));
    let regions = &solution.regions;
    let mut lp = LpWorkspace::default();
    let mut tree_progress = |done| {
        progress(Progress {
            stage: Stage::Tree,
            done,
            total: 1000,
        })
    };
    let mut sp = Splitter {
        p,
        planes: &pool.planes,
        facets: &pool.facets,
        reg_a: regions
            .iter()
            .map(|r| r.a.transpose().as_slice().to_vec())
            .collect(),
        reg_b: regions.iter().map(|r| r.b.as_slice().to_vec()).collect(),
        center: regions
            .iter()
            .map(|r| r.center.as_slice().to_vec())
            .collect(),
        radius: regions.iter().map(|r| r.radius).collect(),
        boxes: regions.iter().map(|r| bounding_box(r, &mut lp)).collect(),
        law: &laws.region_law,
        leaf_regions: settings.leaf_regions,
        max_depth: settings.max_depth,
        candidates: settings.candidates,
        tries: settings.tries,
        shrink: settings.shrink,
        tol: 1e-9 * scale,
        lp: Vec::new(),
        parallel: settings.parallel,
        lps: 2 * p * regions.len(),
        nodes: Vec::new(),
        leaves: Vec::new(),
        entries: Vec::new(),
        depth: 0,
        done: 0.0,
    };
    let members = (0..regions.len())
        .map(|r| (r as u32, Some(sp.center[r].clone())))
        .collect();
    let root = sp.build(members, &mut Vec::new(), 0, 1.0, &mut tree_progress);
    let (nodes, leaves, entries, depth, lps) = (
        std::mem::take(&mut sp.nodes),
        std::mem::take(&mut sp.leaves),
        std::mem::take(&mut sp.entries),
        sp.depth,
        sp.lps,
    );
    drop(sp);
    progress(Progress {
        stage: Stage::Tables,
        done: 0,
        total: 1,
    });
    let mut region_start = vec![0u32];
    let mut facets = Vec::new();
    for fs in &pool.facets {
        facets.extend(
            fs.iter()
                .map(|&(h, below)| if below { h } else { h | WIDE_LEAF }),
        );
        region_start.push(facets.len() as u32);
    }
    let mut hull = Vec::new();
    for i in 0..solution.hull_a.nrows() {
        hull.extend(solution.hull_a.row(i).iter());
        hull.push(solution.hull_b[i]);
    }
    let tables = ListTables {
        n_params: p,
        n_outputs: k,
        root,
        nodes,
        leaves,
        entries,
        region_start,
        facets,
        region_law: laws.region_law.clone(),
        hyperplanes: pool.rows.clone(),
        laws: laws.laws.clone(),
        rows: laws.rows.clone(),
        hull,
        theta_lb: solution.theta_lb.iter().copied().collect(),
        theta_ub: solution.theta_ub.iter().copied().collect(),
        bounds: laws.bounds.clone(),
    };
    if tables.rows.len() / (p + 1) >= WIDE_NO_ROW as usize {
        return Err(EmpcError::TooLarge(format!(
            "{} affine rows",
            tables.rows.len() / (p + 1)
        )));
    }
    let narrow = tables.narrow();
    let (worst_case, worst_case_hyperplanes) = worst_case(&tables);
    let stats = ListStats {
        regions: regions.len(),
        distinct_laws: laws.distinct_laws,
        distinct_rows: tables.rows.len() / (p + 1),
        hyperplanes: tables.hyperplanes.len(),
        explicit_hyperplanes: pool.explicit,
        facets: tables.facets.len(),
        nodes: tables.nodes.len(),
        leaves: tables.leaves.len(),
        entries: tables.entries.len(),
        depth,
        max_leaf_regions: tables
            .leaves
            .iter()
            .map(|l| (l[1] - l[0]) as usize)
            .max()
            .unwrap_or(0),
        worst_case,
        worst_case_hyperplanes,
        lps,
        bytes_f32: narrow.as_ref().map_or(tables.bytes(4), |t| t.bytes(4)),
        bytes_f64: narrow.as_ref().map_or(tables.bytes(8), |t| t.bytes(8)),
        fits_u16: narrow.is_some(),
        build_seconds: start.elapsed().as_secs_f64(),
    };
    progress(Progress {
        stage: Stage::Tables,
        done: 1,
        total: 1,
    });
    Ok(ListController {
        tables,
        region_law: laws.region_law,
        stats,
    })
}

/// The bounding box of a region (2p LPs from its centre; the region's own
/// rows include the parameter box, so each LP is bounded).
fn bounding_box(r: &CriticalRegion, lp: &mut LpWorkspace) -> (Vec<f64>, Vec<f64>) {
    let p = r.center.len();
    let a = r.a.transpose().as_slice().to_vec();
    let b = r.b.as_slice();
    let (mut lo, mut up) = (vec![f64::NEG_INFINITY; p], vec![f64::INFINITY; p]);
    let mut c = vec![0.0; p];
    for j in 0..p {
        for sign in [1.0, -1.0] {
            c[j] = sign;
            if let (LpStatus::Optimal, v) = lp.maximize_from(&c, &a, b, r.center.as_slice()) {
                if sign > 0.0 {
                    up[j] = v;
                } else {
                    lo[j] = -v;
                }
            }
        }
        c[j] = 0.0;
    }
    (lo, up)
}

/// The most operations and hyperplanes of one evaluation of `t`.
fn worst_case(t: &ListTables<f64>) -> (OpCount, usize) {
    let p = t.n_params;
    let hp = |h: u32| -> OpCount {
        let [_, r2] = t.hyperplanes[(h & !WIDE_LEAF) as usize];
        OpCount {
            mul_adds: if r2 == WIDE_NO_ROW { p } else { 2 * p },
            comparisons: 1,
        }
    };
    let add = |a: OpCount, b: OpCount| OpCount {
        mul_adds: a.mul_adds + b.mul_adds,
        comparisons: a.comparisons + b.comparisons,
    };
    let leaf_cost = |l: &[u32; 3]| -> (OpCount, usize) {
        let mut c = OpCount::default();
        let mut n = 0;
        for &r in &t.entries[l[0] as usize..l[1] as usize] {
            let fs = &t.facets
                [t.region_start[r as usize] as usize..t.region_start[r as usize + 1] as usize];
            for &f in fs {
                c = add(c, hp(f));
            }
            n += fs.len();
        }
        (c, n)
    };
    // Depth-first over (code, cost so far, hyperplanes so far).
    let mut worst = (OpCount::default(), 0usize);
    let mut stack = vec![(t.root, OpCount::default(), 0usize)];
    while let Some((code, c, n)) = stack.pop() {
        if code & WIDE_LEAF != 0 {
            let (lc, ln) = leaf_cost(&t.leaves[(code & !WIDE_LEAF) as usize]);
            let total = add(c, lc);
            worst.0.mul_adds = worst.0.mul_adds.max(total.mul_adds);
            worst.0.comparisons = worst.0.comparisons.max(total.comparisons);
            worst.1 = worst.1.max(n + ln);
        } else {
            let [h, lo, hi] = t.nodes[code as usize];
            let c = add(c, hp(h));
            stack.push((lo, c, n + 1));
            stack.push((hi, c, n + 1));
        }
    }
    // Box and hull tests, outputs and their clamps.
    let n_hull = t.hull.len() / (p + 1);
    let mut fixed = OpCount {
        mul_adds: n_hull * p + t.n_outputs * p,
        comparisons: 2 * p + n_hull,
    };
    for b in &t.bounds {
        for &r in b {
            if r != WIDE_NO_ROW {
                fixed.mul_adds += p;
                fixed.comparisons += 1;
            }
        }
    }
    (add(worst.0, fixed), worst.1)
}

/// Builds the point location the settings choose: [`LocateMethod::Tree`]
/// ([`build_any`] with [`LocateSettings::tree`], its outputs and law
/// tolerance from `settings`), [`LocateMethod::Lists`] ([`build_lists`]),
/// or for [`LocateMethod::Auto`] the tree up to
/// [`LocateSettings::auto_tree_regions`] regions and the lists above.
pub fn build_locator(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &LocateSettings,
    progress: &mut dyn FnMut(Progress),
) -> Result<Locator, EmpcError> {
    kept(problem, solution, settings)?;
    match resolve(settings, solution.regions.len()) {
        LocateMethod::Tree => {
            progress(Progress {
                stage: Stage::Tree,
                done: 0,
                total: 1,
            });
            let ts = TreeSettings {
                outputs: settings.outputs,
                law_tol: settings.law_tol,
                ..settings.tree.clone()
            };
            let c = build_any(problem, solution, &ts)?;
            progress(Progress {
                stage: Stage::Tree,
                done: 1,
                total: 1,
            });
            Ok(Locator::Tree(Box::new(c)))
        }
        LocateMethod::Auto | LocateMethod::Lists => {
            build_lists(problem, solution, settings, progress).map(|c| Locator::Lists(Box::new(c)))
        }
    }
}

/// Estimates the point location [`build_locator`] would build, without
/// LPs (the laws and hyperplanes are counted exactly; the tree's nodes and
/// the leaves' lists by rules of thumb from measured builds: about
/// `regions^2 / 6` nodes for the exact tree, about two list entries per
/// region for the lists).
pub fn estimate(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &LocateSettings,
) -> Result<Estimate, EmpcError> {
    let outs = kept(problem, solution, settings)?;
    let (k, p) = (outs.len(), solution.p);
    let regions = solution.regions.len();
    let method = resolve(settings, regions);
    let (laws, pool) = shared(problem, solution, &outs, settings, &mut |_| {});
    let nrows = laws.rows.len() / (p + 1);
    let facets: usize = pool.facets.iter().map(Vec::len).sum();
    let numbers = laws.rows.len() + (solution.hull_a.nrows() + 2) * (p + 1);
    let (nodes, indices, seconds) = match method {
        LocateMethod::Tree => {
            let nodes = regions * regions / 6 + 1;
            (nodes, 4 * nodes + laws.laws.len(), nodes as f64 * 5e-4)
        }
        LocateMethod::Auto | LocateMethod::Lists => {
            let entries = 2 * regions;
            let nodes = entries / settings.leaf_regions.max(1) + 1;
            let idx = 6 * nodes
                + entries
                + 3 * regions
                + facets
                + 2 * pool.planes.len()
                + laws.laws.len();
            (nodes, idx, regions as f64 * 1e-3)
        }
    };
    let wide = nrows >= 0xFFFF || indices >= 0xFFFF || nodes >= 0x7FFF;
    let numbers = match method {
        LocateMethod::Tree => numbers,
        LocateMethod::Auto | LocateMethod::Lists => numbers + pool.explicit * (p + 1),
    };
    let _ = k;
    Ok(Estimate {
        method,
        regions,
        distinct_laws: laws.distinct_laws,
        nodes,
        bytes_f32: 4 * numbers + if wide { 4 } else { 2 } * indices,
        seconds,
    })
}
