//! Row sharing of the compact layout: node hyperplanes as differences of
//! stored rows, equal hyperplane rows stored once.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::eval::{LEAF, NO_ROW};
use std::collections::HashMap;

/// Stores the compact trees' hyperplanes without rows of their own where
/// possible: a node `[h, NO_ROW]` whose hyperplane `h(theta) <= 0` is a
/// positive multiple of the difference of two law or bound rows (of any
/// output's tree) becomes `[r1, r2]`, hyperplane rows equal up to a
/// positive factor are shared, and rows no longer used are dropped (the
/// indices in nodes, roots and bounds are renumbered).
pub(super) fn share_hyperplane_rows(
    rows: Vec<f64>,
    p: usize,
    scale: f64,
    nodes: &mut [[u16; 4]],
    roots: &mut [u16],
    bounds: &mut [[u16; 2]],
) -> Vec<f64> {
    let w = p + 1;
    let nrows = rows.len() / w;
    let row = |i: usize| &rows[i * w..(i + 1) * w];
    // Rows holding values: leaves and bounds.
    let mut value = vec![false; nrows];
    let mark = |c: u16, value: &mut Vec<bool>| {
        if c & LEAF != 0
            && let Some(v) = value.get_mut((c & !LEAF) as usize)
        {
            *v = true;
        }
    };
    for nd in nodes.iter() {
        mark(nd[2], &mut value);
        mark(nd[3], &mut value);
        if nd[1] != NO_ROW {
            for &i in &nd[..2] {
                if let Some(v) = value.get_mut(i as usize) {
                    *v = true;
                }
            }
        }
    }
    for &r in roots.iter() {
        mark(r, &mut value);
    }
    for b in bounds.iter() {
        for &i in b {
            if let Some(v) = value.get_mut(i as usize) {
                *v = true;
            }
        }
    }
    // The direction of an affine row (unit gains, constant relative to scale).
    let key = |d: &[f64]| -> Option<Vec<i64>> {
        let nrm = d[..p].iter().map(|v| v * v).sum::<f64>().sqrt();
        (nrm > 1e-9).then(|| {
            d.iter()
                .enumerate()
                .map(|(j, v)| {
                    let s = if j == p { scale } else { 1.0 };
                    (v / nrm / s * 1e7).round() as i64
                })
                .collect()
        })
    };
    let same_direction = |x: &[f64], y: &[f64]| -> bool {
        let nx = x[..p].iter().map(|v| v * v).sum::<f64>().sqrt();
        let ny = y[..p].iter().map(|v| v * v).sum::<f64>().sqrt();
        (0..w).all(|j| {
            let s = if j == p { scale } else { 1.0 };
            (x[j] / nx - y[j] / ny).abs() <= 1e-11 * s
        })
    };
    let mut pairs: HashMap<Vec<i64>, Vec<(usize, usize)>> = HashMap::new();
    let vals: Vec<usize> = (0..nrows).filter(|&i| value[i]).collect();
    for &r1 in &vals {
        for &r2 in &vals {
            if r1 == r2 {
                continue;
            }
            let d: Vec<f64> = (0..w).map(|j| row(r1)[j] - row(r2)[j]).collect();
            if let Some(k) = key(&d) {
                pairs.entry(k).or_default().push((r1, r2));
            }
        }
    }
    let mut shared_hp: HashMap<Vec<i64>, Vec<usize>> = HashMap::new();
    for nd in nodes.iter_mut() {
        if nd[1] != NO_ROW || value.get(nd[0] as usize).is_none_or(|&v| v) {
            continue;
        }
        let h = row(nd[0] as usize);
        let Some(k) = key(h) else { continue };
        let found = pairs.get(&k).and_then(|c| {
            c.iter().copied().find(|&(r1, r2)| {
                let d: Vec<f64> = (0..w).map(|j| row(r1)[j] - row(r2)[j]).collect();
                same_direction(&d, h)
            })
        });
        if let Some((r1, r2)) = found {
            *nd = [r1 as u16, r2 as u16, nd[2], nd[3]];
            continue;
        }
        let list = shared_hp.entry(k).or_default();
        match list.iter().find(|&&o| same_direction(row(o), h)) {
            Some(&o) => nd[0] = o as u16,
            None => list.push(nd[0] as usize),
        }
    }
    // Drop unused rows and renumber.
    let mut used = value;
    for nd in nodes.iter() {
        for &i in &nd[..2] {
            if let Some(u) = used.get_mut(i as usize) {
                *u = true;
            }
        }
    }
    let mut new_index = vec![NO_ROW; nrows];
    let mut out = Vec::with_capacity(rows.len());
    for i in 0..nrows {
        if used[i] {
            new_index[i] = (out.len() / w) as u16;
            out.extend_from_slice(row(i));
        }
    }
    let re = |i: u16| {
        if i == NO_ROW {
            NO_ROW
        } else {
            new_index.get(i as usize).copied().unwrap_or(NO_ROW)
        }
    };
    let re_child = |c: u16| {
        if c & LEAF != 0 {
            LEAF | re(c & !LEAF)
        } else {
            c
        }
    };
    for nd in nodes.iter_mut() {
        *nd = [re(nd[0]), re(nd[1]), re_child(nd[2]), re_child(nd[3])];
    }
    for r in roots.iter_mut() {
        *r = re_child(*r);
    }
    for b in bounds.iter_mut() {
        *b = [re(b[0]), re(b[1])];
    }
    out
}
