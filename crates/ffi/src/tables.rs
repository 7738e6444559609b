//! The table sets C hands over ([`KestrelDesign`], [`KestrelEmpc16Tables`])
//! and their reading into kestrel-avr-rt's types, with every check.

use crate::bytes::{KestrelBytes, Table};
use crate::status::KestrelStatus;
use crate::{
    KESTREL_FGM_T, KESTREL_FGM16_BYTES, KESTREL_FORMAT_F32, KESTREL_FORMAT_Q16,
    KESTREL_KALMAN16_BYTES, KESTREL_N_VALUES, KESTREL_NP, KESTREL_NU, KESTREL_NX, KESTREL_NY,
    KESTREL_NZ, KESTREL_VALUES_BYTES,
};
use kestrel_avr_rt::crc::crc16_update;
use kestrel_avr_rt::explicit::tree16::Tree16Layout;
use kestrel_avr_rt::kalman16::{Kalman16Tables, Row16};
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_avr_rt::output::RtScalar;
use kestrel_avr_rt::progmem::TableRead;
use kestrel_core::Matrix;
use kestrel_fgm::FgmTables;

/// One controller design as `kestrel export --lang c` writes it (the
/// numbers of the Rust firmware's `generated.rs`): what the Kalman
/// filter, the fast gradient law and the rate loop read.
///
/// - `values`: the flat table, `KESTREL_N_VALUES` numbers of 4 bytes in
///   `values_format`: the fast gradient's set-up data `M` (NZ x NZ, row
///   major), `K` (NZ x NP), `k0` (NZ), `lo_theta` (NZ x NP), `lo0` (NZ),
///   `hi_theta` (NZ x NP), `hi0` (NZ), `d` (NZ), `d_inv` (NZ), `betas`
///   (T), then the mixer offsets (4, microseconds) and the gyro bias (3,
///   rad/s): `VALUES_F32` or `VALUES_Q16` of `generated.rs`;
/// - `kalman16`: the stationary Kalman filter's 16-bit rows (`KF16`):
///   `C` (NY rows of NX), `y0` (NY `int32_t`, Q15.16), `M` (NX rows of
///   NY), `A - I` (NX rows of NX), `B` (NX rows of NU), where a row of
///   n is n `int16_t` coefficients, then its shift (`uint8_t`, fraction
///   bits) and start (`uint8_t`, first non-zero column);
/// - `fgm16`: the fast gradient's `M` in 16 bits (`FGM16_M`: NZ rows of
///   NZ, shift 15) and the momentum in Q1.15 (`FGM16_BETAS`: T `int16_t`).
///
/// The struct itself is read from RAM (on the AVR not `PROGMEM`); the
/// tables it describes may be in flash. All values little-endian.
/// `checksum` is `kestrel_checksum`
/// (CRC-16/CCITT-FALSE) over the bytes of `values`, `kalman16`, `fgm16`
/// and then the four bytes `values_format`, `fgm_warm`, `fgm_iterations`
/// (low byte, high byte).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct KestrelDesign {
    /// The flat table (`KESTREL_VALUES_BYTES` bytes).
    pub values: KestrelBytes,
    /// The 16-bit Kalman rows (`KESTREL_KALMAN16_BYTES` bytes).
    pub kalman16: KestrelBytes,
    /// The fast gradient's 16-bit rows and momentum (`KESTREL_FGM16_BYTES` bytes).
    pub fgm16: KestrelBytes,
    /// `KESTREL_FORMAT_F32` or `KESTREL_FORMAT_Q16`: the format of `values`.
    pub values_format: u8,
    /// 1: each period's solve starts from the previous solution; 0: cold.
    pub fgm_warm: u8,
    /// Fast gradient iterations per period (the certified count).
    pub fgm_iterations: u16,
    /// The design checksum (see above).
    pub checksum: u16,
}

/// Counts of an explicit law's 16-bit tree table (kestrel-avr-rt's
/// `Tree16Layout`, the `EMPC16_LAYOUT` of `generated_empc.rs`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KestrelTree16Layout {
    /// Parameters (must be `KESTREL_NP`).
    pub n_params: u16,
    /// Outputs (must be `KESTREL_NU`).
    pub n_outputs: u16,
    /// Tree nodes.
    pub n_nodes: u16,
    /// Laws.
    pub n_laws: u16,
    /// Affine rows (narrow: at most `KESTREL_EMPC_CACHE_ROWS`).
    pub n_rows: u16,
    /// The root child code.
    pub root: u16,
    /// Fraction bits of every row's value.
    pub scale: u8,
    /// 1: the wide layout (`u16` indices, 8-byte nodes); 0: narrow.
    pub wide: u8,
}

/// An explicit law's 16-bit tree table, in `n_chunks` pieces (C objects
/// are limited to 32 kB; the Ns = 2 table is 100 kB): every chunk but the
/// last holds exactly `2^chunk_bits` bytes, the last at most that; read as
/// one table. With one chunk `chunk_bits` is not used. `chunks` points at
/// `n_chunks` descriptors that must stay valid (and unchanged) while a
/// law made from them is used: declare them `static const`, in RAM (on
/// the AVR not `PROGMEM`: the descriptors are read as data, the tables
/// they describe may be in flash).
///
/// `checksum` is `kestrel_checksum` over the chunks' bytes in
/// order, then the layout's 14 bytes: `n_params`, `n_outputs`, `n_nodes`,
/// `n_laws`, `n_rows`, `root` (each `uint16_t`, little-endian), `scale`,
/// `wide`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct KestrelEmpc16Tables {
    /// The chunks' descriptors.
    pub chunks: *const KestrelBytes,
    /// Number of chunks (at least 1).
    pub n_chunks: u16,
    /// log2 of a full chunk's length (below 24).
    pub chunk_bits: u8,
    /// The table's counts.
    pub layout: KestrelTree16Layout,
    /// The checksum (see above).
    pub checksum: u16,
}

/// A scalar the design's values are read as.
pub(crate) trait ValueScalar: RtScalar {
    /// The `values_format` this scalar reads.
    const FORMAT: u8;
    /// The value of 4 little-endian bytes.
    fn from_le(b: [u8; 4]) -> Self;
}

impl ValueScalar for f32 {
    const FORMAT: u8 = KESTREL_FORMAT_F32;
    fn from_le(b: [u8; 4]) -> Self {
        f32::from_le_bytes(b)
    }
}

impl ValueScalar for Q16Mac {
    const FORMAT: u8 = KESTREL_FORMAT_Q16;
    fn from_le(b: [u8; 4]) -> Self {
        Q16Mac::from_bits(i32::from_le_bytes(b))
    }
}

/// The design's tables, checked: sizes, format, checksum.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Design {
    pub(crate) values: Table,
    pub(crate) kalman16: Table,
    pub(crate) fgm16: Table,
    pub(crate) warm: bool,
    pub(crate) iterations: u16,
}

/// Offsets in the flat table.
pub(crate) mod at {
    use crate::{KESTREL_FGM_T, KESTREL_NP, KESTREL_NZ};
    const N: usize = KESTREL_NZ;
    const P: usize = KESTREL_NP;
    /// `M`.
    pub(crate) const M: usize = 0;
    /// `K`.
    pub(crate) const K: usize = M + N * N;
    /// `k0`.
    pub(crate) const K0: usize = K + N * P;
    /// `lo_theta`.
    pub(crate) const LO: usize = K0 + N;
    /// `lo0`.
    pub(crate) const LO0: usize = LO + N * P;
    /// `hi_theta`.
    pub(crate) const HI: usize = LO0 + N;
    /// `hi0`.
    pub(crate) const HI0: usize = HI + N * P;
    /// `d`.
    pub(crate) const D: usize = HI0 + N;
    /// `d_inv`.
    pub(crate) const DINV: usize = D + N;
    /// `betas`.
    pub(crate) const BETAS: usize = DINV + N;
    /// The mixer offsets.
    pub(crate) const MIX_OFFSET: usize = BETAS + KESTREL_FGM_T;
    /// The gyro bias.
    pub(crate) const BIAS: usize = MIX_OFFSET + 4;
    /// Values in all.
    pub(crate) const END: usize = BIAS + 3;
}

const _: () = assert!(at::END == KESTREL_N_VALUES);
const _: () = assert!(
    KESTREL_KALMAN16_BYTES
        == KESTREL_NY * (2 * KESTREL_NX + 2)
            + 4 * KESTREL_NY
            + KESTREL_NX * (2 * KESTREL_NY + 2 + 2 * KESTREL_NX + 2 + 2 * KESTREL_NU + 2)
);
const _: () = assert!(KESTREL_FGM16_BYTES == KESTREL_NZ * (2 * KESTREL_NZ + 2) + 2 * KESTREL_FGM_T);

impl Design {
    /// The checked tables of `*d`, with values in `format` if given.
    ///
    /// # Safety
    /// `d` is NULL or points at a design whose descriptors keep their
    /// contract (`Table.new`).
    pub(crate) unsafe fn new(
        d: *const KestrelDesign,
        format: Option<u8>,
    ) -> Result<Self, KestrelStatus> {
        // SAFETY: NULL or valid (the caller's contract).
        let d = unsafe { d.as_ref() }.ok_or(KestrelStatus::NullPointer)?;
        // SAFETY: as above, for each descriptor.
        let (values, kalman16, fgm16) = unsafe {
            (
                Table::new(&d.values)?,
                Table::new(&d.kalman16)?,
                Table::new(&d.fgm16)?,
            )
        };
        values.expect_len(KESTREL_VALUES_BYTES)?;
        kalman16.expect_len(KESTREL_KALMAN16_BYTES)?;
        fgm16.expect_len(KESTREL_FGM16_BYTES)?;
        if d.values_format != KESTREL_FORMAT_F32 && d.values_format != KESTREL_FORMAT_Q16 {
            return Err(KestrelStatus::BadFormat);
        }
        let crc = fgm16.crc(kalman16.crc(values.crc(0xFFFF)));
        let [lo, hi] = d.fgm_iterations.to_le_bytes();
        let crc = crc16_update(crc, &[d.values_format, d.fgm_warm, lo, hi]);
        if crc != d.checksum {
            return Err(KestrelStatus::BadChecksum);
        }
        if format.is_some_and(|f| f != d.values_format) {
            return Err(KestrelStatus::BadFormat);
        }
        if d.fgm_warm > 1 || d.fgm_iterations == 0 {
            return Err(KestrelStatus::InvalidTable);
        }
        Ok(Design {
            values,
            kalman16,
            fgm16,
            warm: d.fgm_warm == 1,
            iterations: d.fgm_iterations,
        })
    }

    /// Value `i` of the flat table.
    pub(crate) fn value<S: ValueScalar>(&self, i: usize) -> Result<S, KestrelStatus> {
        let b = self
            .values
            .read_array::<4>(4 * i as u32)
            .ok_or(KestrelStatus::BadSize)?;
        Ok(S::from_le(b))
    }

    fn array<S: ValueScalar, const N: usize>(&self, at: usize) -> Result<[S; N], KestrelStatus> {
        let mut out = [S::ZERO; N];
        for (k, o) in out.iter_mut().enumerate() {
            *o = self.value(at + k)?;
        }
        Ok(out)
    }

    fn matrix<S: ValueScalar, const R: usize, const C: usize>(
        &self,
        at: usize,
    ) -> Result<Matrix<S, R, C>, KestrelStatus> {
        let mut m = Matrix::<S, R, C>::zeros();
        for (i, row) in m.data.iter_mut().enumerate() {
            *row = self.array(at + C * i)?;
        }
        Ok(m)
    }

    /// kestrel-fgm's tables in `S` (as the firmware reads them).
    pub(crate) fn fgm<S: ValueScalar>(
        &self,
    ) -> Result<FgmTables<S, KESTREL_NZ, KESTREL_NP, KESTREL_FGM_T>, KestrelStatus> {
        let k = usize::from(self.iterations);
        Ok(FgmTables {
            m: self.matrix(at::M)?,
            k_theta: self.matrix(at::K)?,
            k0: self.array(at::K0)?,
            lo_theta: self.matrix(at::LO)?,
            lo0: self.array(at::LO0)?,
            hi_theta: self.matrix(at::HI)?,
            hi0: self.array(at::HI0)?,
            d: self.array(at::D)?,
            d_inv: self.array(at::DINV)?,
            betas: self.array(at::BETAS)?,
            iterations: k,
            warm_iterations: k,
            shift: 0,
        })
    }

    /// The mixer offsets and the gyro bias.
    pub(crate) fn mixer_and_bias<S: ValueScalar>(
        &self,
    ) -> Result<([S; 4], [S; KESTREL_NY]), KestrelStatus> {
        Ok((self.array(at::MIX_OFFSET)?, self.array(at::BIAS)?))
    }

    /// The 16-bit Kalman tables.
    pub(crate) fn kalman16(
        &self,
    ) -> Result<Kalman16Tables<KESTREL_NX, KESTREL_NU, KESTREL_NY>, KestrelStatus> {
        let mut r = Reader {
            t: &self.kalman16,
            at: 0,
        };
        let c = r.rows()?;
        let mut y0 = [0i32; KESTREL_NY];
        for y in y0.iter_mut() {
            *y = i32::from_le_bytes(r.bytes()?);
        }
        let t = Kalman16Tables {
            c,
            y0,
            m: r.rows()?,
            a: r.rows()?,
            b: r.rows()?,
        };
        t.check()?;
        Ok(t)
    }

    /// The fast gradient's 16-bit `M` rows and momentum.
    #[allow(clippy::type_complexity)]
    pub(crate) fn fgm16(
        &self,
    ) -> Result<([Row16<KESTREL_NZ>; KESTREL_NZ], [i16; KESTREL_FGM_T]), KestrelStatus> {
        let mut r = Reader {
            t: &self.fgm16,
            at: 0,
        };
        let m = r.rows()?;
        let mut betas = [0i16; KESTREL_FGM_T];
        for b in betas.iter_mut() {
            *b = i16::from_le_bytes(r.bytes()?);
        }
        Ok((m, betas))
    }
}

/// Reads consecutive little-endian fields of a table.
struct Reader<'a> {
    t: &'a Table,
    at: u32,
}

impl Reader<'_> {
    fn bytes<const N: usize>(&mut self) -> Result<[u8; N], KestrelStatus> {
        let b = self
            .t
            .read_array::<N>(self.at)
            .ok_or(KestrelStatus::BadSize)?;
        self.at += N as u32;
        Ok(b)
    }

    fn row<const N: usize>(&mut self) -> Result<Row16<N>, KestrelStatus> {
        let mut c = [0i16; N];
        for v in c.iter_mut() {
            *v = i16::from_le_bytes(self.bytes()?);
        }
        let [shift, start] = self.bytes()?;
        Ok(Row16::new(c, shift, start))
    }

    fn rows<const N: usize, const R: usize>(&mut self) -> Result<[Row16<N>; R], KestrelStatus> {
        let mut out = [Row16::new([0; N], 0, 0); R];
        for r in out.iter_mut() {
            *r = self.row()?;
        }
        Ok(out)
    }
}

impl KestrelTree16Layout {
    /// The run-time's layout.
    pub(crate) fn to_rt(self) -> Tree16Layout {
        Tree16Layout {
            n_params: usize::from(self.n_params),
            n_outputs: usize::from(self.n_outputs),
            n_nodes: usize::from(self.n_nodes),
            n_laws: usize::from(self.n_laws),
            n_rows: usize::from(self.n_rows),
            root: self.root,
            scale: self.scale,
            wide: self.wide != 0,
        }
    }

    /// The 14 bytes the checksum ends with.
    pub(crate) fn checksum_bytes(&self) -> [u8; 14] {
        let mut b = [0u8; 14];
        let words = [
            self.n_params,
            self.n_outputs,
            self.n_nodes,
            self.n_laws,
            self.n_rows,
            self.root,
        ];
        for (k, w) in words.iter().enumerate() {
            b[2 * k..2 * k + 2].copy_from_slice(&w.to_le_bytes());
        }
        b[12] = self.scale;
        b[13] = self.wide;
        b
    }
}
