//! PX4 ULog through px4-ulog, on logs written here by a small ULog writer
//! (header, flag bits, formats, subscriptions, data records as the ULog
//! specification lays them out): the samples come back as written, the
//! default signals and the airborne segment are found, and truncated,
//! bit-flipped and malformed copies are errors naming the record's offset.

use kestrel_logs::{ImportSettings, LogError, LogFormat, ReadOptions, import, read_bytes};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

mod common;
use common::Writer;

/// 10 s: body rates at 800 Hz (p = sin(2 pi t), q = t, r = -1), four of
/// twelve motor controls at 400 Hz (0 on the ground, 0.5 from 2 s to 7 s,
/// the rest NaN).
fn flight() -> Vec<u8> {
    let mut w = Writer::new();
    w.format("vehicle_angular_velocity:uint64_t timestamp;float[3] xyz;");
    w.format("actuator_motors:uint64_t timestamp;float[12] control;uint16_t reversible_flags;uint8_t[2] _padding0;");
    w.subscribe(0, 0, "vehicle_angular_velocity");
    w.subscribe(0, 1, "actuator_motors");
    for k in 0..8000u64 {
        let t = k as f64 / 800.0;
        let us = 1_000_000 + k * 1250;
        w.data(
            0,
            us,
            &[
                (2.0 * std::f64::consts::PI * t).sin() as f32,
                t as f32,
                -1.0,
            ],
            &[],
        );
        if k % 2 == 0 {
            let level = if (2.0..7.0).contains(&t) { 0.5 } else { 0.0 };
            let mut c = [f32::NAN; 12];
            c[..4].fill(level);
            w.data(1, us, &c, &[0, 0]); // reversible_flags; trailing padding is not logged
        }
    }
    w.0
}

#[test]
fn samples_come_back_as_written() {
    let bytes = flight();
    assert_eq!(LogFormat::detect(&bytes), Some(LogFormat::Ulog));
    let logs = read_bytes(&bytes, &ReadOptions::default()).unwrap();
    let log = &logs[0];
    let w = log.topic("vehicle_angular_velocity").unwrap();
    assert_eq!(w.t.len(), 8000);
    assert!((w.t[1] - w.t[0] - 1.25e-3).abs() < 1e-12 && (w.t[0] - 1.0).abs() < 1e-12);
    assert_eq!(w.field("xyz[1]").unwrap().values[800], 1.0);
    assert_eq!(
        w.field("xyz[2]").unwrap().unit,
        kestrel_logs::Unit::RadPerSecond
    );
    let m = log.topic("actuator_motors").unwrap();
    assert_eq!(m.t.len(), 4000);
    assert_eq!(m.field("control[0]").unwrap().range, Some([0.0, 1.0]));
    assert!(
        m.field("control[7]")
            .unwrap()
            .values
            .iter()
            .all(|v| v.is_nan())
    );
}

#[test]
fn default_signals_and_the_airborne_segment() {
    let logs = read_bytes(&flight(), &ReadOptions::default()).unwrap();
    let imp = import(&logs, &ImportSettings::default()).unwrap();
    let names: Vec<&str> = imp.signals.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        names,
        ["motor0", "motor1", "motor2", "motor3", "p", "q", "r"]
    );
    assert_eq!(imp.experiments.len(), 1);
    let seg = imp.logs[0].segments[0];
    // Motors up from 3 s to 8 s of the clock (started at 1 s), trimmed 0.5 s.
    assert!(
        (seg.start - 3.5).abs() < 0.11 && (seg.end - 7.5).abs() < 0.11,
        "{seg:?}"
    );
    // q = t: each 20 ms cell holds 16 samples 1/800 s apart, whose mean is
    // the cell's centre within half a sample interval (a sample on a cell
    // edge goes to one side or the other by rounding).
    let e = &imp.experiments[0];
    for (t, q) in e.t.iter().zip(&e.columns[5]) {
        assert!((q - (t - 1.0)).abs() <= 0.5 / 800.0 + 1e-5, "{t}: {q}");
    }
}

fn offset(e: &LogError) -> Option<u64> {
    match e {
        LogError::Corrupt { offset, .. } | LogError::Truncated { offset, .. } => Some(*offset),
        _ => None,
    }
}

#[test]
fn damaged_copies_are_errors_at_a_record() {
    let bytes = flight();
    // Cut inside a record (records here are 3 + 2 + 8 + 12 or 3 + 2 + 8 + 52 bytes).
    let mut rng = SplitMix64::seed_from_u64(7);
    for _ in 0..8 {
        let cut = 20 + (rng.random::<f64>() * (bytes.len() - 20) as f64) as usize;
        match read_bytes(&bytes[..cut], &ReadOptions::default()) {
            Ok(logs) => assert!(logs[0].topics.iter().all(|t| t.t.len() <= 8000)),
            Err(e) => {
                let at = offset(&e).unwrap_or_else(|| panic!("cut {cut}: {e}"));
                assert!(at < cut as u64 && e.to_string().contains("expected"), "{e}");
            }
        }
    }
    for _ in 0..40 {
        let mut copy = bytes.clone();
        let at = (rng.random::<f64>() * copy.len() as f64) as usize;
        copy[at] ^= 1 << ((rng.random::<f64>() * 8.0) as u32);
        if let Err(e) = read_bytes(&copy, &ReadOptions::default()) {
            assert!(
                offset(&e).is_some() || matches!(e, LogError::UnknownFormat { .. }),
                "{e}"
            );
        }
    }
    // A subscription record too short for its fields, a parameter whose key
    // runs past its end, a data record of an unknown subscription.
    let mut w = Writer::new();
    w.format("vehicle_angular_velocity:uint64_t timestamp;float[3] xyz;");
    let at = w.0.len();
    w.record(b'A', &[0, 0]);
    let e = read_bytes(&w.0, &ReadOptions::default()).unwrap_err();
    assert_eq!(offset(&e), Some(at as u64), "{e}");
    let mut w = Writer::new();
    let at = w.0.len();
    w.record(b'P', &[200, b'x']);
    let e = read_bytes(&w.0, &ReadOptions::default()).unwrap_err();
    assert_eq!(offset(&e), Some(at as u64), "{e}");
    let mut w = Writer::new();
    w.format("vehicle_angular_velocity:uint64_t timestamp;float[3] xyz;");
    w.subscribe(0, 0, "vehicle_angular_velocity");
    let at = w.0.len();
    w.data(5, 0, &[0.0; 3], &[]);
    let e = read_bytes(&w.0, &ReadOptions::default()).unwrap_err();
    assert_eq!(offset(&e), Some(at as u64), "{e}");
    // Salvage keeps the records before the damage.
    let logs = read_bytes(&w.0, &ReadOptions { salvage: true }).unwrap();
    assert_eq!(logs[0].issues[0].offset, at as u64);
}

#[test]
fn samples_out_of_time_order_are_sorted() {
    let mut w = Writer::new();
    w.format("vehicle_angular_velocity:uint64_t timestamp;float[3] xyz;");
    w.subscribe(0, 0, "vehicle_angular_velocity");
    for (t, v) in [(3000, 3.0), (1000, 1.0), (2000, 2.0)] {
        w.data(0, t, &[v, 0.0, 0.0], &[]);
    }
    let logs = read_bytes(&w.0, &ReadOptions::default()).unwrap();
    let topic = logs[0].topic("vehicle_angular_velocity").unwrap();
    assert_eq!(topic.t, [1e-3, 2e-3, 3e-3]);
    assert_eq!(topic.field("xyz[0]").unwrap().values, [1.0, 2.0, 3.0]);
}
