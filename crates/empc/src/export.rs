//! The solution file (`kestrel.empc.v1`) and the Rust table export.
//!
//! The solution file is the `kestrel.empc.v1` summary of `shared/FORMATS.md`
//! (`regions`, `distinct_laws`, `solve_seconds`, `tree {depth, nodes, bytes}`,
//! optional `region_list`) plus what evaluation needs, under added keys:
//! `n`, `p`, `outputs` and `tables` = `{root, nodes: [[row_a, row_b, le, gt]],
//! laws: [[row..]], rows: [[gain.., const]],
//! hull: [[a.., b]], theta_lb, theta_ub, bounds: [[lo, hi]]}` with the
//! encoding of [`crate::eval`] (`tree.bytes` counts these tables in f32).
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::error::EmpcError;
use crate::eval::{LEAF, NO_ROW};
use crate::mpqp::MpqpSolution;
use crate::tree::{CompactController, CompactTables, ExplicitController, OwnedTables};
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
}

impl ExportScalar {
    /// Bytes per number.
    pub fn bytes(self) -> usize {
        4
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
    json::to_pretty_string(&solution_object(solution, controller, include_regions))
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
    let mut o = solution_object(solution, controller, include_regions);
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
    controller: &ExplicitController,
    include_regions: bool,
) -> Object {
    let t = &controller.tables;
    let w = t.n_params + 1;
    let mut o = Object::new();
    o.insert("format".into(), FORMAT.into());
    o.insert("regions".into(), solution.regions.len().into());
    o.insert(
        "distinct_laws".into(),
        controller.stats.distinct_laws.into(),
    );
    o.insert("solve_seconds".into(), json!(solution.stats.solve_seconds));
    o.insert(
        "tree".into(),
        json!({"depth": controller.stats.depth, "nodes": controller.stats.nodes,
               "bytes": t.bytes(4)}),
    );
    o.insert("n".into(), solution.n.into());
    o.insert("p".into(), solution.p.into());
    o.insert("outputs".into(), t.n_outputs.into());
    let s = &solution.stats;
    o.insert(
        "stats".into(),
        json!({"active_sets_tested": s.active_sets_tested, "discarded": s.discarded,
               "fallback_qps": s.fallback_qps, "lps": s.lps, "duplicate_rows": s.duplicate_rows,
               "distinct_rows": controller.stats.distinct_rows,
               "hyperplanes": controller.stats.hyperplanes,
               "ambiguous_leaves": controller.stats.ambiguous_leaves,
               "tree_build_seconds": controller.stats.build_seconds}),
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
    o.insert(
        "tables".into(),
        json!({
            "root": t.root,
            "nodes": t.nodes,
            "laws": Value::Array(t.laws.chunks(t.n_outputs.max(1)).map(|r| json!(r)).collect()),
            "rows": rows_value(&t.rows, w),
            "hull": rows_value(&t.hull, w),
            "theta_lb": t.theta_lb,
            "theta_ub": t.theta_ub,
            "bounds": t.bounds,
        }),
    );
    o
}

fn index_rows(v: &Value, key: &str, width: usize) -> Result<Vec<Vec<u16>>, FormatError> {
    let m = json::matrix_value(v, key, None, Some(width))?;
    let mut out = Vec::with_capacity(m.nrows());
    for i in 0..m.nrows() {
        let mut r = Vec::with_capacity(width);
        for j in 0..width {
            let x = m[(i, j)];
            if !(0.0..=65535.0).contains(&x) || x.fract() != 0.0 {
                return Err(FormatError::invalid(
                    format!("{key}[{i}][{j}]"),
                    format!("expected an integer index in 0..=65535, found {x}"),
                ));
            }
            r.push(x as u16);
        }
        out.push(r);
    }
    Ok(out)
}

/// Reads the tables of a solution file and checks every index.
pub fn tables_from_json(text: &str) -> Result<OwnedTables<f64>, EmpcError> {
    let obj = json::parse_object(text)?;
    json::check_format(&obj, FORMAT)?;
    let p = json::number(&obj, "p")?;
    let k = json::number(&obj, "outputs")?;
    if p < 1.0 || p.fract() != 0.0 || k < 1.0 || k.fract() != 0.0 || p > 1e4 || k > 1e4 {
        return Err(FormatError::invalid("p", "p and outputs must be positive integers").into());
    }
    let (p, k) = (p as usize, k as usize);
    let t = obj
        .get("tables")
        .and_then(Value::as_object)
        .ok_or_else(|| FormatError::MissingKey {
            key: "tables".into(),
            expected: "an object with the evaluation tables (written by `kestrel empc solve`)"
                .into(),
        })?;
    let w = p + 1;
    let root = json::number(t, "root")?;
    if !(0.0..=65535.0).contains(&root) || root.fract() != 0.0 {
        return Err(FormatError::invalid("tables.root", "expected an index in 0..=65535").into());
    }
    let get = |key: &str| {
        t.get(key).ok_or_else(|| FormatError::MissingKey {
            key: format!("tables.{key}"),
            expected: "an array".into(),
        })
    };
    let flat = |key: &str, width: usize| -> Result<Vec<f64>, FormatError> {
        let m = json::matrix_value(get(key)?, &format!("tables.{key}"), None, Some(width))?;
        Ok((0..m.nrows())
            .flat_map(|i| (0..width).map(move |j| (i, j)))
            .map(|(i, j)| m[(i, j)])
            .collect())
    };
    let nodes: Vec<[u16; 4]> = index_rows(get("nodes")?, "tables.nodes", 4)?
        .into_iter()
        .map(|r| [r[0], r[1], r[2], r[3]])
        .collect();
    let laws: Vec<u16> = index_rows(get("laws")?, "tables.laws", k)?
        .into_iter()
        .flatten()
        .collect();
    let rows = flat("rows", w)?;
    let hull = flat("hull", w)?;
    let theta_lb: Vec<f64> = json::vector(t, "theta_lb", Some(p))?
        .iter()
        .copied()
        .collect();
    let theta_ub: Vec<f64> = json::vector(t, "theta_ub", Some(p))?
        .iter()
        .copied()
        .collect();
    let bounds: Vec<[u16; 2]> = index_rows(get("bounds")?, "tables.bounds", 2)?
        .into_iter()
        .map(|r| [r[0], r[1]])
        .collect();
    if bounds.len() != k {
        return Err(FormatError::invalid("tables.bounds", format!("expected {k} rows")).into());
    }
    let tables = OwnedTables {
        n_params: p,
        n_outputs: k,
        root: root as u16,
        nodes,
        laws,
        rows,
        hull,
        theta_lb,
        theta_ub,
        bounds,
    };
    check_tables(&tables)?;
    Ok(tables)
}

/// Checks that every index of the tables points inside its table.
pub fn check_tables<S: Scalar>(t: &OwnedTables<S>) -> Result<(), EmpcError> {
    let w = t.n_params + 1;
    let nr = t.rows.len() / w;
    let nl = t.laws.len() / t.n_outputs.max(1);
    let bad = |what: String| Err(FormatError::invalid("tables", what).into());
    let child_ok = |c: u16| {
        if c & LEAF != 0 {
            ((c & !LEAF) as usize) < nl
        } else {
            (c as usize) < t.nodes.len()
        }
    };
    if !child_ok(t.root) {
        return bad(format!("root {} points outside the tables", t.root));
    }
    for (i, n) in t.nodes.iter().enumerate() {
        let row_ok = |r: u16| (r as usize) < nr;
        if !row_ok(n[0]) || !(n[1] == NO_ROW || row_ok(n[1])) || !child_ok(n[2]) || !child_ok(n[3])
        {
            return bad(format!("node {i} {n:?} points outside the tables"));
        }
        // Children come after their parent: no cycles.
        for c in [n[2], n[3]] {
            if c & LEAF == 0 && c as usize <= i {
                return bad(format!("node {i} has a child {c} that is not after it"));
            }
        }
    }
    if let Some(l) = t.laws.iter().find(|&&r| r as usize >= nr) {
        return bad(format!("a law uses row {l} of {nr}"));
    }
    for b in &t.bounds {
        for &r in b {
            if r != NO_ROW && r as usize >= nr {
                return bad(format!("an output bound uses row {r} of {nr}"));
            }
        }
    }
    if t.theta_lb.iter().zip(&t.theta_ub).any(|(l, u)| l > u) {
        return bad("theta_lb exceeds theta_ub".into());
    }
    Ok(())
}

/// The tables as Rust source: `static` arrays and a `pub static TABLES:
/// kestrel_empc::SliceTables<'static, S>`.
pub fn rust_source(t: &OwnedTables<f64>, scalar: ExportScalar) -> Result<String, EmpcError> {
    check_tables(t)?;
    let ty = match scalar {
        ExportScalar::F32 => "f32",
        ExportScalar::Q16 => "kestrel_core::Q16",
    };
    let num = |v: f64| -> Result<String, EmpcError> {
        match scalar {
            ExportScalar::F32 => {
                let f = v as f32;
                let s = format!("{f:?}");
                Ok(
                    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN")
                    {
                        s
                    } else {
                        format!("{s}.0")
                    },
                )
            }
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
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// Explicit MPC tables generated by `kestrel empc export` ({} parameters, {} outputs,\n// {} nodes, {} laws, {} bytes). Do not edit.",
        t.n_params,
        t.n_outputs,
        t.nodes.len(),
        t.laws.len() / t.n_outputs.max(1),
        t.bytes(scalar.bytes())
    );
    let arr = |s: &mut String, name: &str, v: &[f64]| -> Result<(), EmpcError> {
        let mut body = String::new();
        for (i, x) in v.iter().enumerate() {
            if i % 8 == 0 {
                body.push_str("\n    ");
            }
            body.push_str(&num(*x)?);
            body.push_str(", ");
        }
        let _ = writeln!(s, "pub static {name}: [{ty}; {}] = [{body}\n];", v.len());
        Ok(())
    };
    let _ = writeln!(
        s,
        "/// Tree nodes `[row a, row b, child if a(theta) <= b(theta), child otherwise]`."
    );
    let mut nb = String::new();
    for (i, n) in t.nodes.iter().enumerate() {
        if i % 6 == 0 {
            nb.push_str("\n    ");
        }
        let _ = write!(nb, "[{}, {}, {}, {}], ", n[0], n[1], n[2], n[3]);
    }
    let _ = writeln!(
        s,
        "pub static NODES: [[u16; 4]; {}] = [{nb}\n];",
        t.nodes.len()
    );
    let _ = writeln!(s, "/// Affine rows `gains, constant` shared by the laws.");
    arr(&mut s, "ROWS", &t.rows)?;
    let _ = writeln!(s, "/// Explored set `a, b` (a'theta <= b).");
    arr(&mut s, "HULL", &t.hull)?;
    let _ = writeln!(s, "/// Parameter box.");
    arr(&mut s, "THETA_LB", &t.theta_lb)?;
    arr(&mut s, "THETA_UB", &t.theta_ub)?;
    let laws: Vec<String> = t.laws.iter().map(|v| v.to_string()).collect();
    let _ = writeln!(s, "/// Laws: one row index per output.");
    let _ = writeln!(
        s,
        "pub static LAWS: [u16; {}] = [{}];",
        laws.len(),
        laws.join(", ")
    );
    let b: Vec<String> = t
        .bounds
        .iter()
        .map(|x| format!("[{}, {}]", x[0], x[1]))
        .collect();
    let _ = writeln!(
        s,
        "/// Output bounds: rows of the lower and upper bound (65535: none)."
    );
    let _ = writeln!(
        s,
        "pub static BOUNDS: [[u16; 2]; {}] = [{}];",
        b.len(),
        b.join(", ")
    );
    let _ = writeln!(s, "/// The tables for `kestrel_empc::evaluate`.");
    let _ = writeln!(
        s,
        "pub static TABLES: kestrel_empc::SliceTables<'static, {ty}> = kestrel_empc::SliceTables {{\n    n_params: {},\n    n_outputs: {},\n    root: {},\n    nodes: &NODES,\n    laws: &LAWS,\n    rows: &ROWS,\n    hull: &HULL,\n    theta_lb: &THETA_LB,\n    theta_ub: &THETA_UB,\n    bounds: &BOUNDS,\n}};",
        t.n_params, t.n_outputs, t.root
    );
    Ok(s)
}

/// Reads a problem file (convenience for the CLI and tests).
pub fn read_problem(path: &std::path::Path) -> Result<MpqpProblem, EmpcError> {
    Ok(MpqpProblem::read(path)?)
}
