//! What the solver returns: the critical regions and the explored set.

use nalgebra::{DMatrix, DVector};

/// One critical region: `theta` with `a theta <= b` has the optimal active
/// set `active_set` and the optimiser `z = fz theta + gz`.
#[derive(Clone, Debug, PartialEq)]
pub struct CriticalRegion {
    /// Indices of the active constraints (rows of the problem's `G`).
    pub active_set: Vec<usize>,
    /// Half-space normals, one non-redundant facet per row, unit length.
    pub a: DMatrix<f64>,
    /// Half-space offsets.
    pub b: DVector<f64>,
    /// Gain of the optimiser, `n x p`.
    pub fz: DMatrix<f64>,
    /// Offset of the optimiser, `n`.
    pub gz: DVector<f64>,
    /// Centre of the largest ball inside the region.
    pub center: DVector<f64>,
    /// Radius of that ball.
    pub radius: f64,
}

impl CriticalRegion {
    /// Whether `theta` satisfies every half-space within `tol`.
    pub fn contains(&self, theta: &[f64], tol: f64) -> bool {
        (0..self.a.nrows()).all(|i| {
            let s: f64 = (0..self.a.ncols()).map(|j| self.a[(i, j)] * theta[j]).sum();
            s <= self.b[i] + tol
        })
    }
    /// The optimiser `fz theta + gz`.
    pub fn z(&self, theta: &[f64]) -> DVector<f64> {
        &self.fz * DVector::from_column_slice(theta) + &self.gz
    }
}

/// Counters of a solve.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SolveStats {
    /// Active sets whose region was computed.
    pub active_sets_tested: usize,
    /// Of those, how many were lower-dimensional, empty or violated LICQ.
    pub discarded: usize,
    /// QP solves at probe points where the facet rule failed (degeneracy).
    pub fallback_qps: usize,
    /// LPs solved.
    pub lps: usize,
    /// Constraint rows removed as exact duplicates of another row.
    pub duplicate_rows: usize,
    /// Wall-clock seconds of the solve (measured inside [`solve`](crate::mpqp::solve)).
    pub solve_seconds: f64,
}

/// The explicit solution: all full-dimensional critical regions.
#[derive(Clone, Debug)]
pub struct MpqpSolution {
    /// Number of decision variables.
    pub n: usize,
    /// Number of parameters.
    pub p: usize,
    /// The regions.
    pub regions: Vec<CriticalRegion>,
    /// The explored set (parameters with a feasible QP) is the parameter box
    /// intersected with `hull_a theta <= hull_b`.
    pub hull_a: DMatrix<f64>,
    /// Offsets of the explored set.
    pub hull_b: DVector<f64>,
    /// Lower corner of the parameter box.
    pub theta_lb: DVector<f64>,
    /// Upper corner of the parameter box.
    pub theta_ub: DVector<f64>,
    /// Counters and timing.
    pub stats: SolveStats,
}

impl MpqpSolution {
    /// The index of the first region containing `theta` (within `tol`).
    pub fn locate(&self, theta: &[f64], tol: f64) -> Option<usize> {
        self.regions.iter().position(|r| r.contains(theta, tol))
    }

    /// The first `k` entries of the optimiser `fz theta + gz` of the first
    /// region containing `theta`, each half-space `a_i theta <= b_i` allowed
    /// the relative slack `1e-9 (1 + |b_i|)`: the solution's own answer, the
    /// reference a search tree is checked against. `None` where no region
    /// contains `theta`, or where `theta.len() != p` or `k > n`.
    ///
    /// ```
    /// use kestrel_core::formats::MpqpProblem;
    /// use kestrel_empc::{Settings, solve};
    ///
    /// // min 1/2 z^2 + theta z on |z| <= 1: z = clamp(-theta).
    /// let prob = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
    ///   "H": [[1]], "F": [[1]], "G": [[1], [-1]], "W": [1, 1],
    ///   "E": [[0], [0]], "theta_lb": [-3], "theta_ub": [3]}"#).unwrap();
    /// let sol = solve(&prob, &Settings::default()).unwrap();
    /// assert!((sol.first_outputs_at(&[0.5], 1).unwrap()[0] + 0.5).abs() < 1e-12);
    /// assert_eq!(sol.first_outputs_at(&[2.0], 1).unwrap(), vec![-1.0]);
    /// assert!(sol.first_outputs_at(&[0.5, 0.0], 1).is_none());
    /// ```
    pub fn first_outputs_at(&self, theta: &[f64], k: usize) -> Option<Vec<f64>> {
        if theta.len() != self.p || k > self.n {
            return None;
        }
        let r = self.regions.iter().find(|r| {
            (0..r.a.nrows()).all(|i| {
                let v: f64 = (0..theta.len()).map(|j| r.a[(i, j)] * theta[j]).sum();
                v <= r.b[i] + 1e-9 * (1.0 + r.b[i].abs())
            })
        })?;
        Some(
            (0..k)
                .map(|o| {
                    r.gz[o]
                        + (0..theta.len())
                            .map(|j| r.fz[(o, j)] * theta[j])
                            .sum::<f64>()
                })
                .collect(),
        )
    }
}
