//! Thousands of mutated copies (bit flips, overwritten bytes, cut,
//! deleted and repeated ranges) of small logs of each format, read strict
//! and salvaging and imported: every outcome is a log or an error that
//! names an offset inside the input (or says why it is not a log), never a
//! panic. A stable-toolchain stand-in for fuzzing, seeded.

mod common;

use common::Writer;
use kestrel_logs::{ImportSettings, LogError, ReadOptions, import, read_bytes};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;
use std::path::PathBuf;

fn flight(file: &str) -> Vec<u8> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/flight")
        .join(file);
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The Betaflight header, its first 4,000 bytes of frames and the end event.
fn small_betaflight() -> Vec<u8> {
    let bf = flight("betaflight/btfl_002.bbl");
    let mut end = 0;
    while bf[end..].starts_with(b"H ") {
        end += bf[end..].iter().position(|&c| c == b'\n').unwrap() + 1;
    }
    // Cut before the frame marker nearest 4,000 bytes on (an I or P frame).
    let mut cut = end + 4000;
    while !matches!(bf[cut], b'I' | b'P') {
        cut += 1;
    }
    [&bf[..cut], b"E\xffEnd of log\0"].concat()
}

/// The Crazyflie header, 60 records and a fresh CRC-32 trailer.
fn small_crazyflie() -> Vec<u8> {
    let cf = flight("crazyflie/log16");
    let body = &cf[..129 + 60 * 50];
    let crc = crc32(body);
    [body, &crc.to_le_bytes()].concat()
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                0xEDB8_8320 ^ (crc >> 1)
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

fn small_ulog() -> Vec<u8> {
    let mut w = Writer::new();
    w.format("vehicle_angular_velocity:uint64_t timestamp;float[3] xyz;");
    w.format("actuator_motors:uint64_t timestamp;float[4] control;");
    w.subscribe(0, 0, "vehicle_angular_velocity");
    w.subscribe(0, 1, "actuator_motors");
    for k in 0..200u64 {
        w.data(0, 1000 * k, &[k as f32, 0.0, 1.0], &[]);
        w.data(1, 1000 * k, &[0.5; 4], &[]);
    }
    w.0
}

fn mutate(rng: &mut SplitMix64, seed: &[u8]) -> Vec<u8> {
    let mut v = seed.to_vec();
    let pick = |rng: &mut SplitMix64, n: usize| (rng.random::<f64>() * n as f64) as usize;
    for _ in 0..1 + pick(rng, 3) {
        if v.is_empty() {
            break;
        }
        let at = pick(rng, v.len());
        match pick(rng, 5) {
            0 => v[at] ^= 1 << pick(rng, 8),
            1 => v[at] = pick(rng, 256) as u8,
            2 => v.truncate(at),
            3 => {
                let end = (at + 1 + pick(rng, 64)).min(v.len());
                v.drain(at..end);
            }
            _ => {
                let end = (at + 1 + pick(rng, 64)).min(v.len());
                let piece = v[at..end].to_vec();
                let to = pick(rng, v.len());
                v.splice(to..to, piece);
            }
        }
    }
    v
}

fn check(input: &[u8], e: &LogError) {
    match e {
        LogError::Corrupt { offset, .. } | LogError::Truncated { offset, .. } => {
            assert!(*offset <= input.len() as u64, "{e}")
        }
        LogError::UnknownFormat { .. }
        | LogError::Empty(_)
        | LogError::Signal { .. }
        | LogError::Invalid(_) => {}
        LogError::Io { .. } => panic!("no file was read: {e}"),
    }
}

#[test]
fn mutated_logs_read_or_fail_cleanly() {
    let mut rng = SplitMix64::seed_from_u64(2026);
    for (name, seed) in [
        ("betaflight", small_betaflight()),
        ("crazyflie", small_crazyflie()),
        ("ulog", small_ulog()),
    ] {
        // The seeds themselves are good logs.
        let logs = read_bytes(&seed, &ReadOptions::default()).unwrap();
        let imp = import(
            &logs,
            &ImportSettings {
                segment: kestrel_logs::SegmentChoice::All,
                ..Default::default()
            },
        );
        assert!(imp.is_ok(), "{name}: {imp:?}");
        let mut errors = 0;
        for _ in 0..4000 {
            let input = mutate(&mut rng, &seed);
            for salvage in [false, true] {
                match read_bytes(&input, &ReadOptions { salvage }) {
                    Ok(logs) => {
                        if let Err(e) = import(&logs, &ImportSettings::default()) {
                            check(&input, &e);
                        }
                    }
                    Err(e) => {
                        errors += 1;
                        check(&input, &e);
                    }
                }
            }
        }
        assert!(
            errors > 300,
            "{name}: only {errors} of 8,000 mutated reads failed"
        );
    }
}

#[test]
fn fuzzing_finds_stay_fixed() {
    // A mutated ULog (found by libFuzzer) whose salvaged topics have 2 and
    // 3 samples spread over 10^11 s or more: resampling it once asked for
    // a grid of about 10^13 cells. Now a clean error; any clock gives a
    // grid in proportion to the samples.
    let bytes = std::fs::read(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/fuzz-ulog-huge-grid.ulg"),
    )
    .unwrap();
    let e = read_bytes(&bytes, &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("byte offset 364"), "{e}");
    let logs = read_bytes(&bytes, &ReadOptions { salvage: true }).unwrap();
    for segment in [
        kestrel_logs::SegmentChoice::Airborne,
        kestrel_logs::SegmentChoice::All,
    ] {
        let settings = ImportSettings {
            segment,
            ..Default::default()
        };
        if let Err(e) = import(&logs, &settings) {
            check(&bytes, &e);
        }
    }
}
