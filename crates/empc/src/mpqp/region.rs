//! A region while exploring: its half-spaces with their origins, its
//! facets and its affine law (reduced row indices).

use nalgebra::{DMatrix, DVector};

/// Where a half-space of a region comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Origin {
    /// The inactive constraint `i` (reduced index): crossing it activates `i`.
    Primal(usize),
    /// The multiplier of the active constraint `j`: crossing it drops `j`.
    Dual(usize),
    /// A row of the parameter set (a boundary of the exploration).
    Param,
}

/// A facet of a computed region, with a point in its relative interior.
#[derive(Clone, Debug)]
pub(super) struct Facet {
    pub(super) hs: usize,
    pub(super) point: Vec<f64>,
    pub(super) radius: f64,
}

/// A region while exploring (reduced row indices).
#[derive(Clone, Debug)]
pub(super) struct RegionData {
    pub(super) active: Vec<usize>,
    /// All distinct half-spaces (rows of length p), with origins.
    pub(super) hs_a: Vec<f64>,
    pub(super) hs_b: Vec<f64>,
    pub(super) origins: Vec<Vec<Origin>>,
    pub(super) facets: Vec<Facet>,
    pub(super) kz: DMatrix<f64>,
    pub(super) kzc: DVector<f64>,
    pub(super) center: Vec<f64>,
    pub(super) radius: f64,
    pub(super) lps: usize,
}

impl RegionData {
    /// Whether `theta` satisfies every facet within `tol`.
    pub(super) fn contains(&self, theta: &[f64], tol: f64) -> bool {
        let p = theta.len();
        self.facets.iter().all(|f| {
            let a = &self.hs_a[f.hs * p..(f.hs + 1) * p];
            a.iter().zip(theta).map(|(x, y)| x * y).sum::<f64>() <= self.hs_b[f.hs] + tol
        })
    }
}

/// A seed from an active set (FNV-1a), so that a region's random
/// directions do not depend on the order of exploration.
pub(super) fn seed_of(set: &[usize]) -> u64 {
    set.iter().fold(0xCBF2_9CE4_8422_2325u64, |h, &i| {
        (h ^ i as u64).wrapping_mul(0x0100_0000_01B3)
    })
}
