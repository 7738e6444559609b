//! The real flight logs of `../shared/data/flight` (see its README): what
//! each yields, checked against independent figures (the `fc-blackbox`
//! crate's own snapshot of `btfl_002.bbl`, the README's flight times).

use kestrel_logs::{
    ImportSettings, LogFormat, ReadOptions, SegmentChoice, Unit, import, read_bytes,
};
use std::path::PathBuf;

fn flight(file: &str) -> Vec<u8> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/flight")
        .join(file);
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn betaflight_matches_fc_blackbox_snapshot() {
    let logs = read_bytes(&flight("betaflight/btfl_002.bbl"), &ReadOptions::default()).unwrap();
    assert_eq!(logs.len(), 1);
    let log = &logs[0];
    assert_eq!(log.format, LogFormat::Betaflight);
    assert!(log.issues.is_empty());
    let main = log.topic("main").unwrap();
    // fc-blackbox's snapshot: main 66640, slow 17.
    assert_eq!(main.t.len(), 66_640);
    assert_eq!(log.topic("slow").unwrap().t.len(), 17);
    // Its histogram of gyroADC[0] (raw deg/s): zeros, and per power of two
    // 2^k <= |v| < 2^(k+1) (k = 0..9) of the positive and negative values.
    let g = main.field("gyroADC[0]").unwrap();
    assert_eq!(g.unit, Unit::RadPerSecond);
    let raw: Vec<i64> = g
        .values
        .iter()
        .map(|v| v.to_degrees().round() as i64)
        .collect();
    assert_eq!(raw.iter().filter(|&&v| v == 0).count(), 3154);
    let bins = |sign: i64| -> Vec<usize> {
        (0..10)
            .map(|k| {
                raw.iter()
                    .filter(|&&v| v * sign >= 1 << k && v * sign < 1 << (k + 1))
                    .count()
            })
            .collect()
    };
    assert_eq!(
        bins(1),
        [2367, 2618, 3158, 4087, 5929, 5910, 3191, 2147, 481, 533]
    );
    assert_eq!(
        bins(-1).iter().sum::<usize>(),
        1069 + 2323 + 4583 + 7623 + 6458 + 4443 + 3725 + 2841
    );
    // Flips up to about 730 deg/s on roll (README).
    let max = g.values.iter().copied().fold(0.0, f64::max).to_degrees();
    assert!((700.0..760.0).contains(&max), "{max}");
    // 500 Hz logging (8 kHz loop, every 16th); motor range from the header.
    let dt = (main.t[main.t.len() - 1] - main.t[0]) / (main.t.len() - 1) as f64;
    assert!((dt - 0.002).abs() < 2e-5, "{dt}");
    let m = main.field("motor[0]").unwrap();
    assert_eq!(m.range, Some([158.0, 2047.0]));
    assert!(m.values.iter().all(|&v| (48.0..=2047.0).contains(&v)));
}

#[test]
fn betaflight_airborne_and_multi_log() {
    let one = flight("betaflight/btfl_002.bbl");
    // Two logs back to back, as the firmware writes them, and a third one
    // armed and disarmed at once: its header and the end event only.
    let mut end = 0;
    while one[end..].starts_with(b"H ") {
        end += one[end..].iter().position(|&c| c == b'\n').unwrap() + 1;
    }
    let header = &one[..end];
    let empty = [header, b"E\xffEnd of log\0"].concat();
    let three = [one.clone(), one, empty].concat();
    let logs = read_bytes(&three, &ReadOptions::default()).unwrap();
    assert_eq!(logs.len(), 3);
    assert_eq!(logs[0].topics, logs[1].topics);
    assert!(logs[2].topic("main").unwrap().t.is_empty());
    let imp = import(&logs, &ImportSettings::default()).unwrap();
    assert_eq!(imp.logs.len(), 3);
    assert!(imp.logs[2].segments.is_empty() && imp.logs[2].span.start.is_nan());
    assert_eq!(imp.experiments.len(), 2);
    for l in &imp.logs[..2] {
        // Airborne from about 17.5 s of flight to the log's end at 151 s (README).
        assert_eq!(l.segments.len(), 1, "{:?}", l.segments);
        let s = l.segments[0];
        assert!((18.0..20.0).contains(&s.start) && s.end > 150.0, "{s:?}");
    }
    let names: Vec<&str> = imp.signals.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        names,
        ["motor0", "motor1", "motor2", "motor3", "p", "q", "r"]
    );
    let csv = imp.to_csv();
    assert!(csv.starts_with("t,motor0,motor1,motor2,motor3,p,q,r,experiment\n"));
    assert_eq!(csv.lines().count(), 1 + imp.n_samples());
    assert!(csv.trim_end().ends_with(",2"));
}

#[test]
fn crazyflie_logs_yield_their_flights() {
    // (file, records, airborne seconds per segment from the README)
    let cases: [(&str, usize, &[f64]); 3] = [
        ("crazyflie/log10", 50_496, &[37.0]),
        ("crazyflie/log15", 62_774, &[43.0]),
        ("crazyflie/log16", 47_182, &[8.0, 6.0]),
    ];
    for (file, records, flights) in cases {
        let logs = read_bytes(&flight(file), &ReadOptions::default()).unwrap();
        let log = &logs[0];
        assert_eq!(log.format, LogFormat::Crazyflie);
        let topic = &log.topics[0];
        assert_eq!(topic.t.len(), records, "{file}");
        let rate = (topic.t.len() - 1) as f64 / (topic.t[topic.t.len() - 1] - topic.t[0]);
        assert!((1000.0..1020.0).contains(&rate), "{file}: {rate}");
        assert_eq!(topic.field("gyro.x").unwrap().unit, Unit::RadPerSecond);
        for rate_hz in [50.0, 500.0] {
            let imp = import(
                &logs,
                &ImportSettings {
                    rate_hz,
                    ..Default::default()
                },
            )
            .unwrap();
            let segs = &imp.logs[0].segments;
            assert_eq!(segs.len(), flights.len(), "{file}: {segs:?}");
            for (s, want) in segs.iter().zip(flights) {
                // Trimmed by 0.5 s at each end.
                let d = s.end - s.start + 1.0;
                assert!((d - want).abs() < 1.5, "{file}: {d} s, README {want} s");
            }
            for e in &imp.experiments {
                let dt: Vec<f64> = e.t.windows(2).map(|w| w[1] - w[0]).collect();
                assert!(dt.iter().all(|d| (d - 1.0 / rate_hz).abs() < 1e-9));
                assert!(e.columns.iter().flatten().all(|v| v.is_finite()));
            }
        }
    }
}

#[test]
fn the_whole_log_and_cell_means() {
    let logs = read_bytes(&flight("crazyflie/log16"), &ReadOptions::default()).unwrap();
    let settings = ImportSettings {
        rate_hz: 50.0,
        segment: SegmentChoice::All,
        ..Default::default()
    };
    let imp = import(&logs, &settings).unwrap();
    assert_eq!(imp.experiments.len(), 1);
    let e = &imp.experiments[0];
    // Cell k's p is the mean of the gyro.x samples in its 20 ms.
    let topic = &logs[0].topics[0];
    let gx = &topic.field("gyro.x").unwrap().values;
    let p = imp.signals.iter().position(|s| s.name == "p").unwrap();
    for k in [0, 100, 1000, e.t.len() - 1] {
        let (a, b) = (e.t[k] - 0.01, e.t[k] + 0.01);
        let cell: Vec<f64> = topic
            .t
            .iter()
            .zip(gx)
            .filter(|(t, _)| **t >= a && **t < b)
            .map(|(_, v)| *v)
            .collect();
        let mean = cell.iter().sum::<f64>() / cell.len() as f64;
        assert!((e.columns[p][k] - mean).abs() < 1e-9, "cell {k}");
    }
}

#[test]
fn segments_do_not_hang_on_the_threshold() {
    // Hover is about 0.2 (Betaflight) and 0.6 (Crazyflie) of the command
    // range, the ground 0: any threshold from 0.03 to 0.15 finds the same
    // flights to within 0.3 s.
    for file in [
        "betaflight/btfl_002.bbl",
        "crazyflie/log10",
        "crazyflie/log15",
        "crazyflie/log16",
    ] {
        let logs = read_bytes(&flight(file), &ReadOptions::default()).unwrap();
        let segments = |threshold| {
            let mut s = ImportSettings::default();
            s.airborne.threshold = threshold;
            import(&logs, &s).unwrap().logs[0].segments.clone()
        };
        let reference = segments(0.05);
        for threshold in [0.03, 0.1, 0.15] {
            let other = segments(threshold);
            assert_eq!(other.len(), reference.len(), "{file} at {threshold}");
            for (a, b) in other.iter().zip(&reference) {
                assert!(
                    (a.start - b.start).abs() < 0.3 && (a.end - b.end).abs() < 0.3,
                    "{file} at {threshold}: {a:?} vs {b:?}"
                );
            }
        }
    }
}

#[test]
fn no_segment_left_names_every_setting_that_can_cause_it() {
    // A trim longer than the flight leaves nothing: the error must point at
    // --trim as well, not only at the threshold.
    let logs = read_bytes(&flight("betaflight/btfl_002.bbl"), &ReadOptions::default()).unwrap();
    let mut s = ImportSettings::default();
    s.airborne.trim_s = 1e4;
    let e = import(&logs, &s).unwrap_err().to_string();
    assert!(
        e.contains("no airborne segment")
            && e.contains("10000 s are trimmed")
            && e.contains("--trim"),
        "{e}"
    );
    s.airborne.trim_s = 0.5;
    assert!(import(&logs, &s).is_ok());
}

/// Airborne settings out of range are refused naming the setting and the
/// value (not as a dump of the settings struct).
#[test]
fn bad_airborne_settings_name_the_setting() {
    let logs = read_bytes(&flight("betaflight/btfl_002.bbl"), &ReadOptions::default()).unwrap();
    for name in ["threshold", "minimum duration", "bridged gap", "trim"] {
        let mut s = ImportSettings::default();
        let a = &mut s.airborne;
        match name {
            "threshold" => a.threshold = f64::NAN,
            "minimum duration" => a.min_duration_s = -1.0,
            "bridged gap" => a.bridge_s = f64::NAN,
            _ => a.trim_s = -0.5,
        }
        let e = import(&logs, &s).unwrap_err().to_string();
        assert!(
            e.contains(name) && !e.contains("AirborneSettings"),
            "{name}: {e}"
        );
    }
}
