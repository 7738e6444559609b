//! [`FrameDecoder`]: frames from the byte stream, one byte at a time,
//! with CRC check and resynchronisation.

use super::codec::{Frame, FrameError, Kind, MAX_PAYLOAD, SYNC0, SYNC1};
use crate::crc::{crc16, crc16_update};

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
