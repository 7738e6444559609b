//! Sections 6 (explicit MPC), 7 (fast-gradient certificates) and 8
//! (Table 7.2).

use super::fmt::f4;
use crate::report::document::Report;
use crate::report::plot::{Polygon, partition_svg};
use crate::report::table::{Table, fmt_sig};
use kestrel_tricopter::pipeline::PipelineResult;
use kestrel_tricopter::pipeline::fast_gradient::{CHECK_SLACK, EpsSource, preconditioner};
use kestrel_tricopter::pipeline::table_7_2::{REPETITIONS, Solver};

/// Section 6.
pub fn explicit(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    let ex = &res.explicit;
    let cfg = &res.config;
    r.text("\n## 6. Explicit MPC (sections 6.2, 7.6.1)\n");
    let mut t = Table::new([
        "problem",
        "tree over",
        "regions",
        "distinct laws",
        "tree depth",
        "nodes",
        "bytes (f32)",
        "solve [s]",
        "tree build [s]",
    ]);
    let mut check = Table::new([
        "problem",
        "random theta",
        "outside explored set",
        "max |z_explicit - z_QP| [us]",
        "max |J_explicit - J_QP|",
    ]);
    for e in ex.solutions() {
        let name = e.name.as_str();
        for (over, c) in [("all of z", &e.full), ("first move", &e.first)] {
            t.row([
                name.to_string(),
                over.to_string(),
                e.solution.regions.len().to_string(),
                c.stats.distinct_laws.to_string(),
                c.stats.depth.to_string(),
                c.stats.nodes.to_string(),
                c.tables.bytes(4).to_string(),
                format!("{:.4}", e.solution.stats.solve_seconds),
                format!("{:.4}", c.stats.build_seconds),
            ]);
        }
        check.row([
            name.to_string(),
            e.check.points.to_string(),
            e.check.outside.to_string(),
            fmt_sig(e.check.max_dz, 3),
            fmt_sig(e.check.max_dj, 3),
        ]);
        let json_text = kestrel_empc::export::solution_json(&e.solution, &e.full, false);
        r.write(&format!("explicit-{name}.json"), json_text)?;
        if e.name == ex.thesis.name {
            partition(r, res)?;
        }
    }
    r.table(
        "explicit",
        "Explicit solutions and search trees (f32 tables)",
        &t,
    )?;
    r.table(
        "explicit_check",
        "The explicit law against the clarabel QP at random parameters of the box",
        &check,
    )?;
    if !cfg.empc.solve_larger {
        r.text("The larger problem is not solved explicitly by default (`empc.solve_larger`).");
    }
    Ok(())
}

fn partition(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    let s = &res.explicit.slice;
    let polys: Vec<Polygon> = s
        .polygons
        .iter()
        .map(|p| Polygon {
            vertices: p.vertices.clone(),
            group: p.law,
        })
        .collect();
    let [xr, yr] = s.range;
    let name = "figures/partition.svg";
    partition_svg(
        &r.path(name),
        &format!(
            "Explicit MPC: {} regions cut by the slice (other parameters 0, throttle {} us)",
            polys.len(),
            s.throttle
        ),
        (&s.axis_names[0], &s.axis_names[1]),
        (xr[0], xr[1]),
        (yr[0], yr[1]),
        &polys,
    )?;
    r.figure(
        name,
        "A 2-D slice of the explicit-MPC partition (colours: distinct laws)",
    );
    Ok(())
}

/// Section 7.
pub fn fast_gradient(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    let fg = &res.fast_gradient;
    let cfg = &res.config;
    r.text("\n## 7. Fast gradient method: certification (sections 6.3, 7.6.2)\n");
    let mut scaling = Table::new([
        "problem",
        "preconditioner",
        "L",
        "mu",
        "L/mu before",
        "L/mu after",
        "iterations (eps = 1e2) unscaled",
        "iterations (eps = 1e2) scaled",
    ]);
    let mut cert_t = Table::new([
        "problem",
        "eps",
        "certified iterations",
        "random theta",
        "max J(z_i) - J*",
        "holds",
    ]);
    let mut unpolished = 0;
    for f in fg.list() {
        let name = f.name.as_str();
        let pc = &f.design.preconditioning;
        scaling.row([
            name.to_string(),
            pc.method.name().to_string(),
            f4(pc.before.l),
            f4(pc.before.mu),
            f4(pc.before.condition()),
            f4(pc.after.condition()),
            f.iterations_unscaled.to_string(),
            f.iterations_scaled.to_string(),
        ]);
        for c in &f.certificates {
            let label = match c.source {
                EpsSource::Table => fmt_sig(c.eps, 2),
                EpsSource::PwmError(us) => {
                    format!("{} ({us} us PWM error)", fmt_sig(c.eps, 3))
                }
            };
            cert_t.row([
                name.to_string(),
                label,
                c.certificate.iterations.to_string(),
                f.check_points.to_string(),
                fmt_sig(c.max_gap, 3),
                if c.holds { "yes" } else { "NO" }.to_string(),
            ]);
        }
        unpolished += f.unpolished;
    }
    r.text(format!(
        "Cold-start certificates (Richter, Jones, Morari 2012) of the constant-step fast gradient method on \
         the box-constrained condensed QP, after {} preconditioning. Each certificate is checked at {} \
         random parameters of the box against the optimum of the reference QP (clarabel, refined by an \
         active-set polish to rounding accuracy; {}); a certificate holds when the largest gap found is at \
         most eps + {} (1 + |gap|).",
        preconditioner(cfg.fgm.preconditioner).name(),
        cfg.fgm.check_points,
        if unpolished == 0 {
            "the polish verified at every point".to_string()
        } else {
            format!("at {unpolished} points the polish did not verify and clarabel's own optimum was used")
        },
        fmt_sig(CHECK_SLACK, 1),
    ));
    r.table(
        "fgm_scaling",
        "Conditioning before and after preconditioning",
        &scaling,
    )?;
    r.table(
        "fgm_certificates",
        "Certified iterations for J(z_i) - J* <= eps, checked",
        &cert_t,
    )?;
    if !fg.all_hold {
        r.text(
            "Not every certificate holds at the check points: a gap above eps means the certificate's \
             bound is violated (or the reference optimum is not accurate there); see the rows marked NO.",
        );
    }
    Ok(())
}

/// Section 8: Table 7.2.
pub fn table_7_2(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    let t72 = &res.table_7_2;
    let cfg = &res.config;
    r.text("\n## 8. Explicit MPC, active set and fast gradient against the QP (Table 7.2, section 7.7.2)\n");
    let mut headers: Vec<String> = ["solver", "iterations", "eps", "J(U, theta)", "J - J*"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    headers.extend((1..=t72.nu).map(|i| format!("U{i} [us]")));
    headers.push("max |U - U*| [us]".into());
    headers.push("host time [us]".into());
    let mut t = Table::new(headers);
    for row in &t72.rows {
        let (solver, it, eps) = match &row.solver {
            Solver::Qp => ("QP (clarabel)", "-".to_string(), "-".to_string()),
            Solver::Explicit => ("explicit MPC", "-".to_string(), "-".to_string()),
            Solver::ActiveSet { iterations } => (
                "active set (kestrel-qp)",
                iterations.to_string(),
                "-".to_string(),
            ),
            Solver::FgmFixed(k) => ("fast gradient", k.to_string(), "(fixed)".to_string()),
            Solver::FgmCertified {
                iterations,
                eps,
                pwm,
            } => (
                "fast gradient",
                iterations.to_string(),
                if *pwm {
                    format!("{} (PWM)", fmt_sig(*eps, 3))
                } else {
                    fmt_sig(*eps, 2)
                },
            ),
        };
        let mut cells = vec![
            solver.to_string(),
            it,
            eps,
            fmt_sig(row.cost, 7),
            fmt_sig(row.gap, 3),
        ];
        cells.extend(t72.first_move(row).iter().map(|v| format!("{v:.3}")));
        cells.push(fmt_sig(row.first_move_error, 3));
        cells.push(format!("{:.2}", row.host_seconds * 1e6));
        t.row(cells);
    }
    r.text(format!(
        "Thesis-sized problem, initial body rates {:?} rad/s (x = pinv(C) y), references {:?} rad/s, \
         throttle {} us. U is the first move, pulses from the trim (us). The active-set row is \
         kestrel-qp's exact dual active-set solver from a cold start, its iterations the active-set \
         changes. Host times are means over {REPETITIONS} solves on this machine (the AVR figures \
         are kestrel-avr-rt's).",
        cfg.comparison.rates, cfg.comparison.reference, cfg.comparison.throttle
    ));
    r.table(
        "table_7_2",
        "Table 7.2: cost and first move of each solver",
        &t,
    )?;
    Ok(())
}
