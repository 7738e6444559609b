//! Scratch: tree size vs settings on the thesis-sized problem.
use kestrel_empc::{Settings, TreeSettings, build_controller, solve, testing};
fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let p = testing::thesis_sized(1);
    let sol = solve(&p, &Settings::default()).unwrap();
    let t = TreeSettings {
        exact_budget: args[0],
        max_candidates: args[1],
        ..Default::default()
    };
    let c = build_controller(&p, &sol, &t).unwrap();
    println!("{:?} bytes {}", c.stats, c.tables.bytes(4));
}
