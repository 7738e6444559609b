//! The table's byte layout: [`Tree16Layout`] and the index markers.

/// Marks a child code as a leaf (the low 15 bits are the law index).
pub const LEAF: u16 = 0x8000;
/// "None" in a `u8` field: no row `b` (zero), the next node, no bound.
pub const NONE: u8 = 0xFF;
/// "None" in a `u16` field of the wide layout ([`Tree16Layout::wide`]).
pub const NONE16: u16 = 0xFFFF;

/// Counts and scale of a `Tree16` table (the generated constants).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tree16Layout {
    /// Parameters `P`.
    pub n_params: usize,
    /// Outputs `NU`.
    pub n_outputs: usize,
    /// Tree nodes.
    pub n_nodes: usize,
    /// Laws.
    pub n_laws: usize,
    /// Affine rows (at most 255 in the narrow layout, 65534 in the wide).
    pub n_rows: usize,
    /// The root child code (node 0, or a leaf).
    pub root: u16,
    /// Fraction bits `K` of every row's value (value = row / 2^K).
    pub scale: u8,
    /// The wide layout: row and law indices are `u16` ([`NONE16`] for
    /// none; nodes of 8 bytes: `a`, `b`, the `a <= b` child, the other
    /// child), for trees beyond 255 rows or laws (Ns = 2). The narrow one
    /// (`u8` indices, 5-byte nodes) is what the assembly walk reads.
    pub wide: bool,
}

impl Tree16Layout {
    /// Bytes per parameter entry.
    pub const PARAM_BYTES: usize = 5;
    /// Bytes per node of the narrow layout.
    pub const NODE_BYTES: usize = 5;
    /// Bytes per node: 5 narrow, 8 wide.
    pub const fn node_bytes(&self) -> usize {
        if self.wide { 8 } else { Self::NODE_BYTES }
    }
    /// Bytes per row or law index: 1 narrow, 2 wide.
    pub const fn index_bytes(&self) -> usize {
        if self.wide { 2 } else { 1 }
    }
    /// Bytes per row: `start`, the constant, `P` gains.
    pub const fn row_bytes(&self) -> usize {
        5 + 2 * self.n_params
    }
    /// Byte offset of the nodes.
    pub const fn nodes_at(&self) -> usize {
        Self::PARAM_BYTES * self.n_params
    }
    /// Byte offset of the laws.
    pub const fn laws_at(&self) -> usize {
        self.nodes_at() + self.node_bytes() * self.n_nodes
    }
    /// Byte offset of the output bounds.
    pub const fn bounds_at(&self) -> usize {
        self.laws_at() + self.index_bytes() * self.n_laws * self.n_outputs
    }
    /// Byte offset of the rows.
    pub const fn rows_at(&self) -> usize {
        self.bounds_at() + 2 * self.index_bytes() * self.n_outputs
    }
    /// Total bytes.
    pub const fn bytes(&self) -> usize {
        self.rows_at() + self.n_rows * self.row_bytes()
    }
    /// The byte offsets of the nodes, laws, bounds and rows and the total
    /// bytes, computed in `u32`: the run-time's figures, since a wide table
    /// may pass 64 KiB, where the AVR's 16-bit `usize` (and so
    /// [`Tree16Layout::bytes`] there) would overflow.
    pub const fn offsets(&self) -> [u32; 5] {
        let nodes = (Self::PARAM_BYTES as u32) * (self.n_params as u32);
        let laws = nodes + (self.node_bytes() as u32) * (self.n_nodes as u32);
        let bounds =
            laws + (self.index_bytes() as u32) * (self.n_laws as u32) * (self.n_outputs as u32);
        let rows = bounds + 2 * (self.index_bytes() as u32) * (self.n_outputs as u32);
        let total = rows + (self.n_rows as u32) * (self.row_bytes() as u32);
        [nodes, laws, bounds, rows, total]
    }
    /// [`Tree16Layout::offsets`], or `None` if a count or an offset does
    /// not fit in `u32` (where `offsets` would wrap): the check
    /// [`super::Tree16::new`] makes of a layout before it trusts its offsets.
    pub const fn checked_offsets(&self) -> Option<[u32; 5]> {
        const fn mul(a: Option<u32>, b: usize) -> Option<u32> {
            match a {
                Some(a) if b <= u32::MAX as usize => a.checked_mul(b as u32),
                _ => None,
            }
        }
        const fn add(a: Option<u32>, b: Option<u32>) -> Option<u32> {
            match (a, b) {
                (Some(a), Some(b)) => a.checked_add(b),
                _ => None,
            }
        }
        let index = Some(self.index_bytes() as u32);
        let nodes = mul(Some(Self::PARAM_BYTES as u32), self.n_params);
        let laws = add(nodes, mul(Some(self.node_bytes() as u32), self.n_nodes));
        let bounds = add(laws, mul(mul(index, self.n_laws), self.n_outputs));
        let rows = add(bounds, mul(mul(index, 2), self.n_outputs));
        let row_bytes = add(Some(5), mul(Some(2), self.n_params));
        let total = match row_bytes {
            Some(r) => add(rows, mul(Some(r), self.n_rows)),
            None => None,
        };
        match (nodes, laws, bounds, rows, total) {
            (Some(a), Some(b), Some(c), Some(d), Some(e)) => Some([a, b, c, d, e]),
            _ => None,
        }
    }
}
