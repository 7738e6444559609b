//! Solves a `kestrel.mpqp.v1` problem file and builds the first-move trees,
//! printing regions, laws, depth, bytes and times:
//! `cargo run --release -p kestrel-empc --example solve_file -- problem.json
//! [first_move] [compact|default|both] [solution.json]` (the last writes the
//! solution file of `kestrel empc solve --compact --no-regions`).
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::export::SolutionTables;
use kestrel_empc::{Outputs, Settings, TreeSettings, build_compact, build_controller, solve};

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("a problem file");
    let first: Option<usize> = args.next().and_then(|v| v.parse().ok());
    // "compact": only the compact layout; "default": only the default one.
    let only = args.next().unwrap_or_default();
    let out = args.next();
    let prob = MpqpProblem::read(std::path::Path::new(&path)).expect("problem");
    let t0 = std::time::Instant::now();
    let sol = solve(&prob, &Settings::default()).expect("solve");
    println!(
        "p {} n {}: {} regions, {} LPs, {} fallback QPs, solve {:.3} s",
        prob.p(),
        prob.n(),
        sol.regions.len(),
        sol.stats.lps,
        sol.stats.fallback_qps,
        t0.elapsed().as_secs_f64()
    );
    let tree = TreeSettings {
        outputs: first.map_or(Outputs::All, Outputs::First),
        ..TreeSettings::default()
    };
    let t1 = std::time::Instant::now();
    let mut default = None;
    if only != "compact" {
        let ctl = build_controller(&prob, &sol, &tree).expect("tree");
        println!(
            "default tree: {} laws, depth {}, {} nodes, {} bytes (f32), ambiguous {}, {:.3} s",
            ctl.stats.distinct_laws,
            ctl.stats.depth,
            ctl.stats.nodes,
            ctl.tables.bytes(4),
            ctl.stats.ambiguous_leaves,
            t1.elapsed().as_secs_f64()
        );
        default = Some(ctl);
    }
    if only == "default" {
        return;
    }
    let t2 = std::time::Instant::now();
    let c = build_compact(&prob, &sol, &tree).expect("compact");
    println!(
        "compact: depth {}, {} nodes, {} bytes (f32), ambiguous {}, {:.3} s",
        c.depth,
        c.tables.nodes.len(),
        c.tables.bytes(4),
        c.ambiguous_leaves,
        t2.elapsed().as_secs_f64()
    );
    if let (Some(path), Some(ctl)) = (out, default) {
        let text = kestrel_empc::export::solution_json(
            &sol,
            SolutionTables::from(&ctl).with_compact(&c),
            false,
        );
        std::fs::write(&path, text).expect("writing the solution");
        println!("wrote {path}");
    }
}
