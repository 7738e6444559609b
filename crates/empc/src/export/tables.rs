//! The table types every format is read into and written from
//! ([`ExportTables`]) and the entry points that take them:
//! [`read_tables`], [`check_tables`], [`rust_source`].

use crate::error::EmpcError;
use crate::export::format::TableFormat;
use crate::export::scalar::ExportScalar;
use crate::tree::{AnyTables, CompactTables, OwnedTables, WideTables};
use sealed::Sealed;

/// The per-type operations behind [`ExportTables`]; not implementable
/// outside this crate.
mod sealed {
    use crate::error::EmpcError;
    use crate::export::scalar::ExportScalar;
    use crate::export::{check, read, source};
    use crate::tree::{AnyTables, CompactTables, OwnedTables, WideTables};

    /// Reading, checking and the Rust source of one table type.
    pub trait Sealed: Sized {
        /// Reads the tables from a solution file, every index checked.
        fn read(text: &str) -> Result<Self, EmpcError>;
        /// Checks every index and the shapes.
        fn check(&self) -> Result<(), EmpcError>;
        /// The Rust source (checked first).
        fn source(&self, scalar: ExportScalar) -> Result<String, EmpcError>;
    }

    impl Sealed for OwnedTables<f64> {
        fn read(text: &str) -> Result<Self, EmpcError> {
            read::read_tree(text)
        }
        fn check(&self) -> Result<(), EmpcError> {
            check::check_tables(self)
        }
        fn source(&self, scalar: ExportScalar) -> Result<String, EmpcError> {
            source::tree_source(self, scalar)
        }
    }

    impl Sealed for WideTables<f64> {
        fn read(text: &str) -> Result<Self, EmpcError> {
            read::read_tree(text)
        }
        fn check(&self) -> Result<(), EmpcError> {
            check::check_tables(self)
        }
        fn source(&self, scalar: ExportScalar) -> Result<String, EmpcError> {
            source::tree_source(self, scalar)
        }
    }

    impl Sealed for AnyTables {
        fn read(text: &str) -> Result<Self, EmpcError> {
            read::read_any(text)
        }
        fn check(&self) -> Result<(), EmpcError> {
            match self {
                AnyTables::Narrow(t) => t.check(),
                AnyTables::Wide(t) => t.check(),
            }
        }
        fn source(&self, scalar: ExportScalar) -> Result<String, EmpcError> {
            match self {
                AnyTables::Narrow(t) => t.source(scalar),
                AnyTables::Wide(t) => t.source(scalar),
            }
        }
    }

    impl Sealed for CompactTables<f64> {
        fn read(text: &str) -> Result<Self, EmpcError> {
            read::read_compact(text)
        }
        fn check(&self) -> Result<(), EmpcError> {
            check::check_compact_tables(self)
        }
        fn source(&self, scalar: ExportScalar) -> Result<String, EmpcError> {
            source::compact_source(self, scalar)
        }
    }
}

/// Tables in one of the [`TableFormat`]s, in `f64`: what [`read_tables`]
/// reads, [`check_tables`] checks and [`rust_source`] writes.
///
/// | type | format |
/// |---|---|
/// | [`OwnedTables<f64>`] | [`TableFormat::Narrow`] |
/// | [`WideTables<f64>`] | [`TableFormat::Wide`] |
/// | [`AnyTables`] | either, as stored |
/// | [`CompactTables<f64>`] | [`TableFormat::Compact`] |
///
/// Sealed: implemented for these types only.
pub trait ExportTables: Sealed {
    /// The format of these tables.
    fn format(&self) -> TableFormat;
}

impl ExportTables for OwnedTables<f64> {
    fn format(&self) -> TableFormat {
        TableFormat::Narrow
    }
}

impl ExportTables for WideTables<f64> {
    fn format(&self) -> TableFormat {
        TableFormat::Wide
    }
}

impl ExportTables for AnyTables {
    fn format(&self) -> TableFormat {
        match self {
            AnyTables::Narrow(_) => TableFormat::Narrow,
            AnyTables::Wide(_) => TableFormat::Wide,
        }
    }
}

impl ExportTables for CompactTables<f64> {
    fn format(&self) -> TableFormat {
        TableFormat::Compact
    }
}

/// Reads the tables of type `T` from a solution file
/// ([`solution_json`](crate::export::solution_json)) and checks every
/// index ([`check_tables`]).
///
/// `OwnedTables<f64>` and `WideTables<f64>` read the single tree and
/// refuse the other index width; `AnyTables` reads the single tree in the
/// width it was written in; `CompactTables<f64>` reads `compact_tables`
/// (an error naming `--compact` if the file has none).
pub fn read_tables<T: ExportTables>(text: &str) -> Result<T, EmpcError> {
    T::read(text)
}

/// Checks that every index of the tables points inside its table (roots,
/// node rows and children, laws, output bounds), that children come after
/// their parent (no cycles), and the table shapes.
pub fn check_tables<T: ExportTables>(tables: &T) -> Result<(), EmpcError> {
    tables.check()
}

/// The tables as Rust source for `no_std` firmware: `static` arrays and a
/// `pub static TABLES` of the format's tables type
/// ([`TableFormat::rust_tables_type`]) with numbers of type `scalar`, to
/// evaluate with [`crate::evaluate`]. The tables are checked first
/// ([`check_tables`]).
///
/// - [`TableFormat::Narrow`] and [`TableFormat::Wide`]: `NODES: [[X; 4];
///   _]`, `ROWS`, `HULL`, `THETA_LB`, `THETA_UB`, `LAWS: [X; _]`, `BOUNDS:
///   [[X; 2]; k]` with `X` = [`TableFormat::index_type`].
/// - [`TableFormat::Compact`]: `ROOTS: [u16; k]` (one root child code per
///   output), `NODES: [kestrel_empc::CompactNode; _]`, `ROWS`, `HULL`,
///   `THETA_LB`, `THETA_UB`, `BOUNDS: [[u16; 2]; k]`.
pub fn rust_source<T: ExportTables>(tables: &T, scalar: ExportScalar) -> Result<String, EmpcError> {
    tables.source(scalar)
}
