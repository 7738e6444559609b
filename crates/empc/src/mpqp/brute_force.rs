//! The brute-force reference of the explorer ([`brute_force_active_sets`]).

use crate::error::EmpcError;
use crate::lp::{LpStatus, LpWorkspace, slack_start};
use crate::mpqp::prepare::{Prepared, prepare};
use crate::mpqp::settings::Settings;
use crate::qp;
use kestrel_core::formats::MpqpProblem;

/// All full-dimensional critical regions by brute force: every linearly
/// independent subset of the (deduplicated) constraints, pruned only by
/// infeasibility. Exponential: for testing the explorer on small problems.
/// Returns the sorted active sets (original row indices).
pub fn brute_force_active_sets(
    problem: &MpqpProblem,
    settings: &Settings,
) -> Result<Vec<Vec<usize>>, EmpcError> {
    let prep = prepare(problem, settings)?;
    let mut lp = LpWorkspace::default();
    let mut found = Vec::new();
    let mut stack: Vec<Vec<usize>> = vec![Vec::new()];
    while let Some(set) = stack.pop() {
        if prep.region(&set, &mut lp).is_some() {
            found.push(set.iter().map(|&i| prep.kept[i]).collect::<Vec<_>>());
        }
        if set.len() == prep.n {
            continue;
        }
        let next = set.last().map_or(0, |&l| l + 1);
        for i in next..prep.m {
            if !qp::independent(&prep.g, &set, i) {
                continue;
            }
            let mut s = set.clone();
            s.push(i);
            if feasible_set(&prep, &s, &mut lp) {
                stack.push(s);
            }
        }
    }
    for s in &mut found {
        s.sort_unstable();
    }
    found.sort();
    Ok(found)
}

/// Whether some (z, theta) satisfies all constraints with those of `set` active.
fn feasible_set(prep: &Prepared, set: &[usize], lp: &mut LpWorkspace) -> bool {
    let (n, p, m) = (prep.n, prep.p, prep.m);
    // Variables (z, theta, r): maximise the smallest slack r <= 0.
    let d = n + p + 1;
    let mut a = Vec::new();
    let mut b = Vec::new();
    let tol = 1e-9 * prep.scale;
    for i in 0..m {
        a.extend(prep.g.row(i).iter());
        a.extend(prep.e.row(i).iter().map(|v| -v));
        a.push(1.0);
        b.push(prep.w[i] + tol);
        if set.contains(&i) {
            a.extend(prep.g.row(i).iter().map(|v| -v));
            a.extend(prep.e.row(i).iter());
            a.push(1.0);
            b.push(-prep.w[i] + tol);
        }
    }
    for i in 0..prep.param_b.len() {
        a.extend(std::iter::repeat_n(0.0, n));
        a.extend(prep.param_a.row(i).iter());
        a.push(1.0);
        b.push(prep.param_b[i]);
    }
    a.extend(std::iter::repeat_n(0.0, n + p));
    a.push(1.0);
    b.push(0.0);
    let mut c = vec![0.0; d];
    c[d - 1] = 1.0;
    let mut x0: Vec<f64> = std::iter::repeat_n(0.0, n)
        .chain((0..p).map(|j| 0.5 * (prep.theta_lb[j] + prep.theta_ub[j])))
        .chain([0.0])
        .collect();
    slack_start(&a, &b, &mut x0, d - 1);
    let (st, r) = lp.maximize_from(&c, &a, &b, &x0);
    st == LpStatus::Optimal && r >= -1e-12 * prep.scale
}
