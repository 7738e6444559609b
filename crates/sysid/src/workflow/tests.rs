//! Tests of the workflow against the separate steps.

use super::report::IdentifyReport;
use super::run::identify;
use super::segment::{Segment, select_segments};
use super::spec::{AfterReduction, IdentifySpec, InputMap, Method, PemFocus};
use crate::data::{IoData, TimeInterval};
use crate::error::SysidError;
use crate::model::InnovationModel;
use crate::n4sid::N4sidResult;
use crate::pem::{Criterion, PemSettings, pem};
use crate::reduce::{BalredSettings, balred};
use crate::synthetic;
use crate::validate::validate;
use nalgebra::DMatrix;

/// The default spec without the structure choice (the fits by hand
/// below follow the spec as given).
fn fixed() -> IdentifySpec {
    IdentifySpec {
        auto: None,
        arx_baseline: None,
        ..Default::default()
    }
}

fn data() -> IoData {
    let truth = synthetic::random_model(2, 2, 1, 9, 0.9);
    synthetic::simulate(&truth, 1200, 0.05, 3).unwrap()
}

/// `identify` on all of `d` and the same start by hand: the mean-free
/// data and their N4SID start of the spec's order.
struct ByHand {
    /// `identify`'s report.
    r: IdentifyReport,
    /// The mean-free data.
    est: IoData,
    /// N4SID on `est`.
    start: N4sidResult,
}

fn by_hand(d: &IoData, spec: &IdentifySpec) -> ByHand {
    let r = identify(d, spec).unwrap();
    let (est, _) = d.remove_means().unwrap();
    let start = crate::n4sid::n4sid_of_order(&est, spec.order.unwrap());
    ByHand { r, est, start }
}

#[test]
fn identify_matches_the_separate_steps() {
    let d = data();
    let spec = IdentifySpec {
        estimate: vec![Segment::all(TimeInterval::new(0.0, 799.0).unwrap())],
        validate: vec![Segment::all(TimeInterval::new(800.0, 1199.0).unwrap())],
        order: Some(3),
        reduce: Some(2),
        after_reduction: AfterReduction::Keep,
        ..fixed()
    };
    let r = identify(&d, &spec).unwrap();
    // The same steps by hand.
    let est = d.select(&[spec.estimate[0].interval]).unwrap();
    let (est, off) = est.remove_means().unwrap();
    let val = d
        .select(&[spec.validate[0].interval])
        .unwrap()
        .subtract(&off)
        .unwrap();
    let start = crate::n4sid::n4sid_of_order(&est, 3);
    let p = pem(&est, &start.model, &PemSettings::default()).unwrap();
    let red = balred(
        &p.model,
        2,
        &BalredSettings {
            include_noise: true,
            ..Default::default()
        },
    )
    .unwrap();
    let rep = validate(&red.model, &val, &[1, 5]).unwrap();
    assert_eq!(r.validation, rep);
    assert_eq!(r.model, red.model);
    assert_eq!(r.full_model, p.model);
    assert_eq!(r.offsets.u0, off.u0);
    assert_eq!(r.model.nx(), 2);
    assert!(r.on_validation_data);
    assert_eq!(r.pem.unwrap().stop, p.stop);
    let text = r.to_string();
    for want in [
        "PEM:",
        "balred 3 -> 2",
        "model simulation",
        "persistence 5-step",
    ] {
        assert!(text.contains(want), "{want} missing in {text}");
    }
    let ss = r.to_ss_model().unwrap();
    assert_eq!(ss.u0.unwrap().len(), 2);
}

/// After `balred` the noise model is re-estimated with the reduced
/// dynamics fixed: `A, B, C, D` are `balred`'s, `K` is the PEM
/// estimate from the reduced model (the same call by hand), and its
/// one-step prediction on the estimation data is at least as good as
/// the reduced `K`'s; refining everything lowers it further.
#[test]
fn reduced_model_gets_its_own_noise_model() {
    let truth = synthetic::random_model(4, 2, 2, 31, 0.9);
    let d = synthetic::simulate(&truth, 1500, 0.3, 5).unwrap();
    let base = IdentifySpec {
        estimate: Segment::parse_list("0:999").unwrap(),
        validate: Segment::parse_list("1000:1499").unwrap(),
        order: Some(4),
        reduce: Some(2),
        after_reduction: AfterReduction::Keep,
        ..fixed()
    };
    let kept = identify(&d, &base).unwrap();
    assert!(kept.pem_reduced.is_none());
    let noise = identify(
        &d,
        &IdentifySpec {
            after_reduction: AfterReduction::NoiseModel,
            ..base.clone()
        },
    )
    .unwrap();
    let all = identify(
        &d,
        &IdentifySpec {
            after_reduction: AfterReduction::All,
            ..base.clone()
        },
    )
    .unwrap();
    for m in [&noise.model, &all.model] {
        assert_eq!(m.nx(), 2);
    }
    // Same dynamics (up to the scaling round trip), new K.
    let same = |x: &DMatrix<f64>, y: &DMatrix<f64>| (x - y).amax() <= 1e-12 * (1.0 + y.amax());
    assert!(same(&noise.model.a, &kept.model.a));
    assert!(same(&noise.model.b, &kept.model.b));
    assert!(same(&noise.model.c, &kept.model.c));
    assert!(same(&noise.model.d, &kept.model.d));
    assert!((&noise.model.k - &kept.model.k).amax() > 1e-6);
    // The same as the PEM call by hand on the estimation data.
    let est = d
        .select(&[base.estimate[0].interval])
        .unwrap()
        .subtract(&kept.offsets)
        .unwrap();
    let by_hand = pem(
        &est,
        &kept.model,
        &PemSettings {
            fixed_dynamics: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(noise.model, by_hand.model);
    let p = noise.pem_reduced.unwrap();
    assert!(p.cost <= p.initial_cost);
    // One-step cost on the estimation data: kept >= noise >= all.
    let cost = |m: &InnovationModel| {
        pem(
            &est,
            m,
            &PemSettings {
                max_iterations: 0,
                ..Default::default()
            },
        )
        .unwrap()
        .cost
    };
    let (ck, cn, ca) = (cost(&kept.model), cost(&noise.model), cost(&all.model));
    assert!(ck >= cn && cn >= ca * (1.0 - 1e-9), "{ck} {cn} {ca}");
    assert!(noise.to_string().contains("PEM refit after balred"));
}

/// `pem_horizon` reaches PEM (the same model as the call by hand) and
/// a zero horizon is an error.
#[test]
fn pem_horizon_is_passed_on_and_checked() {
    let d = data();
    let spec = IdentifySpec {
        order: Some(2),
        pem_horizon: 3,
        ..fixed()
    };
    let ByHand { r, est, start } = by_hand(&d, &spec);
    let settings = PemSettings {
        horizon: 3,
        ..Default::default()
    };
    let p = pem(&est, &start.model, &settings).unwrap();
    assert_eq!(r.full_model, p.model);
    let one = pem(&est, &start.model, &PemSettings::default()).unwrap();
    assert!((&p.model.a - &one.model.a).amax() > 1e-9);
    let bad = IdentifySpec {
        pem_horizon: 0,
        ..spec
    };
    assert!(matches!(
        identify(&d, &bad),
        Err(SysidError::InvalidArgument(_))
    ));
}

/// `criterion` reaches both PEM stages (the same model as the calls by
/// hand) and differs from the trace.
#[test]
fn criterion_is_passed_on() {
    let d = data();
    let spec = IdentifySpec {
        order: Some(2),
        focus: PemFocus::MultiStepThenNoise { horizon: 3 },
        criterion: Criterion::Fit,
        ..fixed()
    };
    let ByHand { r, est, start } = by_hand(&d, &spec);
    let settings = PemSettings {
        horizon: 3,
        criterion: Criterion::Fit,
        ..Default::default()
    };
    let p = pem(&est, &start.model, &settings).unwrap();
    let noise = PemSettings {
        fixed_dynamics: true,
        criterion: Criterion::Fit,
        ..Default::default()
    };
    let k = pem(&est, &p.model, &noise).unwrap();
    assert_eq!(r.full_model, k.model);
    let trace = identify(
        &d,
        &IdentifySpec {
            criterion: Criterion::Trace,
            ..spec
        },
    )
    .unwrap();
    assert!((&trace.full_model.a - &r.full_model.a).amax() > 1e-9);
}

/// `MultiStepThenNoise` is the multi-step fit followed by the K-only
/// stage (the same models as the calls by hand): the dynamics and so
/// the simulation fit stay, the noise stage's criterion does not rise,
/// and a zero horizon in either stage is an error.
#[test]
fn multi_step_then_noise_keeps_the_dynamics_and_refits_k() {
    let d = data();
    let spec = IdentifySpec {
        order: Some(2),
        focus: PemFocus::MultiStepThenNoise { horizon: 4 },
        ..fixed()
    };
    let ByHand { r, est, start } = by_hand(&d, &spec);
    let multi = pem(
        &est,
        &start.model,
        &PemSettings {
            horizon: 4,
            ..Default::default()
        },
    )
    .unwrap();
    let noise_settings = PemSettings {
        fixed_dynamics: true,
        ..Default::default()
    };
    let noise = pem(&est, &multi.model, &noise_settings).unwrap();
    assert_eq!(r.full_model, noise.model);
    let same = |x: &DMatrix<f64>, y: &DMatrix<f64>| (x - y).amax() <= 1e-12 * (1.0 + y.amax());
    assert!(same(&r.model.a, &multi.model.a));
    assert!(same(&r.model.b, &multi.model.b));
    assert!(same(&r.model.c, &multi.model.c));
    assert!(same(&r.model.d, &multi.model.d));
    assert!((&r.model.k - &multi.model.k).amax() > 1e-9);
    // Simulation fit unchanged (it does not depend on K).
    let sim = |m: &InnovationModel| {
        validate(m, &est, &[1])
            .unwrap()
            .row("model simulation")
            .unwrap()
            .fit
            .clone()
    };
    for (a, b) in sim(&r.model).iter().zip(sim(&multi.model)) {
        assert!((a - b).abs() < 1e-6, "{a} {b}");
    }
    // The K stage starts from the multi-step K and lowers its own cost.
    let p = r.pem_noise.unwrap();
    assert!(p.cost <= p.initial_cost);
    assert!(r.to_string().contains("PEM noise model"));
    // The noise stage follows `pem_horizon`.
    let r3 = identify(
        &d,
        &IdentifySpec {
            pem_horizon: 3,
            ..spec.clone()
        },
    )
    .unwrap();
    let noise3 = pem(
        &est,
        &multi.model,
        &PemSettings {
            horizon: 3,
            ..noise_settings
        },
    )
    .unwrap();
    assert_eq!(r3.full_model, noise3.model);
    for bad in [
        IdentifySpec {
            focus: PemFocus::MultiStepThenNoise { horizon: 0 },
            ..spec.clone()
        },
        IdentifySpec {
            pem_horizon: 0,
            ..spec.clone()
        },
    ] {
        assert!(matches!(
            identify(&d, &bad),
            Err(SysidError::InvalidArgument(_))
        ));
    }
}

#[test]
fn given_offsets_are_checked_and_mapped() {
    let d = data();
    let spec = IdentifySpec {
        order: Some(2),
        method: Method::N4sid,
        u0: Some(vec![1.0]),
        ..fixed()
    };
    assert!(matches!(
        identify(&d, &spec),
        Err(SysidError::Dimension { .. })
    ));
    // An input map maps a given u0 too.
    let spec = IdentifySpec {
        order: Some(2),
        method: Method::N4sid,
        u0: Some(vec![1.0, 2.0]),
        input_map: Some(InputMap {
            matrix: DMatrix::from_row_slice(1, 2, &[1.0, 1.0]),
            names: vec!["s".into()],
        }),
        ..fixed()
    };
    let r = identify(&d, &spec).unwrap();
    assert_eq!(r.offsets.u0.as_slice(), &[3.0]);
    assert_eq!(r.input_names, vec!["s".to_string()]);
    assert!(r.pem.is_none() && !r.on_validation_data);
}

#[test]
fn segments_pick_intervals_of_one_experiment() {
    let a = synthetic::simulate(&synthetic::random_model(2, 1, 1, 1, 0.9), 100, 0.1, 1).unwrap();
    let b = synthetic::simulate(&synthetic::random_model(2, 1, 1, 2, 0.9), 100, 0.1, 2).unwrap();
    let d = IoData::merge(&[a.clone(), b.clone()]).unwrap();
    let segs = Segment::parse_list("2@10:19, 1@0:4,50:59").unwrap();
    assert_eq!(segs[0].experiment, Some(1));
    assert_eq!(segs[2].experiment, None);
    let s = select_segments(&d, &segs).unwrap();
    let lens: Vec<usize> = s.experiments().iter().map(|e| e.len()).collect();
    assert_eq!(lens, vec![10, 5, 10, 10]);
    assert_eq!(
        s.experiments()[0].y,
        b.experiments()[0].y.rows(10, 10).into_owned()
    );
    assert_eq!(
        s.experiments()[1].u,
        a.experiments()[0].u.rows(0, 5).into_owned()
    );
    for bad in ["0@1:2", "x@1:2", "1@2:1", "1@1:2:3"] {
        assert!(Segment::parse_list(bad).is_err(), "{bad}");
    }
    let e = select_segments(&d, &Segment::parse_list("3@1:2").unwrap()).unwrap_err();
    assert!(e.to_string().contains("2 experiment(s)"), "{e}");
}
