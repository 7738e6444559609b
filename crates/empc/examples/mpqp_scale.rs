//! Solves a `kestrel.mpqp.v1` problem file (the mpQP alone, no point
//! location) and prints the solver's counters and the time per region:
//!
//! ```text
//! cargo run --release -p kestrel-empc --features parallel --example mpqp_scale -- \
//!     PROBLEM.json [parallel|sequential] [MAX_REGIONS]
//! ```
//!
//! The measurement behind docs/empc.md's "mpQP at scale" and
//! `scripts/empc-scale.sh`.
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::{Settings, solve};

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().expect("a problem file");
    let parallel = args.next().is_none_or(|m| m != "sequential");
    let max_regions = args
        .next()
        .and_then(|v| v.parse().ok())
        .unwrap_or(Settings::default().max_regions);
    let prob = MpqpProblem::read(std::path::Path::new(&path)).expect("problem");
    let settings = Settings {
        parallel,
        max_regions,
        ..Settings::default()
    };
    let sol = solve(&prob, &settings).expect("solve");
    // A hash of every region's data (active set, half-spaces, law, ball) in
    // order: equal hashes mean a bit-identical solution.
    let mut h = 0xCBF2_9CE4_8422_2325u64;
    let mut eat = |v: u64| h = (h ^ v).wrapping_mul(0x0100_0000_01B3);
    for r in &sol.regions {
        r.active_set.iter().for_each(|&i| eat(i as u64));
        for m in [&r.a, &r.fz] {
            m.iter().for_each(|v| eat(v.to_bits()));
        }
        for v in [&r.b, &r.gz, &r.center] {
            v.iter().for_each(|v| eat(v.to_bits()));
        }
        eat(r.radius.to_bits());
    }
    let s = &sol.stats;
    println!(
        "{path}: n {} m {} p {}: {} regions in {:.3} s ({:.3} ms per region); {} active sets tested, {} discarded, {} fallback QPs, {} LPs ({:.1} per region), {} duplicate rows; regions hash {h:016x}",
        prob.n(),
        prob.m(),
        prob.p(),
        sol.regions.len(),
        s.solve_seconds,
        1e3 * s.solve_seconds / sol.regions.len().max(1) as f64,
        s.active_sets_tested,
        s.discarded,
        s.fallback_qps,
        s.lps,
        s.lps as f64 / sol.regions.len().max(1) as f64,
        s.duplicate_rows,
    );
}
