//! From a solution to the tables: law sharing, output bounds, the
//! hyperplane pool, the search ([`crate::tree::search`]) and the node rows.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::error::EmpcError;
use crate::eval::{LEAF, NO_ROW, WIDE_LEAF, WIDE_NO_ROW};
use crate::lp::LpWorkspace;
use crate::mpqp::MpqpSolution;
use crate::tree::search::Builder;
use crate::tree::settings::{AUTO_SAMPLED_REGIONS, TreeMethod, TreeSettings, WIDE_MAX_NODES};
use crate::tree::stats::TreeStats;
use crate::tree::tables::{WideTables, widen_row};
use kestrel_core::formats::MpqpProblem;
use std::collections::HashMap;

/// Dedupes `row` into `rows` (width p + 1) and returns its index: a row
/// within `10 tol` (relative to its size) of a stored row is that row.
///
/// The key quantises the row relative to its own largest entry, so every
/// positive multiple of a row has the same key (the constant rows `1.19`
/// and `1.0017` once did, and two different moves became one law): the
/// rows under a key are candidates, compared entry by entry.
pub(super) fn intern(
    rows: &mut Vec<f64>,
    index: &mut HashMap<Vec<i64>, Vec<usize>>,
    row: &[f64],
    tol: f64,
) -> usize {
    let scale = row.iter().fold(1.0_f64, |s, v| s.max(v.abs()));
    let quantum = scale * tol * 10.0;
    let key: Vec<i64> = row.iter().map(|&v| (v / quantum).round() as i64).collect();
    let width = row.len();
    let same = |i: usize| {
        rows[i * width..(i + 1) * width]
            .iter()
            .zip(row)
            .all(|(a, b)| (a - b).abs() <= quantum)
    };
    let candidates = index.entry(key).or_default();
    if let Some(&i) = candidates.iter().find(|&&i| same(i)) {
        return i;
    }
    let i = rows.len() / width;
    rows.extend_from_slice(row);
    candidates.push(i);
    i
}

/// The kept outputs' affine rows shared between laws, identical laws
/// stored once, and the output bounds ([`share_laws`]).
pub(crate) struct SharedLaws {
    /// Distinct affine rows, `p + 1` entries each.
    pub(crate) rows: Vec<f64>,
    /// Laws, `k` row indices each.
    pub(crate) laws: Vec<u32>,
    /// The law of every region.
    pub(crate) region_law: Vec<u32>,
    /// Per output: rows of the lower and upper bound ([`WIDE_NO_ROW`]: none).
    pub(crate) bounds: Vec<[u32; 2]>,
    /// Distinct laws.
    pub(crate) distinct_laws: usize,
}

/// Shares the affine rows of the outputs `outs` between the regions' laws
/// (rows within `10 law_tol` are one row, see [`intern`]), stores identical
/// laws once, and adds each output's bounds (single-variable rows of `G`).
pub(crate) fn share_laws(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    outs: &[usize],
    law_tol: f64,
) -> SharedLaws {
    let p = solution.p;
    let n = solution.n;
    let k = outs.len();
    let mut rows: Vec<f64> = Vec::new();
    let mut row_index = HashMap::new();
    let mut laws: Vec<u32> = Vec::new();
    let mut law_index: HashMap<Vec<usize>, usize> = HashMap::new();
    let mut region_law = Vec::with_capacity(solution.regions.len());
    for r in &solution.regions {
        let mut ids = Vec::with_capacity(k);
        for &o in outs {
            let row: Vec<f64> = (0..p).map(|j| r.fz[(o, j)]).chain([r.gz[o]]).collect();
            ids.push(intern(&mut rows, &mut row_index, &row, law_tol));
        }
        let nl = law_index.len();
        let id = *law_index.entry(ids.clone()).or_insert_with(|| {
            laws.extend(ids.iter().map(|&i| i as u32));
            nl
        });
        region_law.push(id as u32);
    }
    let distinct_laws = law_index.len();
    // Output bounds from single-variable rows of G.
    let mut bounds = vec![[WIDE_NO_ROW, WIDE_NO_ROW]; k];
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
            if bounds[o][slot] == WIDE_NO_ROW {
                bounds[o][slot] = intern(&mut rows, &mut row_index, &row, law_tol) as u32;
            }
        }
    }
    SharedLaws {
        rows,
        laws,
        region_law,
        bounds,
        distinct_laws,
    }
}

/// What [`build_wide_for`] found.
pub(super) struct WideBuild {
    pub(super) tables: WideTables<f64>,
    pub(super) region_law: Vec<u16>,
    pub(super) stats: TreeStats,
}

/// The tree and tables in the wide layout, at most `max_nodes` nodes.
pub(super) fn build_wide_for(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
    outs: &[usize],
    max_nodes: usize,
) -> Result<WideBuild, EmpcError> {
    let start = std::time::Instant::now();
    let p = solution.p;
    let k = outs.len();
    let w = p + 1;
    let SharedLaws {
        mut rows,
        laws,
        region_law,
        bounds,
        distinct_laws,
    } = share_laws(problem, solution, outs, settings.law_tol);
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
    // Every index fits u16 now.
    let laws: Vec<u16> = laws.iter().map(|&i| i as u16).collect();
    let region_law: Vec<u16> = region_law.iter().map(|&i| i as u16).collect();
    let bounds: Vec<[u16; 2]> = bounds
        .iter()
        .map(|b| b.map(|r| if r == WIDE_NO_ROW { NO_ROW } else { r as u16 }))
        .collect();
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
