//! Truncated and bit-flipped copies of every real log (made here, in
//! memory): an error naming the byte offset and what was expected, or (a
//! flip the format cannot see) a log read in full; never a panic. With
//! salvage, the readable part and the problem's offset.

use kestrel_logs::{LogError, ReadOptions, read_bytes};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;
use std::path::PathBuf;

const FILES: [&str; 4] = [
    "betaflight/btfl_002.bbl",
    "crazyflie/log10",
    "crazyflie/log15",
    "crazyflie/log16",
];

fn flight(file: &str) -> Vec<u8> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/flight")
        .join(file);
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn strict() -> ReadOptions {
    ReadOptions::default()
}

/// The byte offset an error names.
fn offset(e: &LogError) -> Option<u64> {
    match e {
        LogError::Corrupt { offset, .. } | LogError::Truncated { offset, .. } => Some(*offset),
        _ => None,
    }
}

/// Crazyflie header length and record size of the real logs (one event
/// type, 10 variables of 4 bytes, u64 timestamps).
const CF_HEADER: usize = 129;
const CF_RECORD: usize = 50;

#[test]
fn truncated_copies_are_errors_naming_the_offset() {
    let mut rng = SplitMix64::seed_from_u64(21);
    for file in FILES {
        let bytes = flight(file);
        // Betaflight's erased-flash tail (0xFF) after "End of log" is no loss.
        let end = bytes.len() - bytes.iter().rev().take_while(|&&b| b == 0xff).count();
        let mut cuts = vec![10, 60, end / 2, end - 7];
        cuts.extend((0..4).map(|_| (rng.random::<f64>() * end as f64) as usize));
        for cut in cuts {
            let cut = if file.starts_with("crazyflie")
                && cut > CF_HEADER
                && (cut - CF_HEADER).is_multiple_of(CF_RECORD)
            {
                cut + 1 // a cut between records is a shorter log; see below
            } else {
                cut
            };
            let e = read_bytes(&bytes[..cut], &strict())
                .err()
                .unwrap_or_else(|| panic!("{file} cut at {cut} read without error"));
            let text = e.to_string();
            let at = offset(&e).unwrap_or_else(|| panic!("{file} cut at {cut}: {text}"));
            assert!(at <= cut as u64, "{file} cut at {cut}: {text}");
            assert!(
                text.contains(&format!("byte offset {at}")) && text.contains("expected"),
                "{text}"
            );
        }
    }
}

#[test]
fn a_crazyflie_log_cut_between_records_is_a_shorter_log() {
    // Without its CRC-32 trailer a log cut at a record boundary cannot be
    // told from one written by a firmware that adds none.
    let bytes = flight("crazyflie/log16");
    let cut = CF_HEADER + 1000 * CF_RECORD;
    let logs = read_bytes(&bytes[..cut], &strict()).unwrap();
    assert_eq!(logs[0].topics[0].t.len(), 1000);
}

#[test]
fn bit_flips_never_panic() {
    let mut rng = SplitMix64::seed_from_u64(2121);
    for file in FILES {
        let bytes = flight(file);
        for _ in 0..10 {
            let mut copy = bytes.clone();
            let at = (rng.random::<f64>() * copy.len() as f64) as usize;
            copy[at] ^= 1 << ((rng.random::<f64>() * 8.0) as u32);
            match read_bytes(&copy, &strict()) {
                Ok(logs) => {
                    // Only a Betaflight value can change unseen (no checksum);
                    // a Crazyflie record is covered by the CRC-32.
                    assert!(
                        file.starts_with("betaflight"),
                        "{file}: flip at {at} unseen"
                    );
                    assert!(!logs.is_empty());
                }
                Err(e) => {
                    let text = e.to_string();
                    assert!(
                        offset(&e).is_some() || matches!(e, LogError::UnknownFormat { .. }),
                        "{file}: flip at {at}: {text}"
                    );
                }
            }
        }
    }
}

#[test]
fn targeted_damage_is_named_where_it_is() {
    // Crazyflie: record 1000's event id.
    let mut cf = flight("crazyflie/log15");
    let at = CF_HEADER + 1000 * CF_RECORD;
    cf[at] = 0x12;
    let e = read_bytes(&cf, &strict()).unwrap_err();
    assert_eq!(offset(&e), Some(at as u64), "{e}");
    assert!(e.to_string().contains("event id"), "{e}");
    // ... a timestamp running backwards (record 2000's high byte).
    let mut cf = flight("crazyflie/log15");
    let at = CF_HEADER + 2000 * CF_RECORD;
    cf[at + 2] = 0;
    cf[at + 3] = 0;
    cf[at + 4] = 0;
    let e = read_bytes(&cf, &strict()).unwrap_err();
    assert_eq!(offset(&e), Some(at as u64 + 2), "{e}");
    // ... a value: only the CRC-32 trailer sees it.
    let mut cf = flight("crazyflie/log15");
    cf[CF_HEADER + 3000 * CF_RECORD + 20] ^= 0x40;
    let e = read_bytes(&cf, &strict()).unwrap_err();
    assert_eq!(offset(&e), Some(cf.len() as u64 - 4), "{e}");
    assert!(e.to_string().contains("CRC-32"), "{e}");
    // Betaflight: an encoding number in the header, and the first frame's marker.
    let bf = flight("betaflight/btfl_002.bbl");
    let line = b"H Field I encoding:1,1,0";
    let at = bf.windows(line.len()).position(|w| w == line).unwrap();
    let mut copy = bf.clone();
    copy[at + line.len() - 3] = b'2';
    let e = read_bytes(&copy, &strict()).unwrap_err();
    assert_eq!(offset(&e), Some(at as u64), "{e}");
    assert!(e.to_string().contains("encoding numbers"), "{e}");
    let data = header_end(&bf);
    assert!(b"IE".contains(&bf[data]), "{}", bf[data]);
    let mut copy = bf.clone();
    copy[data] = b'X';
    let e = read_bytes(&copy, &strict()).unwrap_err();
    assert_eq!(offset(&e), Some(data as u64), "{e}");
    assert!(e.to_string().contains("frame marker"), "{e}");
}

/// Offset of the first byte after the `H ...` lines.
fn header_end(b: &[u8]) -> usize {
    let mut pos = 0;
    while b[pos..].starts_with(b"H ") {
        pos += b[pos..].iter().position(|&c| c == b'\n').unwrap() + 1;
    }
    pos
}

#[test]
fn salvage_keeps_the_readable_part() {
    let salvage = ReadOptions { salvage: true };
    let bf = flight("betaflight/btfl_002.bbl");
    let half = &bf[..bf.len() / 2];
    let logs = read_bytes(half, &salvage).unwrap();
    let n = logs[0].topic("main").unwrap().t.len();
    assert!((25_000..45_000).contains(&n), "{n} of 66,640 frames");
    assert_eq!(logs[0].issues.len(), 1);
    assert!(logs[0].issues[0].offset <= half.len() as u64);
    // A damaged frame in the middle: skipped to the next intra frame.
    let mut copy = bf.clone();
    let mid = bf.len() / 2;
    copy[mid..mid + 4].copy_from_slice(b"XXXX");
    let logs = read_bytes(&copy, &salvage).unwrap();
    let n = logs[0].topic("main").unwrap().t.len();
    assert!((66_000..66_640).contains(&n), "{n}");
    assert!(
        logs[0].issues[0].text.contains("skipped"),
        "{:?}",
        logs[0].issues
    );
    // Crazyflie: a CRC mismatch is noted, the records kept.
    let mut cf = flight("crazyflie/log10");
    cf[CF_HEADER + 10 * CF_RECORD + 20] ^= 1;
    let logs = read_bytes(&cf, &salvage).unwrap();
    assert_eq!(logs[0].topics[0].t.len(), 50_496);
    assert!(logs[0].issues[0].text.contains("CRC-32"));
}
