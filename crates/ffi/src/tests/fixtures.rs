//! The thesis design as C would hand it over, the run-time's reference
//! objects built from the same generated constants, and random inputs.

use crate::{KestrelBytes, KestrelDesign, KestrelEmpc16Tables, KestrelTree16Layout};
use kestrel_avr_rt::crc::crc16;
use kestrel_avr_rt::explicit::tree16::Tree16Layout;
use kestrel_avr_rt::kalman16::Row16;
use std::vec::Vec;

/// The Rust firmware's tables (`kestrel codegen`).
#[allow(dead_code, missing_docs, clippy::all)]
pub(super) mod generated {
    include!("../../../../avr/firmware/src/generated.rs");
}

/// The Ns = 1 explicit law's tables.
#[allow(dead_code, missing_docs, clippy::all)]
pub(super) mod generated_empc {
    include!("../../../../avr/firmware/src/generated_empc.rs");
}

/// The Ns = 2 explicit law's wide table in chunks.
#[allow(dead_code, missing_docs, clippy::all)]
pub(super) mod generated_empc_ns2 {
    include!("../../../../avr/firmware/src/generated_empc_ns2.rs");
}

/// A descriptor of bytes in RAM.
pub(super) fn ram(b: &[u8]) -> KestrelBytes {
    KestrelBytes {
        data: b.as_ptr(),
        flash: 0,
        len: b.len() as u32,
    }
}

fn push_rows<const N: usize>(out: &mut Vec<u8>, rows: &[Row16<N>]) {
    for r in rows {
        for c in r.c {
            out.extend_from_slice(&c.to_le_bytes());
        }
        out.push(r.shift);
        out.push(r.start);
    }
}

/// The design's bytes, owned (the C arrays of `kestrel export --lang c`).
pub(super) struct Owned {
    pub(super) values: Vec<u8>,
    pub(super) kalman16: Vec<u8>,
    pub(super) fgm16: Vec<u8>,
    pub(super) format: u8,
}

impl Owned {
    /// The f32 or the Q15.16 design.
    pub(super) fn new(format: u8) -> Self {
        use generated as g;
        let values = if format == crate::KESTREL_FORMAT_F32 {
            g::VALUES_F32.iter().flat_map(|v| v.to_le_bytes()).collect()
        } else {
            g::VALUES_Q16.iter().flat_map(|v| v.to_le_bytes()).collect()
        };
        let mut kalman16 = Vec::new();
        push_rows(&mut kalman16, &g::KF16.c);
        for y in g::KF16.y0 {
            kalman16.extend_from_slice(&y.to_le_bytes());
        }
        push_rows(&mut kalman16, &g::KF16.m);
        push_rows(&mut kalman16, &g::KF16.a);
        push_rows(&mut kalman16, &g::KF16.b);
        let mut fgm16 = Vec::new();
        push_rows(&mut fgm16, &g::FGM16_M);
        for b in g::FGM16_BETAS {
            fgm16.extend_from_slice(&b.to_le_bytes());
        }
        Owned {
            values,
            kalman16,
            fgm16,
            format,
        }
    }

    /// The descriptor, with the checksum computed as the notes define it.
    pub(super) fn design(&self) -> KestrelDesign {
        use generated as g;
        let iterations = g::FGM_LOOP_ITERATIONS as u16;
        let [lo, hi] = iterations.to_le_bytes();
        let tail = [self.format, g::FGM_WARM as u8, lo, hi];
        let all = [&self.values[..], &self.kalman16, &self.fgm16, &tail].concat();
        KestrelDesign {
            values: ram(&self.values),
            kalman16: ram(&self.kalman16),
            fgm16: ram(&self.fgm16),
            values_format: self.format,
            fgm_warm: g::FGM_WARM as u8,
            fgm_iterations: iterations,
            checksum: crc16(&all),
        }
    }
}

/// The C layout of a run-time layout.
pub(super) fn layout(l: Tree16Layout) -> KestrelTree16Layout {
    KestrelTree16Layout {
        n_params: l.n_params as u16,
        n_outputs: l.n_outputs as u16,
        n_nodes: l.n_nodes as u16,
        n_laws: l.n_laws as u16,
        n_rows: l.n_rows as u16,
        root: l.root,
        scale: l.scale,
        wide: l.wide as u8,
    }
}

/// The explicit law's tables over `chunks`, with their checksum.
pub(super) fn empc_tables(
    chunks: &[KestrelBytes],
    bytes: &[&[u8]],
    l: Tree16Layout,
    bits: u8,
) -> KestrelEmpc16Tables {
    let layout = layout(l);
    let mut all: Vec<u8> = bytes.concat();
    all.extend_from_slice(&layout.checksum_bytes());
    KestrelEmpc16Tables {
        chunks: chunks.as_ptr(),
        n_chunks: chunks.len() as u16,
        chunk_bits: bits,
        layout,
        checksum: crc16(&all),
    }
}

/// The Ns = 2 table's chunks.
pub(super) fn ns2_chunks() -> Vec<&'static [u8]> {
    use generated_empc_ns2 as n;
    std::vec![
        &n::EMPC_NS2_0[..],
        &n::EMPC_NS2_1[..],
        &n::EMPC_NS2_2[..],
        &n::EMPC_NS2_3[..],
        &n::EMPC_NS2_4[..],
        &n::EMPC_NS2_5[..],
        &n::EMPC_NS2_6[..],
        &n::EMPC_NS2_7[..],
        &n::EMPC_NS2_8[..],
        &n::EMPC_NS2_9[..],
        &n::EMPC_NS2_10[..],
        &n::EMPC_NS2_11[..],
        &n::EMPC_NS2_12[..],
        &n::EMPC_NS2_13[..],
        &n::EMPC_NS2_14[..],
        &n::EMPC_NS2_15[..],
        &n::EMPC_NS2_16[..],
        &n::EMPC_NS2_17[..],
        &n::EMPC_NS2_18[..],
        &n::EMPC_NS2_19[..],
        &n::EMPC_NS2_20[..],
        &n::EMPC_NS2_21[..],
        &n::EMPC_NS2_22[..],
        &n::EMPC_NS2_23[..],
        &n::EMPC_NS2_24[..],
    ]
}

/// A deterministic generator (xorshift64*).
pub(super) struct Rng(pub(super) u64);

impl Rng {
    /// Uniform in [0, 1).
    pub(super) fn unit(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let v = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (v >> 40) as f32 / (1u64 << 24) as f32
    }
    /// Uniform in [-a, a).
    pub(super) fn sym(&mut self, a: f32) -> f32 {
        a * (2.0 * self.unit() - 1.0)
    }
}
