//! Reading constant tables from program memory, including above 64 kB.
//!
//! The ATmega2560 has 256 kB of flash but 16-bit data pointers: `LPM` reaches
//! only the low 64 kB, and a Rust `&STATIC` taken on the AVR is a 16-bit
//! address, silently truncated for anything placed higher. Single objects
//! are also limited to 32 kB (`isize::MAX` on a 16-bit target).
//!
//! The design around that:
//!
//! - a table is a `static [u8; N]` (N < 32 kB) in flash; bigger data is split
//!   into several such chunks;
//! - its full 24-bit flash address is taken by the linker, not by Rust:
//!   [`far_table!`](crate::far_table) emits `ldi r, lo8(sym)` / `hi8(sym)` / `hh8(sym)`, whose
//!   relocations carry all 24 bits;
//! - bytes are read with `ELPM` after loading `RAMPZ` with the address's
//!   high byte ([`FarTable`]), so a table may sit anywhere in the 256 kB;
//! - values are little-endian; [`TableRead`] gives typed reads and works the
//!   same on a RAM slice, which is how the host tests and the host-side
//!   reference computations read the very same bytes.
//!
//! ```
//! use kestrel_avr_rt::progmem::{FarTable, TableRead};
//! static GAINS: [u8; 8] = kestrel_avr_rt::progmem::f32_bytes([0.5, -2.0]);
//! let t: FarTable = kestrel_avr_rt::far_table!(GAINS);
//! assert_eq!(t.read_f32(4), Some(-2.0));
//! assert_eq!(t.read_f32(8), None); // out of range is an error value, not a panic
//! ```

/// Typed little-endian reads from a constant table; every read is bounds-checked.
pub trait TableRead {
    /// Length in bytes.
    fn len_bytes(&self) -> u32;
    /// The table's 24-bit flash address, for assembly kernels that read it
    /// with `ELPM` themselves (`None`: not in flash, read through the trait).
    fn flash_address(&self) -> Option<u32> {
        None
    }
    /// Reads one byte; the caller has checked `offset < len_bytes()`.
    fn read_u8_unchecked(&self, offset: u32) -> u8;
    /// Reads `N` consecutive bytes; the caller has checked the range.
    fn read_array_unchecked<const N: usize>(&self, offset: u32) -> [u8; N] {
        let mut out = [0u8; N];
        for (i, b) in out.iter_mut().enumerate() {
            *b = self.read_u8_unchecked(offset + i as u32);
        }
        out
    }
    /// Reads `N` bytes at `offset`, or `None` if out of range.
    #[inline]
    fn read_array<const N: usize>(&self, offset: u32) -> Option<[u8; N]> {
        let end = offset.checked_add(N as u32)?;
        (end <= self.len_bytes()).then(|| self.read_array_unchecked(offset))
    }
    /// A byte.
    #[inline]
    fn read_u8(&self, offset: u32) -> Option<u8> {
        self.read_array::<1>(offset).map(|b| b[0])
    }
    /// A little-endian `u16`.
    #[inline]
    fn read_u16(&self, offset: u32) -> Option<u16> {
        self.read_array(offset).map(u16::from_le_bytes)
    }
    /// A little-endian `i32` (the raw bits of a [`kestrel_core::Fixed`]).
    #[inline]
    fn read_i32(&self, offset: u32) -> Option<i32> {
        self.read_array(offset).map(i32::from_le_bytes)
    }
    /// A little-endian `f32`.
    #[inline]
    fn read_f32(&self, offset: u32) -> Option<f32> {
        self.read_array(offset).map(f32::from_le_bytes)
    }
}

impl<T: TableRead + ?Sized> TableRead for &T {
    #[inline]
    fn len_bytes(&self) -> u32 {
        (**self).len_bytes()
    }
    #[inline]
    fn flash_address(&self) -> Option<u32> {
        (**self).flash_address()
    }
    #[inline]
    fn read_u8_unchecked(&self, offset: u32) -> u8 {
        (**self).read_u8_unchecked(offset)
    }
    #[inline]
    fn read_array_unchecked<const N: usize>(&self, offset: u32) -> [u8; N] {
        (**self).read_array_unchecked(offset)
    }
}

impl TableRead for [u8] {
    #[inline]
    fn len_bytes(&self) -> u32 {
        self.len() as u32
    }
    #[inline]
    fn read_u8_unchecked(&self, offset: u32) -> u8 {
        self.get(offset as usize).copied().unwrap_or(0)
    }
}

/// A table in program memory, addressed with 24 bits and read with `ELPM`
/// on the AVR; on other targets it wraps the static's bytes.
///
/// Build it with [`far_table!`](crate::far_table).
#[derive(Clone, Copy, Debug)]
pub struct FarTable {
    #[cfg(target_arch = "avr")]
    addr: u32,
    #[cfg(target_arch = "avr")]
    len: u32,
    #[cfg(not(target_arch = "avr"))]
    bytes: &'static [u8],
}

impl FarTable {
    /// A table at the 24-bit flash byte address `addr` with `len` bytes.
    ///
    /// # Safety
    /// `addr..addr + len` must be constant data in flash.
    #[cfg(target_arch = "avr")]
    pub const unsafe fn from_raw(addr: u32, len: u32) -> Self {
        FarTable { addr, len }
    }
    /// The 24-bit flash byte address.
    #[cfg(target_arch = "avr")]
    pub fn address(&self) -> u32 {
        self.addr
    }
    /// A table over bytes the host can read directly.
    #[cfg(not(target_arch = "avr"))]
    pub const fn from_slice(bytes: &'static [u8]) -> Self {
        FarTable { bytes }
    }
}

#[cfg(target_arch = "avr")]
impl TableRead for FarTable {
    #[inline]
    fn len_bytes(&self) -> u32 {
        self.len
    }
    #[inline]
    fn flash_address(&self) -> Option<u32> {
        Some(self.addr)
    }
    #[inline]
    fn read_u8_unchecked(&self, offset: u32) -> u8 {
        let a = self.addr.wrapping_add(offset);
        let b: u8;
        // SAFETY: reads one byte of flash; RAMPZ only affects ELPM/SPM on the ATmega2560.
        unsafe {
            core::arch::asm!(
                "out 0x3B, {hh}",
                "elpm {b}, Z",
                hh = in(reg) (a >> 16) as u8,
                b = out(reg) b,
                in("Z") a as u16,
                options(nostack, preserves_flags, readonly),
            );
        }
        b
    }
    #[inline]
    fn read_array_unchecked<const N: usize>(&self, offset: u32) -> [u8; N] {
        let a = self.addr.wrapping_add(offset);
        let mut out = [0u8; N];
        let mut z = a as u16;
        let mut hh = (a >> 16) as u8;
        for b in out.iter_mut() {
            // SAFETY: as above; `ELPM Z+` increments the whole RAMPZ:Z, so
            // reads may cross a 64 kB boundary; RAMPZ is read back afterwards.
            unsafe {
                core::arch::asm!(
                    "out 0x3B, {hh}",
                    "elpm {b}, Z+",
                    "in {hh}, 0x3B",
                    hh = inout(reg) hh,
                    b = out(reg) *b,
                    inout("Z") z,
                    options(nostack, preserves_flags, readonly),
                );
            }
        }
        out
    }
}

#[cfg(not(target_arch = "avr"))]
impl TableRead for FarTable {
    #[inline]
    fn len_bytes(&self) -> u32 {
        self.bytes.len() as u32
    }
    #[inline]
    fn read_u8_unchecked(&self, offset: u32) -> u8 {
        self.bytes.get(offset as usize).copied().unwrap_or(0)
    }
}

/// One table made of `N` flash chunks of `2^chunk_bits` bytes each (the
/// last may be shorter): data beyond the 32 kB limit of a single Rust
/// object, read at one offset as if contiguous (the chunks may sit
/// anywhere in flash). On the host the chunks are byte slices.
///
/// ```
/// use kestrel_avr_rt::progmem::{FarChunks, FarTable, TableRead};
/// static A: [u8; 4] = [1, 2, 3, 4];
/// static B: [u8; 2] = [5, 6];
/// let t = FarChunks::new([kestrel_avr_rt::far_table!(A), kestrel_avr_rt::far_table!(B)], 2).unwrap();
/// assert_eq!(t.len_bytes(), 6);
/// assert_eq!(t.read_array::<3>(2), Some([3, 4, 5])); // across the seam
/// assert_eq!(t.read_u8(6), None);
/// ```
#[derive(Clone, Copy, Debug)]
pub struct FarChunks<const N: usize> {
    chunks: [FarTable; N],
    bits: u8,
    len: u32,
}

impl<const N: usize> FarChunks<N> {
    /// The table; `None` unless every chunk but the last holds exactly
    /// `2^chunk_bits` bytes, the last at most that, and `chunk_bits < 24`.
    pub fn new(chunks: [FarTable; N], chunk_bits: u8) -> Option<Self> {
        if chunk_bits >= 24 || N == 0 {
            return None;
        }
        let size = 1u32 << chunk_bits;
        let mut len = 0u32;
        for (i, c) in chunks.iter().enumerate() {
            let l = c.len_bytes();
            if l > size || (i + 1 < N && l != size) {
                return None;
            }
            len += l;
        }
        Some(FarChunks {
            chunks,
            bits: chunk_bits,
            len,
        })
    }
}

impl<const N: usize> TableRead for FarChunks<N> {
    #[inline]
    fn len_bytes(&self) -> u32 {
        self.len
    }
    #[inline]
    fn read_u8_unchecked(&self, offset: u32) -> u8 {
        let c = (offset >> self.bits) as usize;
        let within = offset & ((1 << self.bits) - 1);
        self.chunks
            .get(c)
            .map_or(0, |t| t.read_u8_unchecked(within))
    }
    #[inline]
    fn read_array_unchecked<const M: usize>(&self, offset: u32) -> [u8; M] {
        let c = (offset >> self.bits) as usize;
        let within = offset & ((1 << self.bits) - 1);
        match self.chunks.get(c) {
            // Inside one chunk: that chunk's (ELPM Z+) reads.
            Some(t) if within + M as u32 <= t.len_bytes() => t.read_array_unchecked(within),
            _ => {
                let mut out = [0u8; M];
                for (i, b) in out.iter_mut().enumerate() {
                    *b = self.read_u8_unchecked(offset + i as u32);
                }
                out
            }
        }
    }
}

/// A [`FarTable`] over a `static NAME: [u8; N]`, with the full 24-bit flash
/// address on the AVR (taken through the linker's `lo8`/`hi8`/`hh8`
/// relocations, never through a truncated 16-bit Rust pointer).
///
/// On the AVR the static must live in flash: declare it with
/// `#[unsafe(link_section = ".text.kestrel_tables")]` (anywhere in the
/// 256 kB, read with `ELPM`) or `".progmem.data"` (low 64 kB).
#[macro_export]
macro_rules! far_table {
    ($sym:path) => {{
        #[cfg(target_arch = "avr")]
        {
            let (lo, hi, hh): (u8, u8, u8);
            // SAFETY: only loads the linker-resolved address of the static.
            unsafe {
                ::core::arch::asm!(
                    "ldi {lo}, lo8({s})",
                    "ldi {hi}, hi8({s})",
                    "ldi {hh}, hh8({s})",
                    lo = out(reg_upper) lo,
                    hi = out(reg_upper) hi,
                    hh = out(reg_upper) hh,
                    s = sym $sym,
                    options(pure, nomem, nostack, preserves_flags),
                );
            }
            let addr = u32::from_le_bytes([lo, hi, hh, 0]);
            let len = ::core::mem::size_of_val(&$sym) as u32;
            // SAFETY: the static is constant data placed in flash by its declaration.
            unsafe { $crate::progmem::FarTable::from_raw(addr, len) }
        }
        #[cfg(not(target_arch = "avr"))]
        {
            $crate::progmem::FarTable::from_slice(&$sym)
        }
    }};
}

/// The little-endian bytes of `N` `f32` values (`M` must be `4 * N`), for
/// declaring tables in `const` context.
pub const fn f32_bytes<const N: usize, const M: usize>(v: [f32; N]) -> [u8; M] {
    let mut out = [0u8; M];
    let mut i = 0;
    while i < N && 4 * i + 3 < M {
        let b = v[i].to_le_bytes();
        out[4 * i] = b[0];
        out[4 * i + 1] = b[1];
        out[4 * i + 2] = b[2];
        out[4 * i + 3] = b[3];
        i += 1;
    }
    out
}

/// The little-endian bytes of `N` `i32` values (`M` must be `4 * N`).
pub const fn i32_bytes<const N: usize, const M: usize>(v: [i32; N]) -> [u8; M] {
    let mut out = [0u8; M];
    let mut i = 0;
    while i < N && 4 * i + 3 < M {
        let b = v[i].to_le_bytes();
        out[4 * i] = b[0];
        out[4 * i + 1] = b[1];
        out[4 * i + 2] = b[2];
        out[4 * i + 3] = b[3];
        i += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    static T: [u8; 14] = {
        let f: [u8; 8] = f32_bytes([1.25, -3.5]);
        let i: [u8; 4] = i32_bytes([-65536]);
        let mut out = [0u8; 14];
        let mut k = 0;
        while k < 8 {
            out[k] = f[k];
            k += 1;
        }
        while k < 12 {
            out[k] = i[k - 8];
            k += 1;
        }
        out[12] = 0x34;
        out[13] = 0x12;
        out
    };

    #[test]
    fn typed_reads_and_bounds() {
        let t = far_table!(T);
        assert_eq!(t.len_bytes(), 14);
        assert_eq!(t.read_f32(0), Some(1.25));
        assert_eq!(t.read_f32(4), Some(-3.5));
        assert_eq!(t.read_i32(8), Some(-65536));
        assert_eq!(t.read_u16(12), Some(0x1234));
        assert_eq!(t.read_u16(13), None);
        assert_eq!(t.read_u8(14), None);
        assert_eq!(t.read_f32(u32::MAX - 1), None);
        // The same bytes read as a RAM slice give the same answers.
        assert_eq!(T[..].read_f32(4), t.read_f32(4));
    }

    static C0: [u8; 4] = [1, 2, 3, 4];
    static C1: [u8; 3] = [5, 6, 7];

    #[test]
    fn chunks_read_as_one_table_and_refuse_bad_shapes() {
        let t = FarChunks::new([far_table!(C0), far_table!(C1)], 2).unwrap();
        assert_eq!(t.len_bytes(), 7);
        let all: Vec<u8> = (0..7).map(|i| t.read_u8(i).unwrap()).collect();
        assert_eq!(all, [1, 2, 3, 4, 5, 6, 7]);
        assert_eq!(t.read_array::<4>(3), Some([4, 5, 6, 7]));
        assert_eq!(t.read_array::<2>(6), None);
        // A short chunk before the last, a chunk over the size, no chunks.
        assert!(FarChunks::new([far_table!(C1), far_table!(C0)], 2).is_none());
        assert!(FarChunks::new([far_table!(C0), far_table!(C1)], 1).is_none());
        assert!(FarChunks::<0>::new([], 2).is_none());
        assert!(FarChunks::new([far_table!(C0)], 24).is_none());
    }
}
