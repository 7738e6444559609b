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
    /// Regions whose ball is smaller are dropped (lower-dimensional).
    pub min_radius: f64,
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
    /// result has no ball of radius `min_radius`.
    pub fn restrict(&mut self, parent: &Poly, extra: &[Half]) -> Option<Poly> {
        let mut a = parent.a.clone();
        let mut b = parent.b.clone();
        for h in extra {
            match h {
                Half::Never => return None,
                Half::Always => {}
                Half::Row(r, c) => {
                    a.extend_from_slice(r);
                    b.push(*c);
                }
            }
        }
        if b.len() == parent.b.len() {
            return Some(parent.clone());
        }
        let (centre, radius) = self.chebyshev(&a, &b, &parent.centre)?;
        (radius >= self.min_radius).then_some(Poly {
            a,
            b,
            centre,
            radius,
        })
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
