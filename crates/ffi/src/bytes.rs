//! [`KestrelBytes`]: one constant table handed over by C, in RAM or (on
//! the AVR) in flash, read through kestrel-avr-rt's [`TableRead`]; and the
//! design checksum.

use crate::status::KestrelStatus;
use kestrel_avr_rt::crc::crc16_update;
use kestrel_avr_rt::progmem::TableRead;

/// One constant table: `len` bytes, little-endian values, no alignment
/// required (read a byte at a time).
///
/// - In RAM (every target): `data` points at the bytes, `flash` is 0.
/// - In AVR flash: `data` is NULL and `flash` is the table's 24-bit flash
///   byte address, as avr-libc's `pgm_get_far_address(table)` gives it
///   (the table may sit anywhere in the 256 kB, above 64 kB too; it is
///   read with `ELPM`, as the Rust firmware reads its tables). Declare it
///   `const uint8_t table[] PROGMEM` (or in a `.progmem.data`/
///   `.text.kestrel_tables` section); a C object is limited to 32 kB, so
///   bigger data goes in chunks (`KestrelEmpc16Tables`).
///
/// `data == NULL` with `flash == 0` (or any flash address on a target
/// other than the AVR) is `KESTREL_STATUS_NULL_POINTER`. The bytes are
/// borrowed: they must stay unchanged for as long as a state made from
/// them is used (the explicit law reads its table at every call; the
/// other states copy what they need at init).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct KestrelBytes {
    /// The bytes in RAM, or NULL for a table in flash.
    pub data: *const u8,
    /// AVR only: the 24-bit flash byte address when `data` is NULL.
    pub flash: u32,
    /// Length in bytes.
    pub len: u32,
}

/// A `KestrelBytes` checked once: where its bytes are read from.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Table {
    /// Bytes in RAM.
    Ram { data: *const u8, len: u32 },
    /// Bytes in AVR flash (read with `ELPM`).
    #[cfg(target_arch = "avr")]
    Flash(kestrel_avr_rt::progmem::FarTable),
}

impl Table {
    /// The table of `b`, or `KESTREL_STATUS_NULL_POINTER`.
    ///
    /// # Safety
    /// `b.data`, when not NULL, points at `b.len` readable bytes; on the
    /// AVR a flash address `b.flash` starts `b.len` bytes of flash.
    pub(crate) unsafe fn new(b: &KestrelBytes) -> Result<Self, KestrelStatus> {
        if !b.data.is_null() {
            return Ok(Table::Ram {
                data: b.data,
                len: b.len,
            });
        }
        #[cfg(target_arch = "avr")]
        if b.flash != 0 {
            // SAFETY: the caller's contract (a flash table of `len` bytes).
            return Ok(Table::Flash(unsafe {
                kestrel_avr_rt::progmem::FarTable::from_raw(b.flash, b.len)
            }));
        }
        Err(KestrelStatus::NullPointer)
    }

    /// Continues the CRC `crc` over every byte of the table.
    pub(crate) fn crc(&self, mut crc: u16) -> u16 {
        for i in 0..self.len_bytes() {
            crc = crc16_update(crc, &[self.read_u8_unchecked(i)]);
        }
        crc
    }

    /// Fails with `KESTREL_STATUS_BAD_SIZE` unless the table holds `len` bytes.
    pub(crate) fn expect_len(&self, len: usize) -> Result<(), KestrelStatus> {
        if self.len_bytes() as usize == len {
            Ok(())
        } else {
            Err(KestrelStatus::BadSize)
        }
    }
}

impl TableRead for Table {
    #[inline]
    fn len_bytes(&self) -> u32 {
        match self {
            Table::Ram { len, .. } => *len,
            #[cfg(target_arch = "avr")]
            Table::Flash(t) => t.len_bytes(),
        }
    }
    #[inline]
    fn flash_address(&self) -> Option<u32> {
        match self {
            Table::Ram { .. } => None,
            #[cfg(target_arch = "avr")]
            Table::Flash(t) => t.flash_address(),
        }
    }
    #[inline]
    fn read_u8_unchecked(&self, offset: u32) -> u8 {
        match self {
            Table::Ram { data, len } => {
                if offset < *len {
                    // SAFETY: `data` points at `len` readable bytes
                    // (`Table::new`'s contract) and `offset < len`.
                    unsafe { data.add(offset as usize).read() }
                } else {
                    0
                }
            }
            #[cfg(target_arch = "avr")]
            Table::Flash(t) => t.read_u8_unchecked(offset),
        }
    }
}

/// The design checksum of `n` tables: CRC-16/CCITT-FALSE (polynomial
/// 0x1021, initial value 0xFFFF, no reflection, no final XOR;
/// `kestrel_avr_rt::crc16`, check value 0x29B1 for "123456789") over the
/// bytes of `tables[0]`, then `tables[1]`, ... continued, each table's
/// `len` bytes as stored (the little-endian values). The checksum fields
/// of `KestrelDesign` and `KestrelEmpc16Tables` are
/// defined by it (see there which tables, in which order). Writes the
/// checksum to `*out`.
///
/// # Errors
/// `KESTREL_STATUS_NULL_POINTER` for a NULL `tables` (with `n > 0`) or
/// `out`, or a table without bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_checksum(
    tables: *const KestrelBytes,
    n: u16,
    out: *mut u16,
) -> KestrelStatus {
    if out.is_null() || (tables.is_null() && n > 0) {
        return KestrelStatus::NullPointer;
    }
    let mut crc = 0xFFFF;
    for i in 0..usize::from(n) {
        // SAFETY: `tables` points at `n` descriptors (the C contract).
        let b = unsafe { &*tables.add(i) };
        // SAFETY: the descriptor's own contract.
        match unsafe { Table::new(b) } {
            Ok(t) => crc = t.crc(crc),
            Err(e) => return e,
        }
    }
    // SAFETY: `out` is not NULL and points at a writable u16.
    unsafe { out.write(crc) };
    KestrelStatus::Ok
}
