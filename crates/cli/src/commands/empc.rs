//! `kestrel empc`: explicit MPC — solve an mpQP, evaluate the solution, export tables.

mod locate;

use super::problem_thetas::read_parameter_rows;
use super::scalar_arg::ScalarArg;
use crate::io;
use anyhow::{Context, bail};
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::eval::{TreeIndex, TreeTables};
use kestrel_empc::export::{self, ExportScalar, SolutionTables};
use kestrel_empc::locate::{LocateMethod, LocateSettings, build_lists, estimate};
use kestrel_empc::tree::{AnyTables, TreeLayout, build_any};
use kestrel_empc::{
    ExplicitController, Outputs, Settings, TreeSettings, build_compact, evaluate_lists,
    evaluate_with, solve,
};
use locate::Stored;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Explicit MPC: `solve` a `kestrel.mpqp.v1` problem into a `kestrel.empc.v1`
/// solution (critical regions, search tree, tables), `eval` it at parameters
/// from a CSV file, `export` its tables as Rust source.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    command: Sub,
}

#[derive(clap::Subcommand, Debug)]
enum Sub {
    /// Solve the mpQP; write the solution (summary, regions, tree tables).
    ///
    /// Input: a `kestrel.mpqp.v1` problem `min 1/2 z'Hz + (F'theta + f)'z
    /// subject to G z <= W + E theta`, theta in the box [theta_lb, theta_ub]
    /// (keys H, F, f, G, W, E, theta_lb, theta_ub; H positive definite, the
    /// box finite). Output (--out, default standard output): a
    /// `kestrel.empc.v1` solution file with the summary (regions,
    /// distinct_laws, solve_seconds, tree {depth, nodes, bytes}), the region
    /// list (active set, half-spaces A theta <= b, law z = Fz theta + gz;
    /// leave out with --no-regions) and the evaluation tables that `eval`
    /// and `export` read (u16 indices; trees beyond 32767 nodes in the wide
    /// u32 layout, `tables.index = "u32"`, see --layout). A one-line
    /// summary goes to standard error; on a terminal (or with --progress)
    /// the stages too: exploring the regions, the point location (its size
    /// estimated before it is built), writing.
    ///
    /// Point location (--locate): `tree` is the exact search tree above;
    /// `lists` a shallow tree whose leaves list a few candidate regions,
    /// each tested by its facets (size and build time about linear in the
    /// regions; the file then holds `locate` and `lists` instead of `tree`
    /// and `tables`); `auto` (the default) the tree up to 200 regions (or
    /// with --compact) and the lists above. --no-tree writes the regions
    /// alone (no point location; `eval` and `export` refuse such a file).
    /// Unbounded parameter sets, an indefinite H and an empty feasible set
    /// are errors.
    Solve(SolveArgs),
    /// Evaluate a solution at parameters (CSV, one theta per row, no header).
    ///
    /// Input: a solution file from `kestrel empc solve` and a CSV file with
    /// one parameter vector theta per row (p numbers, no header). Output
    /// (--out, default standard output): CSV, one row per theta, with the
    /// optimal z (or its first K entries when solved with --first-move K),
    /// from the search tree. Parameters outside the explored set get the
    /// nearest region's law clamped to the bounds, with a warning on
    /// standard error. With --compact the compact layout (one tree per
    /// output, from `solve --compact`) is evaluated instead of the default
    /// tree: the same z.
    Eval(EvalArgs),
    /// Export a solution's tables as Rust source with `static` arrays.
    ///
    /// Input: a solution file from `kestrel empc solve`. Output (--out,
    /// default standard output): Rust source defining `NODES`, `LAWS`,
    /// `ROWS`, `HULL`, `THETA_LB`, `THETA_UB`, `BOUNDS` (u16 indices, numbers
    /// in the chosen --scalar) and `TABLES: kestrel_empc::SliceTables`, to
    /// evaluate with `kestrel_empc::evaluate` in no_std firmware; a wide
    /// solution (u32 layout) gives u32 `NODES`, `LAWS`, `BOUNDS` and
    /// `TABLES: kestrel_empc::eval::WideSliceTables`. With
    /// --compact (a solution from `solve --compact`): the compact layout,
    /// `ROOTS`, `NODES: [kestrel_empc::CompactNode; _]` (u8 rows, u16
    /// children), `ROWS`, `HULL`, `THETA_LB`, `THETA_UB`, `BOUNDS` and
    /// `TABLES: kestrel_empc::ForestTables`, evaluated by the same
    /// `kestrel_empc::evaluate`. A solution with candidate lists (`solve
    /// --locate lists`, or `auto` above 200 regions) gives their tables and
    /// `TABLES: kestrel_empc::ListSlices`, evaluated by
    /// `kestrel_empc::evaluate_lists` (u16 indices only).
    Export(ExportArgs),
}

/// `kestrel empc solve`.
#[derive(clap::Args, Debug)]
struct SolveArgs {
    /// Problem file (`kestrel.mpqp.v1`).
    #[arg(long)]
    problem: PathBuf,
    /// Solution file to write (`kestrel.empc.v1` with `region_list` and `tables`);
    /// default: standard output.
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    replace: io::Replace,
    /// Keep only the first K entries of z (the first move) in the tree and tables.
    #[arg(long, value_name = "K")]
    first_move: Option<usize>,
    /// Leave the region list out of the solution file.
    #[arg(long)]
    no_regions: bool,
    /// Explore on one thread.
    #[arg(long)]
    sequential: bool,
    /// Show a progress bar on standard error (always shown when standard
    /// error is a terminal).
    #[arg(long)]
    progress: bool,
    /// Keep one leaf per law: no clipping (by default a leaf may serve
    /// regions whose differing outputs saturate, with the same clamped z).
    #[arg(long)]
    no_clipping: bool,
    /// How the search tree scores candidate hyperplanes: `lp` (exact LP
    /// scores of the best few, small trees, slow beyond a few hundred
    /// regions), `sampled` (scores from sample points inside the regions,
    /// only the chosen split runs LPs; fast on thousands of regions) or
    /// `auto` (`lp` up to 400 regions). Both trees are exact.
    #[arg(long, value_enum, default_value = "auto")]
    tree_method: TreeMethodArg,
    /// Stop with an error once the search tree has this many nodes (the
    /// u16 layout holds at most 32767; larger trees take the u32 layout).
    #[arg(long, value_name = "NODES", default_value_t = kestrel_empc::tree::DEFAULT_MAX_NODES)]
    max_nodes: usize,
    /// Index width of the tables: `auto` (u16 when the tree fits, else
    /// u32), `u16` (an error beyond 32767 nodes) or `u32` (always wide).
    #[arg(long, value_enum, default_value = "auto")]
    layout: LayoutArg,
    /// Also build the compact layout (one search tree per output, 6-byte
    /// nodes): adds `tree_compact` (with its f32 `bytes`) and
    /// `compact_tables` to the solution file.
    #[arg(long)]
    compact: bool,
    /// Point location: `auto` (the exact tree up to 200 regions or with
    /// --compact, candidate lists above), `tree` (the exact search tree)
    /// or `lists` (leaves listing a few candidate regions tested in turn;
    /// grows about linearly with the regions).
    #[arg(long, value_enum, default_value = "auto")]
    locate: LocateArg,
    /// Solve the mpQP alone: write the regions (and the summary) without
    /// any point location.
    #[arg(long, conflicts_with_all = ["no_regions", "compact"])]
    no_tree: bool,
}

/// Point-location structure (`kestrel_empc::locate::LocateMethod`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum LocateArg {
    /// The tree up to 200 regions, candidate lists above.
    Auto,
    /// The exact search tree.
    Tree,
    /// Candidate lists in the leaves of a shallow tree.
    Lists,
}

/// Tree construction method (`kestrel_empc::tree::TreeMethod`).
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum TreeMethodArg {
    /// LP scoring up to 400 regions, sampled scoring above.
    Auto,
    /// Exact LP scores of the best few candidates.
    Lp,
    /// Scores from sample points; LPs only for the chosen split.
    Sampled,
}

/// Table layout (`kestrel_empc::tree::TreeLayout`).
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum LayoutArg {
    /// u16 indices when the tree fits, else u32.
    Auto,
    /// u16 indices (flash-ready), at most 32767 nodes.
    U16,
    /// u32 indices.
    U32,
}

/// `kestrel empc eval`.
#[derive(clap::Args, Debug)]
struct EvalArgs {
    /// Solution file written by `kestrel empc solve`.
    #[arg(long)]
    solution: PathBuf,
    /// CSV file: one parameter vector per row, no header.
    #[arg(long)]
    thetas: PathBuf,
    /// Output CSV (default: standard output): the optimal z (or its first
    /// move, as solved), one row per theta.
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    replace: io::Replace,
    /// Evaluate the compact layout (`compact_tables`, written by `solve
    /// --compact`) instead of the default tree.
    #[arg(long)]
    compact: bool,
}

/// `kestrel empc export`.
#[derive(clap::Args, Debug)]
struct ExportArgs {
    /// Solution file written by `kestrel empc solve`.
    #[arg(long)]
    solution: PathBuf,
    /// Number type of the tables.
    #[arg(long, value_enum, default_value = "f32")]
    scalar: ScalarArg,
    /// Rust source file to write (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    replace: io::Replace,
    /// Export the compact layout (`compact_tables`, written by `solve
    /// --compact`): one tree per output, 6-byte nodes.
    #[arg(long)]
    compact: bool,
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Sub::Solve(a) => run_solve(a),
        Sub::Eval(a) => run_eval(a),
        Sub::Export(a) => run_export(a),
    }
}

fn run_solve(a: SolveArgs) -> anyhow::Result<()> {
    a.replace.check(&[a.out.as_deref()])?;
    if a.max_nodes == 0 {
        bail!("--max-nodes: a search tree has at least 1 node, got 0");
    }
    let name = a.problem.display().to_string();
    let problem = MpqpProblem::read(&a.problem).with_context(|| name.clone())?;
    let settings = Settings {
        parallel: !a.sequential,
        // A bar on a terminal always; --progress also elsewhere.
        progress: a.progress || crate::progress::enabled(),
        ..Settings::default()
    };
    crate::guards::announce_explicit(
        problem.n(),
        problem.m(),
        "a smaller parameter box (kestrel mpc --x-max, --r-max) or fewer move blocks shrink it, and kestrel fgm solves the same problem online without it",
    );
    if let Some(k) = a.first_move.filter(|&k| k == 0 || k > problem.n()) {
        bail!(
            "--first-move {k}: the problem has {} variables; keep between 1 and {} of them",
            problem.n(),
            problem.n()
        );
    }
    // Stages on a terminal (or with --progress).
    let show = settings.progress;
    let stages = if a.no_tree { 2 } else { 3 };
    locate::stage(show, 1, stages, "exploring the critical regions");
    let sol = solve(&problem, &settings).with_context(|| name.clone())?;
    locate::stage(
        show,
        1,
        stages,
        &format!(
            "{} regions in {:.2} s ({} LPs, {} QPs at probe points)",
            sol.regions.len(),
            sol.stats.solve_seconds,
            sol.stats.lps,
            sol.stats.fallback_qps
        ),
    );
    if a.no_tree {
        locate::stage(show, 2, stages, "writing the solution (no point location)");
        eprintln!(
            "{} regions, solved in {:.4} s; no point location (--no-tree)",
            sol.regions.len(),
            sol.stats.solve_seconds
        );
        let text = locate::solution_only_json(&sol, true);
        return io::write_output(a.out.as_deref(), &text);
    }
    let outputs = match a.first_move {
        Some(k) => Outputs::First(k),
        None => Outputs::All,
    };
    let tree = TreeSettings {
        outputs,
        clipping: !a.no_clipping,
        method: match a.tree_method {
            TreeMethodArg::Auto => kestrel_empc::tree::TreeMethod::Auto,
            TreeMethodArg::Lp => kestrel_empc::tree::TreeMethod::Lp,
            TreeMethodArg::Sampled => kestrel_empc::tree::TreeMethod::Sampled,
        },
        max_nodes: a.max_nodes,
        layout: match a.layout {
            LayoutArg::Auto => TreeLayout::Auto,
            LayoutArg::U16 => TreeLayout::Narrow,
            LayoutArg::U32 => TreeLayout::Wide,
        },
        ..TreeSettings::default()
    };
    let lsettings = LocateSettings {
        method: match a.locate {
            // The compact layout is a form of the exact tree.
            LocateArg::Tree => LocateMethod::Tree,
            LocateArg::Auto if a.compact => LocateMethod::Tree,
            LocateArg::Auto => LocateMethod::Auto,
            LocateArg::Lists => LocateMethod::Lists,
        },
        outputs,
        parallel: !a.sequential,
        tree: tree.clone(),
        ..LocateSettings::default()
    };
    if a.compact && a.locate == LocateArg::Lists {
        bail!("--compact is a layout of the exact search tree: use it with --locate tree or auto");
    }
    lsettings.validate().with_context(|| name.clone())?;
    let est = estimate(&problem, &sol, &lsettings).with_context(|| name.clone())?;
    locate::stage(show, 2, stages, &locate::describe(&est));
    if est.method == LocateMethod::Lists {
        let bar = locate::LocateProgress::new(show);
        let lists = build_lists(&problem, &sol, &lsettings, &mut |p| bar.report(p))
            .with_context(|| name.clone())?;
        drop(bar);
        let st = &lists.stats;
        eprintln!(
            "{} regions, {} distinct laws, solved in {:.4} s; candidate lists: depth {}, {} nodes, {} leaves (longest list {}), {} bytes (f32, {} indices), worst case {} multiply-adds and {} comparisons, built in {:.2} s",
            sol.regions.len(),
            st.distinct_laws,
            sol.stats.solve_seconds,
            st.depth,
            st.nodes,
            st.leaves,
            st.max_leaf_regions,
            st.bytes_f32,
            if st.fits_u16 { "u16" } else { "u32" },
            st.worst_case.mul_adds,
            st.worst_case.comparisons,
            st.build_seconds
        );
        if st.nodes == 0 && st.max_leaf_regions > lsettings.leaf_regions {
            eprintln!(
                "warning: no facet split the {} regions (every candidate left more than {:.0} % of them on a side): the lists are one leaf, and an evaluation tests the regions in turn; a smaller parameter box (kestrel mpc --x-max, --r-max) or fewer move blocks give fewer regions",
                st.max_leaf_regions,
                100.0 * lsettings.shrink
            );
        }
        locate::stage(show, 3, stages, "writing the solution");
        let text = locate::solution_lists_json(&sol, &lists, !a.no_regions);
        return write_solution(&a, &text, sol.regions.len());
    }
    let layout_limit = match a.layout {
        LayoutArg::U16 => kestrel_empc::tree::MAX_NODES,
        LayoutArg::Auto | LayoutArg::U32 => kestrel_empc::tree::WIDE_MAX_NODES,
    };
    if sol.regions.len() >= 1000 {
        eprintln!(
            "note: building the search tree of {} regions may take minutes (1,545 regions took 163 s of CPU); it stops at --max-nodes {}; Ctrl-C stops it, and --first-move keeps the tree smaller",
            sol.regions.len(),
            a.max_nodes
        );
    }
    let spinner = crate::progress::Spinner::new(&format!(
        "building the search tree of {} regions",
        sol.regions.len()
    ));
    let any = build_any(&problem, &sol, &tree).map_err(|e| match e {
        // The search stopped at the user's cap, not at the layout's.
        kestrel_empc::EmpcError::TooLarge(_) if a.max_nodes < layout_limit => anyhow::anyhow!(
            "{name}: --max-nodes {}: the search tree needs more nodes; raise --max-nodes, or keep only the first move with --first-move",
            a.max_nodes
        ),
        e => anyhow::Error::new(e).context(name.clone()),
    })?;
    drop(spinner);
    // Every tree method stops at --max-nodes (the sampled search while it
    // grows, the LP search here, once built).
    if any.stats.nodes > a.max_nodes {
        bail!(
            "{name}: --max-nodes {}: the search tree has {} nodes; raise --max-nodes, or keep only the first move with --first-move",
            a.max_nodes,
            any.stats.nodes
        );
    }
    eprintln!(
        "{} regions, {} distinct laws, solved in {:.4} s; tree depth {}, {} nodes, {} bytes (f32, {} indices)",
        sol.regions.len(),
        any.stats.distinct_laws,
        sol.stats.solve_seconds,
        any.stats.depth,
        any.stats.nodes,
        any.tables.bytes(4),
        if any.tables.is_wide() { "u32" } else { "u16" }
    );
    locate::stage(show, 3, stages, "writing the solution");
    let ctl = match any.tables {
        AnyTables::Narrow(tables) => ExplicitController {
            tables,
            region_law: any.region_law,
            stats: any.stats,
        },
        AnyTables::Wide(_) if a.compact => {
            bail!("{name}: --compact needs a tree in the u16 layout (this one is wide)")
        }
        AnyTables::Wide(_) => {
            let text = export::solution_json(&sol, &any, !a.no_regions);
            return write_solution(&a, &text, sol.regions.len());
        }
    };
    let text = if a.compact {
        let compact = build_compact(&problem, &sol, &tree).with_context(|| name.clone())?;
        eprintln!(
            "compact layout (one tree per output): depth {}, {} nodes, {} bytes (f32)",
            compact.depth,
            compact.tables.nodes.len(),
            compact.tables.bytes(4)
        );
        export::solution_json(
            &sol,
            SolutionTables::from(&ctl).with_compact(&compact),
            !a.no_regions,
        )
    } else {
        export::solution_json(&sol, &ctl, !a.no_regions)
    };
    write_solution(&a, &text, sol.regions.len())
}

/// Solution files from this size on get a note on their size.
const LARGE_SOLUTION_BYTES: usize = 100 << 20;

/// Writes a solution with its evaluation tables; a large file with its
/// region list gets a note saying so and how to leave the list out.
fn write_solution(a: &SolveArgs, text: &str, regions: usize) -> anyhow::Result<()> {
    if text.len() >= LARGE_SOLUTION_BYTES && !a.no_regions {
        eprintln!(
            "note: the solution file is {}, most of it the {regions} regions' rows (region_list); `eval` and `export` need only the tables, and --no-regions leaves the list out",
            kestrel_mpc::human_bytes(text.len() as f64)
        );
    }
    io::write_output(a.out.as_deref(), text)
}

fn read_text(path: &std::path::Path) -> anyhow::Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))
}

/// The tables of a solution file's `text` (read from `path`) in the
/// format `T` ([`export::ExportTables`]).
fn read_tables<T: export::ExportTables>(text: &str, path: &std::path::Path) -> anyhow::Result<T> {
    export::read_tables(text).with_context(|| path.display().to_string())
}

fn run_eval(a: EvalArgs) -> anyhow::Result<()> {
    a.replace.check(&[a.out.as_deref()])?;
    let text = read_text(&a.solution)?;
    let stored = locate::stored(&text).with_context(|| a.solution.display().to_string())?;
    match stored {
        Stored::Lists(_) if a.compact => bail!(
            "{}: --compact: the solution holds candidate lists (`lists`), not the compact tree; leave out --compact",
            a.solution.display()
        ),
        Stored::Lists(tables) => eval_lists(&a, &tables),
        Stored::Tree if a.compact => {
            let tables: kestrel_empc::CompactTables<f64> = read_tables(&text, &a.solution)?;
            eval_with(&a, &tables.tables())
        }
        Stored::Tree => match read_tables::<AnyTables>(&text, &a.solution)? {
            AnyTables::Narrow(t) => eval_with(&a, &t.tables()),
            AnyTables::Wide(t) => eval_with(&a, &t.tables()),
        },
    }
}

/// `eval` of candidate lists (the same CSV as the tree's).
fn eval_lists(a: &EvalArgs, t: &kestrel_empc::locate::ListTables<f64>) -> anyhow::Result<()> {
    let slices = t.tables();
    eval_rows(a, slices.n_params, slices.n_outputs, |theta, scratch, z| {
        evaluate_lists(&slices, theta, scratch, z).map(|e| e.outside)
    })
}

/// Evaluates every row of `--thetas` (`p` numbers each) with `eval`
/// (the outputs into its last argument; whether the row lies outside the
/// explored set), writes one CSV row of outputs per row; an error names
/// the row's line.
fn eval_rows<E: std::fmt::Display>(
    a: &EvalArgs,
    p: usize,
    n_outputs: usize,
    mut eval: impl FnMut(&[f64], &mut [f64], &mut [f64]) -> Result<bool, E>,
) -> anyhow::Result<()> {
    let thetas = read_parameter_rows(&a.thetas, p, n_outputs)?;
    let mut out = String::new();
    let mut scratch = vec![0.0; p];
    let mut z = vec![0.0; n_outputs];
    let mut outside = 0usize;
    for (theta, line) in thetas.rows.iter().zip(&thetas.lines) {
        let e = eval(theta, &mut scratch, &mut z)
            .map_err(|e| anyhow::anyhow!("{}: line {line}: {e}", a.thetas.display()))?;
        outside += usize::from(e);
        let row: Vec<String> = z.iter().map(|v| format!("{v:?}")).collect();
        let _ = writeln!(out, "{}", row.join(","));
    }
    warn_outside(outside, thetas.rows.len());
    io::write_output(a.out.as_deref(), &out)
}

fn warn_outside(outside: usize, total: usize) {
    if outside > 0 {
        eprintln!(
            "warning: {outside} of {total} parameters lie outside the explored set; their rows are the nearest region's law clamped to the bounds"
        );
    }
}

fn eval_with<I: TreeIndex, T: TreeTables<f64, I>>(a: &EvalArgs, t: &T) -> anyhow::Result<()> {
    eval_rows(a, t.n_params(), t.n_outputs(), |theta, scratch, z| {
        evaluate_with(t, theta, scratch, z).map(|e| e.outside)
    })
}

fn run_export(a: ExportArgs) -> anyhow::Result<()> {
    a.replace.check(&[a.out.as_deref()])?;
    let scalar = ExportScalar::from(a.scalar);
    let text = read_text(&a.solution)?;
    if let Stored::Lists(lists) =
        locate::stored(&text).with_context(|| a.solution.display().to_string())?
    {
        if a.compact {
            bail!(
                "{}: --compact: the solution holds candidate lists (`lists`), not the compact tree; leave out --compact",
                a.solution.display()
            );
        }
        let Some(narrow) = lists.narrow() else {
            bail!(
                "{}: the candidate lists need u32 indices; Rust source is written for lists whose indices fit u16",
                a.solution.display()
            );
        };
        let src = narrow
            .rust_source(scalar)
            .with_context(|| a.solution.display().to_string())?;
        return io::write_output(a.out.as_deref(), &src);
    }
    let src = if a.compact {
        export::rust_source(
            &read_tables::<kestrel_empc::CompactTables<f64>>(&text, &a.solution)?,
            scalar,
        )
    } else {
        export::rust_source(&read_tables::<AnyTables>(&text, &a.solution)?, scalar)
    }
    .with_context(|| a.solution.display().to_string())?;
    io::write_output(a.out.as_deref(), &src)
}
