//! The table formats ([`TableFormat`]): tree shape and index width.

/// The wire format of a set of explicit MPC tables: the tree shape and the
/// index width. Each is written to the solution file (`kestrel.empc.v1`)
/// and as Rust source (in an [`ExportScalar`](crate::export::ExportScalar)),
/// and read back from the solution file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TableFormat {
    /// One search tree, `u16` indices ([`OwnedTables`](crate::tree::OwnedTables),
    /// [`SliceTables`](crate::SliceTables)): the solution file's `tables`.
    Narrow,
    /// One search tree, `u32` indices ([`WideTables`](crate::tree::WideTables),
    /// [`WideSliceTables`](crate::WideSliceTables)): the solution file's
    /// `tables` with `index: "u32"`.
    Wide,
    /// One tree per output, `u8` row and `u16` child indices
    /// ([`CompactTables`](crate::tree::CompactTables),
    /// [`ForestTables`](crate::ForestTables)): the solution file's
    /// `compact_tables`.
    Compact,
}

impl TableFormat {
    /// The Rust type of the indices (of the child codes in the compact
    /// format, whose node rows are `u8`).
    pub fn index_type(self) -> &'static str {
        match self {
            TableFormat::Narrow | TableFormat::Compact => "u16",
            TableFormat::Wide => "u32",
        }
    }

    /// The key of the tables object in the solution file.
    pub fn json_key(self) -> &'static str {
        match self {
            TableFormat::Narrow | TableFormat::Wide => "tables",
            TableFormat::Compact => "compact_tables",
        }
    }

    /// The tables type of the Rust source's `TABLES`.
    pub fn rust_tables_type(self) -> &'static str {
        match self {
            TableFormat::Narrow => "kestrel_empc::SliceTables",
            TableFormat::Wide => "kestrel_empc::eval::WideSliceTables",
            TableFormat::Compact => "kestrel_empc::ForestTables",
        }
    }
}
