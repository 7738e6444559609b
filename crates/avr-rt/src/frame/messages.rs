//! The messages carried in frames: [`Command`] (host to flight computer),
//! [`Reply`] with its [`status`] bits, [`Boot`] and [`Bench`].

use super::codec::{Frame, FrameError, Kind};

fn get_f32(p: &[u8], i: usize) -> f32 {
    let mut b = [0u8; 4];
    if let Some(s) = p.get(i..i + 4) {
        b.copy_from_slice(s);
    }
    f32::from_le_bytes(b)
}
fn get_u16(p: &[u8], i: usize) -> u16 {
    let mut b = [0u8; 2];
    if let Some(s) = p.get(i..i + 2) {
        b.copy_from_slice(s);
    }
    u16::from_le_bytes(b)
}
fn get_u32(p: &[u8], i: usize) -> u32 {
    let mut b = [0u8; 4];
    if let Some(s) = p.get(i..i + 4) {
        b.copy_from_slice(s);
    }
    u32::from_le_bytes(b)
}

/// Host to flight computer, once per period: the gyro measurement, the
/// pilot's rate references and the throttle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Command {
    /// Measured body rates p, q, r in rad/s (bias not removed).
    pub gyro: [f32; 3],
    /// Reference body rates in rad/s.
    pub reference: [f32; 3],
    /// Throttle as an ESC pulse width in microseconds.
    pub throttle: f32,
}

impl Command {
    /// Payload length on the wire.
    pub const LEN: usize = 28;
    /// The payload bytes.
    pub fn to_payload(&self) -> [u8; Self::LEN] {
        let mut p = [0u8; Self::LEN];
        let vals = [
            self.gyro[0],
            self.gyro[1],
            self.gyro[2],
            self.reference[0],
            self.reference[1],
            self.reference[2],
            self.throttle,
        ];
        for (c, v) in p.chunks_exact_mut(4).zip(vals) {
            c.copy_from_slice(&v.to_le_bytes());
        }
        p
    }
    /// Parses a command frame.
    pub fn from_frame(f: &Frame) -> Result<Command, FrameError> {
        let p = f.payload();
        if f.kind != Kind::Command || p.len() != Self::LEN {
            return Err(FrameError::BadLength);
        }
        Ok(Command {
            gyro: [get_f32(p, 0), get_f32(p, 4), get_f32(p, 8)],
            reference: [get_f32(p, 12), get_f32(p, 16), get_f32(p, 20)],
            throttle: get_f32(p, 24),
        })
    }
    /// Whether every value is finite.
    pub fn is_finite(&self) -> bool {
        self.gyro
            .iter()
            .chain(self.reference.iter())
            .chain(core::iter::once(&self.throttle))
            .all(|v| v.is_finite())
    }
}

/// Status bits of a [`Reply`].
pub mod status {
    /// The failsafe output is being held.
    pub const FAILSAFE: u8 = 1 << 0;
    /// No new command this period: the previous output is held (one period at most).
    pub const HOLD: u8 = 1 << 1;
    /// The failsafe was entered because of a non-finite value.
    pub const NON_FINITE: u8 = 1 << 2;
    /// The previous period overran its deadline.
    pub const OVERRUN: u8 = 1 << 3;
    /// The failsafe was entered because no valid frame came for two periods.
    pub const TIMEOUT: u8 = 1 << 4;
}

/// Flight computer to host, once per period: the outputs and the cycles
/// spent in each stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Reply {
    /// Sequence number of the command these outputs answer.
    pub cmd_seq: u8,
    /// [`status`] bits.
    pub status: u8,
    /// Pulse widths in microseconds: ESC 1, ESC 2, ESC 3, servo.
    pub pwm: [u16; 4],
    /// Cycles of the estimator stage (bias removal and Kalman step).
    pub kalman_cycles: u32,
    /// Cycles of the solver stage (explicit MPC or fast gradient).
    pub solver_cycles: u32,
    /// Cycles of the whole period's work (decode to outputs written).
    pub period_cycles: u32,
    /// Solver iterations (fast gradient) or tree nodes visited (explicit MPC).
    pub iterations: u16,
    /// Frames rejected by the decoder so far.
    pub frame_errors: u16,
}

impl Reply {
    /// Payload length on the wire.
    pub const LEN: usize = 26;
    /// The payload bytes.
    pub fn to_payload(&self) -> [u8; Self::LEN] {
        let mut p = [0u8; Self::LEN];
        p[0] = self.cmd_seq;
        p[1] = self.status;
        for (i, w) in self.pwm.iter().enumerate() {
            p[2 + 2 * i..4 + 2 * i].copy_from_slice(&w.to_le_bytes());
        }
        p[10..14].copy_from_slice(&self.kalman_cycles.to_le_bytes());
        p[14..18].copy_from_slice(&self.solver_cycles.to_le_bytes());
        p[18..22].copy_from_slice(&self.period_cycles.to_le_bytes());
        p[22..24].copy_from_slice(&self.iterations.to_le_bytes());
        p[24..26].copy_from_slice(&self.frame_errors.to_le_bytes());
        p
    }
    /// Parses a reply frame.
    pub fn from_frame(f: &Frame) -> Result<Reply, FrameError> {
        let p = f.payload();
        if f.kind != Kind::Reply || p.len() != Self::LEN {
            return Err(FrameError::BadLength);
        }
        Ok(Reply {
            cmd_seq: p[0],
            status: p[1],
            pwm: [get_u16(p, 2), get_u16(p, 4), get_u16(p, 6), get_u16(p, 8)],
            kalman_cycles: get_u32(p, 10),
            solver_cycles: get_u32(p, 14),
            period_cycles: get_u32(p, 18),
            iterations: get_u16(p, 22),
            frame_errors: get_u16(p, 24),
        })
    }
}

/// Flight computer to host, once after reset: where the controller tables
/// sit in flash and whether reading them back with `ELPM` gives the bytes
/// the firmware was built with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Boot {
    /// 24-bit flash byte address of the table.
    pub table_address: u32,
    /// Table length in bytes.
    pub table_len: u16,
    /// CRC of the bytes read back from flash at run time.
    pub crc_read: u16,
    /// CRC computed at build time.
    pub crc_expected: u16,
    /// Configuration code: bit 0 fixed point (else f32); bits 4..7 the solver
    /// (0 interim, 1 explicit MPC, 2 fast gradient).
    pub config: u8,
    /// On-target self-test of [`crate::mac::Q16Mac`]: products and dot
    /// products that differ from [`kestrel_core::Q16`]'s (0 when correct).
    pub mac_mismatches: u8,
}

impl Boot {
    /// Payload length on the wire.
    pub const LEN: usize = 12;
    /// The payload bytes.
    pub fn to_payload(&self) -> [u8; Self::LEN] {
        let mut p = [0u8; Self::LEN];
        p[0..4].copy_from_slice(&self.table_address.to_le_bytes());
        p[4..6].copy_from_slice(&self.table_len.to_le_bytes());
        p[6..8].copy_from_slice(&self.crc_read.to_le_bytes());
        p[8..10].copy_from_slice(&self.crc_expected.to_le_bytes());
        p[10] = self.config;
        p[11] = self.mac_mismatches;
        p
    }
    /// Parses a boot frame.
    pub fn from_frame(f: &Frame) -> Result<Boot, FrameError> {
        let p = f.payload();
        if f.kind != Kind::Boot || p.len() != Self::LEN {
            return Err(FrameError::BadLength);
        }
        Ok(Boot {
            table_address: get_u32(p, 0),
            table_len: get_u16(p, 4),
            crc_read: get_u16(p, 6),
            crc_expected: get_u16(p, 8),
            config: p[10],
            mac_mismatches: p[11],
        })
    }
}

/// Flight computer to host: the cycles of one timed run of a solver kernel
/// (firmware benchmark builds).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Bench {
    /// Which measurement (firmware-defined order).
    pub id: u8,
    /// 1 if the kernel returned `Ok`.
    pub ok: u8,
    /// Iterations run.
    pub iterations: u16,
    /// Decision variables.
    pub n: u8,
    /// Parameters.
    pub p: u8,
    /// Cycles taken.
    pub cycles: u32,
}

impl Bench {
    /// Payload length on the wire.
    pub const LEN: usize = 10;
    /// The payload bytes.
    pub fn to_payload(&self) -> [u8; Self::LEN] {
        let mut p = [0u8; Self::LEN];
        p[0] = self.id;
        p[1] = self.ok;
        p[2..4].copy_from_slice(&self.iterations.to_le_bytes());
        p[4] = self.n;
        p[5] = self.p;
        p[6..10].copy_from_slice(&self.cycles.to_le_bytes());
        p
    }
    /// Parses a bench frame.
    pub fn from_frame(f: &Frame) -> Result<Bench, FrameError> {
        let p = f.payload();
        if f.kind != Kind::Bench || p.len() != Self::LEN {
            return Err(FrameError::BadLength);
        }
        Ok(Bench {
            id: p[0],
            ok: p[1],
            iterations: get_u16(p, 2),
            n: p[4],
            p: p[5],
            cycles: get_u32(p, 6),
        })
    }
}
