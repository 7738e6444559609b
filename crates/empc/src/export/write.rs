//! Writing the solution file (`kestrel.empc.v1`).

use crate::export::format::TableFormat;
use crate::export::index::ExportIndex;
use crate::mpqp::MpqpSolution;
use crate::tree::{
    AnyController, AnyTables, CompactController, CompactTables, ExplicitController, OwnedTables,
    TreeStats, WideTables,
};
use kestrel_core::formats::json::{self, Object};
use serde_json::{Value, json};

/// The format name of the summary / solution file.
pub const FORMAT: &str = "kestrel.empc.v1";

/// Rows of `width` numbers as a JSON array of arrays.
fn rows_value(v: &[f64], width: usize) -> Value {
    Value::Array(v.chunks(width.max(1)).map(|r| json!(r)).collect())
}

/// What a solution file carries besides the solution: the single tree
/// (statistics and tables, [`TableFormat::Narrow`] or [`TableFormat::Wide`])
/// and optionally the compact format ([`TableFormat::Compact`]).
///
/// Made from an [`ExplicitController`] or an [`AnyController`] (`From`),
/// the compact format added with [`SolutionTables::with_compact`].
#[derive(Clone, Copy, Debug)]
pub struct SolutionTables<'a> {
    stats: &'a TreeStats,
    tree: Tree<'a>,
    compact: Option<&'a CompactController>,
}

/// The single tree in either index width.
#[derive(Clone, Copy, Debug)]
enum Tree<'a> {
    Narrow(&'a OwnedTables<f64>),
    Wide(&'a WideTables<f64>),
}

impl<'a> SolutionTables<'a> {
    /// The same with the compact format added: the summary key
    /// `tree_compact` = `{depth, nodes, bytes, hyperplanes, rows,
    /// laws_per_output, depth_per_output, nodes_per_output}` (`bytes` counts
    /// the compact tables in f32, as [`CompactTables::bytes`]) and
    /// `compact_tables` = `{roots, nodes: [[row_a, row_b, le, gt]] (255: no
    /// row), rows, hull, theta_lb, theta_ub, bounds}`. The single tree's keys
    /// are unchanged.
    pub fn with_compact(self, compact: &'a CompactController) -> SolutionTables<'a> {
        SolutionTables {
            compact: Some(compact),
            ..self
        }
    }
}

impl<'a> From<&'a ExplicitController> for SolutionTables<'a> {
    fn from(c: &'a ExplicitController) -> SolutionTables<'a> {
        SolutionTables {
            stats: &c.stats,
            tree: Tree::Narrow(&c.tables),
            compact: None,
        }
    }
}

impl<'a> From<&'a AnyController> for SolutionTables<'a> {
    fn from(c: &'a AnyController) -> SolutionTables<'a> {
        let tree = match &c.tables {
            AnyTables::Narrow(t) => Tree::Narrow(t),
            AnyTables::Wide(t) => Tree::Wide(t),
        };
        SolutionTables {
            stats: &c.stats,
            tree,
            compact: None,
        }
    }
}

/// The `kestrel.empc.v1` solution file: summary, optional region list
/// (`include_regions`) and the tables of every format `tables` carries.
///
/// The single tree goes under `tables`; in the wide format with
/// `tables.index = "u32"` and `tree.index_bytes = 4` (`tree.bytes` counts
/// the wide tables in f32, 4 bytes per index). The compact format, if
/// added ([`SolutionTables::with_compact`]), goes under `tree_compact` and
/// `compact_tables`. [`read_tables`](crate::export::read_tables) reads
/// each format back.
pub fn solution_json<'a>(
    solution: &MpqpSolution,
    tables: impl Into<SolutionTables<'a>>,
    include_regions: bool,
) -> String {
    let tables = tables.into();
    let view = match tables.tree {
        Tree::Narrow(t) => TablesView::of(t),
        Tree::Wide(t) => TablesView::of(t),
    };
    let mut o = solution_object(solution, tables.stats, view, include_regions);
    if let Some(compact) = tables.compact {
        insert_compact(&mut o, compact);
    }
    json::to_pretty_string(&o)
}

/// What the solution file writes of a layout: its tables object, f32
/// bytes, outputs and index width.
struct TablesView {
    tables: Value,
    bytes: usize,
    n_outputs: usize,
    wide: bool,
}

impl TablesView {
    fn of<X: ExportIndex>(t: &OwnedTables<f64, X>) -> TablesView {
        let w = t.n_params + 1;
        let idx = |v: &[X]| json!(v.iter().map(|x| x.index()).collect::<Vec<_>>());
        let mut m = Object::new();
        let wide = X::FORMAT == TableFormat::Wide;
        if wide {
            m.insert("index".into(), X::FORMAT.index_type().into());
        }
        m.insert("root".into(), t.root.index().into());
        m.insert(
            "nodes".into(),
            Value::Array(t.nodes.iter().map(|n| idx(n)).collect()),
        );
        m.insert(
            "laws".into(),
            Value::Array(t.laws.chunks(t.n_outputs.max(1)).map(idx).collect()),
        );
        m.insert("rows".into(), rows_value(&t.rows, w));
        m.insert("hull".into(), rows_value(&t.hull, w));
        m.insert("theta_lb".into(), json!(t.theta_lb));
        m.insert("theta_ub".into(), json!(t.theta_ub));
        m.insert(
            "bounds".into(),
            Value::Array(t.bounds.iter().map(|b| idx(b)).collect()),
        );
        TablesView {
            tables: Value::Object(m),
            bytes: t.bytes(4),
            n_outputs: t.n_outputs,
            wide,
        }
    }
}

/// Adds the compact format's keys `tree_compact` and `compact_tables`.
fn insert_compact(o: &mut Object, compact: &CompactController) {
    let t: &CompactTables<f64> = &compact.tables;
    let w = t.n_params + 1;
    let per =
        |f: fn(&TreeStats) -> usize| -> Vec<usize> { compact.per_output.iter().map(f).collect() };
    o.insert(
        "tree_compact".into(),
        json!({"depth": compact.depth, "nodes": t.nodes.len(), "bytes": t.bytes(4),
               "hyperplanes": compact.hyperplanes, "rows": t.rows.len() / w,
               "laws_per_output": per(|s| s.distinct_laws),
               "depth_per_output": per(|s| s.depth),
               "nodes_per_output": per(|s| s.nodes)}),
    );
    let nodes: Vec<Value> = t
        .nodes
        .iter()
        .map(|n| json!([n.rows[0], n.rows[1], n.children[0], n.children[1]]))
        .collect();
    o.insert(
        "compact_tables".into(),
        json!({
            "roots": t.roots,
            "nodes": nodes,
            "rows": rows_value(&t.rows, w),
            "hull": rows_value(&t.hull, w),
            "theta_lb": t.theta_lb,
            "theta_ub": t.theta_ub,
            "bounds": t.bounds,
        }),
    );
}

/// The summary, the optional region list and the tables of the solution file.
fn solution_object(
    solution: &MpqpSolution,
    stats: &TreeStats,
    view: TablesView,
    include_regions: bool,
) -> Object {
    let mut o = Object::new();
    o.insert("format".into(), FORMAT.into());
    o.insert("regions".into(), solution.regions.len().into());
    o.insert("distinct_laws".into(), stats.distinct_laws.into());
    o.insert("solve_seconds".into(), json!(solution.stats.solve_seconds));
    let mut tree = json!({"depth": stats.depth, "nodes": stats.nodes, "bytes": view.bytes});
    if view.wide {
        tree["index_bytes"] = json!(4);
    }
    o.insert("tree".into(), tree);
    o.insert("n".into(), solution.n.into());
    o.insert("p".into(), solution.p.into());
    o.insert("outputs".into(), view.n_outputs.into());
    let s = &solution.stats;
    o.insert(
        "stats".into(),
        json!({"active_sets_tested": s.active_sets_tested, "discarded": s.discarded,
               "fallback_qps": s.fallback_qps, "lps": s.lps, "duplicate_rows": s.duplicate_rows,
               "distinct_rows": stats.distinct_rows,
               "hyperplanes": stats.hyperplanes,
               "ambiguous_leaves": stats.ambiguous_leaves,
               "tree_build_seconds": stats.build_seconds}),
    );
    if include_regions {
        let list: Vec<Value> = solution
            .regions
            .iter()
            .map(|r| {
                json!({"active_set": r.active_set, "A": json::matrix_to_value(&r.a),
                       "b": json::vector_to_value(&r.b), "Fz": json::matrix_to_value(&r.fz),
                       "gz": json::vector_to_value(&r.gz)})
            })
            .collect();
        o.insert("region_list".into(), Value::Array(list));
    }
    o.insert("tables".into(), view.tables);
    o
}
