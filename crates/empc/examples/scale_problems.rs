//! The random problems of the explicit-MPC-at-scale measurements
//! (BENCHMARKS.md "Explicit MPC at scale", `scripts/empc-scale.sh`):
//! `kestrel_empc::testing`'s thesis-sized system (5 states, 4 inputs, 3
//! tracked outputs, a throttle on inputs 0..3: 9 parameters) with a longer
//! horizon and more free moves.
//!
//! ```text
//! cargo run --release -p kestrel-empc --features parallel --example scale_problems -- \
//!     write SEED N NS OUT.mpqp.json     # write the problem (then solve it: regions)
//! cargo run --release -p kestrel-empc --features parallel --example scale_problems -- \
//!     scan N NS FIRST LAST [MAX_REGIONS]   # regions for each seed in FIRST..=LAST
//! ```
//!
//! `N` is the horizon and `NS` the free moves (blocks `[1, .., 1, N - NS + 1]`,
//! `testing::MpcSpec::condense`); the problems of the issue are seed 11 with
//! N = 5, NS = 2 (1,075 regions) and so on, as listed in BENCHMARKS.md.
use kestrel_empc::testing::scaled_thesis;
use kestrel_empc::{EmpcError, Settings, solve};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let num = |i: usize| -> u64 {
        args.get(i)
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("argument {} must be a number", i + 1))
    };
    match args.first().map(String::as_str) {
        Some("write") => {
            let prob = scaled_thesis(num(1), num(2) as usize, num(3) as usize);
            let out = args.get(4).expect("an output file");
            std::fs::write(out, prob.to_json_string()).expect("writing the problem");
            let t = std::time::Instant::now();
            let sol = solve(&prob, &Settings::default()).expect("solve");
            println!(
                "{out}: n {} m {} p {}: {} regions in {:.3} s",
                prob.n(),
                prob.m(),
                prob.p(),
                sol.regions.len(),
                t.elapsed().as_secs_f64()
            );
        }
        Some("scan") => {
            let (n, ns) = (num(1) as usize, num(2) as usize);
            let max = args.get(5).and_then(|v| v.parse().ok()).unwrap_or(20_000);
            for seed in num(3)..=num(4) {
                let prob = scaled_thesis(seed, n, ns);
                let settings = Settings {
                    max_regions: max,
                    ..Settings::default()
                };
                let t = std::time::Instant::now();
                match solve(&prob, &settings) {
                    Ok(sol) => println!(
                        "seed {seed}: {} regions, {:.3} s",
                        sol.regions.len(),
                        t.elapsed().as_secs_f64()
                    ),
                    Err(EmpcError::TooManyRegions(k)) => println!("seed {seed}: more than {k}"),
                    Err(e) => println!("seed {seed}: {e}"),
                }
            }
        }
        _ => eprintln!("usage: scale_problems write SEED N NS OUT | scan N NS FIRST LAST [MAX]"),
    }
}
