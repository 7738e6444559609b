//! The estimation: the stages of the focus from the start to the report.

use crate::error::sysid_invalid;
use crate::ident::greybox::model::grey_box_model;
use crate::ident::greybox::problem::{Problem, series_of, start_gain};
use crate::ident::greybox::report::{GreyBoxReport, ParameterEstimate, Stage};
use crate::ident::greybox::search::{run_stage, standard_errors};
use crate::ident::greybox::spec::{GreyBoxFocus, GreyBoxSpec};
use crate::ident::greybox::start::{check_data, feasible_start, thrust_and_drag_from_trim};
use kestrel_sysid::{IoData, Result, SysidError, estimate_x0_simulation, validate};
use kestrel_tricopter_model::{GreyBoxParams, RateModelKind};
use nalgebra::DVector;

/// Estimates the physical parameters of the tricopter's linearised rate
/// model from input/output data (deviations from the operating point) by
/// the prediction-error method (see the module docs).
///
/// Errors: non-finite data, data columns that do not match the model
/// (`spec.inputs`: 4 PWM or 3 virtual inputs; outputs `p, q, r`), too few
/// samples, a non-positive or non-finite initial parameter, bounds that
/// do not hold the initial value, no free parameter, a free parameter the
/// model does not depend on (actuator constants with
/// [`RateModelKind::Rates`]), an initial guess that cannot hover.
pub fn estimate_grey_box(
    data: &IoData,
    spec: &GreyBoxSpec,
    initial: &GreyBoxParams,
) -> Result<GreyBoxReport> {
    let ts = data.ts();
    let init = initial.to_array();
    let (lo, hi) = (spec.lower.to_array(), spec.upper.to_array());
    for i in 0..8 {
        let name = GreyBoxParams::NAMES[i];
        if !(init[i].is_finite() && init[i] > 0.0) {
            return Err(sysid_invalid(format!(
                "initial grey-box parameter {name} = {} must be positive and finite",
                init[i]
            )));
        }
        if lo[i].is_nan() || hi[i].is_nan() || lo[i] < 0.0 || hi[i] <= lo[i] {
            return Err(sysid_invalid(format!(
                "bounds of {name} [{}, {}] must satisfy 0 <= lower < upper",
                lo[i], hi[i]
            )));
        }
        if spec.free[i] && !(init[i] >= lo[i] && init[i] <= hi[i]) {
            return Err(sysid_invalid(format!(
                "initial {name} = {} is outside its bounds [{}, {}]",
                init[i], lo[i], hi[i]
            )));
        }
    }
    let phys: Vec<usize> = (0..8).filter(|&i| spec.free[i]).collect();
    if phys.is_empty() {
        return Err(sysid_invalid("no free grey-box parameter"));
    }
    if let (RateModelKind::Rates, Some(&i)) = (spec.kind, phys.iter().find(|&&i| i >= 5)) {
        return Err(sysid_invalid(format!(
            "{} does not enter the rate model without actuators (RateModelKind::Rates): fix it",
            GreyBoxParams::NAMES[i]
        )));
    }
    // The model's shape (the initial guess may not hover; the base does).
    let probe = grey_box_model(initial, spec, ts)
        .or_else(|_| grey_box_model(&GreyBoxParams::from_params(&spec.base), spec, ts))?;
    let (nx, nu, ny) = (probe.nx(), probe.nu(), probe.ny());
    check_data(data, nu, ny)?;
    let (start, start_adjusted, spec) = match spec.operating_point {
        Some(u0) => {
            let g = thrust_and_drag_from_trim(&spec.base, initial, &u0)?;
            let mut fixed = spec.clone();
            fixed.free[3] = false;
            fixed.free[4] = false;
            (g, false, std::borrow::Cow::Owned(fixed))
        }
        None => {
            let (g, adj) = feasible_start(initial, spec, ts)?;
            (g, adj, std::borrow::Cow::Borrowed(spec))
        }
    };
    let spec: &GreyBoxSpec = &spec;
    let phys: Vec<usize> = (0..8).filter(|&i| spec.free[i]).collect();
    if phys.is_empty() {
        return Err(sysid_invalid("no free grey-box parameter"));
    }
    let (_, sy) = data.stds();
    for j in 0..ny {
        if sy[j].partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            return Err(SysidError::ConstantOutput {
                name: data.output_names()[j].clone(),
            });
        }
    }
    let series = series_of(data);
    let k_free = spec.focus == GreyBoxFocus::Prediction;
    let np = phys.len() + if k_free { nx * ny } else { 0 } + nx * series.len();
    let m_total = data.n_samples() * ny;
    let shortest = series.iter().map(|s| s.u.len()).min().unwrap_or(0);
    if m_total < 2 * np || shortest < nx + 1 {
        return Err(SysidError::TooFewSamples {
            what: format!("grey-box PEM with {np} parameters (order {nx})"),
            needed: (2 * np).div_ceil(ny).max(nx + 1),
            found: data.n_samples(),
        });
    }
    let mut prob = Problem::new(spec, data, start, nx, ny, series, &sy);
    let mut stages = Vec::new();
    let mut current = start;
    let mut x0: Vec<DVector<f64>> = data
        .experiments()
        .iter()
        .map(|e| DVector::from_fn(nx, |i, _| if i < ny { e.y[(0, i)] } else { 0.0 }))
        .collect();
    if spec.settings.equation_error_start {
        let s = run_stage(&mut prob, Stage::EquationError, &current, None, &x0)?;
        current = prob.params_of(&s.theta);
        x0 = prob.x0s_of(&s.theta);
        stages.push(s.summary(Stage::EquationError));
    }
    let main = match spec.focus {
        GreyBoxFocus::Prediction => {
            let m = grey_box_model(&current, spec, ts)?;
            run_stage(
                &mut prob,
                Stage::Prediction,
                &current,
                Some(start_gain(&m, spec.disturbance)),
                &x0,
            )?
        }
        GreyBoxFocus::Simulation | GreyBoxFocus::SimulationThenNoise => {
            let m = grey_box_model(&current, spec, ts)?;
            x0 = data
                .experiments()
                .iter()
                .map(|e| estimate_x0_simulation(&m, &e.u, &e.y))
                .collect::<Result<_>>()?;
            run_stage(&mut prob, Stage::Simulation, &current, None, &x0)?
        }
    };
    let main_stage = if spec.focus == GreyBoxFocus::Prediction {
        Stage::Prediction
    } else {
        Stage::Simulation
    };
    stages.push(main.summary(main_stage));
    let estimate = prob.params_of(&main.theta);
    let std_errors = standard_errors(&prob, &main.eval);
    let (iterations, stop) = (main.iterations, main.stop);
    let mut model = main.eval.model.clone();
    let mut cost = main.cost;
    x0 = prob.x0s_of(&main.theta);
    if spec.focus == GreyBoxFocus::SimulationThenNoise {
        prob.phys.clear();
        prob.lo.clear();
        prob.hi.clear();
        let s2 = run_stage(
            &mut prob,
            Stage::Noise,
            &estimate,
            Some(start_gain(&model, spec.disturbance)),
            &x0,
        )?;
        stages.push(s2.summary(Stage::Noise));
        model = s2.eval.model.clone();
        cost = s2.cost;
        x0 = prob.x0s_of(&s2.theta);
    }
    let est = estimate.to_array();
    let st = start.to_array();
    let mut parameters = Vec::with_capacity(8);
    let mut k = 0;
    for i in 0..8 {
        let se = if spec.free[i] {
            let s = std_errors.as_ref().and_then(|v| v.get(k).copied());
            k += 1;
            s.map(|s| s * est[i])
        } else {
            None
        };
        parameters.push(ParameterEstimate {
            name: GreyBoxParams::NAMES[i],
            free: spec.free[i],
            initial: init[i],
            start: st[i],
            estimate: est[i],
            std_error: se,
        });
    }
    let fit = validate(&model, data, &spec.settings.horizons)?;
    Ok(GreyBoxReport {
        estimate,
        initial: *initial,
        start,
        start_adjusted,
        from_operating_point: spec.operating_point.is_some(),
        parameters,
        model,
        x0,
        initial_cost: stages.first().map(|s| s.initial_cost).unwrap_or(cost),
        cost,
        stages,
        iterations,
        stop,
        fit,
    })
}
