//! Tests of the data sets: CSV loading, selection, offsets, maps.

use super::read::snap_sample_time;
use super::{CsvColumns, IoData, Offsets, TimeInterval, TimeUnit};
use crate::error::SysidError;
use nalgebra::DMatrix;

const CSV: &str = "t,experiment,a,b,p,q\n\
    0.00,2,1,5,0.1,0.2\n0.02,2,2,5,0.2,0.1\n0.04,2,3,6,0.3,0.0\n0.06,2,4,6,0.4,0.1\n\
    0.00,3,1,1,0.5,0.5\n0.02,3,1,2,0.6,0.4\n0.04,3,2,2,0.7,0.3\n";

fn cols() -> CsvColumns {
    CsvColumns::new(&["b", "a"], &["q"])
}

#[test]
fn csv_selects_columns_and_splits_experiments() {
    let d = IoData::from_csv_reader(CSV.as_bytes(), &cols(), "mem").unwrap();
    assert!((d.ts() - 0.02).abs() < 1e-12);
    assert_eq!(d.experiments().len(), 2);
    assert_eq!(d.input_names(), &["b".to_string(), "a".to_string()]);
    let e0 = &d.experiments()[0];
    assert_eq!(e0.len(), 4);
    assert_eq!(e0.u[(2, 0)], 6.0);
    assert_eq!(e0.u[(2, 1)], 3.0);
    assert_eq!(e0.y[(3, 0)], 0.1);
}

#[test]
fn csv_sample_time_is_snapped_to_the_nominal_value() {
    // A time column accumulated in floating point and printed in full,
    // like 0.019999999999999574 steps.
    let mut text = String::from("t,a,q\n");
    let mut t = 25.0f64;
    for k in 0..200 {
        text.push_str(&format!("{t:?},{},{}\n", k % 3, k % 5));
        t += 0.02;
    }
    let d =
        IoData::from_csv_reader(text.as_bytes(), &CsvColumns::new(&["a"], &["q"]), "f").unwrap();
    assert_eq!(d.ts(), 0.02);
    assert_eq!(format!("{}", d.ts()), "0.02");
    assert_eq!(snap_sample_time(0.019999999999999574), 0.02);
    assert_eq!(snap_sample_time(0.0010000000000000009), 0.001);
    assert_eq!(snap_sample_time(1.0), 1.0);
    assert_eq!(snap_sample_time(0.1 + 0.2), 0.3);
    // A genuinely odd sample time keeps its 6 significant digits.
    assert_eq!(snap_sample_time(0.0123457), 0.0123457);
}

#[test]
fn csv_errors_are_clear() {
    let bad = CSV.replace("0.3,0.0", "0.3,NaN");
    let e = IoData::from_csv_reader(bad.as_bytes(), &cols(), "f.csv")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("f.csv") && e.contains("line 4") && e.contains("non-finite"),
        "{e}"
    );
    let e = IoData::from_csv_reader(CSV.as_bytes(), &CsvColumns::new(&["zz"], &["q"]), "f")
        .unwrap_err()
        .to_string();
    assert!(e.contains("no column \"zz\""), "{e}");
    let ragged = "t,a,q\n0,1,2\n1,2\n";
    assert!(
        IoData::from_csv_reader(ragged.as_bytes(), &CsvColumns::new(&["a"], &["q"]), "f").is_err()
    );
    let nonuni = "t,a,q\n0,1,2\n1,2,3\n3,1,1\n";
    let e = IoData::from_csv_reader(nonuni.as_bytes(), &CsvColumns::new(&["a"], &["q"]), "f")
        .unwrap_err()
        .to_string();
    assert!(e.contains("non-uniform"), "{e}");
    // A header naming a used column twice is ambiguous; an unused
    // duplicate is harmless.
    let dup = "t,a,a,q\n0,1,5,2\n1,2,6,3\n2,1,7,1\n";
    let e = IoData::from_csv_reader(dup.as_bytes(), &CsvColumns::new(&["a"], &["q"]), "f")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("\"a\" appears more than once") && e.contains("columns 2 and 3"),
        "{e}"
    );
    let d = IoData::from_csv_reader(dup.as_bytes(), &CsvColumns::new(&[], &["q"]), "f").unwrap();
    assert_eq!(d.n_samples(), 3);
    // One column as two signals.
    for (inputs, outputs, role) in [
        (&["q"][..], &["q"][..], "both an input and an output"),
        (&["a", "a"][..], &["q"][..], "an input twice"),
        (&["a"][..], &["q", "q"][..], "an output twice"),
    ] {
        let e = IoData::from_csv_reader(CSV.as_bytes(), &CsvColumns::new(inputs, outputs), "f")
            .unwrap_err()
            .to_string();
        assert!(e.contains(role), "{e}");
    }
}

#[test]
fn mismatched_lengths_and_nan_rejected() {
    let e = IoData::new(1.0, DMatrix::zeros(5, 1), DMatrix::zeros(4, 1)).unwrap_err();
    assert!(matches!(e, SysidError::Dimension { .. }), "{e}");
    let mut y = DMatrix::zeros(5, 1);
    y[(3, 0)] = f64::NAN;
    let e = IoData::new(1.0, DMatrix::zeros(5, 1), y).unwrap_err();
    assert!(matches!(e, SysidError::NonFinite { sample: 3, .. }), "{e}");
}

#[test]
fn select_intervals_make_experiments() {
    let d = IoData::from_csv_reader(CSV.as_bytes(), &cols(), "mem").unwrap();
    let s = d
        .select(&TimeInterval::parse_list("0.01:0.05").unwrap())
        .unwrap();
    assert_eq!(s.experiments().len(), 2);
    assert_eq!(s.experiments()[0].len(), 2);
    assert_eq!(s.experiments()[1].t, vec![0.02, 0.04]);
    assert!(d.select(&TimeInterval::parse_list("5:6").unwrap()).is_err());
    assert!(TimeInterval::parse_list("3:1").is_err());
    assert!(TimeInterval::parse_list("a:1").is_err());
}

#[test]
fn offsets_and_trends() {
    let n = 100;
    let u = DMatrix::from_fn(n, 1, |k, _| 3.0 + 0.5 * k as f64 + ((k * 13) % 7) as f64);
    let y = DMatrix::from_fn(n, 1, |k, _| -2.0 + ((k * 5) % 3) as f64);
    let d = IoData::new(0.1, u, y).unwrap();
    let (z, o) = d.remove_means().unwrap();
    assert!(z.means().u0.norm() < 1e-12 && z.means().y0.norm() < 1e-12);
    let back = z
        .subtract(&Offsets {
            u0: -o.u0.clone(),
            y0: -o.y0.clone(),
        })
        .unwrap();
    assert!((&back.experiments()[0].u - &d.experiments()[0].u).norm() < 1e-9);
    let dt = d.detrend();
    // A detrended signal is orthogonal to 1 and to k.
    let c = dt.experiments()[0].u.column(0).clone_owned();
    let s1: f64 = c.iter().sum();
    let sk: f64 = c.iter().enumerate().map(|(k, v)| k as f64 * v).sum();
    assert!(s1.abs() < 1e-9 && sk.abs() < 1e-7);
}

#[test]
fn constant_input_detected() {
    let u = DMatrix::from_fn(50, 2, |k, j| if j == 0 { k as f64 } else { 4.0 });
    let d = IoData::new(1.0, u, DMatrix::from_fn(50, 1, |k, _| k as f64)).unwrap();
    let e = d.check_excitation().unwrap_err();
    assert!(e.to_string().contains("\"u2\" is constant"), "{e}");
}

#[test]
fn merge_and_map_inputs() {
    let d = IoData::new(
        1.0,
        DMatrix::from_fn(10, 2, |k, j| (k + j) as f64),
        DMatrix::zeros(10, 1),
    )
    .unwrap();
    let m = IoData::merge(&[d.clone(), d.clone()]).unwrap();
    assert_eq!(m.experiments().len(), 2);
    assert_eq!(m.n_samples(), 20);
    let v = d
        .map_inputs(
            &DMatrix::from_row_slice(1, 2, &[1.0, -1.0]),
            vec!["diff".into()],
        )
        .unwrap();
    assert!(
        v.experiments()[0]
            .u
            .iter()
            .all(|x| (*x + 1.0).abs() < 1e-15)
    );
    let other = IoData::new(2.0, DMatrix::zeros(3, 2), DMatrix::zeros(3, 1)).unwrap();
    assert!(IoData::merge(&[d, other]).is_err());
}

/// Issue 20, finding 11: without a time column the sample time was a
/// silent 1 s; it is now required. With one, a sample time given as well
/// must agree with it.
#[test]
fn csv_sample_time_is_never_guessed() {
    let no_t = "a,q\n1,2\n2,3\n3,1\n";
    let cols = CsvColumns::new(&["a"], &["q"]);
    let e = IoData::from_csv_reader(no_t.as_bytes(), &cols, "f.csv")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("f.csv") && e.contains("no time column \"t\"") && e.contains("sample time"),
        "{e}"
    );
    let given = CsvColumns {
        ts: Some(0.02),
        ..cols.clone()
    };
    let d = IoData::from_csv_reader(no_t.as_bytes(), &given, "f.csv").unwrap();
    assert_eq!(d.ts(), 0.02);
    // Times stay row indices (the unit of intervals without a time column).
    assert_eq!(d.experiments()[0].t, vec![0.0, 1.0, 2.0]);
    for bad in [0.0, -1.0, f64::NAN] {
        let c = CsvColumns {
            ts: Some(bad),
            ..cols.clone()
        };
        assert!(IoData::from_csv_reader(no_t.as_bytes(), &c, "f").is_err());
    }
    // A time column and a sample time: they must agree (to 1 %).
    let agree = CsvColumns {
        ts: Some(0.02),
        ..self::cols()
    };
    assert_eq!(
        IoData::from_csv_reader(CSV.as_bytes(), &agree, "f")
            .unwrap()
            .ts(),
        0.02
    );
    let disagree = CsvColumns {
        ts: Some(0.01),
        ..self::cols()
    };
    let e = IoData::from_csv_reader(CSV.as_bytes(), &disagree, "f.csv")
        .unwrap_err()
        .to_string();
    assert!(e.contains("0.01 s") && e.contains("0.02 s"), "{e}");
}

/// A time column in milliseconds, stated as such, gives seconds.
#[test]
fn csv_time_column_in_milliseconds() {
    let ms = CSV
        .replace("0.00,", "0,")
        .replace("0.02,", "20,")
        .replace("0.04,", "40,")
        .replace("0.06,", "60,");
    let c = CsvColumns {
        time_unit: TimeUnit::Milliseconds,
        ..cols()
    };
    let d = IoData::from_csv_reader(ms.as_bytes(), &c, "ms.csv").unwrap();
    assert_eq!(d.ts(), 0.02);
    assert_eq!(d.experiments()[0].t, vec![0.0, 0.02, 0.04, 0.06]);
    // Read as seconds (the default) the step is 20 s.
    assert_eq!(
        IoData::from_csv_reader(ms.as_bytes(), &cols(), "ms.csv")
            .unwrap()
            .ts(),
        20.0
    );
    assert_eq!(TimeUnit::default(), TimeUnit::Seconds);
}
