//! The evaluator on hand-made tables: answers, errors instead of panics,
//! the compact layout and fixed point.

use crate::eval::{CompactNode, ForestTables, LEAF, NO_ROW, NO_ROW8, SliceTables, evaluate};
use kestrel_core::{Error, Q16, Scalar};

// Node: row 3 (theta0) <= 0 -> law 0.
static NODES: [[u16; 4]; 1] = [[3, NO_ROW, LEAF, LEAF | 1]];
fn tables<S: Scalar>(buf: &mut [S; 12]) -> SliceTables<'_, S> {
    // rows: [-1, 0 | 0], [0, 0 | 0.25], [0, 0 | -1], [1, 0 | 0]
    let v = [
        -1.0, 0.0, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0,
    ];
    for (d, s) in buf.iter_mut().zip(v) {
        *d = S::from_f64(s);
    }
    let rows = &buf[..];
    SliceTables {
        n_params: 2,
        n_outputs: 1,
        root: 0,
        nodes: &NODES,
        laws: &[0, 1],
        rows,
        hull: &[],
        theta_lb: &[],
        theta_ub: &[],
        bounds: &[[NO_ROW, NO_ROW]],
    }
}

#[test]
fn errors_not_panics() {
    let mut buf = [0.0f64; 12];
    let t = tables(&mut buf);
    let mut z = [0.0];
    // theta bounds table is empty: corrupted -> OutOfRange.
    assert_eq!(evaluate(&t, &[0.0, 0.0], &mut z), Err(Error::OutOfRange));
    let lb = [-1.0, -1.0];
    let ub = [1.0, 1.0];
    let t = SliceTables {
        theta_lb: &lb,
        theta_ub: &ub,
        ..t
    };
    assert_eq!(
        evaluate(&t, &[f64::NAN, 0.0], &mut z),
        Err(Error::NonFinite)
    );
    assert_eq!(
        evaluate(&t, &[0.0, 0.0, 0.0], &mut z),
        Err(Error::DimensionMismatch {
            expected: 2,
            found: 3
        })
    );
    let mut z2 = [0.0; 2];
    assert!(matches!(
        evaluate(&t, &[0.0, 0.0], &mut z2),
        Err(Error::DimensionMismatch { .. })
    ));
    let e = evaluate(&t, &[-0.5, 0.0], &mut z).unwrap();
    assert_eq!((e.law, z[0]), (0, 0.5));
    let e = evaluate(&t, &[0.5, 0.0], &mut z).unwrap();
    assert_eq!((e.law, z[0]), (1, 0.25));
    // A cycle in the node table is detected.
    let cyc = [[3u16, NO_ROW, 0, 0]];
    let t2 = SliceTables { nodes: &cyc, ..t };
    assert_eq!(evaluate(&t2, &[0.5, 0.0], &mut z), Err(Error::OutOfRange));
    // A law pointing past the row table.
    let t3 = SliceTables { laws: &[0, 9], ..t };
    assert_eq!(evaluate(&t3, &[0.5, 0.0], &mut z), Err(Error::OutOfRange));
}

#[test]
fn forest_tables_and_their_errors() {
    // Two outputs, one parameter: z0 = -theta for theta <= 0 else 0,
    // z1 = 0.25 everywhere (a lone leaf).
    let rows = [-1.0, 0.0, 0.0, 0.0, 0.0, 0.25, 1.0, 0.0];
    let nodes = [CompactNode {
        rows: [3, NO_ROW8],
        children: [LEAF, LEAF | 1],
    }];
    let t = ForestTables {
        n_params: 1,
        n_outputs: 2,
        roots: &[0, LEAF | 2],
        nodes: &nodes,
        rows: &rows,
        hull: &[],
        theta_lb: &[-1.0],
        theta_ub: &[1.0],
        bounds: &[[NO_ROW, NO_ROW]; 2],
    };
    let mut z = [0.0; 2];
    let e = evaluate(&t, &[-0.5], &mut z).unwrap();
    assert_eq!((z, e.law, e.steps, e.outside), ([0.5, 0.25], 0, 1, false));
    let e = evaluate(&t, &[0.5], &mut z).unwrap();
    assert_eq!((z, e.law), ([0.0, 0.25], 1));
    // A missing root, a leaf past the rows, a cycle: errors, no panic.
    let t1 = ForestTables { roots: &[0], ..t };
    assert_eq!(evaluate(&t1, &[0.5], &mut z), Err(Error::OutOfRange));
    let t2 = ForestTables { roots: &[], ..t };
    assert_eq!(evaluate(&t2, &[0.5], &mut z), Err(Error::OutOfRange));
    let t3 = ForestTables {
        roots: &[0, LEAF | 9],
        ..t
    };
    assert_eq!(evaluate(&t3, &[0.5], &mut z), Err(Error::OutOfRange));
    let cyc = [CompactNode {
        rows: [3, NO_ROW8],
        children: [0, 0],
    }];
    let t4 = ForestTables { nodes: &cyc, ..t };
    assert_eq!(evaluate(&t4, &[0.5], &mut z), Err(Error::OutOfRange));
}

#[test]
fn fixed_point_same_leaf() {
    let mut buf = [Q16::ZERO; 12];
    let t = tables(&mut buf);
    let lb = [Q16::from_f64(-1.0); 2];
    let ub = [Q16::from_f64(1.0); 2];
    let t = SliceTables {
        theta_lb: &lb,
        theta_ub: &ub,
        ..t
    };
    let mut z = [Q16::ZERO];
    let e = evaluate(&t, &[Q16::from_f64(-0.25), Q16::ZERO], &mut z).unwrap();
    assert_eq!(e.law, 0);
    assert_eq!(z[0].to_f64(), 0.25);
    let e = evaluate(&t, &[Q16::from_f64(-3.0), Q16::ZERO], &mut z).unwrap();
    assert!(e.outside);
    assert_eq!(z[0].to_f64(), 1.0);
}
