//! Stage 6: the explicit MPC (sections 6.2, 7.6.1): the mpQP solution, its
//! search trees, a check against the reference QP at random parameters,
//! and a 2-D slice of the partition (polygons for a figure).

use super::config::Config;
use super::error::{Context, PipelineError, Result};
use super::problems::{Problem, ProblemName, Problems};
use super::sample::{BoxSampler, qp_cost};
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::{
    ExplicitController, ExplicitSolver, MpqpSolution, Outputs, TreeSettings, build_controller,
};
use kestrel_mpc::{ParametricQpSolver, QpSettings, ReferenceSolver};
use nalgebra::DVector;

/// The explicit law against the reference QP at random parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExplicitCheck {
    /// Random parameters drawn.
    pub points: usize,
    /// Those outside the explored set (skipped).
    pub outside: usize,
    /// Largest `|z_explicit - z_QP|` (us).
    pub max_dz: f64,
    /// Largest `|J_explicit - J_QP|`.
    pub max_dj: f64,
}

/// The explicit solution of one problem.
#[derive(Clone, Debug)]
pub struct ExplicitSolution {
    /// Which problem.
    pub name: ProblemName,
    /// The regions and their laws.
    pub solution: MpqpSolution,
    /// Tree over the whole `z` (the closed loop's and Table 7.2's).
    pub full: ExplicitController,
    /// Tree over the first move (the firmware's).
    pub first: ExplicitController,
    /// The check against the reference QP.
    pub check: ExplicitCheck,
}

/// One region cut by the slice.
#[derive(Clone, Debug, PartialEq)]
pub struct SlicePolygon {
    /// Vertices in the slice's coordinates.
    pub vertices: Vec<(f64, f64)>,
    /// The region's law (regions of one law share it).
    pub law: usize,
}

/// A 2-D slice of the partition: two parameters vary over a box, the
/// others are 0 but for the throttle.
#[derive(Clone, Debug, PartialEq)]
pub struct PartitionSlice {
    /// Parameter indices of the axes.
    pub axes: [usize; 2],
    /// Their names.
    pub axis_names: [String; 2],
    /// Ranges of the axes.
    pub range: [[f64; 2]; 2],
    /// Throttle of the slice point (us).
    pub throttle: f64,
    /// The regions the slice cuts.
    pub polygons: Vec<SlicePolygon>,
}

/// Stage 6's result.
#[derive(Clone, Debug)]
pub struct Explicit {
    /// The thesis-sized problem.
    pub thesis: ExplicitSolution,
    /// The larger problem, when `empc.solve_larger`.
    pub larger: Option<ExplicitSolution>,
    /// The slice of the thesis-sized problem's partition.
    pub slice: PartitionSlice,
}

impl Explicit {
    /// The solutions computed, thesis-sized first.
    pub fn solutions(&self) -> impl Iterator<Item = &ExplicitSolution> {
        std::iter::once(&self.thesis).chain(self.larger.as_ref())
    }
}

/// Clips the polygon `poly` by `a . v <= b` (Sutherland-Hodgman).
pub fn clip(poly: &[(f64, f64)], a: (f64, f64), b: f64) -> Vec<(f64, f64)> {
    let inside = |p: &(f64, f64)| a.0 * p.0 + a.1 * p.1 <= b + 1e-12;
    let mut out = Vec::new();
    for i in 0..poly.len() {
        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
        let (ip, iq) = (inside(&p), inside(&q));
        if ip {
            out.push(p);
        }
        if ip != iq {
            let fp = a.0 * p.0 + a.1 * p.1 - b;
            let fq = a.0 * q.0 + a.1 * q.1 - b;
            let s = fp / (fp - fq);
            out.push((p.0 + s * (q.0 - p.0), p.1 + s * (q.1 - p.1)));
        }
    }
    out
}

fn partition_slice(
    cfg: &Config,
    pr: &Problems,
    problem: &Problem,
    sol: &MpqpSolution,
    ctl: &ExplicitController,
) -> Result<PartitionSlice> {
    let [i, j] = cfg.empc.slice_axes;
    let p = problem.mpqp.p();
    if i >= p || j >= p {
        return Err(PipelineError::config_message(format!(
            "empc.slice_axes = [{i}, {j}]: the problem has {p} parameters (0..{p})"
        )));
    }
    let mut theta0 = DVector::zeros(p);
    // The thesis's one extra parameter is the throttle.
    for t in problem.problem.layout.parameters() {
        theta0[t] = cfg.empc.slice_throttle;
    }
    let [xr, yr] = cfg.empc.slice_range;
    let square = vec![
        (xr[0], yr[0]),
        (xr[1], yr[0]),
        (xr[1], yr[1]),
        (xr[0], yr[1]),
    ];
    let mut polygons = Vec::new();
    for (k, reg) in sol.regions.iter().enumerate() {
        let rhs = &reg.b - &reg.a * &theta0;
        let mut poly = square.clone();
        for row in 0..reg.a.nrows() {
            poly = clip(&poly, (reg.a[(row, i)], reg.a[(row, j)]), rhs[row]);
            if poly.len() < 3 {
                break;
            }
        }
        if poly.len() >= 3 {
            polygons.push(SlicePolygon {
                vertices: poly,
                law: ctl.region_law.get(k).copied().unwrap_or(0) as usize,
            });
        }
    }
    Ok(PartitionSlice {
        axes: [i, j],
        axis_names: [pr.parameter_name(i), pr.parameter_name(j)],
        range: cfg.empc.slice_range,
        throttle: cfg.empc.slice_throttle,
        polygons,
    })
}

fn check(cfg: &Config, mpqp: &MpqpProblem, full: &ExplicitController) -> Result<ExplicitCheck> {
    let mut qp =
        ReferenceSolver::new(mpqp, QpSettings::default()).ctx(|| "the reference QP".into())?;
    let mut solver = ExplicitSolver::new(full.tables.clone());
    let mut rng = BoxSampler::new(0x5EED + mpqp.p() as u64);
    let (mut dz, mut dj) = (0.0f64, 0.0f64);
    let mut z = vec![0.0; mpqp.n()];
    for _ in 0..cfg.empc.check_points {
        let th = rng.theta(mpqp);
        let before = solver.outside();
        solver
            .solve_into(th.as_slice(), &mut z)
            .ctx(|| "the explicit law".into())?;
        if solver.outside() > before {
            continue;
        }
        let q = qp.solve(&th).ctx(|| "the reference QP".into())?;
        let ze = DVector::from_column_slice(&z);
        dz = dz.max((&ze - &q.z).amax());
        dj = dj.max((qp_cost(mpqp, &ze, &th) - qp_cost(mpqp, &q.z, &th)).abs());
    }
    Ok(ExplicitCheck {
        points: cfg.empc.check_points,
        outside: solver.outside(),
        max_dz: dz,
        max_dj: dj,
    })
}

fn solve(
    cfg: &Config,
    problem: &Problem,
    progress: &mut dyn FnMut(&str),
) -> Result<ExplicitSolution> {
    let name = problem.name.as_str();
    progress(&format!("6. explicit MPC: {name}"));
    let mpqp = &problem.mpqp;
    let solution = kestrel_empc::solve(
        mpqp,
        &kestrel_empc::Settings {
            parallel: true,
            progress: false,
            ..kestrel_empc::Settings::default()
        },
    )
    .ctx(|| format!("explicit solution of the {name} problem"))?;
    let full = build_controller(mpqp, &solution, &TreeSettings::default())
        .ctx(|| format!("the {name} problem's search tree"))?;
    let nu = problem.nu();
    // With one block the first move is all of z: the same tree.
    let first = if mpqp.n() == nu {
        full.clone()
    } else {
        build_controller(
            mpqp,
            &solution,
            &TreeSettings {
                outputs: Outputs::First(nu),
                ..TreeSettings::default()
            },
        )
        .ctx(|| format!("the {name} problem's first-move tree"))?
    };
    let check = check(cfg, mpqp, &full)?;
    Ok(ExplicitSolution {
        name: problem.name,
        solution,
        full,
        first,
        check,
    })
}

/// Stage 6.
///
/// # Errors
/// Bad slice axes; kestrel-empc's and the reference QP's errors.
pub fn run(cfg: &Config, pr: &Problems, progress: &mut dyn FnMut(&str)) -> Result<Explicit> {
    let thesis = solve(cfg, &pr.thesis, progress)?;
    let larger = if cfg.empc.solve_larger {
        Some(solve(cfg, &pr.larger, progress)?)
    } else {
        None
    };
    let slice = partition_slice(cfg, pr, &pr.thesis, &thesis.solution, &thesis.full)?;
    Ok(Explicit {
        thesis,
        larger,
        slice,
    })
}
