//! The framed UART protocol between the flight computer and the host (or
//! the hardware-in-the-loop test).
//!
//! A frame on the wire:
//!
//! | bytes | field |
//! |---|---|
//! | 2 | sync `0xA5 0x5A` |
//! | 1 | kind ([`Kind`]) |
//! | 1 | sequence number (wraps at 256) |
//! | 1 | payload length `n` (at most [`MAX_PAYLOAD`]) |
//! | n | payload (little-endian fields) |
//! | 2 | CRC-16/CCITT-FALSE of kind, sequence, length and payload, little-endian |
//!
//! [`FrameDecoder`] consumes bytes one at a time (it is fed from the receive
//! interrupt's ring buffer), rejects frames with a bad CRC, an unknown kind or
//! an oversized length, and resynchronises on the next sync pattern.
//! Sequence numbers let the receiver spot dropped frames
//! ([`SeqTracker`]) and ignore duplicated ones.

use crate::crc::{crc16, crc16_update};

/// First sync byte.
pub const SYNC0: u8 = 0xA5;
/// Second sync byte.
pub const SYNC1: u8 = 0x5A;
/// The largest payload a frame may carry.
pub const MAX_PAYLOAD: usize = 40;
/// Header (sync, kind, sequence, length) plus CRC: the bytes a frame adds to its payload.
pub const OVERHEAD: usize = 7;
/// The largest frame on the wire.
pub const MAX_FRAME: usize = MAX_PAYLOAD + OVERHEAD;

/// The kinds of frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Kind {
    /// Host to flight computer: a [`Command`].
    Command = 0x01,
    /// Flight computer to host: a [`Reply`].
    Reply = 0x81,
    /// Flight computer to host, once after reset: a [`Boot`] self-test report.
    Boot = 0x82,
    /// Flight computer to host, after boot in benchmark builds: a [`Bench`] timing.
    Bench = 0x83,
}

impl Kind {
    /// The kind for a wire byte, if it is one.
    pub fn from_u8(b: u8) -> Option<Kind> {
        match b {
            0x01 => Some(Kind::Command),
            0x81 => Some(Kind::Reply),
            0x82 => Some(Kind::Boot),
            0x83 => Some(Kind::Bench),
            _ => None,
        }
    }
}

/// Why a frame was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// The CRC did not match.
    Crc,
    /// The kind byte is not a known [`Kind`].
    UnknownKind(u8),
    /// The length byte exceeds [`MAX_PAYLOAD`].
    TooLong(u8),
    /// The payload length does not fit the message of that kind.
    BadLength,
    /// The decoder was reset in the middle of a frame (inter-frame timeout).
    Truncated,
    /// An output buffer was too small.
    BufferTooSmall,
}

/// A frame as decoded: kind, sequence number and payload.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame {
    /// The frame kind.
    pub kind: Kind,
    /// The sender's sequence number.
    pub seq: u8,
    len: u8,
    payload: [u8; MAX_PAYLOAD],
}

impl Frame {
    /// A frame from its parts; `None` if the payload is longer than [`MAX_PAYLOAD`].
    pub fn new(kind: Kind, seq: u8, payload: &[u8]) -> Option<Frame> {
        if payload.len() > MAX_PAYLOAD {
            return None;
        }
        let mut p = [0u8; MAX_PAYLOAD];
        p[..payload.len()].copy_from_slice(payload);
        Some(Frame {
            kind,
            seq,
            len: payload.len() as u8,
            payload: p,
        })
    }
    /// The payload bytes.
    pub fn payload(&self) -> &[u8] {
        &self.payload[..self.len as usize]
    }
    /// Writes the frame to `out`, returning the number of bytes written.
    pub fn encode(&self, out: &mut [u8]) -> Result<usize, FrameError> {
        let n = self.len as usize;
        let total = n + OVERHEAD;
        let out = out.get_mut(..total).ok_or(FrameError::BufferTooSmall)?;
        out[0] = SYNC0;
        out[1] = SYNC1;
        out[2] = self.kind as u8;
        out[3] = self.seq;
        out[4] = self.len;
        out[5..5 + n].copy_from_slice(self.payload());
        let crc = crc16(&out[2..5 + n]);
        out[5 + n..total].copy_from_slice(&crc.to_le_bytes());
        Ok(total)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Sync0,
    Sync1,
    Kind,
    Seq,
    Len,
    Payload,
    Crc0,
    Crc1,
}

/// Byte-at-a-time frame decoder with error counters.
///
/// ```
/// use kestrel_avr_rt::frame::{Frame, FrameDecoder, Kind, MAX_FRAME};
/// let mut wire = [0u8; MAX_FRAME];
/// let n = Frame::new(Kind::Command, 7, &[1, 2, 3]).unwrap().encode(&mut wire).unwrap();
/// let mut dec = FrameDecoder::new();
/// let got = wire[..n].iter().filter_map(|&b| dec.push(b)).next().unwrap().unwrap();
/// assert_eq!((got.seq, got.payload()), (7, &[1u8, 2, 3][..]));
/// ```
#[derive(Clone, Debug)]
pub struct FrameDecoder {
    state: State,
    kind: u8,
    seq: u8,
    len: u8,
    pos: u8,
    crc_lo: u8,
    payload: [u8; MAX_PAYLOAD],
    /// Frames accepted.
    pub ok: u16,
    /// Frames rejected (bad CRC, kind or length, or truncated).
    pub errors: u16,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// A decoder waiting for a sync pattern.
    pub const fn new() -> Self {
        FrameDecoder {
            state: State::Sync0,
            kind: 0,
            seq: 0,
            len: 0,
            pos: 0,
            crc_lo: 0,
            payload: [0; MAX_PAYLOAD],
            ok: 0,
            errors: 0,
        }
    }

    /// Whether the decoder is between frames (not inside one).
    pub fn is_idle(&self) -> bool {
        matches!(self.state, State::Sync0 | State::Sync1)
    }

    /// Abandons a partly received frame (the inter-frame timeout: the host
    /// sends whole frames well before each control tick, so a frame still
    /// incomplete at the tick is garbage). Returns `Err(Truncated)` if a frame
    /// was in progress.
    pub fn reset(&mut self) -> Result<(), FrameError> {
        let was_idle = self.is_idle();
        self.state = State::Sync0;
        if was_idle {
            Ok(())
        } else {
            self.errors = self.errors.wrapping_add(1);
            Err(FrameError::Truncated)
        }
    }

    fn fail(&mut self, e: FrameError) -> Option<Result<Frame, FrameError>> {
        self.errors = self.errors.wrapping_add(1);
        self.state = State::Sync0;
        Some(Err(e))
    }

    /// Feeds one byte; returns a frame (or the reason one was rejected) when
    /// a frame ends with this byte.
    pub fn push(&mut self, b: u8) -> Option<Result<Frame, FrameError>> {
        match self.state {
            State::Sync0 => {
                if b == SYNC0 {
                    self.state = State::Sync1;
                }
            }
            State::Sync1 => {
                self.state = match b {
                    SYNC1 => State::Kind,
                    SYNC0 => State::Sync1,
                    _ => State::Sync0,
                };
            }
            State::Kind => {
                self.kind = b;
                self.state = State::Seq;
            }
            State::Seq => {
                self.seq = b;
                self.state = State::Len;
            }
            State::Len => {
                if b as usize > MAX_PAYLOAD {
                    return self.fail(FrameError::TooLong(b));
                }
                self.len = b;
                self.pos = 0;
                self.state = if b == 0 { State::Crc0 } else { State::Payload };
            }
            State::Payload => {
                if let Some(slot) = self.payload.get_mut(self.pos as usize) {
                    *slot = b;
                }
                self.pos += 1;
                if self.pos >= self.len {
                    self.state = State::Crc0;
                }
            }
            State::Crc0 => {
                self.crc_lo = b;
                self.state = State::Crc1;
            }
            State::Crc1 => {
                self.state = State::Sync0;
                let got = u16::from_le_bytes([self.crc_lo, b]);
                let crc = crc16_update(crc16(&[self.kind, self.seq, self.len]), self.payload());
                if got != crc {
                    return self.fail(FrameError::Crc);
                }
                let Some(kind) = Kind::from_u8(self.kind) else {
                    return self.fail(FrameError::UnknownKind(self.kind));
                };
                self.ok = self.ok.wrapping_add(1);
                return Some(Ok(Frame {
                    kind,
                    seq: self.seq,
                    len: self.len,
                    payload: self.payload,
                }));
            }
        }
        None
    }

    fn payload(&self) -> &[u8] {
        self.payload.get(..self.len as usize).unwrap_or(&[])
    }
}

/// Tracks the sequence numbers of accepted frames: counts the frames lost in
/// gaps and rejects duplicates (a repeated sequence number).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SeqTracker {
    last: Option<u8>,
    /// Frames missing from gaps in the sequence seen so far.
    pub lost: u16,
    /// Duplicates rejected.
    pub duplicates: u16,
}

impl SeqTracker {
    /// A tracker that has seen nothing yet.
    pub const fn new() -> Self {
        SeqTracker {
            last: None,
            lost: 0,
            duplicates: 0,
        }
    }
    /// Records `seq`; returns `false` (and counts it) for a duplicate of the last one.
    pub fn accept(&mut self, seq: u8) -> bool {
        if let Some(last) = self.last {
            let gap = seq.wrapping_sub(last);
            if gap == 0 {
                self.duplicates = self.duplicates.wrapping_add(1);
                return false;
            }
            self.lost = self.lost.wrapping_add(gap as u16 - 1);
        }
        self.last = Some(seq);
        true
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn wire(kind: Kind, seq: u8, payload: &[u8]) -> Vec<u8> {
        let mut out = [0u8; MAX_FRAME];
        let n = Frame::new(kind, seq, payload)
            .unwrap()
            .encode(&mut out)
            .unwrap();
        out[..n].to_vec()
    }

    fn decode_all(bytes: &[u8]) -> (Vec<Frame>, Vec<FrameError>) {
        let mut d = FrameDecoder::new();
        let (mut ok, mut bad) = (vec![], vec![]);
        for &b in bytes {
            match d.push(b) {
                Some(Ok(f)) => ok.push(f),
                Some(Err(e)) => bad.push(e),
                None => {}
            }
        }
        (ok, bad)
    }

    #[test]
    fn command_round_trip() {
        let c = Command {
            gyro: [0.1, -0.2, 2.5],
            reference: [1.0, -1.0, 0.5],
            throttle: 1500.0,
        };
        let (ok, bad) = decode_all(&wire(Kind::Command, 3, &c.to_payload()));
        assert!(bad.is_empty());
        assert_eq!(Command::from_frame(&ok[0]).unwrap(), c);
        assert!(c.is_finite());
        let nan = Command {
            throttle: f32::NAN,
            ..c
        };
        assert!(!nan.is_finite());
    }

    #[test]
    fn reply_round_trip_and_kind_check() {
        let r = Reply {
            cmd_seq: 9,
            status: status::HOLD,
            pwm: [1000, 1500, 2000, 1800],
            kalman_cycles: 1234,
            solver_cycles: 150_000,
            period_cycles: 170_000,
            iterations: 17,
            frame_errors: 2,
        };
        let (ok, _) = decode_all(&wire(Kind::Reply, 200, &r.to_payload()));
        assert_eq!(Reply::from_frame(&ok[0]).unwrap(), r);
        assert_eq!(Command::from_frame(&ok[0]), Err(FrameError::BadLength));
    }

    #[test]
    fn corrupted_frame_is_rejected_and_the_next_one_decodes() {
        let mut bytes = wire(Kind::Command, 1, &[5; Command::LEN]);
        bytes[10] ^= 0x10; // a payload bit flips on the line
        bytes.extend(wire(Kind::Command, 2, &[6; Command::LEN]));
        let (ok, bad) = decode_all(&bytes);
        assert_eq!(bad, vec![FrameError::Crc]);
        assert_eq!(ok.len(), 1);
        assert_eq!(ok[0].seq, 2);
    }

    #[test]
    fn oversized_length_and_unknown_kind_are_rejected() {
        let mut bytes = vec![SYNC0, SYNC1, 0x01, 0, 200];
        bytes.extend(wire(Kind::Command, 4, &[1, 2]));
        let mut unknown = wire(Kind::Command, 5, &[]);
        unknown[2] = 0x33;
        let crc = crc16(&unknown[2..5]);
        unknown[5..7].copy_from_slice(&crc.to_le_bytes());
        bytes.extend(unknown);
        let (ok, bad) = decode_all(&bytes);
        assert_eq!(
            bad,
            vec![FrameError::TooLong(200), FrameError::UnknownKind(0x33)]
        );
        assert_eq!(ok.len(), 1);
        assert_eq!(ok[0].seq, 4);
    }

    #[test]
    fn truncated_frame_is_dropped_by_reset() {
        let bytes = wire(Kind::Command, 1, &[7; 10]);
        let mut d = FrameDecoder::new();
        for &b in &bytes[..8] {
            assert!(d.push(b).is_none());
        }
        assert_eq!(d.reset(), Err(FrameError::Truncated));
        assert_eq!(d.reset(), Ok(()));
        let got: Vec<_> = bytes.iter().filter_map(|&b| d.push(b)).collect();
        assert_eq!(got.len(), 1);
        assert_eq!(d.errors, 1);
        assert_eq!(d.ok, 1);
    }

    #[test]
    fn sequence_gaps_and_duplicates() {
        let mut t = SeqTracker::new();
        assert!(t.accept(254));
        assert!(t.accept(255));
        assert!(t.accept(2)); // 0 and 1 dropped, across the wrap
        assert!(!t.accept(2));
        assert_eq!((t.lost, t.duplicates), (2, 1));
    }

    #[test]
    fn boot_round_trip() {
        let b = Boot {
            table_address: 0x1_2345,
            table_len: 152,
            crc_read: 0xBEEF,
            crc_expected: 0xBEEF,
            config: 0x11,
            mac_mismatches: 0,
        };
        let (ok, _) = decode_all(&wire(Kind::Boot, 0, &b.to_payload()));
        assert_eq!(Boot::from_frame(&ok[0]).unwrap(), b);
    }

    #[test]
    fn bench_round_trip() {
        let b = Bench {
            id: 2,
            ok: 1,
            iterations: 56,
            n: 4,
            p: 9,
            cycles: 123_456,
        };
        let (ok, _) = decode_all(&wire(Kind::Bench, 2, &b.to_payload()));
        assert_eq!(Bench::from_frame(&ok[0]).unwrap(), b);
    }

    #[test]
    fn encode_needs_room() {
        let f = Frame::new(Kind::Reply, 0, &[0; 10]).unwrap();
        assert_eq!(f.encode(&mut [0u8; 16]), Err(FrameError::BufferTooSmall));
        assert!(Frame::new(Kind::Reply, 0, &[0; MAX_PAYLOAD + 1]).is_none());
    }

    proptest! {
        /// Any stream of frames, with arbitrary garbage between them, decodes
        /// to exactly the frames sent (garbage never contains a sync pattern here).
        #[test]
        fn frames_survive_interleaved_garbage(
            frames in proptest::collection::vec((0u8..=255, proptest::collection::vec(any::<u8>(), 0..MAX_PAYLOAD)), 1..6),
            garbage in proptest::collection::vec(0u8..0xA0, 0..20),
        ) {
            let mut bytes = vec![];
            for (seq, p) in &frames {
                bytes.extend(&garbage);
                bytes.extend(wire(Kind::Reply, *seq, p));
            }
            let (ok, _) = decode_all(&bytes);
            prop_assert_eq!(ok.len(), frames.len());
            for (f, (seq, p)) in ok.iter().zip(&frames) {
                prop_assert_eq!(f.seq, *seq);
                prop_assert_eq!(f.payload(), &p[..]);
            }
        }

        /// A single flipped bit anywhere in a frame never yields a wrong frame:
        /// either that frame is rejected, or (a flip in the sync bytes) it is not seen at all.
        #[test]
        fn bit_flip_never_yields_a_wrong_frame(p in proptest::collection::vec(any::<u8>(), 0..MAX_PAYLOAD), bit in 0usize..1000) {
            let good = wire(Kind::Command, 42, &p);
            let mut bad = good.clone();
            let bit = bit % (bad.len() * 8);
            bad[bit / 8] ^= 1 << (bit % 8);
            let (ok, _) = decode_all(&bad);
            for f in ok {
                // The only frame that may come through is the original one
                // (impossible with a single flip, but stated as the law).
                prop_assert_eq!(f.payload(), &p[..]);
                prop_assert_eq!(f.seq, 42);
            }
        }
    }
}
