//! The firmware's 16-bit-coefficient kernels against independent f64
//! computations, on the design of the identified model
//! (`models/tricopter-blackbox-5.json`, `FirmwareDesign::from_model`):
//!
//! - `Kalman16` against kestrel-kalman's f64 `StationaryFilter` over a long
//!   log (5000 samples of the model driven by random pulses, with noise);
//! - `Fgm16Law` with the certified iteration count against the exact
//!   optimum of the QP (clarabel, kestrel-fgm's `ReferenceSolver`) over
//!   random parameters: every input within 1 us.

use kestrel_avr_rt::fgm16::Fgm16Law;
use kestrel_avr_rt::kalman16::{Kalman16, Kalman16Tables, Row16};
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_avr_rt::output::RtScalar;
use kestrel_core::StateEstimator;
use kestrel_core::formats::SsModel;
use kestrel_fgm::FgmData;
use kestrel_fgm::reference::ReferenceSolver;
use kestrel_kalman::StationaryFilter;
use kestrel_tricopter::firmware::{DesignSettings, FirmwareDesign};
use nalgebra::DVector;
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

const NX: usize = 5;
const NZ: usize = 4;
const NP: usize = 9;

fn design() -> &'static FirmwareDesign {
    static D: std::sync::OnceLock<FirmwareDesign> = std::sync::OnceLock::new();
    D.get_or_init(|| {
        let model = SsModel::from_json_str(kestrel_tricopter::IDENTIFIED_MODEL_JSON).unwrap();
        FirmwareDesign::from_model(&model, &DesignSettings::default()).unwrap()
    })
}

/// Uniform deviates in `[-1, 1)` from the workspace's seeded generator.
struct Uniform(SplitMix64);
impl Uniform {
    fn new(seed: u64) -> Self {
        Uniform(SplitMix64::seed_from_u64(seed))
    }
    fn next(&mut self) -> f64 {
        2.0 * self.0.random::<f64>() - 1.0
    }
}

fn row<const N: usize>(r: &kestrel_tricopter::firmware::QuantRow, from: usize) -> Row16<N> {
    Row16::new(
        core::array::from_fn(|j| r.c[from + j]),
        r.shift,
        r.start.min(N) as u8,
    )
}

fn kalman16_tables() -> Kalman16Tables<NX, 4, 3> {
    let k = design().kalman16().unwrap();
    Kalman16Tables {
        c: core::array::from_fn(|i| row(&k.c[i], 0)),
        y0: core::array::from_fn(|i| k.y0[i]),
        m: core::array::from_fn(|i| row(&k.m[i], 0)),
        a: core::array::from_fn(|i| row(&k.a[i], 0)),
        b: core::array::from_fn(|i| row(&k.b[i], 0)),
    }
}

#[test]
fn kalman16_follows_the_f64_filter_over_a_long_log() {
    let d = design();
    let t = kalman16_tables();
    t.check().unwrap();
    // Schur coordinates: A - I is upper quasi-triangular, so fewer MACs.
    let macs = t.multiply_adds();
    assert!(macs < 75, "{macs} multiply-adds");
    let mut k16 = Kalman16::<f32, NX, 4, 3>::new(t);
    let mut k64 = StationaryFilter::new(d.gains::<NX>().unwrap(), [0.0; NX]);
    let model = &d.model;
    let mut x = DVector::zeros(NX);
    let mut rng = Uniform::new(7);
    let mut u = [0.0f64; 4];
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    // The estimate's error in rad/s: the estimated rates C x of both filters.
    let mut worst_rate = 0.0f64;
    for k in 0..5000 {
        if k % 25 == 0 {
            // Random pulse moves held for half a second (up to 150 us).
            u = core::array::from_fn(|_| 150.0 * rng.next());
        }
        let uv = DVector::from_column_slice(&u);
        let y = &model.c * &x
            + model.y0.clone().unwrap()
            + DVector::from_fn(3, |_, _| 0.02 * rng.next());
        let y32: Vec<f32> = y.iter().map(|v| *v as f32).collect();
        k16.measurement_update(&y32).unwrap();
        k64.measurement_update(y.as_slice()).unwrap();
        for (a, b) in k16.estimate().iter().zip(k64.estimate()) {
            worst = worst.max((*a as f64 - b).abs());
            scale = scale.max(b.abs());
        }
        let diff = DVector::from_fn(NX, |i, _| k16.estimate()[i] as f64 - k64.estimate()[i]);
        worst_rate = worst_rate.max((&model.c * diff).amax());
        let u32s: Vec<f32> = u.iter().map(|v| *v as f32).collect();
        k16.time_update(&u32s).unwrap();
        k64.time_update(&u).unwrap();
        x = &model.a * &x + &model.b * &uv;
    }
    println!(
        "Kalman16 vs f64 filter over 5000 samples: max |x16 - x64| = {worst:.3e} (largest |x| {scale:.3}); estimated rates max |C (x16 - x64)| = {worst_rate:.3e} rad/s"
    );
    // The stated bound on the estimated rates (README): 5e-3 rad/s (0.3
    // deg/s, below the gyro noise), measured 2.1e-3 on this log.
    assert!(worst_rate < 5e-3, "rate error {worst_rate} rad/s");
    // A few Q15.16 steps of resolution relative to states of order one.
    assert!(scale > 0.1, "the log excites the filter");
    assert!(worst < 2e-3 * scale.max(1.0), "{worst}");
}

fn law<S: RtScalar>(data: &FgmData<S>) -> Fgm16Law<S, NZ, NP, 1, NZ> {
    let d = design();
    let m = d.fgm16_m().unwrap();
    let betas = d.fgm16_betas();
    Fgm16Law::new(
        data.to_tables::<NZ, NP, 1>().unwrap(),
        core::array::from_fn(|i| row(&m[i], 0)),
        [betas[0]],
        NX,
        false,
        d.cert.iterations as u16,
    )
    .unwrap()
}

/// Worst input error (us) against the exact optimum over random parameters.
fn worst_input_error<S: RtScalar>(data: &FgmData<S>, samples: usize) -> f64 {
    let d = design();
    let mut fast = law(data);
    let mut reference = ReferenceSolver::new(&d.qp).unwrap();
    let (lb, ub) = (&d.problem.theta_lb, &d.problem.theta_ub);
    let mut rng = Uniform::new(11);
    let mut worst = 0.0f64;
    let mut solved = 0;
    while solved < samples {
        // Random parameters in a realistic part of the set: states and
        // references within +-3 rad/s-ish, throttle within its range.
        let theta: [f64; NP] = core::array::from_fn(|i| {
            let mid = 0.5 * (lb[i] + ub[i]);
            let half = 0.5 * (ub[i] - lb[i]);
            let span = if i < NP - 1 { half.min(3.0) } else { half };
            mid + span * rng.next()
        });
        let tv = DVector::from_column_slice(&theta);
        let b = d.qp.bounds(&tv);
        if b.lo.iter().zip(b.hi.iter()).any(|(l, h)| l > h) {
            continue;
        }
        let exact = reference.solve(&tv).unwrap();
        let z = fast.solve(&theta.map(S::from_f64)).unwrap();
        for (a, b) in z.iter().zip(exact.z.iter()) {
            worst = worst.max((a.to_f64() - b).abs());
        }
        solved += 1;
    }
    worst
}

#[test]
fn fgm16_meets_the_certified_input_accuracy() {
    let d = design();
    let e64 = worst_input_error(&d.data_f64, 300);
    let e32 = worst_input_error(&d.data_f32, 300);
    let eq16 = worst_input_error(&d.data_q16.clone(), 300);
    let emac = worst_input_error(
        &FgmData::<Q16Mac> {
            n: d.data_q16.n,
            p: d.data_q16.p,
            m: d.data_q16.m.iter().map(|v| Q16Mac(v.0)).collect(),
            k_theta: d.data_q16.k_theta.iter().map(|v| Q16Mac(v.0)).collect(),
            k0: d.data_q16.k0.iter().map(|v| Q16Mac(v.0)).collect(),
            lo_theta: d.data_q16.lo_theta.iter().map(|v| Q16Mac(v.0)).collect(),
            lo0: d.data_q16.lo0.iter().map(|v| Q16Mac(v.0)).collect(),
            hi_theta: d.data_q16.hi_theta.iter().map(|v| Q16Mac(v.0)).collect(),
            hi0: d.data_q16.hi0.iter().map(|v| Q16Mac(v.0)).collect(),
            d: d.data_q16.d.iter().map(|v| Q16Mac(v.0)).collect(),
            d_inv: d.data_q16.d_inv.iter().map(|v| Q16Mac(v.0)).collect(),
            betas: d.data_q16.betas.iter().map(|v| Q16Mac(v.0)).collect(),
            iterations: d.data_q16.iterations,
            warm_iterations: d.data_q16.warm_iterations,
            shift: d.data_q16.shift,
        },
        100,
    );
    println!(
        "Fgm16 ({} certified iterations) worst input error vs the exact optimum: set-up f64 {e64:.3} us, f32 {e32:.3} us, Q16 {eq16:.3} us, Q16Mac {emac:.3} us",
        d.cert.iterations
    );
    for e in [e64, e32, eq16, emac] {
        assert!(e < 1.0, "input error {e} us");
    }
}
