use super::*;
use crate::crc::crc16;
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

/// Found by fuzzing (`fuzz/regressions/frame/seed-stream.bin`): the
/// decoder reuses its payload buffer, so a short frame after a long one
/// kept the long one's bytes past its length, and the derived equality
/// called the same frame on the wire unequal to itself re-encoded.
#[test]
fn frames_compare_by_their_bytes_on_the_wire() {
    let mut bytes = wire(Kind::Reply, 1, &[7; 30]);
    bytes.extend(wire(Kind::Reply, 2, &[1, 2, 3]));
    let (ok, bad) = decode_all(&bytes);
    assert!(bad.is_empty());
    assert_eq!(ok[1], Frame::new(Kind::Reply, 2, &[1, 2, 3]).unwrap());
    assert_ne!(ok[1], Frame::new(Kind::Reply, 2, &[1, 2, 4]).unwrap());
    assert_ne!(ok[1], Frame::new(Kind::Reply, 3, &[1, 2, 3]).unwrap());
}
