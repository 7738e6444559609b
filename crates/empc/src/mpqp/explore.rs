//! The facet-to-facet exploration ([`solve`]): waves of neighbour active
//! sets and probe points, on several threads with the `parallel` feature.
#![allow(clippy::needless_range_loop)] // dense numerical kernels read best with indices

use crate::error::EmpcError;
use crate::lp::{LpStatus, LpWorkspace, slack_start};
use crate::mpqp::prepare::{Prepared, prepare};
use crate::mpqp::region::{Origin, RegionData, seed_of};
use crate::mpqp::settings::Settings;
use crate::mpqp::solution::{CriticalRegion, MpqpSolution, SolveStats};
use crate::mpqp::wave::{Event, Witness, Work, run_wave};
use crate::rng::Rng;
use kestrel_core::formats::MpqpProblem;
use nalgebra::{DMatrix, DVector};
use std::collections::HashMap;

/// Solves the mpQP: all full-dimensional critical regions over the parameter set.
///
/// ```
/// use kestrel_core::formats::MpqpProblem;
/// use kestrel_empc::{solve, Settings};
/// // min 1/2 z^2 + theta z  s.t. -1 <= z <= 1,  theta in [-2, 2]: z = clamp(-theta).
/// let p = MpqpProblem::from_json_str(r#"{"format": "kestrel.mpqp.v1",
///   "H": [[1]], "F": [[1]], "G": [[1], [-1]], "W": [1, 1], "E": [[0], [0]],
///   "theta_lb": [-2], "theta_ub": [2]}"#).unwrap();
/// let sol = solve(&p, &Settings::default()).unwrap();
/// assert_eq!(sol.regions.len(), 3);
/// let r = sol.locate(&[0.5], 1e-9).unwrap();
/// assert!((sol.regions[r].z(&[0.5])[0] + 0.5).abs() < 1e-12);
/// ```
pub fn solve(problem: &MpqpProblem, settings: &Settings) -> Result<MpqpSolution, EmpcError> {
    let start = std::time::Instant::now();
    let prep = prepare(problem, settings)?;
    let mut lp = LpWorkspace::default();
    let mut stats = SolveStats {
        duplicate_rows: prep.duplicates,
        ..Default::default()
    };
    // An interior feasible parameter: maximise the smallest slack over (z, theta).
    let (theta0, r0) = interior_parameter(&prep, &mut lp)?;
    stats.lps += 1;
    let mut regions: Vec<RegionData> = Vec::new();
    let mut status: HashMap<Vec<usize>, Option<usize>> = HashMap::new();
    let mut hull: Vec<(Vec<f64>, f64)> = Vec::new();
    // Initial regions: at theta0, perturbed if it sits on a boundary.
    let mut rng = Rng::new(1);
    let mut initial = Vec::new();
    for attempt in 0..20 {
        let th: Vec<f64> = if attempt == 0 {
            theta0.clone()
        } else {
            theta0
                .iter()
                .map(|v| v + 0.5 * r0 * rng.sym() / (prep.p as f64).sqrt())
                .collect()
        };
        stats.fallback_qps += 1;
        if let Some(rs) = prep.regions_at(&th, settings.max_degenerate_set, &mut lp)?
            && !rs.is_empty()
        {
            initial = rs;
            break;
        }
    }
    if initial.is_empty() {
        return Err(EmpcError::Numerical(
            "no full-dimensional region found around an interior feasible parameter".into(),
        ));
    }
    #[cfg(feature = "progress")]
    let bar = settings.progress.then(|| {
        let b = indicatif::ProgressBar::new_spinner();
        b.set_style(
            indicatif::ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        b.enable_steady_tick(std::time::Duration::from_millis(200));
        b.set_message("exploring critical regions");
        b
    });
    let mut fresh: Vec<usize> = Vec::new();
    let add_region = |r: RegionData,
                      regions: &mut Vec<RegionData>,
                      status: &mut HashMap<Vec<usize>, Option<usize>>,
                      fresh: &mut Vec<usize>| {
        if let Some(Some(_)) = status.get(&r.active) {
            return;
        }
        status.insert(r.active.clone(), Some(regions.len()));
        fresh.push(regions.len());
        regions.push(r);
    };
    for r in initial {
        stats.active_sets_tested += 1;
        stats.lps += r.lps;
        add_region(r, &mut regions, &mut status, &mut fresh);
    }
    let step = settings.step * prep.scale;
    let tol_in = 1e-9 * prep.scale;
    let p = prep.p;
    while !fresh.is_empty() {
        if regions.len() > settings.max_regions {
            return Err(EmpcError::TooManyRegions(settings.max_regions));
        }
        // Generate the next wave from the facets of the fresh regions.
        let mut pending: Vec<(Vec<usize>, Vec<Witness>)> = Vec::new();
        let mut pending_idx: HashMap<Vec<usize>, usize> = HashMap::new();
        let mut probes: Vec<Witness> = Vec::new();
        for &ri in &fresh {
            let r = &regions[ri];
            let mut rng = Rng::new(seed_of(&r.active));
            for fct in &r.facets {
                let orig = &r.origins[fct.hs];
                let a = &r.hs_a[fct.hs * p..(fct.hs + 1) * p];
                let b = r.hs_b[fct.hs];
                if orig.contains(&Origin::Param) {
                    continue; // boundary of the parameter set
                }
                // A point inside the facet, randomly moved within it, then stepped out.
                let mut v: Vec<f64> = (0..p).map(|_| rng.sym()).collect();
                let av: f64 = a.iter().zip(&v).map(|(x, y)| x * y).sum();
                for j in 0..p {
                    v[j] -= av * a[j];
                }
                let vn = v.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300);
                let len = 0.5 * fct.radius * rng.sym().abs();
                let theta: Vec<f64> = (0..p)
                    .map(|j| fct.point[j] + len * v[j] / vn + step * a[j])
                    .collect();
                let wit = Witness {
                    theta,
                    facet_a: a.to_vec(),
                    facet_b: b,
                };
                if orig.len() != 1 {
                    probes.push(wit);
                    continue;
                }
                let cand = match orig[0] {
                    Origin::Primal(i) => {
                        let mut c = r.active.clone();
                        let pos = c.binary_search(&i).unwrap_or_else(|e| e);
                        c.insert(pos, i);
                        c
                    }
                    Origin::Dual(j) => r.active.iter().copied().filter(|&x| x != j).collect(),
                    Origin::Param => unreachable!(),
                };
                match status.get(&cand) {
                    Some(Some(j)) => {
                        if !regions[*j].contains(&wit.theta, tol_in) {
                            probes.push(wit);
                        }
                    }
                    Some(None) => probes.push(wit),
                    None => match pending_idx.get(&cand) {
                        Some(&k) => pending[k].1.push(wit),
                        None => {
                            pending_idx.insert(cand.clone(), pending.len());
                            pending.push((cand, vec![wit]));
                        }
                    },
                }
            }
        }
        fresh.clear();
        let mut items: Vec<Work> = pending.into_iter().map(|(c, w)| Work::Set(c, w)).collect();
        items.extend(probes.into_iter().map(Work::Probe));
        let wave = run_wave(&prep, &items, settings, &status, &mut lp)?;
        stats.active_sets_tested += wave.tested;
        stats.discarded += wave.discarded;
        stats.fallback_qps += wave.fallbacks;
        stats.lps += wave.lps;
        for event in wave.events {
            match event {
                Event::Region(r) => add_region(r, &mut regions, &mut status, &mut fresh),
                Event::NoRegion(s) => {
                    status.entry(s).or_insert(None);
                }
                Event::Hull(a, b) => hull.push((a, b)),
            }
        }
        #[cfg(feature = "progress")]
        if let Some(b) = &bar {
            b.set_message(format!(
                "exploring critical regions: {} (stops at {})",
                regions.len(),
                settings.max_regions
            ));
        }
    }
    #[cfg(feature = "progress")]
    if let Some(b) = bar {
        b.finish_with_message(format!("{} critical regions", regions.len()));
    }
    // The explored set: the box (stored apart), extra parameter rows and the
    // facets beyond which the QP is infeasible. Box rows come first in param_a.
    let mut hrows: Vec<(Vec<f64>, f64)> = (2 * p..prep.param_b.len())
        .map(|i| {
            (
                prep.param_a.row(i).iter().copied().collect(),
                prep.param_b[i],
            )
        })
        .collect();
    for (a, b) in hull {
        let dup = hrows.iter().any(|(a2, b2)| {
            (b2 - b).abs() <= 1e-7 * prep.scale
                && a2.iter().zip(&a).all(|(x, y)| (x - y).abs() <= 1e-7)
        });
        if !dup {
            hrows.push((a, b));
        }
    }
    let hull_a = DMatrix::from_fn(hrows.len(), p, |i, j| hrows[i].0[j]);
    let hull_b = DVector::from_iterator(hrows.len(), hrows.iter().map(|r| r.1));
    let out_regions = regions.iter().map(|r| finish_region(&prep, r)).collect();
    stats.solve_seconds = start.elapsed().as_secs_f64();
    Ok(MpqpSolution {
        n: prep.n,
        p,
        regions: out_regions,
        hull_a,
        hull_b,
        theta_lb: prep.theta_lb.clone(),
        theta_ub: prep.theta_ub.clone(),
        stats,
    })
}

fn finish_region(prep: &Prepared, r: &RegionData) -> CriticalRegion {
    let p = prep.p;
    let nf = r.facets.len();
    let a = DMatrix::from_fn(nf, p, |i, j| r.hs_a[r.facets[i].hs * p + j]);
    let b = DVector::from_iterator(nf, r.facets.iter().map(|f| r.hs_b[f.hs]));
    CriticalRegion {
        active_set: r.active.iter().map(|&i| prep.kept[i]).collect(),
        a,
        b,
        fz: r.kz.clone(),
        gz: r.kzc.clone(),
        center: DVector::from_column_slice(&r.center),
        radius: r.radius,
    }
}

/// An interior point of the set of parameters with a feasible QP.
fn interior_parameter(prep: &Prepared, lp: &mut LpWorkspace) -> Result<(Vec<f64>, f64), EmpcError> {
    let (n, p, m) = (prep.n, prep.p, prep.m);
    let d = n + p + 1;
    let np = prep.param_b.len();
    let mut a = Vec::with_capacity((m + np + 1) * d);
    let mut b = Vec::with_capacity(m + np + 1);
    for i in 0..m {
        a.extend(prep.g.row(i).iter());
        a.extend(prep.e.row(i).iter().map(|v| -v));
        a.push(1.0);
        b.push(prep.w[i]);
    }
    for i in 0..np {
        a.extend(std::iter::repeat_n(0.0, n));
        a.extend(prep.param_a.row(i).iter());
        a.push(1.0);
        b.push(prep.param_b[i]);
    }
    a.extend(std::iter::repeat_n(0.0, n + p));
    a.push(1.0);
    b.push(prep.scale);
    let mut c = vec![0.0; d];
    c[d - 1] = 1.0;
    let mut x0: Vec<f64> = std::iter::repeat_n(0.0, n)
        .chain((0..p).map(|j| 0.5 * (prep.theta_lb[j] + prep.theta_ub[j])))
        .chain([0.0])
        .collect();
    slack_start(&a, &b, &mut x0, d - 1);
    let (st, r) = lp.maximize_from(&c, &a, &b, &x0);
    match st {
        LpStatus::Optimal => {}
        other => {
            return Err(EmpcError::Numerical(format!(
                "the LP for an interior feasible parameter ended with {other:?}"
            )));
        }
    }
    if r < -1e-9 * prep.scale {
        return Err(EmpcError::EmptyFeasibleSet);
    }
    if r <= prep.radius_tol {
        return Err(EmpcError::NoInterior { radius: r });
    }
    Ok((lp.x[n..n + p].to_vec(), r))
}
