//! The explicit MPC law over a 16-bit tree table (kestrel-avr-rt's
//! `Empc16Law`, both layouts the firmware uses: narrow for Ns = 1, wide
//! in flash chunks for Ns = 2).

use crate::bytes::{KestrelBytes, Table};
use crate::slot::{self, read_array, write_array};
use crate::status::{KestrelStatus, code};
use crate::tables::{KestrelEmpc16Tables, ValueScalar};
use crate::{KESTREL_EMPC_CACHE_ROWS, KESTREL_NP, KESTREL_NR, KESTREL_NU, KESTREL_NX};
use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16};
use kestrel_avr_rt::law::LawInfo;
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_avr_rt::progmem::TableRead;
use kestrel_core::ControlLaw;

/// Words of an explicit law's state.
pub const KESTREL_EMPC16_WORDS: usize = 260;

/// The explicit MPC law in f32 (caller-owned; initialise it with
/// `kestrel_empc16_init_f32`). It reads its table at every call: the
/// table (and its chunk descriptors) must outlive it.
#[repr(C)]
pub struct KestrelEmpc16F32 {
    _opaque: [u64; KESTREL_EMPC16_WORDS],
}

/// The explicit MPC law in Q15.16; see `KestrelEmpc16F32`.
#[repr(C)]
pub struct KestrelEmpc16Q16 {
    _opaque: [u64; KESTREL_EMPC16_WORDS],
}

/// The tree table: one piece (read in place; on the AVR in flash by the
/// assembly walk), or several read as one.
#[derive(Clone, Copy, Debug)]
pub(crate) enum TreeTable {
    /// One table.
    One(Table),
    /// Chunks of `2^bits` bytes (descriptors checked at init).
    Chunks {
        /// The C descriptors.
        chunks: *const KestrelBytes,
        /// How many.
        n: u16,
        /// log2 of a full chunk.
        bits: u8,
        /// Total bytes.
        len: u32,
    },
}

impl TreeTable {
    /// The checked table of `t` (chunk lengths) and its checksum.
    ///
    /// # Safety
    /// `t.chunks` points at `t.n_chunks` descriptors that keep their
    /// contract (`Table.new`).
    unsafe fn new(t: &KestrelEmpc16Tables) -> Result<(Self, u16), KestrelStatus> {
        if t.chunks.is_null() {
            return Err(KestrelStatus::NullPointer);
        }
        let n = usize::from(t.n_chunks);
        if n == 0 || (n > 1 && t.chunk_bits >= 24) {
            return Err(KestrelStatus::BadSize);
        }
        let full = 1u32 << t.chunk_bits.min(23);
        let (mut crc, mut len) = (0xFFFF, 0u32);
        let mut first = None;
        for i in 0..n {
            // SAFETY: `n` descriptors (the contract).
            let c = unsafe { Table::new(&*t.chunks.add(i))? };
            let l = c.len_bytes();
            if n > 1 && (l > full || (i + 1 < n && l != full)) {
                return Err(KestrelStatus::BadSize);
            }
            crc = c.crc(crc);
            len = len.checked_add(l).ok_or(KestrelStatus::BadSize)?;
            first.get_or_insert(c);
        }
        let crc = kestrel_avr_rt::crc::crc16_update(crc, &t.layout.checksum_bytes());
        let table = match (n, first) {
            (1, Some(one)) => TreeTable::One(one),
            _ => TreeTable::Chunks {
                chunks: t.chunks,
                n: t.n_chunks,
                bits: t.chunk_bits,
                len,
            },
        };
        Ok((table, crc))
    }

    /// The chunk holding `offset` and the offset in it.
    fn chunk(&self, offset: u32) -> Option<(Table, u32)> {
        match *self {
            TreeTable::One(t) => Some((t, offset)),
            TreeTable::Chunks {
                chunks, n, bits, ..
            } => {
                let c = offset >> bits;
                if c >= u32::from(n) {
                    return None;
                }
                // SAFETY: `c < n` descriptors, checked at init; they stay
                // valid while the law is used (the C contract).
                let t = unsafe { Table::new(&*chunks.add(c as usize)) }.ok()?;
                Some((t, offset & ((1 << bits) - 1)))
            }
        }
    }
}

impl TableRead for TreeTable {
    #[inline]
    fn len_bytes(&self) -> u32 {
        match self {
            TreeTable::One(t) => t.len_bytes(),
            TreeTable::Chunks { len, .. } => *len,
        }
    }
    #[inline]
    fn flash_address(&self) -> Option<u32> {
        match self {
            TreeTable::One(t) => t.flash_address(),
            TreeTable::Chunks { .. } => None,
        }
    }
    #[inline]
    fn read_u8_unchecked(&self, offset: u32) -> u8 {
        self.chunk(offset)
            .map_or(0, |(t, within)| t.read_u8_unchecked(within))
    }
}

/// The law in `S`.
pub(crate) type Law<S> = Empc16Law<S, TreeTable, KESTREL_NP, KESTREL_NU, KESTREL_EMPC_CACHE_ROWS>;

/// The explicit law of the tables at `t`, their checksum verified.
///
/// # Safety
/// `t` is NULL or points at tables that keep their contract.
#[inline(always)]
pub(crate) unsafe fn law<S: ValueScalar>(
    t: *const KestrelEmpc16Tables,
) -> Result<Law<S>, KestrelStatus> {
    // SAFETY: NULL or valid (the contract).
    let t = unsafe { t.as_ref() }.ok_or(KestrelStatus::NullPointer)?;
    // SAFETY: the contract.
    let (table, crc) = unsafe { TreeTable::new(t)? };
    if crc != t.checksum {
        return Err(KestrelStatus::BadChecksum);
    }
    let tree = Tree16::new(table, t.layout.to_rt())?;
    Ok(Law::<S>::new(tree, KESTREL_NX)?)
}

/// [`law`] written into `dst` (its own frame, for the rate loop's
/// in-place build).
///
/// # Safety
/// As [`law`].
#[inline(never)]
pub(crate) unsafe fn law_into<S: ValueScalar>(
    t: *const KestrelEmpc16Tables,
    dst: &mut core::mem::MaybeUninit<Law<S>>,
) -> Result<(), KestrelStatus> {
    // SAFETY: the contract.
    dst.write(unsafe { law::<S>(t)? });
    Ok(())
}

unsafe fn init<S: ValueScalar, O>(out: *mut O, t: *const KestrelEmpc16Tables) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    unsafe { slot::init_with(out, |dst| law_into::<S>(t, dst)) }
}

unsafe fn eval<S: ValueScalar, O>(
    state: *mut O,
    x: *const S,
    r: *const S,
    u: *mut S,
    nodes: *mut u16,
) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    let res = unsafe {
        slot::get::<Law<S>, O>(state).and_then(|law| {
            let x: [S; KESTREL_NX] = read_array(x)?;
            let r: [S; KESTREL_NR] = read_array(r)?;
            if u.is_null() {
                return Err(KestrelStatus::NullPointer);
            }
            let mut out = [S::ZERO; KESTREL_NU];
            law.control(&x, &r, &mut out)?;
            write_array(u, &out);
            if !nodes.is_null() {
                nodes.write(law.iterations());
            }
            Ok(())
        })
    };
    code(res)
}

/// Initialises `law` over the tree table `tables` (verifies its checksum
/// and layout: `n_params == KESTREL_NP`, `n_outputs == KESTREL_NU`, at
/// most `KESTREL_EMPC_CACHE_ROWS` rows in the narrow layout, the length
/// the layout gives, every index in range).
///
/// Returns `KESTREL_STATUS_NULL_POINTER`, `KESTREL_STATUS_BAD_SIZE`,
/// `KESTREL_STATUS_BAD_CHECKSUM`, `KESTREL_STATUS_INVALID_TABLE` or
/// `KESTREL_STATUS_OUT_OF_RANGE`; the law is then not initialised.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_empc16_init_f32(
    law: *mut KestrelEmpc16F32,
    tables: *const KestrelEmpc16Tables,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { init::<f32, _>(law, tables) }
}

/// Evaluates the law at the state `x[KESTREL_NX]` and the references
/// `r[KESTREL_NR]` (`p_ref, q_ref, r_ref, throttle`): the input moves
/// `u[KESTREL_NU]`, and the tree nodes visited (`nodes`, may be NULL).
/// Outside the table's parameter box the parameter is projected onto it.
/// `KESTREL_STATUS_NON_FINITE` for a non-finite input.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_empc16_eval_f32(
    law: *mut KestrelEmpc16F32,
    x: *const f32,
    r: *const f32,
    u: *mut f32,
    nodes: *mut u16,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { eval::<f32, _>(law, x, r, u, nodes) }
}

/// `kestrel_empc16_init_f32` for the Q15.16 law.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_empc16_init_q16(
    law: *mut KestrelEmpc16Q16,
    tables: *const KestrelEmpc16Tables,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { init::<Q16Mac, _>(law, tables) }
}

/// `kestrel_empc16_eval_f32` in Q15.16 (`int32_t` raw bits).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_empc16_eval_q16(
    law: *mut KestrelEmpc16Q16,
    x: *const i32,
    r: *const i32,
    u: *mut i32,
    nodes: *mut u16,
) -> KestrelStatus {
    // SAFETY: the C contract; Q16Mac is a transparent i32.
    unsafe { eval::<Q16Mac, _>(law, x.cast(), r.cast(), u.cast(), nodes) }
}
