//! The solution file (`kestrel.empc.v1`) and the Rust table export.
//!
//! The solution file is the `kestrel.empc.v1` summary of `shared/FORMATS.md`
//! (`regions`, `distinct_laws`, `solve_seconds`, `tree {depth, nodes, bytes}`,
//! optional `region_list`) plus what evaluation needs, under added keys:
//! `n`, `p`, `outputs` and `tables` = `{root, nodes: [[row_a, row_b, le, gt]],
//! laws: [[row..]], rows: [[gain.., const]],
//! hull: [[a.., b]], theta_lb, theta_ub, bounds: [[lo, hi]]}` with the
//! encoding of [`crate::eval`] (`tree.bytes` counts these tables in f32).
//! Trees beyond the `u16` codes ([`crate::tree::build_any`]) are written
//! in the wide layout: the same keys with `u32` indices
//! ([`crate::eval::WIDE_LEAF`] child codes, [`crate::eval::WIDE_NO_ROW`]) and `tables.index = "u32"` (absent or
//! `"u16"`: the `u16` layout); [`any_tables_from_json`] reads either.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::error::EmpcError;
use crate::eval::{CompactNode, NO_ROW, NO_ROW8, TreeIndex};
use crate::mpqp::MpqpSolution;
use crate::tree::{
    AnyController, AnyTables, CompactController, CompactTables, ExplicitController, OwnedTables,
    TreeStats, WideTables,
};
use kestrel_core::formats::json::{self, Object};
use kestrel_core::formats::{FormatError, MpqpProblem};
use kestrel_core::{Q16, Scalar};
use serde_json::{Value, json};
use std::fmt::Write as _;

/// The format name of the summary / solution file.
pub const FORMAT: &str = "kestrel.empc.v1";

/// The number type of exported tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportScalar {
    /// `f32` tables.
    F32,
    /// `kestrel_core::Q16` (Q15.16 saturating fixed point) tables.
    Q16,
    /// `f64` tables (host use, or a reference build of the firmware).
    F64,
}

impl ExportScalar {
    /// Bytes per number.
    pub fn bytes(self) -> usize {
        match self {
            ExportScalar::F32 | ExportScalar::Q16 => 4,
            ExportScalar::F64 => 8,
        }
    }

    /// The Rust type of the numbers.
    pub fn rust_type(self) -> &'static str {
        match self {
            ExportScalar::F32 => "f32",
            ExportScalar::Q16 => "kestrel_core::Q16",
            ExportScalar::F64 => "f64",
        }
    }

    /// One number as a Rust expression of [`ExportScalar::rust_type`];
    /// an error for a value `Q16` cannot hold.
    pub fn literal(self, v: f64) -> Result<String, EmpcError> {
        let float = |s: String| {
            if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
                s
            } else {
                format!("{s}.0")
            }
        };
        match self {
            ExportScalar::F32 => Ok(float(format!("{:?}", v as f32))),
            ExportScalar::F64 => Ok(float(format!("{v:?}"))),
            ExportScalar::Q16 => {
                if v.abs() >= 32767.0 {
                    return Err(EmpcError::InvalidArgument(format!(
                        "the value {v} does not fit Q16 (|x| < 32767); scale the problem or use f32"
                    )));
                }
                Ok(format!(
                    "kestrel_core::Q16::from_bits({})",
                    Q16::from_f64(v).to_bits()
                ))
            }
        }
    }
}

/// `pub static NAME: [ty; len] = [...];`, 8 numbers a line.
fn write_numbers(
    s: &mut String,
    name: &str,
    v: &[f64],
    scalar: ExportScalar,
) -> Result<(), EmpcError> {
    let mut body = String::new();
    for (i, x) in v.iter().enumerate() {
        if i % 8 == 0 {
            body.push_str("\n    ");
        }
        body.push_str(&scalar.literal(*x)?);
        body.push_str(", ");
    }
    let _ = writeln!(
        s,
        "pub static {name}: [{}; {}] = [{body}\n];",
        scalar.rust_type(),
        v.len()
    );
    Ok(())
}

/// The output-bound table as Rust source (index type `ty`).
fn write_bounds<I: TreeIndex + std::fmt::Display>(s: &mut String, bounds: &[[I; 2]], ty: &str) {
    let b: Vec<String> = bounds
        .iter()
        .map(|x| format!("[{}, {}]", x[0], x[1]))
        .collect();
    let _ = writeln!(
        s,
        "/// Output bounds: rows of the lower and upper bound ({}: none).",
        I::NO_ROW
    );
    let _ = writeln!(
        s,
        "pub static BOUNDS: [[{ty}; 2]; {}] = [{}];",
        b.len(),
        b.join(", ")
    );
}

/// What the solution file and the Rust export need of an index type
/// (`u16`: the default layout, `u32`: the wide one).
trait ExportIndex: TreeIndex + std::fmt::Display {
    /// The Rust type name.
    const NAME: &'static str;
    /// The largest value in the solution file.
    const MAX: u32;
    /// Wide layout (`tables.index = "u32"`, `tree.index_bytes = 4`).
    const WIDE: bool;
    /// The header line of the Rust source.
    const SOURCE_HEADER: &'static str;
    /// Between "outputs," and "nodes" in the Rust source's header.
    const HEADER_BREAK: &'static str;
    /// The comment of the Rust source's `NODES`.
    const NODES_DOC: &'static str;
    /// The Rust source's tables type.
    const TABLES_TYPE: &'static str;
    /// A value at most [`ExportIndex::MAX`].
    fn from_u32(v: u32) -> Self;
}

impl ExportIndex for u16 {
    const NAME: &'static str = "u16";
    const MAX: u32 = 65535;
    const WIDE: bool = false;
    const SOURCE_HEADER: &'static str =
        "// Explicit MPC tables generated by `kestrel empc export` ";
    const HEADER_BREAK: &'static str = "\n// ";
    const NODES_DOC: &'static str =
        "/// Tree nodes `[row a, row b, child if a(theta) <= b(theta), child otherwise]`.";
    const TABLES_TYPE: &'static str = "kestrel_empc::SliceTables";
    fn from_u32(v: u32) -> u16 {
        v as u16
    }
}

impl ExportIndex for u32 {
    const NAME: &'static str = "u32";
    const MAX: u32 = u32::MAX;
    const WIDE: bool = true;
    const SOURCE_HEADER: &'static str = "// Explicit MPC tables, wide layout (u32 indices), generated by `kestrel empc export`\n// ";
    const HEADER_BREAK: &'static str = " ";
    const NODES_DOC: &'static str = "/// Tree nodes `[row a, row b, child if a(theta) <= b(theta), child otherwise]`\n/// (0x80000000 | law: a leaf; 4294967295: no row).";
    const TABLES_TYPE: &'static str = "kestrel_empc::eval::WideSliceTables";
    fn from_u32(v: u32) -> u32 {
        v
    }
}

fn rows_value(v: &[f64], width: usize) -> Value {
    Value::Array(v.chunks(width.max(1)).map(|r| json!(r)).collect())
}

/// The `kestrel.empc.v1` solution file: summary, optional region list and tables.
pub fn solution_json(
    solution: &MpqpSolution,
    controller: &ExplicitController,
    include_regions: bool,
) -> String {
    json::to_pretty_string(&solution_object(
        solution,
        &controller.stats,
        TablesView::of(&controller.tables),
        include_regions,
    ))
}

/// [`solution_json`] for either layout ([`crate::tree::build_any`]): the
/// `u16` layout as [`solution_json`] writes it, the wide one with
/// `tables.index = "u32"` and `tree.index_bytes = 4` (`tree.bytes` counts
/// the wide tables in f32, 4 bytes per index).
pub fn solution_json_any(
    solution: &MpqpSolution,
    controller: &AnyController,
    include_regions: bool,
) -> String {
    let view = match &controller.tables {
        AnyTables::Narrow(t) => TablesView::of(t),
        AnyTables::Wide(t) => TablesView::of(t),
    };
    json::to_pretty_string(&solution_object(
        solution,
        &controller.stats,
        view,
        include_regions,
    ))
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
        if X::WIDE {
            m.insert("index".into(), X::NAME.into());
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
            wide: X::WIDE,
        }
    }
}

/// [`solution_json`] with the compact layout added (one tree per output,
/// [`crate::build_compact`]): the summary key `tree_compact` = `{depth,
/// nodes, bytes, hyperplanes, rows, laws_per_output, depth_per_output,
/// nodes_per_output}` (`bytes` counts the compact tables in f32, as
/// [`CompactTables::bytes`]) and `compact_tables` = `{roots, nodes:
/// [[row_a, row_b, le, gt]] (255: no row), rows, hull, theta_lb, theta_ub,
/// bounds}`. The default layout's keys are unchanged.
pub fn solution_json_with_compact(
    solution: &MpqpSolution,
    controller: &ExplicitController,
    compact: &CompactController,
    include_regions: bool,
) -> String {
    let mut o = solution_object(
        solution,
        &controller.stats,
        TablesView::of(&controller.tables),
        include_regions,
    );
    let t: &CompactTables<f64> = &compact.tables;
    let w = t.n_params + 1;
    let per = |f: fn(&crate::tree::TreeStats) -> usize| -> Vec<usize> {
        compact.per_output.iter().map(f).collect()
    };
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
    json::to_pretty_string(&o)
}

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

fn index_rows(v: &Value, key: &str, width: usize) -> Result<Vec<Vec<u16>>, FormatError> {
    typed_index_rows(v, key, width)
}

/// Index rows of `width` entries, each an integer in `0..=X::MAX`.
fn typed_index_rows<X: ExportIndex>(
    v: &Value,
    key: &str,
    width: usize,
) -> Result<Vec<Vec<X>>, FormatError> {
    let max = X::MAX;
    let m = json::matrix_value(v, key, None, Some(width))?;
    let mut out = Vec::with_capacity(m.nrows());
    for i in 0..m.nrows() {
        let mut r = Vec::with_capacity(width);
        for j in 0..width {
            let x = m[(i, j)];
            if !(0.0..=f64::from(max)).contains(&x) || x.fract() != 0.0 {
                return Err(FormatError::invalid(
                    format!("{key}[{i}][{j}]"),
                    format!("expected an integer index in 0..={max}, found {x}"),
                ));
            }
            r.push(X::from_u32(x as u32));
        }
        out.push(r);
    }
    Ok(out)
}

/// `p` and `outputs` of a solution file.
fn read_sizes(obj: &Object) -> Result<(usize, usize), EmpcError> {
    json::check_format(obj, FORMAT)?;
    let p = json::number(obj, "p")?;
    let k = json::number(obj, "outputs")?;
    if p < 1.0 || p.fract() != 0.0 || k < 1.0 || k.fract() != 0.0 || p > 1e4 || k > 1e4 {
        return Err(FormatError::invalid("p", "p and outputs must be positive integers").into());
    }
    Ok((p as usize, k as usize))
}

/// The tables object `key` of a solution file.
fn tables_object<'a>(obj: &'a Object, key: &str, what: &str) -> Result<&'a Object, EmpcError> {
    Ok(obj
        .get(key)
        .and_then(Value::as_object)
        .ok_or_else(|| FormatError::MissingKey {
            key: key.into(),
            expected: format!("an object with the evaluation tables ({what})"),
        })?)
}

/// What all layouts store alike: rows, explored set, box, output bounds.
struct CommonTables<X> {
    rows: Vec<f64>,
    hull: Vec<f64>,
    theta_lb: Vec<f64>,
    theta_ub: Vec<f64>,
    bounds: Vec<[X; 2]>,
}

/// The entry `key` of the tables object `prefix`.
fn entry_of<'a>(t: &'a Object, prefix: &str, key: &str) -> Result<&'a Value, FormatError> {
    t.get(key).ok_or_else(|| FormatError::MissingKey {
        key: format!("{prefix}.{key}"),
        expected: "an array".into(),
    })
}

fn read_common<X: ExportIndex>(
    t: &Object,
    prefix: &str,
    p: usize,
    k: usize,
) -> Result<CommonTables<X>, EmpcError> {
    let w = p + 1;
    let flat = |key: &str| -> Result<Vec<f64>, FormatError> {
        let m = json::matrix_value(
            entry_of(t, prefix, key)?,
            &format!("{prefix}.{key}"),
            None,
            Some(w),
        )?;
        Ok((0..m.nrows())
            .flat_map(|i| (0..w).map(move |j| (i, j)))
            .map(|(i, j)| m[(i, j)])
            .collect())
    };
    let vector = |key: &str| -> Result<Vec<f64>, FormatError> {
        Ok(json::vector(t, key, Some(p))?.iter().copied().collect())
    };
    let key = format!("{prefix}.bounds");
    let bounds: Vec<[X; 2]> = typed_index_rows(entry_of(t, prefix, "bounds")?, &key, 2)?
        .into_iter()
        .map(|r| [r[0], r[1]])
        .collect();
    if bounds.len() != k {
        return Err(FormatError::invalid(key, format!("expected {k} rows")).into());
    }
    Ok(CommonTables {
        rows: flat("rows")?,
        hull: flat("hull")?,
        theta_lb: vector("theta_lb")?,
        theta_ub: vector("theta_ub")?,
        bounds,
    })
}

/// Reads the tables of a solution file and checks every index.
pub fn tables_from_json(text: &str) -> Result<OwnedTables<f64>, EmpcError> {
    let obj = json::parse_object(text)?;
    let (p, k) = read_sizes(&obj)?;
    let t = tables_object(&obj, "tables", "written by `kestrel empc solve`")?;
    if is_wide(t)? {
        return Err(FormatError::invalid(
            "tables.index",
            "these are wide (u32) tables: read them with any_tables_from_json",
        )
        .into());
    }
    read_tables(t, p, k)
}

/// The tables object `t` in index type `X`, every index checked.
fn read_tables<X: ExportIndex>(
    t: &Object,
    p: usize,
    k: usize,
) -> Result<OwnedTables<f64, X>, EmpcError> {
    let root = json::number(t, "root")?;
    if !(0.0..=f64::from(X::MAX)).contains(&root) || root.fract() != 0.0 {
        return Err(FormatError::invalid(
            "tables.root",
            format!("expected an index in 0..={}", X::MAX),
        )
        .into());
    }
    let nodes: Vec<[X; 4]> = typed_index_rows(entry_of(t, "tables", "nodes")?, "tables.nodes", 4)?
        .into_iter()
        .map(|r| [r[0], r[1], r[2], r[3]])
        .collect();
    let laws: Vec<X> = typed_index_rows(entry_of(t, "tables", "laws")?, "tables.laws", k)?
        .into_iter()
        .flatten()
        .collect();
    let c = read_common(t, "tables", p, k)?;
    let tables = OwnedTables {
        n_params: p,
        n_outputs: k,
        root: X::from_u32(root as u32),
        nodes,
        laws,
        rows: c.rows,
        hull: c.hull,
        theta_lb: c.theta_lb,
        theta_ub: c.theta_ub,
        bounds: c.bounds,
    };
    check_tables(&tables)?;
    Ok(tables)
}

/// Whether the tables object says `index: "u32"` (absent or `"u16"`: no).
fn is_wide(t: &Object) -> Result<bool, EmpcError> {
    match t.get("index") {
        None => Ok(false),
        Some(v) => match v.as_str() {
            Some("u16") => Ok(false),
            Some("u32") => Ok(true),
            _ => Err(FormatError::invalid("tables.index", "expected \"u16\" or \"u32\"").into()),
        },
    }
}

/// Reads the tables of a solution file in either layout (`tables.index`
/// `"u32"`: [`WideTables`], else [`OwnedTables`]) and checks every index.
pub fn any_tables_from_json(text: &str) -> Result<AnyTables, EmpcError> {
    let obj = json::parse_object(text)?;
    let (p, k) = read_sizes(&obj)?;
    let t = tables_object(&obj, "tables", "written by `kestrel empc solve`")?;
    if !is_wide(t)? {
        return Ok(AnyTables::Narrow(tables_from_json(text)?));
    }
    Ok(AnyTables::Wide(read_tables(t, p, k)?))
}

/// Whether a solution file holds the compact layout (`compact_tables`,
/// written by `kestrel empc solve --compact`).
pub fn has_compact_tables(text: &str) -> Result<bool, EmpcError> {
    let obj = json::parse_object(text)?;
    json::check_format(&obj, FORMAT)?;
    Ok(obj.contains_key("compact_tables"))
}

/// Reads the compact layout of a solution file (`compact_tables`, see
/// [`solution_json_with_compact`]) and checks every index
/// ([`check_compact_tables`]).
pub fn compact_tables_from_json(text: &str) -> Result<CompactTables<f64>, EmpcError> {
    let obj = json::parse_object(text)?;
    let (p, k) = read_sizes(&obj)?;
    let pre = "compact_tables";
    let t = tables_object(
        &obj,
        pre,
        "written by `kestrel empc solve --compact`; solve again with --compact",
    )?;
    let mut roots = Vec::with_capacity(k);
    for (j, x) in json::vector(t, "roots", Some(k))?.iter().enumerate() {
        if !(0.0..=65535.0).contains(x) || x.fract() != 0.0 {
            return Err(FormatError::invalid(
                format!("compact_tables.roots[{j}]"),
                format!("expected a child code in 0..=65535, found {x}"),
            )
            .into());
        }
        roots.push(*x as u16);
    }
    let mut nodes = Vec::new();
    for (i, r) in index_rows(entry_of(t, pre, "nodes")?, "compact_tables.nodes", 4)?
        .into_iter()
        .enumerate()
    {
        let row = |j: usize| {
            u8::try_from(r[j]).map_err(|_| {
                FormatError::invalid(
                    format!("compact_tables.nodes[{i}][{j}]"),
                    format!("expected a row index in 0..=255, found {}", r[j]),
                )
            })
        };
        nodes.push(CompactNode {
            rows: [row(0)?, row(1)?],
            children: [r[2], r[3]],
        });
    }
    let c = read_common(t, pre, p, k)?;
    let tables = CompactTables {
        n_params: p,
        n_outputs: k,
        roots,
        nodes,
        rows: c.rows,
        hull: c.hull,
        theta_lb: c.theta_lb,
        theta_ub: c.theta_ub,
        bounds: c.bounds,
    };
    check_compact_tables(&tables)?;
    Ok(tables)
}

/// Checks that every index of the compact tables points inside its table
/// (roots, node rows and children, output bounds), that children come
/// after their parent (no cycles), and the table shapes.
pub fn check_compact_tables<S: Scalar>(t: &CompactTables<S>) -> Result<(), EmpcError> {
    let w = t.n_params + 1;
    let bad = |what: String| Err(FormatError::invalid("compact_tables", what).into());
    if !t.rows.len().is_multiple_of(w) || !t.hull.len().is_multiple_of(w) {
        return bad(format!("rows and hull must hold {w} numbers per row"));
    }
    if t.theta_lb.len() != t.n_params || t.theta_ub.len() != t.n_params {
        return bad(format!("expected {} parameter bounds", t.n_params));
    }
    if t.roots.len() != t.n_outputs || t.bounds.len() != t.n_outputs {
        return bad(format!(
            "expected one root and one bound pair per output ({})",
            t.n_outputs
        ));
    }
    let nr = t.rows.len() / w;
    let row16 = |v: u8| if v == NO_ROW8 { NO_ROW } else { u16::from(v) };
    let nodes = t.nodes.iter().map(|n| {
        [
            row16(n.rows[0]),
            row16(n.rows[1]),
            n.children[0],
            n.children[1],
        ]
    });
    check_tree(TreeShape {
        what: "compact_tables",
        roots: &t.roots,
        nodes,
        n_nodes: t.nodes.len(),
        n_leaves: nr,
        n_rows: nr,
        bounds: &t.bounds,
        bounds_ok: t.theta_lb.iter().zip(&t.theta_ub).all(|(l, u)| l <= u),
    })
}

/// What [`check_tree`] checks of either layout.
struct TreeShape<'a, I, X> {
    what: &'static str,
    roots: &'a [X],
    /// `[row a, row b (NO_ROW: none), child, child]`.
    nodes: I,
    n_nodes: usize,
    /// Leaf payloads must be below this (laws, or rows in the compact layout).
    n_leaves: usize,
    n_rows: usize,
    bounds: &'a [[X; 2]],
    /// `theta_lb <= theta_ub`.
    bounds_ok: bool,
}

/// Every root, node row, child and output bound inside its table, children
/// after their parent (no cycles), the parameter box not empty.
fn check_tree<X: TreeIndex, I: Iterator<Item = [X; 4]>>(
    t: TreeShape<'_, I, X>,
) -> Result<(), EmpcError> {
    let (nr, nn, nl) = (t.n_rows, t.n_nodes, t.n_leaves);
    let bad = |what: String| Err(FormatError::invalid(t.what, what).into());
    let child_ok = |c: X| {
        if c.is_leaf() {
            c.payload().index() < nl
        } else {
            c.index() < nn
        }
    };
    if let Some(r) = t.roots.iter().find(|&&r| !child_ok(r)) {
        return bad(format!("root {r:?} points outside the tables"));
    }
    for (i, n) in t.nodes.enumerate() {
        let row_ok = |r: X| r.index() < nr;
        if !row_ok(n[0])
            || !(n[1] == X::NO_ROW || row_ok(n[1]))
            || !child_ok(n[2])
            || !child_ok(n[3])
        {
            return bad(format!("node {i} {n:?} points outside the tables"));
        }
        // Children come after their parent: no cycles.
        for c in [n[2], n[3]] {
            if !c.is_leaf() && c.index() <= i {
                return bad(format!("node {i} has a child {c:?} that is not after it"));
            }
        }
    }
    for b in t.bounds {
        for &r in b {
            if r != X::NO_ROW && r.index() >= nr {
                return bad(format!("an output bound uses row {r:?} of {nr}"));
            }
        }
    }
    if !t.bounds_ok {
        return bad("theta_lb exceeds theta_ub".into());
    }
    Ok(())
}

/// Checks that every index of the tables (either index type) points
/// inside its table.
pub fn check_tables<S: Scalar, X: TreeIndex>(t: &OwnedTables<S, X>) -> Result<(), EmpcError> {
    let nr = t.rows.len() / (t.n_params + 1);
    if let Some(l) = t.laws.iter().find(|&&r| r.index() >= nr) {
        let l = l.index();
        return Err(FormatError::invalid("tables", format!("a law uses row {l} of {nr}")).into());
    }
    check_tree(TreeShape {
        what: "tables",
        roots: &[t.root],
        nodes: t.nodes.iter().copied(),
        n_nodes: t.nodes.len(),
        n_leaves: t.laws.len() / t.n_outputs.max(1),
        n_rows: nr,
        bounds: &t.bounds,
        bounds_ok: t.theta_lb.iter().zip(&t.theta_ub).all(|(l, u)| l <= u),
    })
}

/// Checks that every index of the wide tables points inside its table
/// ([`check_tables`] with `u32` indices).
pub fn check_wide_tables<S: Scalar>(t: &WideTables<S>) -> Result<(), EmpcError> {
    check_tables(t)
}

/// Either layout as Rust source ([`rust_source`] or [`rust_source_wide`]).
pub fn rust_source_any(t: &AnyTables, scalar: ExportScalar) -> Result<String, EmpcError> {
    match t {
        AnyTables::Narrow(t) => rust_source(t, scalar),
        AnyTables::Wide(t) => rust_source_wide(t, scalar),
    }
}

/// The wide tables as Rust source: as [`rust_source`] with `u32` index
/// arrays (`NODES: [[u32; 4]; _]`, `LAWS: [u32; _]`, `BOUNDS: [[u32; 2]; k]`)
/// and `pub static TABLES: kestrel_empc::eval::WideSliceTables<'static, S>`.
pub fn rust_source_wide(t: &WideTables<f64>, scalar: ExportScalar) -> Result<String, EmpcError> {
    source_of(t, scalar)
}

/// The tables as Rust source: `static` arrays and a `pub static TABLES:
/// kestrel_empc::SliceTables<'static, S>`.
pub fn rust_source(t: &OwnedTables<f64>, scalar: ExportScalar) -> Result<String, EmpcError> {
    source_of(t, scalar)
}

/// [`rust_source`] and [`rust_source_wide`]: the tables in index type `X`.
fn source_of<X: ExportIndex>(
    t: &OwnedTables<f64, X>,
    scalar: ExportScalar,
) -> Result<String, EmpcError> {
    check_tables(t)?;
    let ty = scalar.rust_type();
    let ix = X::NAME;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}({} parameters, {} outputs,{}{} nodes, {} laws, {} bytes). Do not edit.",
        X::SOURCE_HEADER,
        t.n_params,
        t.n_outputs,
        X::HEADER_BREAK,
        t.nodes.len(),
        t.laws.len() / t.n_outputs.max(1),
        t.bytes(scalar.bytes())
    );
    let _ = writeln!(s, "{}", X::NODES_DOC);
    let mut nb = String::new();
    for (i, n) in t.nodes.iter().enumerate() {
        if i % 6 == 0 {
            nb.push_str("\n    ");
        }
        let _ = write!(nb, "[{}, {}, {}, {}], ", n[0], n[1], n[2], n[3]);
    }
    let _ = writeln!(
        s,
        "pub static NODES: [[{ix}; 4]; {}] = [{nb}\n];",
        t.nodes.len()
    );
    write_common(&mut s, &t.rows, &t.hull, &t.theta_lb, &t.theta_ub, scalar)?;
    let laws: Vec<String> = t.laws.iter().map(|v| v.to_string()).collect();
    let _ = writeln!(s, "/// Laws: one row index per output.");
    let _ = writeln!(
        s,
        "pub static LAWS: [{ix}; {}] = [{}];",
        laws.len(),
        laws.join(", ")
    );
    write_bounds(&mut s, &t.bounds, ix);
    let _ = writeln!(s, "/// The tables for `kestrel_empc::evaluate`.");
    let tt = X::TABLES_TYPE;
    let _ = writeln!(
        s,
        "pub static TABLES: {tt}<'static, {ty}> = {tt} {{\n    n_params: {},\n    n_outputs: {},\n    root: {},\n    nodes: &NODES,\n    laws: &LAWS,\n    rows: &ROWS,\n    hull: &HULL,\n    theta_lb: &THETA_LB,\n    theta_ub: &THETA_UB,\n    bounds: &BOUNDS,\n}};",
        t.n_params, t.n_outputs, t.root
    );
    Ok(s)
}

/// Rows, explored set and parameter box (shared by both layouts).
fn write_common(
    s: &mut String,
    rows: &[f64],
    hull: &[f64],
    lb: &[f64],
    ub: &[f64],
    scalar: ExportScalar,
) -> Result<(), EmpcError> {
    let _ = writeln!(s, "/// Affine rows `gains, constant` shared by the laws.");
    write_numbers(s, "ROWS", rows, scalar)?;
    let _ = writeln!(s, "/// Explored set `a, b` (a'theta <= b).");
    write_numbers(s, "HULL", hull, scalar)?;
    let _ = writeln!(s, "/// Parameter box.");
    write_numbers(s, "THETA_LB", lb, scalar)?;
    write_numbers(s, "THETA_UB", ub, scalar)?;
    Ok(())
}

/// The compact layout ([`crate::build_compact`]) as Rust source: `static`
/// arrays `ROOTS` (one root child code per output), `NODES`
/// (`kestrel_empc::CompactNode`: `u8` rows, `u16` child codes), `ROWS`,
/// `HULL`, `THETA_LB`, `THETA_UB`, `BOUNDS` (`u16` row indices) and
/// `pub static TABLES: kestrel_empc::ForestTables<'static, S>`, to evaluate
/// with [`crate::evaluate`] in `no_std` firmware. The tables are checked
/// first ([`check_compact_tables`]).
pub fn rust_source_compact(
    t: &CompactTables<f64>,
    scalar: ExportScalar,
) -> Result<String, EmpcError> {
    check_compact_tables(t)?;
    let ty = scalar.rust_type();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// Explicit MPC tables, compact layout (one tree per output), generated by\n// `kestrel empc export --compact` ({} parameters, {} outputs, {} nodes, {} rows,\n// {} bytes). Do not edit.",
        t.n_params,
        t.n_outputs,
        t.nodes.len(),
        t.rows.len() / (t.n_params + 1),
        t.bytes(scalar.bytes())
    );
    let roots: Vec<String> = t.roots.iter().map(|v| v.to_string()).collect();
    let _ = writeln!(
        s,
        "/// Root child code of every output's tree (0x8000 | row: a leaf)."
    );
    let _ = writeln!(
        s,
        "pub static ROOTS: [u16; {}] = [{}];",
        roots.len(),
        roots.join(", ")
    );
    let _ = writeln!(
        s,
        "/// Tree nodes: rows `a`, `b` (255: none) and the children if `a(theta) <= b(theta)`, otherwise."
    );
    let mut nb = String::new();
    for n in &t.nodes {
        nb.push_str("\n    ");
        let _ = write!(
            nb,
            "kestrel_empc::CompactNode {{ rows: [{}, {}], children: [{}, {}] }},",
            n.rows[0], n.rows[1], n.children[0], n.children[1]
        );
    }
    let _ = writeln!(
        s,
        "pub static NODES: [kestrel_empc::CompactNode; {}] = [{nb}\n];",
        t.nodes.len()
    );
    write_common(&mut s, &t.rows, &t.hull, &t.theta_lb, &t.theta_ub, scalar)?;
    write_bounds(&mut s, &t.bounds, "u16");
    let _ = writeln!(s, "/// The tables for `kestrel_empc::evaluate`.");
    let _ = writeln!(
        s,
        "pub static TABLES: kestrel_empc::ForestTables<'static, {ty}> = kestrel_empc::ForestTables {{\n    n_params: {},\n    n_outputs: {},\n    roots: &ROOTS,\n    nodes: &NODES,\n    rows: &ROWS,\n    hull: &HULL,\n    theta_lb: &THETA_LB,\n    theta_ub: &THETA_UB,\n    bounds: &BOUNDS,\n}};",
        t.n_params, t.n_outputs
    );
    Ok(s)
}

/// Reads a problem file (convenience for the CLI and tests).
pub fn read_problem(path: &std::path::Path) -> Result<MpqpProblem, EmpcError> {
    Ok(MpqpProblem::read(path)?)
}
