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
//!
//! Files: `codec` (the frame and its encoding), `decoder`, `seq` (the
//! sequence tracker), `messages` (the payloads).

mod codec;
mod decoder;
mod messages;
mod seq;
#[cfg(test)]
mod tests;

pub use codec::{Frame, FrameError, Kind, MAX_FRAME, MAX_PAYLOAD, OVERHEAD, SYNC0, SYNC1};
pub use decoder::FrameDecoder;
pub use messages::{Bench, Boot, Command, Reply, status};
pub use seq::SeqTracker;
