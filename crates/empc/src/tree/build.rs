//! The entry points of the single-tree layout: [`build_controller`]
//! (`u16` tables) and [`build_any`] (either index width).

use crate::error::EmpcError;
use crate::mpqp::MpqpSolution;
use crate::tree::assemble::build_wide_for;
use crate::tree::settings::{MAX_NODES, Outputs, TreeLayout, TreeSettings, WIDE_MAX_NODES};
use crate::tree::stats::TreeStats;
use crate::tree::tables::{AnyTables, OwnedTables, WideTables};
use kestrel_core::formats::MpqpProblem;

/// An explicit controller: the tables and what building them found.
#[derive(Clone, Debug)]
pub struct ExplicitController {
    /// The tables in `f64`.
    pub tables: OwnedTables<f64>,
    /// Law index of every region of the solution.
    pub region_law: Vec<u16>,
    /// Tree statistics.
    pub stats: TreeStats,
}

/// An explicit controller in either layout ([`build_any`]).
#[derive(Clone, Debug)]
pub struct AnyController {
    /// The tables in `f64`.
    pub tables: AnyTables,
    /// Law index of every region of the solution.
    pub region_law: Vec<u16>,
    /// Tree statistics.
    pub stats: TreeStats,
}

/// Builds the explicit controller: law sharing, the search tree and the tables.
///
/// `problem` supplies the output bounds (rows of `G` that bound a single
/// kept output) used to clamp outside the explored set.
pub fn build_controller(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
) -> Result<ExplicitController, EmpcError> {
    let k = kept_outputs(problem, solution, settings)?;
    let outs: Vec<usize> = (0..k).collect();
    build_for(problem, solution, settings, &outs)
}

/// Builds the explicit controller in the layout [`TreeSettings::layout`]
/// asks for: as [`build_controller`] (the same tree, node for node), with
/// the wide `u32` tables ([`WideTables`]) when the tree exceeds the
/// [`MAX_NODES`] of the `u16` layout ([`TreeLayout::Auto`]) or always
/// ([`TreeLayout::Wide`]), up to [`TreeSettings::max_nodes`].
///
/// ```
/// use kestrel_empc::{solve, Settings};
/// use kestrel_empc::tree::{build_any, AnyTables, TreeLayout, TreeSettings};
/// # use kestrel_core::formats::MpqpProblem;
/// # let problem = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
/// #   "H": [[1, 0], [0, 1]], "F": [[1, 0], [0, 1]],
/// #   "G": [[1, 0], [0, 1], [-1, 0], [0, -1]], "W": [1, 1, 1, 1],
/// #   "E": [[0, 0], [0, 0], [0, 0], [0, 0]],
/// #   "theta_lb": [-3, -3], "theta_ub": [3, 3]}"#).unwrap();
/// let solution = solve(&problem, &Settings::default()).unwrap();
/// let settings = TreeSettings { layout: TreeLayout::Wide, ..TreeSettings::default() };
/// let c = build_any(&problem, &solution, &settings).unwrap();
/// let AnyTables::Wide(t) = &c.tables else { unreachable!() };
/// let mut z = [0.0; 2];
/// kestrel_empc::evaluate(&t.tables(), &[0.5, -2.0], &mut z).unwrap();
/// assert_eq!(z, [-0.5, 1.0]);
/// ```
pub fn build_any(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
) -> Result<AnyController, EmpcError> {
    let k = kept_outputs(problem, solution, settings)?;
    let outs: Vec<usize> = (0..k).collect();
    let cap = match settings.layout {
        TreeLayout::Narrow => settings.max_nodes.min(MAX_NODES),
        TreeLayout::Auto | TreeLayout::Wide => settings.max_nodes.min(WIDE_MAX_NODES),
    };
    let w = build_wide_for(problem, solution, settings, &outs, cap)?;
    let tables = match settings.layout {
        TreeLayout::Wide => AnyTables::Wide(w.tables),
        TreeLayout::Auto => match w.tables.narrow() {
            Some(t) => AnyTables::Narrow(t),
            None => AnyTables::Wide(w.tables),
        },
        TreeLayout::Narrow => {
            AnyTables::Narrow(w.tables.narrow().ok_or_else(|| narrow_error(&w.tables))?)
        }
    };
    Ok(AnyController {
        tables,
        region_law: w.region_law,
        stats: w.stats,
    })
}

/// The error for a tree that does not fit the `u16` layout.
fn narrow_error(t: &WideTables<f64>) -> EmpcError {
    EmpcError::TooLarge(format!(
        "{} nodes, {} affine rows: beyond the u16 layout ({MAX_NODES} nodes, 65534 rows); build_any with TreeLayout::Auto or Wide gives u32 tables",
        t.nodes.len(),
        t.rows.len() / (t.n_params + 1)
    ))
}

/// The number of kept outputs, after checking that problem and solution match.
pub(super) fn kept_outputs(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
) -> Result<usize, EmpcError> {
    let p = solution.p;
    let n = solution.n;
    let k = match settings.outputs {
        Outputs::All => n,
        Outputs::First(k) if k >= 1 && k <= n => k,
        Outputs::First(k) => {
            return Err(EmpcError::InvalidArgument(format!(
                "Outputs::First({k}) needs 1 <= k <= n = {n}"
            )));
        }
    };
    if problem.n() != n || problem.p() != p {
        return Err(EmpcError::InvalidArgument(
            "the problem does not match the solution".into(),
        ));
    }
    Ok(k)
}

/// [`build_controller`] for the outputs `outs` of `z` (in that order).
pub(super) fn build_for(
    problem: &MpqpProblem,
    solution: &MpqpSolution,
    settings: &TreeSettings,
    outs: &[usize],
) -> Result<ExplicitController, EmpcError> {
    let w = build_wide_for(
        problem,
        solution,
        settings,
        outs,
        settings.max_nodes.min(MAX_NODES),
    )?;
    let tables = w.tables.narrow().ok_or_else(|| narrow_error(&w.tables))?;
    Ok(ExplicitController {
        tables,
        region_law: w.region_law,
        stats: w.stats,
    })
}
