//! Solves a multi-parametric QP and prints its critical regions:
//! `cargo run -p kestrel-empc --example solve_mpqp`.
//!
//! The problem: `min 1/2 |z|^2 + theta'z` subject to `|z_i| <= 1` over
//! `theta` in `[-3, 3]^2`, whose optimiser is `z = clamp(-theta)`: nine
//! regions, one per combination of the two inputs being free, at the upper
//! or at the lower bound.
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::{Settings, solve};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let problem = MpqpProblem::from_json_str(
        r#"{"format": "kestrel.mpqp.v1",
            "H": [[1, 0], [0, 1]], "F": [[1, 0], [0, 1]],
            "G": [[1, 0], [0, 1], [-1, 0], [0, -1]], "W": [1, 1, 1, 1],
            "E": [[0, 0], [0, 0], [0, 0], [0, 0]],
            "theta_lb": [-3, -3], "theta_ub": [3, 3]}"#,
    )?;
    let solution = solve(&problem, &Settings::default())?;
    println!(
        "{} regions ({} LPs, {:.1} ms)",
        solution.regions.len(),
        solution.stats.lps,
        1e3 * solution.stats.solve_seconds
    );
    for r in &solution.regions {
        let fz: Vec<Vec<f64>> =
            r.fz.row_iter()
                .map(|row| row.iter().copied().collect())
                .collect();
        println!(
            "active set {:?}: {} facets, z = Fz theta + gz with Fz = {fz:?}, gz = {:?}",
            r.active_set,
            r.a.nrows(),
            r.gz.as_slice()
        );
    }
    // The solution's own answer at a parameter (the reference a tree is checked against).
    let theta = [0.5, -2.0];
    let z = solution
        .first_outputs_at(&theta, 2)
        .ok_or("theta is not covered")?;
    println!("z({theta:?}) = {z:?}");
    Ok(())
}
