//! Scratch: find tree/region mismatches on a problem file.
use kestrel_empc::mpqp::Rng;
use kestrel_empc::{Settings, TreeSettings, build_controller, evaluate_with, solve};
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let prob = kestrel_core::formats::MpqpProblem::read(std::path::Path::new(&path)).unwrap();
    let sol = solve(&prob, &Settings::default()).unwrap();
    let ctl = build_controller(&prob, &sol, &TreeSettings::default()).unwrap();
    println!("{:?}", ctl.stats);
    let t = ctl.tables.tables();
    let p = prob.p();
    let mut rng = Rng::new(11);
    let mut bad = 0;
    for r in 0..sol.regions.len() {
        let c: Vec<f64> = sol.regions[r].center.iter().copied().collect();
        let mut z = vec![0.0; prob.n()];
        let mut s = vec![0.0; p];
        let e = evaluate_with(&t, &c, &mut s, &mut z).unwrap();
        if e.law != ctl.region_law[r] {
            bad += 1;
            if bad < 5 {
                println!(
                    "region {r} center -> law {} want {} radius {}",
                    e.law, ctl.region_law[r], sol.regions[r].radius
                );
            }
        }
    }
    println!("centers misplaced: {bad}");
    let mut shown = 0;
    for _ in 0..1000 {
        let th: Vec<f64> = (0..p)
            .map(|j| {
                let (lo, hi) = (prob.theta_lb[j], prob.theta_ub[j]);
                lo + (hi - lo) * 0.5 * (rng.sym() + 1.0)
            })
            .collect();
        let ri = sol.locate(&th, 1e-7).unwrap();
        let zr = sol.regions[ri].z(&th);
        let mut z = vec![0.0; prob.n()];
        let mut s = vec![0.0; p];
        let e = evaluate_with(&t, &th, &mut s, &mut z).unwrap();
        let d = (0..prob.n())
            .map(|j| (z[j] - zr[j]).abs())
            .fold(0.0, f64::max);
        if d > 1e-6 && shown < 5 {
            shown += 1;
            let l = ctl.region_law[ri];
            // evaluate the tree's law at th without clamp
            let raw: Vec<f64> = (0..prob.n())
                .map(|o| {
                    let r = ctl.tables.laws[e.law as usize * prob.n() + o] as usize;
                    (0..p)
                        .map(|j| ctl.tables.rows[r * (p + 1) + j] * th[j])
                        .sum::<f64>()
                        + ctl.tables.rows[r * (p + 1) + p]
                })
                .collect();
            let reg = &sol.regions[ri];
            let slack = (0..reg.a.nrows())
                .map(|i| reg.b[i] - (0..p).map(|j| reg.a[(i, j)] * th[j]).sum::<f64>())
                .fold(f64::INFINITY, f64::min);
            let others: Vec<usize> = (0..sol.regions.len())
                .filter(|&k| sol.regions[k].contains(&th, 1e-6))
                .collect();
            println!(
                "min slack {slack:e}, regions containing (1e-6): {others:?}, laws {:?}",
                others
                    .iter()
                    .map(|&k| ctl.region_law[k])
                    .collect::<Vec<_>>()
            );
            println!(
                "diff {d:.3e} tree law {} region law {l} (region {ri}) z {:?} zr {:?} raw {:?} outside {}",
                e.law,
                z,
                zr.as_slice(),
                raw,
                e.outside
            );
        }
    }
}
