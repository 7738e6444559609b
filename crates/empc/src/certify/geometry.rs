//! Polyhedra of the normalised parameter space: half-spaces from affine
//! functions, and the largest inscribed ball (kestrel-empc's LP) that
//! decides whether a region has an interior and gives its interior point.

use crate::lp::{LpStatus, LpWorkspace, slack_start};

/// A half-space from an affine function `f` (`d + 1` entries): `f(x) < 0`
/// or `f(x) <= 0`; a constant function is always or never satisfied.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Half {
    /// `a x <= b`, `|a| = 1`.
    Row(Vec<f64>, f64),
    /// Holds everywhere.
    Always,
    /// Holds nowhere.
    Never,
}

/// Relative size below which a coefficient vector counts as zero.
const ZERO: f64 = 1e-11;

/// `f(x) < 0` (`strict`) or `f(x) <= 0`. `scale` is the size of the
/// quantities `f` was formed from: `f` counts as constant when its
/// coefficients are below `1e-11 scale`, and a constant as zero when it is;
/// a zero constant satisfies `<= 0` but not `< 0` (the solver's strict and
/// non-strict comparisons of equal values).
pub(super) fn half(f: &[f64], strict: bool, scale: f64) -> Half {
    let d = f.len() - 1;
    let norm = f[..d].iter().map(|v| v * v).sum::<f64>().sqrt();
    let scale = scale.max(f64::MIN_POSITIVE);
    if norm <= ZERO * scale {
        let c = f[d];
        let holds = if c.abs() <= ZERO * scale {
            !strict
        } else {
            c < 0.0
        };
        return if holds { Half::Always } else { Half::Never };
    }
    Half::Row(f[..d].iter().map(|v| v / norm).collect(), -f[d] / norm)
}

/// [`half`], except that with `both` a comparison of identical functions
/// (a zero constant) holds either way: the tie-break of the solver depends
/// on an order the caller does not know, so both outcomes are kept.
pub(super) fn half_tie(f: &[f64], strict: bool, scale: f64, both: bool) -> Half {
    match half(f, strict, scale) {
        Half::Never if both && size(f) <= ZERO * scale.max(f64::MIN_POSITIVE) => Half::Always,
        h => h,
    }
}

/// Whether `f` is the zero function at `scale` (a comparison of identical
/// functions, decided by the solver's order alone).
pub(super) fn identical(f: &[f64], scale: f64) -> bool {
    size(f) <= ZERO * scale.max(f64::MIN_POSITIVE)
}

/// The largest magnitude of an affine function's entries.
pub(super) fn size(f: &[f64]) -> f64 {
    f.iter().fold(0.0_f64, |s, v| s.max(v.abs()))
}

/// `f - g`.
pub(super) fn minus(f: &[f64], g: &[f64]) -> Vec<f64> {
    f.iter().zip(g).map(|(a, b)| a - b).collect()
}

/// A polyhedron `{x : a x <= b}` (unit rows, `d` columns) with its largest
/// inscribed ball.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Poly {
    /// Rows, row-major.
    pub a: Vec<f64>,
    /// Right-hand sides.
    pub b: Vec<f64>,
    /// Centre of the largest inscribed ball.
    pub centre: Vec<f64>,
    /// Its radius.
    pub radius: f64,
    /// A box containing the polyhedron (bound propagation over its rows).
    pub lo: Vec<f64>,
    /// See [`Self::lo`].
    pub hi: Vec<f64>,
}

/// The smallest and largest value of `a x` over the box `[lo, hi]`.
pub(super) fn range(a: &[f64], lo: &[f64], hi: &[f64]) -> (f64, f64) {
    a.iter()
        .zip(lo.iter().zip(hi))
        .fold((0.0, 0.0), |(mn, mx), (&ak, (&l, &h))| {
            let (u, v) = (ak * l, ak * h);
            (mn + u.min(v), mx + u.max(v))
        })
}

/// Tightens `[lo, hi]` to contain `{a x <= b}` ∩ the box: each row bounds
/// each coordinate by the smallest value its other terms take (two
/// passes; coefficients below 1e-9 are not divided by; the result is
/// widened by 1e-12 against rounding).
fn propagate(a: &[f64], b: &[f64], lo: &mut [f64], hi: &mut [f64]) {
    let d = lo.len();
    for _ in 0..2 {
        for (row, &bi) in a.chunks_exact(d).zip(b) {
            let (mn, _) = range(row, lo, hi);
            for k in 0..d {
                let ak = row[k];
                if ak.abs() < 1e-9 {
                    continue;
                }
                let own = (ak * lo[k]).min(ak * hi[k]);
                let bound = (bi - (mn - own)) / ak;
                if ak > 0.0 && bound + 1e-12 < hi[k] {
                    hi[k] = bound + 1e-12;
                } else if ak < 0.0 && bound - 1e-12 > lo[k] {
                    lo[k] = bound - 1e-12;
                }
            }
        }
    }
}

impl Poly {
    /// The box `[-1, 1]^d` plus `rows` (centre found by the caller).
    pub fn cube(d: usize) -> Self {
        let mut a = Vec::with_capacity(2 * d * d);
        let mut b = Vec::with_capacity(2 * d);
        for k in 0..d {
            for s in [1.0, -1.0] {
                let mut row = vec![0.0; d];
                row[k] = s;
                a.extend(row);
                b.push(1.0);
            }
        }
        Poly {
            a,
            b,
            centre: vec![0.0; d],
            radius: 1.0,
            lo: vec![-1.0; d],
            hi: vec![1.0; d],
        }
    }
}

/// The LP workspace, counters and the smallest radius a region must have.
#[derive(Debug, Default)]
pub(super) struct Geometry {
    lp: LpWorkspace,
    la: Vec<f64>,
    lb: Vec<f64>,
    /// LPs solved.
    pub lps: usize,
    /// Pieces found empty on a bounding box (no LP).
    pub pruned: usize,
    /// Regions whose ball is smaller are dropped (lower-dimensional).
    pub min_radius: f64,
    /// Comparisons of identical functions decided by the active list's
    /// order on a region whose members had different orders (union-merge
    /// mode, `crate::certify::union`): the certificate is then refused.
    pub order_ties: usize,
}

impl Geometry {
    /// A workspace dropping regions with balls below `min_radius`.
    pub fn new(min_radius: f64) -> Self {
        Geometry {
            min_radius,
            ..Geometry::default()
        }
    }

    /// `parent` cut by `extra`: `None` if a half-space never holds or the
    /// result has no ball of radius `min_radius`. Rows that hold on the
    /// parent's bounding box are implied and left out; a row that fails on
    /// all of it makes the result empty without an LP.
    pub fn restrict(&mut self, parent: &Poly, extra: &[Half]) -> Option<Poly> {
        let mut a = parent.a.clone();
        let mut b = parent.b.clone();
        for h in extra {
            match h {
                Half::Never => return None,
                Half::Always => {}
                Half::Row(r, c) => {
                    let (mn, mx) = range(r, &parent.lo, &parent.hi);
                    if mn > *c + 1e-12 {
                        self.pruned += 1;
                        return None;
                    }
                    if mx <= *c {
                        continue;
                    }
                    a.extend_from_slice(r);
                    b.push(*c);
                }
            }
        }
        let added = b.len() - parent.b.len();
        if added == 0 {
            return Some(parent.clone());
        }
        let (centre, radius) = self.chebyshev(&a, &b, &parent.centre)?;
        if radius < self.min_radius {
            return None;
        }
        let (mut lo, mut hi) = (parent.lo.clone(), parent.hi.clone());
        let d = lo.len();
        propagate(
            &a[a.len() - added * d..],
            &b[b.len() - added..],
            &mut lo,
            &mut hi,
        );
        Some(Poly {
            a,
            b,
            centre,
            radius,
            lo,
            hi,
        })
    }

    /// The polyhedron `{a x <= b}` (unit rows, containing the cube's rows)
    /// with its ball and bounding box; `None` without a ball of radius
    /// `min_radius`.
    pub fn poly_of(&mut self, a: Vec<f64>, b: Vec<f64>, start: &[f64]) -> Option<Poly> {
        let (centre, radius) = self.chebyshev(&a, &b, start)?;
        if radius < self.min_radius {
            return None;
        }
        let d = start.len();
        let (mut lo, mut hi) = (vec![-1.0; d], vec![1.0; d]);
        propagate(&a, &b, &mut lo, &mut hi);
        Some(Poly {
            a,
            b,
            centre,
            radius,
            lo,
            hi,
        })
    }

    /// The most `c x` over `{a x <= b}` from the feasible `start`, or
    /// `None` if the LP fails; stops early once the value passes `level`
    /// (the value returned is then above `level`, not the maximum).
    pub fn max_until(
        &mut self,
        c: &[f64],
        a: &[f64],
        b: &[f64],
        start: &[f64],
        level: f64,
    ) -> Option<f64> {
        self.lps += 1;
        let (st, v) = self.lp.maximize_until(c, a, b, start, level);
        (st == LpStatus::Optimal).then_some(v)
    }

    /// `poly` without its redundant rows (one LP per row; a row whose
    /// maximum over the others is at most `b + 1e-9` goes).
    pub fn reduce(&mut self, poly: &Poly) -> Poly {
        let d = poly.centre.len();
        let (mut a, mut b) = (poly.a.clone(), poly.b.clone());
        let mut i = 0;
        while i < b.len() {
            let row: Vec<f64> = a[i * d..(i + 1) * d].to_vec();
            let (mn, mx) = range(&row, &poly.lo, &poly.hi);
            let redundant = if mx < b[i] - 1e-10 {
                true
            } else if mn > b[i] {
                false
            } else {
                let mut ra = a.clone();
                ra.drain(i * d..(i + 1) * d);
                let mut rb = b.clone();
                rb.remove(i);
                // Bounded: the cube's rows stay unless redundant.
                match self.max_until(&row, &ra, &rb, &poly.centre, b[i] + 1e-9) {
                    Some(v) => v <= b[i] + 1e-9,
                    None => false,
                }
            };
            if redundant {
                a.drain(i * d..(i + 1) * d);
                b.remove(i);
            } else {
                i += 1;
            }
        }
        Poly {
            a,
            b,
            ..poly.clone()
        }
    }

    /// The largest ball in `{a x <= b}` (unit rows), from `start`.
    pub fn chebyshev(&mut self, a: &[f64], b: &[f64], start: &[f64]) -> Option<(Vec<f64>, f64)> {
        let d = start.len();
        self.la.clear();
        self.lb.clear();
        for (r, &bi) in a.chunks_exact(d).zip(b) {
            self.la.extend_from_slice(r);
            self.la.push(1.0);
            self.lb.push(bi);
        }
        // r <= 2 keeps the LP bounded (the cube has radius 1).
        self.la.extend(std::iter::repeat_n(0.0, d));
        self.la.push(1.0);
        self.lb.push(2.0);
        let mut c = vec![0.0; d + 1];
        c[d] = 1.0;
        let mut x0: Vec<f64> = start.iter().copied().chain([0.0]).collect();
        slack_start(&self.la, &self.lb, &mut x0, d);
        self.lps += 1;
        let (st, r) = self.lp.maximize_from(&c, &self.la, &self.lb, &x0);
        if st != LpStatus::Optimal {
            return None;
        }
        Some((self.lp.x[..d].to_vec(), r))
    }
}
