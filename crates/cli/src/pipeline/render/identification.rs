//! Section 3: the identified models, their fits, residual tests and
//! figures 7.8-7.13.

use super::fmt::{f3, f4, series_t};
use crate::report::document::Report;
use crate::report::plot::{Panel, Series, panels_svg};
use crate::report::table::Table;
use kestrel_sysid::ValidationReport;
use kestrel_tricopter::pipeline::PipelineResult;
use kestrel_tricopter::pipeline::identification::{IdentifiedModel, OutputComparison};
use nalgebra::DVector;

fn fit_rows(t: &mut Table, label: &str, rep: &ValidationReport) {
    for row in &rep.rows {
        let mut cells = vec![label.to_string(), row.label.clone()];
        cells.extend(row.fit.iter().map(|v| format!("{v:.2}")));
        cells.push(format!("{:.2}", row.mean()));
        t.row(cells);
    }
}

/// Section 3.
pub fn section(r: &mut Report, res: &PipelineResult) -> anyhow::Result<()> {
    let id = &res.config.identification;
    r.text("\n## 3. System identification (section 7.4)\n");
    r.text(format!(
        "kestrel-sysid's identification workflow (`workflow::identify` with `tricopter::thesis_spec`): \
         N4SID start, PEM at order {} (at most {} iterations) fitting A, B, C on simulation errors and \
         then the noise model K on one-step errors (the rate dynamics are integrators flown in closed \
         loop, so a one-step fit drifts in simulation), balanced truncation to order {} (`match_dc` \
         off: the MPC needs D = 0). Operating point: the means of the estimation data (stored as \
         `u0`/`y0`). Fits are on the validation intervals (4.11), k-step fits (4.12) beside the \
         persistence predictor y(t+k) = y(t); residual tests with lags -{l}..{l} and 99% bands.",
        id.order, id.pem_max_iterations, id.reduced_order, l = id.residual_lags
    ));
    let mut fit = Table::new(["model", "predictor", "p", "q", "r", "mean"]);
    let mut res_t = Table::new([
        "model",
        "output",
        "autocorr outside band",
        "white",
        "cross-corr (tau >= 0) outside band",
        "independent of inputs",
    ]);
    let mut about = Table::new([
        "model",
        "estimation samples",
        "validation samples",
        "PEM (simulation focus; noise model): iterations, cost",
        "Hankel singular values",
        "zeros outside unit circle",
    ]);
    let mut excitation = Table::new(["model", "data set", "samples", "std p", "std q", "std r"]);
    for m in res.identification.models() {
        let (key, label) = (m.kind.key(), m.kind.label());
        for (set, e) in [
            ("estimation", &m.estimation),
            ("validation", &m.validation_data),
        ] {
            let mut cells = vec![label.to_string(), set.to_string(), e.samples.to_string()];
            cells.extend(e.std.iter().map(|v| f3(*v)));
            excitation.row(cells);
        }
        fit_rows(
            &mut fit,
            &format!("{label}, order {}", m.order),
            &m.full_validation,
        );
        fit_rows(
            &mut fit,
            &format!("{label}, order {}", m.reduced_order),
            &m.validation,
        );
        let ra = &m.validation.residuals;
        for o in &ra.outputs {
            res_t.row([
                format!("{label}, order {}", m.reduced_order),
                o.name.clone(),
                format!("{}/{}", o.auto_outside, ra.max_lag),
                if o.white { "yes" } else { "no" }.to_string(),
                format!("{}/{}", o.cross_outside, (ra.max_lag + 1) * ra.inputs.len()),
                if o.independent { "yes" } else { "no" }.to_string(),
            ]);
        }
        let zeros = match &m.zeros {
            Ok(z) => {
                let nmp: Vec<String> = z
                    .iter()
                    .filter(|z| z.non_minimum_phase)
                    .map(|z| format!("{:.3}{:+.3}i", z.z.re, z.z.im))
                    .collect();
                format!(
                    "{} of {}{}{}",
                    nmp.len(),
                    z.len(),
                    if nmp.is_empty() { "" } else { ": " },
                    nmp.join(", ")
                )
            }
            Err(e) => format!("not computed ({e})"),
        };
        let pem_text = m
            .pem
            .iter()
            .map(|p| {
                format!(
                    "{} it., {} -> {}",
                    p.iterations,
                    f4(p.initial_cost),
                    f4(p.cost)
                )
            })
            .collect::<Vec<_>>()
            .join("; ");
        about.row([
            label.to_string(),
            m.estimation_samples.to_string(),
            m.validation_samples.to_string(),
            pem_text,
            m.hankel_singular_values
                .iter()
                .map(|v| f3(*v))
                .collect::<Vec<_>>()
                .join(", "),
            zeros,
        ]);
        r.write(
            &format!("models/{key}-{}.json", m.reduced_order),
            m.ss.to_json_string(),
        )?;
        r.write(
            &format!("models/{key}-{}.json", m.order),
            m.full_ss.to_json_string(),
        )?;
        figures(r, m)?;
    }
    r.table(
        "excitation",
        "Excitation of the data sets: standard deviation of the measured rates (rad/s)",
        &excitation,
    )?;
    r.table("identification", "Identified models", &about)?;
    r.table(
        "fit",
        "Fit [%] on the validation data (simulation, k-step prediction, persistence baseline)",
        &fit,
    )?;
    r.table("residuals", "Residual tests on the validation data", &res_t)?;
    r.text(format!(
        "Models: `models/blackbox-{o}.json`, `models/virtual-{o}.json` (reduced) and `models/*-{f}.json` \
         (before reduction), all `kestrel.ss.v1`.",
        o = id.reduced_order,
        f = id.order
    ));
    Ok(())
}

/// One panel per rate: the measured output against a model output, both
/// around `y0`.
fn measured_against(
    r: &mut Report,
    c: &OutputComparison,
    y0: &DVector<f64>,
    legend: impl Fn(usize) -> String,
    name: &str,
    title: &str,
    caption: &str,
) -> anyhow::Result<()> {
    let names = ["p (roll rate)", "q (pitch rate)", "r (yaw rate)"];
    let panels: Vec<Panel> = (0..3)
        .map(|j| Panel {
            title: names[j].into(),
            x_label: "time [s]".into(),
            y_label: "rad/s".into(),
            series: vec![
                Series::line(
                    "measured",
                    series_t(&c.t, c.measured.column(j).iter().map(|v| v + y0[j])),
                ),
                Series::dashed(
                    legend(j),
                    series_t(&c.t, c.model.column(j).iter().map(|v| v + y0[j])),
                ),
            ],
            hlines: vec![],
        })
        .collect();
    panels_svg(&r.path(name), title, &panels)?;
    r.figure(name, caption);
    Ok(())
}

fn figures(r: &mut Report, m: &IdentifiedModel) -> anyhow::Result<()> {
    let (key, label) = (m.kind.key(), m.kind.label());
    let fit = m.simulation.fit.clone().unwrap_or_default();
    measured_against(
        r,
        &m.simulation,
        &m.y0,
        |j| {
            format!(
                "simulated (fit {:.1}%)",
                fit.get(j).copied().unwrap_or(f64::NAN)
            )
        },
        &format!("figures/{key}-simulation.svg"),
        &format!("{label} model: simulation on validation data"),
        &format!("Measured and simulated outputs, {label} model (figures 7.8-7.9)"),
    )?;
    measured_against(
        r,
        &m.five_step,
        &m.y0,
        |_| "5-step prediction".to_string(),
        &format!("figures/{key}-5step.svg"),
        &format!("{label} model: 5-step prediction on validation data"),
        &format!("5-step prediction, {label} model (figures 7.10-7.11)"),
    )?;
    // Residuals of the yaw rate: autocorrelation and cross-correlation with
    // the yaw input (servo, or the virtual yaw input).
    let ra = &m.validation.residuals;
    let o = &ra.outputs[2];
    let lag = ra.max_lag as f64;
    let band = vec![
        (ra.bound, "99% band".to_string()),
        (-ra.bound, "99% band".to_string()),
    ];
    let q = ra.inputs.len() - 1;
    let panels = vec![
        Panel {
            title: format!("autocorrelation of the residuals of {}", o.name),
            x_label: "lag [samples]".into(),
            y_label: "".into(),
            series: vec![Series::stems(
                o.name.clone(),
                o.autocorr
                    .iter()
                    .enumerate()
                    .map(|(k, v)| (k as f64, *v))
                    .collect(),
            )],
            hlines: band.clone(),
        },
        Panel {
            title: format!(
                "cross-correlation of {} and the residuals of {}",
                ra.inputs[q], o.name
            ),
            x_label: "lag [samples]".into(),
            y_label: "".into(),
            series: vec![Series::stems(
                format!("{} -> {}", ra.inputs[q], o.name),
                o.crosscorr[q]
                    .iter()
                    .enumerate()
                    .map(|(k, v)| (k as f64 - lag, *v))
                    .collect(),
            )],
            hlines: band,
        },
    ];
    let name = format!("figures/{key}-residuals.svg");
    panels_svg(
        &r.path(&name),
        &format!("{label} model: residual analysis of the yaw rate"),
        &panels,
    )?;
    r.figure(
        &name,
        &format!("Residual correlations with 99% bands, {label} model (figures 7.12-7.13)"),
    );
    Ok(())
}
