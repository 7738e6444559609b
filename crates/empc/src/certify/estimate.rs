//! An estimate of the size of the cold-start partition before it is
//! computed: Knuth's estimator (random root-to-leaf walks, each level's
//! leaves weighted by the product of the branching factors above it),
//! unbiased for the number of regions, and the time at the walks' cost
//! per split region.

use super::error::CertifyError;
use super::geometry::Geometry;
use super::model::Model;
use super::step::{Node, Outcome, expand};
use crate::rng::Rng;
use std::time::Instant;

/// The up-front size estimate of a cold-start partition (see
/// [`crate::certify::CertifySettings::estimate_probes`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Estimated regions of the cold-start partition.
    pub regions: f64,
    /// Estimated time to compute it, at the walks' cost per region.
    pub seconds: f64,
    /// Random walks made.
    pub probes: usize,
}

/// `probes` random walks from `root`.
pub(super) fn estimate(
    model: &Model,
    geo: &mut Geometry,
    root: &Node,
    probes: usize,
) -> Result<Estimate, CertifyError> {
    let started = Instant::now();
    let mut rng = Rng::new(24);
    let (mut total, mut splits) = (0.0, 0usize);
    let mut out = Vec::new();
    for _ in 0..probes {
        let mut node = root.clone();
        let mut weight = 1.0;
        loop {
            out.clear();
            splits += 1;
            expand(model, geo, node, &mut out)?;
            let mut inner: Vec<Node> = Vec::new();
            for o in out.drain(..) {
                match o {
                    Outcome::Leaf(..) => total += weight,
                    Outcome::Node(n) => inner.push(n),
                    Outcome::Canonical(_) => return Err(super::explore::merged_model()),
                }
            }
            if inner.is_empty() {
                break;
            }
            weight *= inner.len() as f64;
            let pick = (rng.next_u64() % inner.len() as u64) as usize;
            node = inner.swap_remove(pick);
        }
    }
    let regions = total / probes.max(1) as f64;
    let per_split = started.elapsed().as_secs_f64() / splits.max(1) as f64;
    Ok(Estimate {
        regions,
        // About as many splits as regions in a partition tree.
        seconds: 2.0 * regions * per_split,
        probes,
    })
}
