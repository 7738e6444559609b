//! [`SeqTracker`]: lost and duplicated frames from the sequence numbers.

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
