//! The tables as Rust source (`static` arrays and a `TABLES` to evaluate
//! in `no_std` firmware).

use crate::error::EmpcError;
use crate::eval::TreeIndex;
use crate::export::check::{check_compact_tables, check_tables};
use crate::export::index::ExportIndex;
use crate::export::scalar::ExportScalar;
use crate::tree::{AnyTables, CompactTables, OwnedTables, WideTables};
use std::fmt::Write as _;

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
