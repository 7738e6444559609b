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
//!
//! One file per operation: writing (`write`) and reading (`read`) the
//! solution file, checking tables (`check`), the Rust source (`source`),
//! the number type (`scalar`) and the index types (`index`).

mod check;
mod index;
mod read;
mod scalar;
mod source;
mod write;

pub use check::{check_compact_tables, check_tables, check_wide_tables};
pub use read::{
    any_tables_from_json, compact_tables_from_json, has_compact_tables, read_problem,
    tables_from_json,
};
pub use scalar::ExportScalar;
pub use source::{rust_source, rust_source_any, rust_source_compact, rust_source_wide};
pub use write::{FORMAT, solution_json, solution_json_any, solution_json_with_compact};
