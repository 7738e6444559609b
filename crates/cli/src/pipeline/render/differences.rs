//! Section 11: where the numbers differ from the thesis's, and why.

use crate::report::document::Report;
use crate::report::table::{Table, fmt_sig};
use kestrel_tricopter::pipeline::PipelineResult;
use kestrel_tricopter::pipeline::differences::{Here, Quantity};

/// The row's quantity, the thesis's value and why they differ.
fn about(q: Quantity) -> (&'static str, &'static str, &'static str) {
    match q {
        Quantity::BlackBoxSimulationFit => (
            "black-box simulation fit p/q/r [%]",
            "41.41 / 43.08 / 42.7",
            "a simulated aircraft (no vibration, no unmodelled frame dynamics, known noise) instead of the real \
             one; PEM from an N4SID start with exact gradients instead of MATLAB's ssest",
        ),
        Quantity::BlackBoxFiveStepFit => (
            "black-box 5-step fit p/q/r [%]",
            "31.39 / 41.54 / 52.18",
            "as above",
        ),
        Quantity::VirtualSimulationFit => (
            "black-box virtual simulation fit p/q/r [%]",
            "58.62 / 45.23 / 42.25",
            "as above; the virtual inputs here are the logged mixer inputs",
        ),
        Quantity::Trim => (
            "trim U0 [us]",
            "15.63, 0.85, -16.01, 1467.7",
            "kestrel-tricopter-model's default aircraft is physically consistent (ERRATA: Table 7.1 is not), \
             so its trim differs from the real aircraft's",
        ),
        Quantity::ExplicitTables => (
            "explicit MPC, thesis-sized: tables",
            "about 35 kB, about 3 ms on the ATmega2560",
            "a binary search tree over the regions' hyperplanes with shared identical laws and u16 indices \
             (MPT's exported tree stores every region's full law); the AVR cycle figures are kestrel-avr-rt's",
        ),
        Quantity::CertifiedIterations => (
            "fast gradient, certified iterations",
            "25, 56, 73, 91 for eps 1e5 ... 1e2",
            "our weights and model differ (Q1, Q2 and the identified model set the scale of J), the bound is \
             the cold-start certificate of Richter et al. after an optimal diagonal preconditioner; the \
             thesis's FiOrdOs numbers are for its own scaling",
        ),
        Quantity::OptimalCost => (
            "Table 7.2 optimal cost J*",
            "4039.228",
            "J here is the condensed QP objective 1/2 z'Hz + theta'F z without the constant term in theta \
             (so it can be negative); it depends on the weights and the model; the initial state is the \
             least-norm state with the thesis's rates y = [0.2, 0.3, 0.4], not the thesis's x (a different \
             state basis)",
        ),
        Quantity::Effort => (
            "closed loop, black-box MPC: pulse effort pwm1/2/3/servo",
            "motors 1 and 2 peak at about 150 us, motor 3 at about 400 us: only motor 3 works (7.7.1)",
            "our model is identified from a simulated, symmetric aircraft with a consistent mixer; the \
             thesis's black-box model was fitted to a real, unbalanced one",
        ),
        Quantity::RiseTime => (
            "closed loop: rise time p/q/r after the step",
            "not reported (figures only)",
            "the thesis compared solvers, not the MPC against the PI",
        ),
        Quantity::MpcDesign => (
            "closed loop: MPC design",
            "plain MPC, Q2 the same on all four pulses",
            "the identified 5-state model's steady-state gain is off (truncation from order 8 keeps \
             D = 0 but not the DC gain, and the near-integrating rate dynamics make the gain hard to \
             identify): the plain MPC then stops short of the pitch reference (never 90 % of the step). \
             With the offset-free MPC and the same weight on every pulse the yaw loop bangs the servo \
             between its limits; a ten times larger weight on the servo settles it",
        ),
    }
}

fn join(v: &[f64], f: impl Fn(f64) -> String, sep: &str) -> String {
    v.iter().map(|x| f(*x)).collect::<Vec<_>>().join(sep)
}

fn here(q: Quantity, h: &Here) -> String {
    match h {
        Here::Fits(f) => f
            .as_ref()
            .map_or_else(|| "-".into(), |v| join(v, |x| format!("{x:.1}"), " / ")),
        Here::Trim(u0) => join(u0, |x| format!("{x:.2}"), ", "),
        Here::ExplicitTables {
            regions,
            bytes,
            depth,
        } => format!("{regions} regions, {bytes} bytes (f32, first move), depth {depth}"),
        Here::Certificates(c) => c
            .iter()
            .map(|(it, eps)| format!("{it} (eps {})", fmt_sig(*eps, 2)))
            .collect::<Vec<_>>()
            .join(", "),
        Here::Cost(j) => fmt_sig(*j, 7),
        Here::AgainstPi { qp, pi } => {
            let (qp, pi) = (
                join(qp, |x| fmt_sig(x, 3), " / "),
                join(pi, |x| fmt_sig(x, 3), " / "),
            );
            match q {
                Quantity::RiseTime => format!("{qp} s (QP) against {pi} s (PI)"),
                _ => format!("RMS {qp} us (QP); the PI: {pi} us"),
            }
        }
        Here::Design { offset_free, q2 } => format!(
            "{}; Q2 = {q2}",
            if *offset_free {
                "offset-free MPC (three torque disturbances estimated by the Kalman filter)"
            } else {
                "plain MPC"
            }
        ),
    }
}

/// Section 11.
pub fn section(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    r.text("\n## 11. Differences from the thesis\n");
    let d = &res.differences;
    let mut t = Table::new(["quantity", "thesis", "here", "why they differ"]);
    for row in &d.rows {
        let (quantity, thesis, why) = about(row.quantity);
        t.row([
            quantity.to_string(),
            thesis.to_string(),
            here(row.quantity, &row.here),
            why.to_string(),
        ]);
    }
    r.table(
        "differences",
        "Where our numbers differ from the thesis's",
        &t,
    )?;
    for w in &d.weak {
        let list: Vec<String> = w
            .outputs
            .iter()
            .map(|(o, s, n)| {
                format!(
                    "{o} (std {} rad/s, gyro noise {} rad/s)",
                    fmt_sig(*s, 2),
                    fmt_sig(*n, 2)
                )
            })
            .collect();
        r.text(format!(
            "\nThe {} model's validation intervals (the thesis's, chosen for its own flights) hardly \
             excite {}: less than ten times the gyro noise, so the fit of those outputs (normalised by \
             their variance) says little about the model. kestrel-tricopter-model's flight no. 2 excites \
             the axes in turn, which does not line up with the real flight's intervals (see the excitation \
             table of section 3).\n",
            w.model.label(),
            list.join(", ")
        ));
    }
    r.text(
        "Beyond the numbers:\n\n\
         - Printed equations corrected (ERRATA.md): the S_u block column (6.13), the constraint \
           matrices (6.22d-e), the active-set law with the linear cost term (6.28), the Riccati \
           equation (7.18), the Kalman time update from the filtered estimate (5.12c, 5.15b), \
           the mixer constants C_r = 1/sqrt(3), C_p = 2/3, C_y = 1 and Nesterov's beta.\n\
         - The thesis's MPC ran with Ns = 1 because MPT's tree did not fit; here the explicit law of \
           the thesis-sized problem is small enough to keep whole, and the larger problem \
           (N = 10, blocks [1, 1, 2, 6]) is solved by the fast gradient method with a certificate.\n\
         - The fast gradient method is cold-started here in the closed loop as in the thesis; the \
           AVR runtime warm-starts it (kestrel-avr-rt).\n\
         - The thesis found the estimated models non-minimum phase; the transmission zeros of our \
           models are in the identification table, from the simulator, which has no propeller \
           flexibility or frame vibration.\n\
         - The closed loop here flies the nonlinear 6-DOF simulator, not the identified linear model \
           as in the thesis's figures 7.16-7.21, so model error is part of every run.\n\
         - The identification is kestrel-sysid's workflow (PEM on simulation errors, then the noise \
           model), not MATLAB's one-step `ssest`: on closed-loop flights of near-integrating rate \
           dynamics the one-step optimum drifts in simulation.\n\
         - One Kalman filter from measurement to firmware: the filter tuned in section 4 (on the measured \
           gyro statistics) is the one the closed loop of section 9 flies and the one `firmware/kalman.json` \
           carries; the thesis's constants (7.5)-(7.6) appear only as the comparison column of section 2.",
    );
    Ok(())
}
