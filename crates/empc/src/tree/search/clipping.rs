//! Clipping: a leaf may hold one law for regions with other laws when,
//! clamped to the output bounds, it gives the same `z` on all of them.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::lp::{LpStatus, slack_start};
use crate::tree::search::state::{Builder, Piece};

impl Builder<'_> {
    /// Whether law `l`, clamped to the output bounds, equals region `r`'s law on all of `r`.
    fn serves(&mut self, l: u16, r: usize) -> bool {
        let lr = self.law[r];
        if l == lr {
            return true;
        }
        if let Some(&v) = self.serve_cache.get(&(l, r)) {
            return v;
        }
        let (a, b, x0) = (
            std::mem::take(&mut self.reg_a[r]),
            std::mem::take(&mut self.reg_b[r]),
            std::mem::take(&mut self.reg_center[r]),
        );
        let ok = self.serves_on(l, lr, &a, &b, &x0);
        self.reg_a[r] = a;
        self.reg_b[r] = b;
        self.reg_center[r] = x0;
        self.serve_cache.insert((l, r), ok);
        ok
    }

    /// Whether law `l` clamped equals law `lr` on the polytope `a x <= b`
    /// (with the interior point `x0`).
    fn serves_on(&mut self, l: u16, lr: u16, a: &[f64], b: &[f64], x0: &[f64]) -> bool {
        let p = self.p;
        let w = p + 1;
        let mut ok = true;
        for o in 0..self.bounds.len() {
            let (rl, rr) = (self.law_rows[l as usize][o], self.law_rows[lr as usize][o]);
            if rl == rr {
                continue;
            }
            // Region r saturates output o at a bound; law l must lie beyond it on r.
            let sign = if rr == self.bounds[o][1] as usize {
                1.0 // upper: max over r of (rr - rl) <= tol
            } else if rr == self.bounds[o][0] as usize {
                -1.0 // lower: max over r of (rl - rr) <= tol
            } else {
                ok = false;
                break;
            };
            let c: Vec<f64> = (0..p)
                .map(|j| sign * (self.rows[rr * w + j] - self.rows[rl * w + j]))
                .collect();
            let c0 = sign * (self.rows[rr * w + p] - self.rows[rl * w + p]);
            let (st, v) = self.lp.maximize_from(&c, a, b, x0);
            if st != LpStatus::Optimal || v + c0 > self.clip_tol {
                ok = false;
                break;
            }
        }
        ok
    }

    /// Region `r` intersected with the cell (rows, offsets) and an interior
    /// point of it, if it is full-dimensional.
    fn in_cell(&mut self, r: usize, cell: &[(Vec<f64>, f64)]) -> Option<Piece> {
        let p = self.p;
        let mut a = self.reg_a[r].clone();
        let mut b = self.reg_b[r].clone();
        for (ca, cb) in cell {
            a.extend_from_slice(ca);
            b.push(*cb);
        }
        let rows = b.len();
        let mut la = Vec::with_capacity((rows + 1) * (p + 1));
        for i in 0..rows {
            la.extend_from_slice(&a[i * p..(i + 1) * p]);
            la.push(1.0);
        }
        la.extend(std::iter::repeat_n(0.0, p));
        la.push(1.0);
        let mut lb = b.clone();
        lb.push(self.scale);
        let mut c = vec![0.0; p + 1];
        c[p] = 1.0;
        let mut x0: Vec<f64> = self.reg_center[r].iter().copied().chain([0.0]).collect();
        slack_start(&la, &lb, &mut x0, p);
        let (st, rad) = self.lp.maximize_from(&c, &la, &lb, &x0);
        (st == LpStatus::Optimal && rad > 1e-9 * self.scale)
            .then(|| (a, b, self.lp.x[..p].to_vec()))
    }

    /// A law that serves every region of the set within the cell (clipping), if any.
    pub(super) fn serving_law(&mut self, set: &[usize], cell: &[(Vec<f64>, f64)]) -> Option<u16> {
        let mut laws: Vec<(usize, u16)> = Vec::new();
        for &r in set {
            let l = self.law[r];
            match laws.iter_mut().find(|x| x.1 == l) {
                Some(x) => x.0 += 1,
                None => laws.push((1, l)),
            }
        }
        laws.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut pieces: Vec<Option<Option<Piece>>> = vec![None; set.len()];
        'law: for (_, l) in laws {
            // Without an LP: every differing output of every region must
            // be saturated in that region's law (else `serves` fails too).
            let saturated = |o: usize, lr: u16| {
                let rr = self.law_rows[lr as usize][o];
                rr == self.bounds[o][0] as usize || rr == self.bounds[o][1] as usize
            };
            for &r in set {
                let lr = self.law[r];
                if lr != l
                    && (0..self.bounds.len()).any(|o| {
                        self.law_rows[l as usize][o] != self.law_rows[lr as usize][o]
                            && !saturated(o, lr)
                    })
                {
                    continue 'law;
                }
            }
            for (i, &r) in set.iter().enumerate() {
                if self.serves(l, r) {
                    continue;
                }
                if cell.is_empty() {
                    continue 'law;
                }
                if pieces[i].is_none() {
                    pieces[i] = Some(self.in_cell(r, cell));
                }
                let Some(Some((a, b, x0))) = &pieces[i] else {
                    continue 'law;
                };
                let (a, b, x0) = (a.clone(), b.clone(), x0.clone());
                if !self.serves_on(l, self.law[r], &a, &b, &x0) {
                    continue 'law;
                }
            }
            return Some(l);
        }
        None
    }
}
