//! `kestrel empc solve` beyond the exact search tree: the solution alone
//! (`--no-tree`), the candidate lists (`--locate lists`, or `auto` above
//! kestrel-empc's size limit of the tree), the stages on a terminal, and
//! reading either kind of solution file back for `eval`.

use kestrel_core::formats::json::{self, matrix_to_value, vector_to_value};
use kestrel_empc::MpqpSolution;
use kestrel_empc::locate::{Estimate, ListController, ListTables, LocateMethod, Progress, Stage};
use serde_json::{Map, Value, json};

/// Key of the candidate-list tables in a solution file.
pub const LISTS_KEY: &str = "lists";

/// A stage line on standard error when `show` (a terminal, or --progress).
pub fn stage(show: bool, k: usize, of: usize, what: &str) {
    if show {
        crate::progress::clear();
        eprintln!("[{k}/{of}] {what}");
    }
}

/// The estimate, said before building.
pub fn describe(e: &Estimate) -> String {
    format!(
        "point location for {} regions ({} distinct laws): {}, estimated {} nodes, {} bytes (f32), about {:.1} s to build",
        e.regions,
        e.distinct_laws,
        method_name(e.method),
        e.nodes,
        e.bytes_f32,
        e.seconds
    )
}

/// The method's name as `--locate` spells it.
pub fn method_name(m: LocateMethod) -> &'static str {
    match m {
        LocateMethod::Auto => "auto",
        LocateMethod::Tree => "tree",
        LocateMethod::Lists => "lists",
    }
}

/// A progress display for the point-location build: a spinner with the
/// stage on a terminal (or with --progress), nothing otherwise.
pub struct LocateProgress(indicatif::ProgressBar);

impl LocateProgress {
    /// Starts the display.
    pub fn new(show: bool) -> Self {
        let bar = if show {
            let pb = indicatif::ProgressBar::new_spinner();
            pb.set_style(
                indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
            );
            pb.enable_steady_tick(std::time::Duration::from_millis(200));
            pb
        } else {
            indicatif::ProgressBar::hidden()
        };
        crate::progress::show(&bar);
        LocateProgress(bar)
    }

    /// Shows a report of the build.
    pub fn report(&self, p: Progress) {
        let msg = match p.stage {
            Stage::Laws => "sharing the laws".to_string(),
            Stage::Hyperplanes => format!("facet hyperplanes: {} of {} regions", p.done, p.total),
            Stage::Tree => format!(
                "tree: {:.1} % of the parameter space placed",
                100.0 * p.done as f64 / p.total.max(1) as f64
            ),
            Stage::Tables => "writing the tables".to_string(),
        };
        self.0.set_message(msg);
    }
}

impl Drop for LocateProgress {
    fn drop(&mut self) {
        self.0.finish_and_clear();
    }
}

/// The `kestrel.empc.v1` keys every solution file has: `format`,
/// `regions`, `solve_seconds`, `n`, `p`, the solver's `stats`, and the
/// optional `region_list` (as `kestrel_empc::export::solution_json`
/// writes them).
fn common(solution: &MpqpSolution, include_regions: bool) -> Map<String, Value> {
    let mut o = Map::new();
    o.insert("format".into(), "kestrel.empc.v1".into());
    o.insert("regions".into(), solution.regions.len().into());
    o.insert("solve_seconds".into(), json!(solution.stats.solve_seconds));
    o.insert("n".into(), solution.n.into());
    o.insert("p".into(), solution.p.into());
    let s = &solution.stats;
    o.insert(
        "stats".into(),
        json!({"active_sets_tested": s.active_sets_tested, "discarded": s.discarded,
               "fallback_qps": s.fallback_qps, "lps": s.lps, "duplicate_rows": s.duplicate_rows}),
    );
    if include_regions {
        let list: Vec<Value> = solution
            .regions
            .iter()
            .map(|r| {
                json!({"active_set": r.active_set, "A": matrix_to_value(&r.a),
                       "b": vector_to_value(&r.b), "Fz": matrix_to_value(&r.fz),
                       "gz": vector_to_value(&r.gz)})
            })
            .collect();
        o.insert("region_list".into(), Value::Array(list));
    }
    o
}

/// The solution file without point location (`--no-tree`).
pub fn solution_only_json(solution: &MpqpSolution, include_regions: bool) -> String {
    json::to_pretty_string(&common(solution, include_regions))
}

/// The solution file with the candidate lists: the common keys, `outputs`,
/// `distinct_laws`, `locate` (the lists' statistics) and `lists` (the
/// tables, `kestrel_empc::locate::ListTables::to_json`).
pub fn solution_lists_json(
    solution: &MpqpSolution,
    lists: &ListController,
    include_regions: bool,
) -> String {
    let mut o = common(solution, include_regions);
    let s = &lists.stats;
    o.insert("outputs".into(), lists.tables.n_outputs.into());
    o.insert("distinct_laws".into(), s.distinct_laws.into());
    o.insert(
        "locate".into(),
        json!({"method": "lists", "depth": s.depth, "nodes": s.nodes, "leaves": s.leaves,
               "entries": s.entries, "max_leaf_regions": s.max_leaf_regions,
               "hyperplanes": s.hyperplanes, "distinct_rows": s.distinct_rows,
               "bytes": s.bytes_f32, "bytes_f64": s.bytes_f64, "fits_u16": s.fits_u16,
               "worst_case_mul_adds": s.worst_case.mul_adds,
               "worst_case_comparisons": s.worst_case.comparisons,
               "worst_case_hyperplanes": s.worst_case_hyperplanes,
               "build_seconds": s.build_seconds}),
    );
    o.insert(LISTS_KEY.into(), lists.tables.to_json());
    json::to_pretty_string(&o)
}

/// The point location a solution file holds.
pub enum Stored {
    /// The search tree's `tables` (read by `kestrel_empc::export::read_tables`).
    Tree,
    /// Candidate lists.
    Lists(Box<ListTables<f64>>),
}

/// What point location the solution text holds; an error saying so when
/// it has none (written with `--no-tree`). Text that is not a
/// `kestrel.empc.v1` object counts as a tree: the tree's reader names
/// what is wrong with it.
pub fn stored(text: &str) -> anyhow::Result<Stored> {
    // The region list, most of a large file, is skipped unbuilt.
    let Ok(v) = json::parse_object_keys(text, &["format", "tables", LISTS_KEY]) else {
        return Ok(Stored::Tree);
    };
    if v.get("format").and_then(Value::as_str) != Some("kestrel.empc.v1")
        || v.get("tables").is_some()
    {
        return Ok(Stored::Tree);
    }
    match v.get(LISTS_KEY) {
        Some(l) => Ok(Stored::Lists(Box::new(ListTables::from_json(l)?))),
        None => anyhow::bail!(
            "the solution has no point location (neither `tables` nor `lists`; written by `kestrel empc solve --no-tree`): solve the problem again without --no-tree"
        ),
    }
}
