//! The child codes and row indices of the tables: `u16` (the default
//! layout) or `u32` (the wide layout).

/// Marks a child code as a leaf; the low 15 bits are then the law index.
pub const LEAF: u16 = 0x8000;
/// "No row" in the output-bound table.
pub const NO_ROW: u16 = 0xFFFF;

/// Marks a child code of the wide layout (index type `u32`) as a leaf;
/// the low 31 bits are then the law index.
pub const WIDE_LEAF: u32 = 0x8000_0000;
/// "No row" in the wide layout.
pub const WIDE_NO_ROW: u32 = u32::MAX;

/// The index type of a table layout: `u16` (the default, flash-ready: at
/// most 32767 nodes and laws, 65534 rows) or `u32` (the wide layout for
/// trees beyond the `u16` codes, with [`WIDE_LEAF`] and [`WIDE_NO_ROW`]).
pub trait TreeIndex: Copy + Eq + core::fmt::Debug {
    /// The leaf bit of a child code.
    const LEAF: Self;
    /// "No row".
    const NO_ROW: Self;
    /// The value as an index.
    fn index(self) -> usize;
    /// Whether the child code is a leaf.
    fn is_leaf(self) -> bool;
    /// The child code without its leaf bit.
    fn payload(self) -> Self;
}

impl TreeIndex for u16 {
    const LEAF: u16 = LEAF;
    const NO_ROW: u16 = NO_ROW;
    #[inline]
    fn index(self) -> usize {
        self as usize
    }
    #[inline]
    fn is_leaf(self) -> bool {
        self & LEAF != 0
    }
    #[inline]
    fn payload(self) -> u16 {
        self & !LEAF
    }
}

impl TreeIndex for u32 {
    const LEAF: u32 = WIDE_LEAF;
    const NO_ROW: u32 = WIDE_NO_ROW;
    /// On a 16-bit target an index beyond `usize` becomes `usize::MAX`,
    /// which no table holds: the accessors return `None`, never a
    /// truncated index.
    #[inline]
    fn index(self) -> usize {
        usize::try_from(self).unwrap_or(usize::MAX)
    }
    #[inline]
    fn is_leaf(self) -> bool {
        self & WIDE_LEAF != 0
    }
    #[inline]
    fn payload(self) -> u32 {
        self & !WIDE_LEAF
    }
}
