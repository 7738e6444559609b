//! The index types of the single-tree formats as the solution file and the
//! Rust source write them (`u16`: [`TableFormat::Narrow`], `u32`:
//! [`TableFormat::Wide`]).

use crate::eval::TreeIndex;
use crate::export::format::TableFormat;

/// What the solution file and the Rust source need of an index type.
pub(super) trait ExportIndex: TreeIndex + std::fmt::Display {
    /// The single-tree format with this index type.
    const FORMAT: TableFormat;
    /// The largest value in the solution file.
    const MAX: u32;
    /// A value at most [`ExportIndex::MAX`].
    fn from_u32(v: u32) -> Self;
}

impl ExportIndex for u16 {
    const FORMAT: TableFormat = TableFormat::Narrow;
    const MAX: u32 = 65535;
    fn from_u32(v: u32) -> u16 {
        v as u16
    }
}

impl ExportIndex for u32 {
    const FORMAT: TableFormat = TableFormat::Wide;
    const MAX: u32 = u32::MAX;
    fn from_u32(v: u32) -> u32 {
        v
    }
}
