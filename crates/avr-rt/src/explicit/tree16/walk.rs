//! The period in Rust (the host's path and the assembly's reference):
//! quantisation of `theta` onto the box, the value cache's period stamp,
//! the row values and the walk from the root to the leaf's clamped outputs.

use super::law::{Empc16Law, Raw};
use super::layout::{LEAF, NONE, NONE16};
use super::table::{read_bytes, row_value};
use crate::output::RtScalar;
use crate::progmem::TableRead;
use crate::shift::round_shift32;
use kestrel_core::Error;

impl<S: RtScalar, T: TableRead, const P: usize, const NU: usize, const R: usize>
    Empc16Law<S, T, P, NU, R>
{
    /// `theta` in the table's `i16` units, projected onto the box; whether
    /// it was outside. [`Error::NonFinite`] for a non-finite entry.
    pub fn quantize(&self, theta: &[S; P]) -> Result<([i16; P], bool), Error> {
        let mut bits = [0i32; P];
        for (b, t) in bits.iter_mut().zip(theta) {
            *b = t.to_q16().ok_or(Error::NonFinite)?;
        }
        Ok(self.quantize_bits(&bits))
    }

    /// [`Empc16Law::quantize`] from the Q15.16 bits (the Rust form of the
    /// assembly's first part).
    pub(super) fn quantize_bits(&self, bits: &[i32; P]) -> ([i16; P], bool) {
        let mut q = [0i16; P];
        let mut outside = false;
        for ((qj, &b), &(s, lb, ub)) in q.iter_mut().zip(bits).zip(&self.params) {
            // `new` checked 0 <= s <= 31.
            let v = round_shift32(b, s as u8);
            *qj = if v < lb as i32 {
                outside = true;
                lb
            } else if v > ub as i32 {
                outside = true;
                ub
            } else {
                v as i16
            };
        }
        (q, outside)
    }

    /// A new period stamp for the value cache (1 to 255: 0 is never used,
    /// so a fresh cache is empty). A stamp comes back after 255 periods:
    /// each period clears `ceil(R / 255)` entries in turn, so every entry
    /// is cleared within 255 periods of its writing and an old value is
    /// never taken for this period's (the same work every period, instead
    /// of clearing the whole cache when the stamp wraps).
    pub(super) fn next_period(&mut self) {
        self.period = self.period.wrapping_add(1);
        if self.period == 0 {
            self.period = 1;
        }
        for _ in 0..R.div_ceil(255) {
            if let Some(e) = self.scratch.cache.get_mut(self.sweep) {
                e[0] = 0;
            }
            self.sweep = if self.sweep + 1 >= R {
                0
            } else {
                self.sweep + 1
            };
        }
    }

    /// The value of row `r` at the scratch's `theta` (cached for the
    /// period); `None` for a row outside the table.
    fn value(&mut self, r: u16) -> Option<i32> {
        let l = &self.tree.layout;
        if r as usize >= l.n_rows {
            return None;
        }
        let wide = l.wide;
        // Narrow: `new` checked n_rows <= R; wide: R is a power of two.
        let i = if wide {
            r as usize & (R - 1)
        } else {
            r as usize
        };
        let period = self.period;
        let e = self.scratch.cache.get(i)?;
        if e[0] == period && (!wide || self.scratch.tags.get(i) == Some(&r)) {
            return Some(i32::from_le_bytes([e[1], e[2], e[3], e[4]]));
        }
        let at = if wide {
            self.at[3] + u32::from(r) * u32::from(self.row_bytes)
        } else {
            // `new` checked that every row's offset fits in 16 bits: a
            // 16-bit product (no 32-bit multiply call on the AVR).
            self.at[3] + u32::from(r.wrapping_mul(self.row_bytes))
        };
        let v = row_value(&self.tree.table, at, &self.scratch.theta)?;
        let b = v.to_le_bytes();
        *self.scratch.cache.get_mut(i)? = [period, b[0], b[1], b[2], b[3]];
        if let Some(t) = self.scratch.tags.get_mut(i) {
            *t = r;
        }
        Some(v)
    }

    /// Node `code`: rows `a`, `b`, the `a <= b` child and the other child
    /// as `u16` ([`NONE16`] for none), from either layout.
    fn node(&self, code: u16) -> Option<[u16; 4]> {
        if self.tree.layout.wide {
            let n: [u8; 8] = read_bytes(&self.tree.table, self.at[0] + 8 * u32::from(code))?;
            Some([
                u16::from_le_bytes([n[0], n[1]]),
                u16::from_le_bytes([n[2], n[3]]),
                u16::from_le_bytes([n[4], n[5]]),
                u16::from_le_bytes([n[6], n[7]]),
            ])
        } else {
            // `new` checked that the nodes fit in 64 KiB: a 16-bit product.
            let n: [u8; 5] = read_bytes(
                &self.tree.table,
                self.at[0] + u32::from(code.wrapping_mul(5)),
            )?;
            let w = |b: u8| if b == NONE { NONE16 } else { u16::from(b) };
            Some([w(n[0]), w(n[1]), w(n[2]), u16::from_le_bytes([n[3], n[4]])])
        }
    }

    /// Index `k` (a row or law index, [`NONE16`] for none) of the index
    /// array at table offset `at`, in the layout's width.
    fn index(&self, at: u32, k: u32) -> Option<u16> {
        if self.tree.layout.wide {
            read_bytes::<_, 2>(&self.tree.table, at + 2 * k).map(u16::from_le_bytes)
        } else {
            read_bytes::<_, 1>(&self.tree.table, at + k)
                .map(|[b]| if b == NONE { NONE16 } else { u16::from(b) })
        }
    }

    /// Evaluates the tree at a quantised `theta` (in the box): the outputs
    /// in units of `2^-K`, the law, and the nodes visited.
    /// [`Error::OutOfRange`] for a corrupted table (a row, law or node
    /// index out of range, a right child that does not come after its node).
    pub fn evaluate_raw(&mut self, theta: &[i16; P]) -> Result<Raw<NU>, Error> {
        self.scratch.theta = *theta;
        self.next_period();
        #[cfg(target_arch = "avr")]
        if let Some(r) = self.walk_asm(None, 0) {
            return r;
        }
        self.walk().ok_or(Error::OutOfRange)
    }

    /// The walk at the scratch's `theta` in Rust (the period is set).
    pub(super) fn walk(&mut self) -> Option<Raw<NU>> {
        let mut code = self.tree.layout.root;
        let mut steps: u16 = 0;
        let limit = self.tree.layout.n_nodes;
        while code & LEAF == 0 {
            if code as usize >= limit {
                return None;
            }
            let [ra, rb, left, right] = self.node(code)?;
            steps = steps.saturating_add(1);
            let a = self.value(ra)?;
            let b = if rb == NONE16 { 0 } else { self.value(rb)? };
            code = if a <= b {
                if left == NONE16 {
                    code + 1
                } else {
                    LEAF | (left & !LEAF)
                }
            } else {
                // Children come after their node (preorder): the walk ends.
                if right & LEAF == 0 && right <= code {
                    return None;
                }
                right
            };
        }
        let law = code & !LEAF;
        if law as usize >= self.tree.layout.n_laws {
            return None;
        }
        let mut z = [0i32; NU];
        for (o, zo) in z.iter_mut().enumerate() {
            let r = self.index(self.at[1], (NU * law as usize + o) as u32)?;
            let lo = self.index(self.at[2], 2 * o as u32)?;
            let hi = self.index(self.at[2], 2 * o as u32 + 1)?;
            let lo = if lo != NONE16 {
                Some(self.value(lo)?)
            } else {
                None
            };
            let hi = if hi != NONE16 {
                Some(self.value(hi)?)
            } else {
                None
            };
            let mut v = self.value(r)?;
            if let Some(lo) = lo {
                v = v.max(lo);
            }
            if let Some(hi) = hi {
                v = v.min(hi);
            }
            *zo = v;
        }
        Some(Raw { z, law, steps })
    }
}
