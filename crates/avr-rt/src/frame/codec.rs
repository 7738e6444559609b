//! A frame and its encoding: the wire constants, [`Kind`], [`FrameError`]
//! and [`Frame`] (built, checked and written with its CRC).

use crate::crc::crc16;

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
    /// Host to flight computer: a `Command`.
    Command = 0x01,
    /// Flight computer to host: a `Reply`.
    Reply = 0x81,
    /// Flight computer to host, once after reset: a `Boot` self-test report.
    Boot = 0x82,
    /// Flight computer to host, after boot in benchmark builds: a `Bench` timing.
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
///
/// Two frames are equal when their kind, sequence number and payload
/// bytes are ([`Frame::payload`]; the unused rest of the buffer, which
/// the decoder does not clear, is not compared).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// The frame kind.
    pub kind: Kind,
    /// The sender's sequence number.
    pub seq: u8,
    pub(super) len: u8,
    pub(super) payload: [u8; MAX_PAYLOAD],
}

impl PartialEq for Frame {
    fn eq(&self, other: &Frame) -> bool {
        (self.kind, self.seq, self.payload()) == (other.kind, other.seq, other.payload())
    }
}

impl Eq for Frame {}

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
        // `len <= MAX_PAYLOAD` by construction; `get` keeps the panic path out.
        self.payload.get(..self.len as usize).unwrap_or(&[])
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
