//! Reading the solution file: the tables of every format, every index
//! checked (`check`).

use crate::error::EmpcError;
use crate::eval::CompactNode;
use crate::export::check::{check_compact_tables, check_tables};
use crate::export::format::TableFormat;
use crate::export::index::ExportIndex;
use crate::export::write::FORMAT;
use crate::tree::{AnyTables, CompactTables, OwnedTables};
use kestrel_core::formats::FormatError;
use kestrel_core::formats::json::{self, Object};
use serde_json::Value;

/// Index rows of `width` `u16` entries.
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

/// The keys the tree readers use; the rest of a solution file (its region
/// list above all, most of a large file) is checked as JSON, never built.
const TREE_KEYS: &[&str] = &["format", "p", "outputs", "tables"];

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

/// The entries all layouts store alike, the output bounds checked against `k`.
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

/// Reads the single tree of a solution file in index type `X`
/// ([`TableFormat::Narrow`] or [`TableFormat::Wide`]) and checks every
/// index; an error if the file holds the other index width.
pub(super) fn read_tree<X: ExportIndex>(text: &str) -> Result<OwnedTables<f64, X>, EmpcError> {
    let obj = json::parse_object_keys(text, TREE_KEYS)?;
    let (p, k) = read_sizes(&obj)?;
    let t = tables_object(&obj, "tables", "written by `kestrel empc solve`")?;
    let found = tree_format(t)?;
    if found != X::FORMAT {
        let (what, ty) = match found {
            TableFormat::Wide => ("wide (u32)", "WideTables"),
            TableFormat::Narrow | TableFormat::Compact => ("u16", "OwnedTables"),
        };
        return Err(FormatError::invalid(
            "tables.index",
            format!("these are {what} tables: read them as {ty} or AnyTables"),
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

/// The format of the tables object: `index: "u32"` wide, absent or
/// `"u16"` narrow.
fn tree_format(t: &Object) -> Result<TableFormat, EmpcError> {
    match t.get("index") {
        None => Ok(TableFormat::Narrow),
        Some(v) => match v.as_str() {
            Some("u16") => Ok(TableFormat::Narrow),
            Some("u32") => Ok(TableFormat::Wide),
            _ => Err(FormatError::invalid("tables.index", "expected \"u16\" or \"u32\"").into()),
        },
    }
}

/// Reads the single tree of a solution file in the index width it was
/// written in (`tables.index` `"u32"`: wide, else narrow) and checks every index.
pub(super) fn read_any(text: &str) -> Result<AnyTables, EmpcError> {
    let obj = json::parse_object_keys(text, TREE_KEYS)?;
    let (p, k) = read_sizes(&obj)?;
    let t = tables_object(&obj, "tables", "written by `kestrel empc solve`")?;
    Ok(match tree_format(t)? {
        TableFormat::Wide => AnyTables::Wide(read_tables(t, p, k)?),
        TableFormat::Narrow | TableFormat::Compact => AnyTables::Narrow(read_tables(t, p, k)?),
    })
}

/// The formats a solution file holds: its single tree's
/// ([`TableFormat::Narrow`] or [`TableFormat::Wide`]), then
/// [`TableFormat::Compact`] if it has `compact_tables` (written by `kestrel
/// empc solve --compact`).
pub fn table_formats(text: &str) -> Result<Vec<TableFormat>, EmpcError> {
    let obj = json::parse_object_keys(text, &["format", "tables", "compact_tables"])?;
    json::check_format(&obj, FORMAT)?;
    let mut out = Vec::with_capacity(2);
    if let Some(t) = obj.get("tables").and_then(Value::as_object) {
        out.push(tree_format(t)?);
    }
    if obj.contains_key("compact_tables") {
        out.push(TableFormat::Compact);
    }
    Ok(out)
}

/// Reads the compact format of a solution file (`compact_tables`) and
/// checks every index (`check_compact_tables`).
pub(super) fn read_compact(text: &str) -> Result<CompactTables<f64>, EmpcError> {
    let obj = json::parse_object_keys(text, &["format", "p", "outputs", "compact_tables"])?;
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
