//! Builds the search tree of an explicit MPC's first move and evaluates it:
//! `cargo run -p kestrel-empc --example search_tree`.
//!
//! The problem is the crate's thesis-sized test problem
//! ([`kestrel_empc::testing::thesis_sized`]: 9 parameters, 4 inputs);
//! only the first move is kept ([`kestrel_empc::Outputs::First`]), and the
//! tree's answers are compared with the solution's own region lookup.
use kestrel_empc::{Outputs, Settings, TreeSettings, build_controller, evaluate_with, solve};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let problem = kestrel_empc::testing::thesis_sized(1);
    let solution = solve(&problem, &Settings::default())?;
    let settings = TreeSettings {
        outputs: Outputs::First(4),
        ..TreeSettings::default()
    };
    let controller = build_controller(&problem, &solution, &settings)?;
    let s = &controller.stats;
    println!(
        "{} regions, {} distinct first-move laws, tree depth {}, {} nodes, {} bytes in f32",
        s.regions,
        s.distinct_laws,
        s.depth,
        s.nodes,
        controller.tables.bytes(4)
    );
    // Evaluate at the centre of every region: the tree gives the region's law.
    let tables = controller.tables.tables();
    let (mut z, mut scratch) = ([0.0; 4], [0.0; 9]);
    let mut worst: f64 = 0.0;
    for r in &solution.regions {
        let theta = r.center.as_slice();
        let e = evaluate_with(&tables, theta, &mut scratch, &mut z)?;
        assert!(!e.outside);
        let want = solution.first_outputs_at(theta, 4).ok_or("not covered")?;
        for (a, b) in want.iter().zip(&z) {
            worst = worst.max((a - b).abs());
        }
    }
    println!("largest difference to the region lookup at the region centres: {worst:.1e}");
    Ok(())
}
