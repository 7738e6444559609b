//! The condensed problem as a function, not only at its optimum: at any
//! `z` and `theta`, its cost equals the uncondensed cost of the trajectory
//! `z` produces, and each of its constraint rows, found by its label,
//! equals the uncondensed row of the same constraint (and every
//! uncondensed row that a condensing keeps has a condensed one).

use super::reference::{DenseQp, Family, Plain};
use kestrel_mpc::{ConstraintKind, MpcProblem, Side};
use nalgebra::DVector;
use std::collections::HashMap;

fn family(kind: ConstraintKind) -> Family {
    match kind {
        ConstraintKind::Input => Family::Input,
        ConstraintKind::InputMove => Family::Du,
        ConstraintKind::Output => Family::Output,
        ConstraintKind::State => Family::State,
        ConstraintKind::TerminalSet => Family::TerminalSet,
        ConstraintKind::Slack => Family::SlackSign,
    }
}

/// The largest differences `(cost, row)` between the condensed problem
/// and the uncondensed one `qp` (built by `pl` at `theta`) at `z`, both
/// relative to `1 + |value|`. Panics on a structural mismatch (a row
/// without a counterpart, a slack in an unexpected column).
pub fn compare_at(
    prob: &MpcProblem,
    pl: &Plain,
    qp: &DenseQp,
    theta: &DVector<f64>,
    z: &DVector<f64>,
) -> (f64, f64) {
    let (nx, nu) = (pl.nx(), pl.nu());
    let n_moves = pl.blocks.len() * nu;
    assert_eq!(prob.rows.len(), prob.m(), "one label per row");
    // The column of each slack, from the soft rows' -1 entries.
    let mut slack_col: HashMap<(Family, usize), usize> = HashMap::new();
    for (i, label) in prob.rows.iter().enumerate() {
        let cols: Vec<usize> = (n_moves..prob.n())
            .filter(|&c| prob.g[(i, c)] != 0.0)
            .collect();
        match (label.soft, label.kind) {
            (true, _) => {
                assert_eq!(cols.len(), 1, "row {i} ({label}): one slack");
                assert_eq!(prob.g[(i, cols[0])], -1.0, "row {i} ({label})");
                let old = slack_col.insert((family(label.kind), label.index), cols[0]);
                assert!(old.is_none_or(|c| c == cols[0]), "row {i} ({label})");
            }
            (false, ConstraintKind::Slack) => {
                assert_eq!(cols, vec![n_moves + label.index], "row {i} ({label})");
            }
            (false, _) => assert!(cols.is_empty(), "row {i} ({label}): no slack"),
        }
    }
    let cols = slack_columns(qp, &slack_col);
    // The trajectory of z.
    let t = pl.split(theta);
    let mut v = DVector::zeros(qp.p.nrows());
    v.rows_mut(pl.xi(0), nx).copy_from(&t.x);
    let mut j = 0;
    for (b, &l) in pl.blocks.iter().enumerate() {
        for _ in 0..l {
            let u = z.rows(b * nu, nu).into_owned();
            let x = v.rows(pl.xi(j), nx).into_owned();
            v.rows_mut(pl.ui(j), nu).copy_from(&u);
            let mut next = &pl.a * x + &pl.b * u;
            if let Some((bd, _)) = &pl.disturbance {
                next += bd * &t.d;
            }
            v.rows_mut(pl.xi(j + 1), nx).copy_from(&next);
            j += 1;
        }
    }
    for (k, &c) in cols.iter().enumerate() {
        v[pl.si() + k] = z[c];
    }
    let mine = 0.5 * v.dot(&(&qp.p * &v)) + qp.q.dot(&v) + qp.c0;
    let d_cost = (prob.cost(z, theta) - mine).abs() / (1.0 + mine.abs());
    // Row by row.
    let index: HashMap<(Family, bool, usize, usize, bool), usize> = qp
        .keys
        .iter()
        .enumerate()
        .filter(|(_, k)| k.canonical)
        .map(|(r, k)| ((k.family, k.upper, k.index, k.step, k.soft), r))
        .collect();
    assert_eq!(
        index.len(),
        prob.m(),
        "as many condensed rows as uncondensed ones outside the blocks"
    );
    let val_c = &prob.g * z - &prob.w - &prob.e * theta;
    let val_m = &qp.a_in * &v - &qp.b_in;
    let mut d_row = 0.0_f64;
    for (i, label) in prob.rows.iter().enumerate() {
        let idx = if label.kind == ConstraintKind::Slack {
            // The uncondensed slack number whose column this row bounds.
            cols.iter()
                .position(|&c| c == n_moves + label.index)
                .unwrap_or_else(|| panic!("row {i} ({label}): unknown slack"))
        } else {
            label.index
        };
        let key = (
            family(label.kind),
            label.side == Side::Upper,
            idx,
            label.step,
            label.soft,
        );
        let r = *index
            .get(&key)
            .unwrap_or_else(|| panic!("row {i} ({label}): no uncondensed row {key:?}"));
        d_row = d_row.max((val_c[i] - val_m[r]).abs() / (1.0 + val_m[r].abs()));
    }
    (d_cost, d_row)
}

/// The condensed column of each of the reference's slacks.
fn slack_columns(qp: &DenseQp, slack_col: &HashMap<(Family, usize), usize>) -> Vec<usize> {
    assert_eq!(slack_col.len(), qp.slack_of.len(), "number of slacks");
    qp.slack_of
        .iter()
        .map(|key| {
            *slack_col
                .get(key)
                .unwrap_or_else(|| panic!("no condensed slack for {key:?}"))
        })
        .collect()
}
