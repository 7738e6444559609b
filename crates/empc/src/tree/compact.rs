//! The compact layout: one search tree per output over shared rows
//! ([`build_compact`], [`CompactTables`]).

use crate::error::EmpcError;
use crate::eval::{CompactNode, ForestTables, LEAF, NO_ROW, NO_ROW8};
use crate::mpqp::MpqpSolution;
use crate::tree::assemble::intern;
use crate::tree::build::{build_for, kept_outputs};
use crate::tree::settings::TreeSettings;
use crate::tree::share_rows::share_hyperplane_rows;
use crate::tree::stats::TreeStats;
use kestrel_core::Scalar;
use kestrel_core::formats::MpqpProblem;
use std::collections::HashMap;

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
    /// per other index (counted as [`OwnedTables::bytes`](crate::tree::OwnedTables::bytes), with the roots
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
/// [`CompactTables::tables`]; the answers are those of [`build_controller`](crate::tree::build_controller).
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
