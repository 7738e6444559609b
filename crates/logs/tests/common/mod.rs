//! Shared by the tests: a minimal ULog writer.

#![allow(dead_code)]

/// A ULog under construction.
pub struct Writer(pub Vec<u8>);

impl Writer {
    pub fn new() -> Self {
        let mut b = b"ULog\x01\x12\x35".to_vec();
        b.push(1); // version
        b.extend(1_000_000u64.to_le_bytes());
        let mut w = Writer(b);
        w.record(b'B', &[0; 40]); // flag bits: nothing incompatible, no appended data
        w
    }

    pub fn record(&mut self, kind: u8, payload: &[u8]) {
        self.0.extend((payload.len() as u16).to_le_bytes());
        self.0.push(kind);
        self.0.extend(payload);
    }

    pub fn format(&mut self, text: &str) {
        self.record(b'F', text.as_bytes());
    }

    pub fn subscribe(&mut self, multi_id: u8, msg_id: u16, name: &str) {
        let mut p = vec![multi_id];
        p.extend(msg_id.to_le_bytes());
        p.extend(name.as_bytes());
        self.record(b'A', &p);
    }

    pub fn data(&mut self, msg_id: u16, t_us: u64, floats: &[f32], tail: &[u8]) {
        let mut p = msg_id.to_le_bytes().to_vec();
        p.extend(t_us.to_le_bytes());
        for f in floats {
            p.extend(f.to_le_bytes());
        }
        p.extend(tail);
        self.record(b'D', &p);
    }
}
