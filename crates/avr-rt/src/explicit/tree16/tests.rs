use super::*;
use crate::law::LawInfo;
use kestrel_core::{ControlLaw, Error};

/// One parameter theta in [-1, 1] (2^15 units per 1), one output:
/// z = -theta for theta <= 0, 0 otherwise; output bounds [-0.25, 0.75]
/// (rows 3, 4), scale 2^16.
fn table() -> (Vec<u8>, Tree16Layout) {
    let layout = Tree16Layout {
        n_params: 1,
        n_outputs: 1,
        n_nodes: 1,
        n_laws: 2,
        n_rows: 5,
        root: 0,
        scale: 16,
        wide: false,
    };
    let mut b = vec![1u8];
    b.extend((-32767i16).to_le_bytes());
    b.extend(32767i16.to_le_bytes());
    b.extend([2, NONE, 0]);
    b.extend((LEAF | 1).to_le_bytes());
    b.extend([0, 1, 3, 4]);
    for (start, c0, g) in [
        (0u8, 0i32, -2i16),
        (1, 0, 0),
        (0, 0, 2),
        (1, -16384, 0),
        (1, 49152, 0),
    ] {
        b.push(start);
        b.extend(c0.to_le_bytes());
        b.extend(g.to_le_bytes());
    }
    assert_eq!(b.len(), layout.bytes());
    (b, layout)
}

fn law(b: &[u8], l: Tree16Layout) -> Empc16Law<f64, &[u8], 1, 1, 8> {
    Empc16Law::new(Tree16::new(b, l).unwrap(), 0).unwrap()
}

#[test]
fn evaluates_the_tree_with_output_bounds_and_box() {
    let (b, l) = table();
    let mut law = law(&b, l);
    let mut u = [0.0];
    for (th, want, outside) in [
        (-0.5, 0.5, 0),
        (-0.9, 0.75, 0), // clamped by the upper bound row
        (0.3, 0.0, 0),
        (-3.0, 0.75, 1), // projected onto the box
    ] {
        law.control(&[], &[th], &mut u).unwrap();
        assert!((u[0] - want).abs() < 1e-4, "theta {th}: {} != {want}", u[0]);
        assert_eq!(law.outside(), outside);
    }
    assert_eq!(law.iterations(), 1);
}

#[test]
fn the_value_cache_is_per_period() {
    // Many periods (the u8 stamp wraps) give the same answers as fresh
    // laws, with a cache swept one entry per period (R = 8) and two
    // (R = 300), and with the same parameter every period (each row
    // cached once and then only read: the sweep must clear it before
    // its stamp comes back).
    let (b, l) = table();
    let mut law = law(&b, l);
    let mut big: Empc16Law<f64, &[u8], 1, 1, 300> =
        Empc16Law::new(Tree16::new(&b[..], l).unwrap(), 0).unwrap();
    let mut same = self::law(&b, l);
    let mut u = [0.0];
    let mut w = [0.0];
    for k in 0..1200 {
        let th = ((k * 37) % 200) as f64 / 100.0 - 1.0;
        law.control(&[], &[th], &mut u).unwrap();
        big.control(&[], &[th], &mut w).unwrap();
        let mut fresh = self::law(&b, l);
        let mut v = [0.0];
        fresh.control(&[], &[th], &mut v).unwrap();
        assert_eq!(u, v, "period {k}");
        assert_eq!(w, v, "period {k}, R = 300");
        // Alternate two parameters in `same` after a long run at one.
        let th2 = if k < 600 { -0.5 } else { th };
        same.control(&[], &[th2], &mut u).unwrap();
        fresh.control(&[], &[th2], &mut v).unwrap();
        assert_eq!(u, v, "period {k}, held parameter");
    }
}

#[test]
fn a_row_unused_for_255_periods_is_not_taken_from_the_cache() {
    // Period 1 caches law 0's row (theta < 0); 254 periods on the other
    // side leave it alone; period 256 has the stamp 1 again: the row
    // must be evaluated anew (the sweep cleared it), not read back.
    let (b, l) = table();
    let mut law = law(&b, l);
    let mut u = [0.0];
    law.control(&[], &[-0.5], &mut u).unwrap();
    assert!((u[0] - 0.5).abs() < 1e-4);
    for _ in 0..254 {
        law.control(&[], &[0.5], &mut u).unwrap();
        assert_eq!(u, [0.0]);
    }
    law.control(&[], &[-0.6], &mut u).unwrap();
    assert!((u[0] - 0.6).abs() < 1e-4, "{} (a stale 0.5?)", u[0]);
}

#[test]
fn bad_tables_and_inputs_are_errors_not_panics() {
    let (b, l) = table();
    assert!(matches!(
        Tree16::new(&b[..b.len() - 1], l),
        Err(Error::DimensionMismatch { .. })
    ));
    let big = Tree16Layout { scale: 31, ..l };
    let mut bb = b.clone();
    bb.truncate(big.bytes());
    assert!(Tree16::new(&bb[..], big).is_err());
    let tree = Tree16::new(&b[..], l).unwrap();
    // Wrong dimensions, too small a cache, no reference.
    assert!(Empc16Law::<f64, _, 2, 1, 8>::new(tree, 0).is_err());
    assert!(Empc16Law::<f64, _, 1, 2, 8>::new(tree, 0).is_err());
    assert!(Empc16Law::<f64, _, 1, 1, 4>::new(tree, 0).is_err());
    assert!(Empc16Law::<f64, _, 1, 1, 8>::new(tree, 1).is_err());
    let mut law = law(&b, l);
    let mut u = [0.0];
    assert_eq!(law.control(&[], &[f64::NAN], &mut u), Err(Error::NonFinite));
    assert_eq!(
        law.control(&[], &[f64::INFINITY], &mut u),
        Err(Error::NonFinite)
    );
    assert!(law.control(&[], &[0.0, 1.0], &mut u).is_err());
    // A node pointing at a row past the table, a child past the nodes,
    // a law past the laws, a cycle.
    let node = l.nodes_at();
    for (at, v) in [(node, 9u8), (node + 3, 5), (node + 2, 7)] {
        let mut bad = b.clone();
        bad[at] = v;
        if at == node + 3 {
            bad[at + 1] = 0; // child node 5 of a 1-node tree
        }
        // Found by the check of every index when the law is made.
        assert_eq!(
            Empc16Law::<f64, _, 1, 1, 8>::new(Tree16::new(&bad[..], l).unwrap(), 0).err(),
            Some(Error::OutOfRange),
            "corrupted byte {at}"
        );
    }
    let mut cyc = b.clone();
    cyc[node + 3] = 0;
    cyc[node + 4] = 0; // theta > 0 loops back to node 0
    assert_eq!(
        Empc16Law::<f64, _, 1, 1, 8>::new(Tree16::new(&cyc[..], l).unwrap(), 0).err(),
        Some(Error::OutOfRange)
    );
    // A law's row and an output bound's row past the rows.
    for at in [l.laws_at(), l.bounds_at() + 1] {
        let mut bad = b.clone();
        bad[at] = 7;
        assert_eq!(
            Empc16Law::<f64, _, 1, 1, 8>::new(Tree16::new(&bad[..], l).unwrap(), 0).err(),
            Some(Error::OutOfRange),
            "corrupted byte {at}"
        );
    }
}

/// Found by fuzzing (`fuzz/regressions/tree16/crash-*`): counts whose
/// offsets overflow `u32` panicked in `Tree16Layout::offsets` (or wrapped
/// in a release build, and a count above `u32::MAX` was truncated, so a
/// layout claiming 2^32 + 1 nodes could match a one-node table's length).
#[test]
fn a_layout_whose_offsets_overflow_is_an_error() {
    let (b, l) = table();
    for huge in [
        Tree16Layout {
            n_nodes: 1 << 30,
            ..l
        },
        Tree16Layout {
            n_laws: 1 << 20,
            n_outputs: 1 << 20,
            ..l
        },
        Tree16Layout {
            n_nodes: (1 << 32) + 1,
            ..l
        },
        Tree16Layout {
            n_params: usize::MAX,
            ..l
        },
    ] {
        assert!(huge.checked_offsets().is_none());
        assert!(matches!(
            Tree16::new(&b[..], huge),
            Err(Error::InvalidArgument(_))
        ));
    }
    assert_eq!(l.checked_offsets(), Some(l.offsets()));
}
