//! The table formats: the solution file (`kestrel.empc.v1`) and the Rust
//! table export.
//!
//! One family ([`TableFormat`]) over the tree shape and index width:
//! [`TableFormat::Narrow`] (one tree, `u16`), [`TableFormat::Wide`] (one
//! tree, `u32`) and [`TableFormat::Compact`] (one tree per output). Each
//! table type ([`ExportTables`]) goes through the same entry points:
//!
//! | operation | entry point |
//! |---|---|
//! | write the solution file | [`solution_json`] ([`SolutionTables`]) |
//! | which formats a file holds | [`table_formats`] |
//! | read back, every index checked | [`read_tables`] |
//! | check tables | [`check_tables`] |
//! | Rust source in an [`ExportScalar`] | [`rust_source`] |
//!
//! The solution file is the `kestrel.empc.v1` summary of `shared/FORMATS.md`
//! (`regions`, `distinct_laws`, `solve_seconds`, `tree {depth, nodes, bytes}`,
//! optional `region_list`) plus what evaluation needs, under added keys:
//! `n`, `p`, `outputs` and `tables` = `{root, nodes: [[row_a, row_b, le, gt]],
//! laws: [[row..]], rows: [[gain.., const]],
//! hull: [[a.., b]], theta_lb, theta_ub, bounds: [[lo, hi]]}` with the
//! encoding of [`crate::eval`] (`tree.bytes` counts these tables in f32).
//! Trees beyond the `u16` codes ([`crate::tree::build_any`]) are written
//! in the wide format: the same keys with `u32` indices
//! ([`crate::eval::WIDE_LEAF`] child codes, [`crate::eval::WIDE_NO_ROW`]) and `tables.index = "u32"` (absent or
//! `"u16"`: the `u16` format). The compact format adds `tree_compact` and
//! `compact_tables` ([`SolutionTables::with_compact`]).
//!
//! ```
//! use kestrel_empc::export::{self, ExportScalar, SolutionTables, TableFormat};
//! use kestrel_empc::{AnyTables, CompactTables, Settings, TreeSettings};
//! use kestrel_empc::{build_compact, build_controller, solve};
//! # use kestrel_core::formats::MpqpProblem;
//! # let problem = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
//! #   "H": [[1]], "F": [[1]], "G": [[1], [-1]], "W": [1, 1], "E": [[0], [0]],
//! #   "theta_lb": [-2], "theta_ub": [2]}"#).unwrap();
//! let solution = solve(&problem, &Settings::default()).unwrap();
//! let settings = TreeSettings::default();
//! let tree = build_controller(&problem, &solution, &settings).unwrap();
//! let compact = build_compact(&problem, &solution, &settings).unwrap();
//!
//! // The solution file with both formats, and each read back.
//! let text = export::solution_json(&solution, SolutionTables::from(&tree).with_compact(&compact), false);
//! assert_eq!(export::table_formats(&text).unwrap(), [TableFormat::Narrow, TableFormat::Compact]);
//! let any: AnyTables = export::read_tables(&text).unwrap();
//! assert_eq!(any, AnyTables::Narrow(tree.tables.clone()));
//! let back: CompactTables<f64> = export::read_tables(&text).unwrap();
//! assert_eq!(back, compact.tables);
//!
//! // Rust source for the firmware, in any format and number type.
//! let src = export::rust_source(&back, ExportScalar::Q16).unwrap();
//! assert!(src.contains("kestrel_empc::ForestTables<'static, kestrel_core::Q16>"));
//! ```
//!
//! One file per operation: the formats (`format`), writing (`write`) and
//! reading (`read`) the solution file, checking tables (`check`), the Rust
//! source (`source`), the table types and entry points (`tables`), the
//! number type (`scalar`) and the index types (`index`).

mod check;
mod format;
mod index;
mod read;
mod scalar;
mod source;
mod tables;
mod write;

pub use format::TableFormat;
pub use read::table_formats;
pub use scalar::ExportScalar;
pub(crate) use scalar::literal;
pub use tables::{ExportTables, check_tables, read_tables, rust_source};
pub use write::{FORMAT, SolutionTables, solution_json};
