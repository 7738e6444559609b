//! The pieces through the C functions equal the run-time's types bit for
//! bit on random inputs: the Kalman step, the fast gradient (the
//! firmware's 16-bit law and kestrel-fgm's solver), the explicit law in
//! both table layouts; f32 and Q15.16.

use super::fixtures::{
    Owned, Rng, empc_tables, generated as g, generated_empc as ge, generated_empc_ns2 as gn,
    ns2_chunks, ram,
};
use crate::*;
use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16};
use kestrel_avr_rt::fgm16::Fgm16Law;
use kestrel_avr_rt::kalman16::Kalman16;
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_core::{ControlLaw, Matrix, StateEstimator};
use kestrel_fgm::{FgmTables, FgmWorkspace, Start};
use std::vec::Vec;

const SAMPLES: usize = 10_000;

/// The firmware's reading of its flat table (`vm`, `va` in main.rs).
pub(super) fn fgm_tables<S: Copy + kestrel_core::Scalar>(
    v: impl Fn(usize) -> S,
) -> FgmTables<S, 4, 9, 1> {
    let m = |at: usize| Matrix::from_fn(|i, j| v(at + 9 * i + j));
    let a = |at: usize| core::array::from_fn(|i| v(at + i));
    FgmTables {
        m: Matrix::from_fn(|i, j| v(g::FGM_M + 4 * i + j)),
        k_theta: m(g::FGM_K),
        k0: a(g::FGM_K0),
        lo_theta: m(g::FGM_LO),
        lo0: a(g::FGM_LO0),
        hi_theta: m(g::FGM_HI),
        hi0: a(g::FGM_HI0),
        d: a(g::FGM_D),
        d_inv: a(g::FGM_DINV),
        betas: [v(g::FGM_BETAS)],
        iterations: g::FGM_ITERATIONS,
        warm_iterations: g::FGM_ITERATIONS,
        shift: 0,
    }
}

pub(super) fn f32_tables() -> FgmTables<f32, 4, 9, 1> {
    fgm_tables(|i| g::VALUES_F32[i])
}

pub(super) fn q16_tables() -> FgmTables<Q16Mac, 4, 9, 1> {
    fgm_tables(|i| Q16Mac::from_bits(g::VALUES_Q16[i]))
}

/// A random parameter `theta = [x; p_ref, q_ref, r_ref, throttle]`.
pub(super) fn theta(rng: &mut Rng) -> [f32; 9] {
    let mut t = [0.0; 9];
    for v in t.iter_mut().take(5) {
        *v = rng.sym(2.0);
    }
    for v in t.iter_mut().skip(5).take(3) {
        *v = rng.sym(3.0);
    }
    t[8] = 1000.0 + 800.0 * rng.unit();
    t
}

fn q(v: &[f32]) -> Vec<Q16Mac> {
    v.iter()
        .map(|x| <Q16Mac as kestrel_avr_rt::output::RtScalar>::from_f32_fast(*x))
        .collect()
}

fn bits(v: &[Q16Mac]) -> Vec<i32> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn kalman_step_equals_kalman16() {
    let owned = Owned::new(KESTREL_FORMAT_F32);
    let d = owned.design();
    let mut kf = core::mem::MaybeUninit::<KestrelKalman16F32>::zeroed();
    let mut kq = core::mem::MaybeUninit::<KestrelKalman16Q16>::zeroed();
    // SAFETY (all unsafe calls below): valid pointers to live locals.
    unsafe {
        assert_eq!(
            kestrel_kalman16_init_f32(kf.as_mut_ptr(), &d),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_kalman16_init_q16(kq.as_mut_ptr(), &d),
            KestrelStatus::Ok
        );
    }
    let mut rf = Kalman16::<f32, 5, 4, 3>::new(g::KF16);
    let mut rq = Kalman16::<Q16Mac, 5, 4, 3>::new(g::KF16);
    let mut rng = Rng(0x1234_5678);
    for _ in 0..SAMPLES {
        let y = [rng.sym(3.0), rng.sym(3.0), rng.sym(3.0)];
        let u = [
            rng.sym(300.0),
            rng.sym(300.0),
            rng.sym(300.0),
            rng.sym(300.0),
        ];
        let (mut xf, mut xq) = ([0f32; 5], [0i32; 5]);
        unsafe {
            assert_eq!(
                kestrel_kalman16_measure_f32(kf.as_mut_ptr(), y.as_ptr(), xf.as_mut_ptr()),
                KestrelStatus::Ok
            );
            rf.measurement_update(&y).unwrap();
            assert_eq!(
                xf.map(f32::to_bits),
                core::array::from_fn(|i| rf.estimate()[i].to_bits())
            );
            let (yq, uq) = (q(&y), q(&u));
            assert_eq!(
                kestrel_kalman16_measure_q16(kq.as_mut_ptr(), bits(&yq).as_ptr(), xq.as_mut_ptr()),
                KestrelStatus::Ok
            );
            rq.measurement_update(&yq).unwrap();
            assert_eq!(&xq[..], &bits(rq.estimate())[..]);
            assert_eq!(
                kestrel_kalman16_predict_f32(kf.as_mut_ptr(), u.as_ptr(), xf.as_mut_ptr()),
                KestrelStatus::Ok
            );
            rf.time_update(&u).unwrap();
            assert_eq!(
                xf.map(f32::to_bits),
                core::array::from_fn(|i| rf.estimate()[i].to_bits())
            );
            assert_eq!(
                kestrel_kalman16_predict_q16(kq.as_mut_ptr(), bits(&uq).as_ptr(), xq.as_mut_ptr()),
                KestrelStatus::Ok
            );
            rq.time_update(&uq).unwrap();
            assert_eq!(&xq[..], &bits(rq.estimate())[..]);
        }
    }
    // A reset is the run-time's reset.
    let x0 = [0.5f32, -0.25, 0.0, 1.0, 2.0];
    let mut x = [0f32; 5];
    unsafe {
        assert_eq!(
            kestrel_kalman16_reset_f32(kf.as_mut_ptr(), x0.as_ptr()),
            KestrelStatus::Ok
        );
        rf.reset(&x0).unwrap();
        let y = [0.1f32, 0.2, 0.3];
        assert_eq!(
            kestrel_kalman16_measure_f32(kf.as_mut_ptr(), y.as_ptr(), x.as_mut_ptr()),
            KestrelStatus::Ok
        );
        rf.measurement_update(&y).unwrap();
        assert_eq!(&x[..], rf.estimate());
    }
}

#[test]
fn fast_gradient_equals_fgm16_law_and_kestrel_fgm() {
    let (of, oq) = (
        Owned::new(KESTREL_FORMAT_F32),
        Owned::new(KESTREL_FORMAT_Q16),
    );
    let (df, dq) = (of.design(), oq.design());
    let mut lf = core::mem::MaybeUninit::<KestrelFgm16F32>::zeroed();
    let mut lq = core::mem::MaybeUninit::<KestrelFgm16Q16>::zeroed();
    unsafe {
        assert_eq!(
            kestrel_fgm16_init_f32(lf.as_mut_ptr(), &df),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_fgm16_init_q16(lq.as_mut_ptr(), &dq),
            KestrelStatus::Ok
        );
    }
    let k = g::FGM_LOOP_ITERATIONS as u16;
    let (tf, tq) = (f32_tables(), q16_tables());
    let mut rf =
        Fgm16Law::<f32, 4, 9, 1, 4>::new(tf, g::FGM16_M, g::FGM16_BETAS, 5, g::FGM_WARM, k)
            .unwrap();
    let mut rq =
        Fgm16Law::<Q16Mac, 4, 9, 1, 4>::new(tq, g::FGM16_M, g::FGM16_BETAS, 5, g::FGM_WARM, k)
            .unwrap();
    let (mut wf, mut wq) = (FgmWorkspace::new(), FgmWorkspace::new());
    let mut rng = Rng(0xdead_beef);
    for s in 0..SAMPLES {
        let t = theta(&mut rng);
        let tq16: [Q16Mac; 9] = q(&t).try_into().unwrap();
        let tb = bits(&tq16);
        let (mut z, mut zq, mut it) = ([0f32; 4], [0i32; 4], 0u16);
        unsafe {
            assert_eq!(
                kestrel_fgm16_solve_f32(lf.as_mut_ptr(), t.as_ptr(), z.as_mut_ptr(), &mut it),
                KestrelStatus::Ok
            );
            assert_eq!(
                z.map(f32::to_bits),
                rf.solve(&t).unwrap().map(f32::to_bits),
                "sample {s}"
            );
            assert_eq!(it, k);
            assert_eq!(
                kestrel_fgm16_solve_q16(lq.as_mut_ptr(), tb.as_ptr(), zq.as_mut_ptr(), &mut it),
                KestrelStatus::Ok
            );
            assert_eq!(&zq[..], &bits(&rq.solve(&tq16).unwrap())[..]);
            // kestrel-fgm's solver, cold and warm from the last solution.
            let warm = if s % 2 == 0 {
                core::ptr::null()
            } else {
                z.as_ptr()
            };
            let mut z2 = [0f32; 4];
            assert_eq!(
                kestrel_fgm_solve_f32(&df, t.as_ptr(), warm, z2.as_mut_ptr()),
                KestrelStatus::Ok
            );
            let start = if s % 2 == 0 {
                Start::Cold
            } else {
                Start::Warm(&z)
            };
            let want = tf.solve_with(&t, start, usize::from(k), &mut wf).unwrap();
            assert_eq!(z2.map(f32::to_bits), want.map(f32::to_bits));
            let mut zq2 = [0i32; 4];
            assert_eq!(
                kestrel_fgm_solve_q16(&dq, tb.as_ptr(), core::ptr::null(), zq2.as_mut_ptr()),
                KestrelStatus::Ok
            );
            let want = tq
                .solve_with(&tq16, Start::Cold, usize::from(k), &mut wq)
                .unwrap();
            assert_eq!(&zq2[..], &bits(&want)[..]);
        }
    }
}

#[test]
fn explicit_law_equals_empc16_law_in_both_layouts() {
    // Narrow (Ns = 1): one table.
    let narrow = [ram(&ge::EMPC16)];
    let tn = empc_tables(&narrow, &[&ge::EMPC16], ge::EMPC16_LAYOUT, 0);
    // Wide (Ns = 2): 25 chunks of 4 kB.
    let chunks = ns2_chunks();
    let wide: Vec<KestrelBytes> = chunks.iter().map(|c| ram(c)).collect();
    let tw = empc_tables(&wide, &chunks, gn::EMPC_NS2_LAYOUT, gn::EMPC_NS2_CHUNK_BITS);
    let mut nf = core::mem::MaybeUninit::<KestrelEmpc16F32>::zeroed();
    let mut nq = core::mem::MaybeUninit::<KestrelEmpc16Q16>::zeroed();
    let mut wf = core::mem::MaybeUninit::<KestrelEmpc16F32>::zeroed();
    unsafe {
        assert_eq!(
            kestrel_empc16_init_f32(nf.as_mut_ptr(), &tn),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_empc16_init_q16(nq.as_mut_ptr(), &tn),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_empc16_init_f32(wf.as_mut_ptr(), &tw),
            KestrelStatus::Ok
        );
    }
    let tree = Tree16::new(&ge::EMPC16[..], ge::EMPC16_LAYOUT).unwrap();
    let mut rnf = Empc16Law::<f32, _, 9, 4, { ge::EMPC16_ROWS }>::new(tree, 5).unwrap();
    let mut rnq = Empc16Law::<Q16Mac, _, 9, 4, { ge::EMPC16_ROWS }>::new(tree, 5).unwrap();
    let ns2 = gn::empc_ns2_table().unwrap();
    let mut rwf =
        Empc16Law::<f32, _, 9, 4, 64>::new(Tree16::new(ns2, gn::EMPC_NS2_LAYOUT).unwrap(), 5)
            .unwrap();
    let mut rng = Rng(0x5eed);
    for s in 0..SAMPLES {
        let t = theta(&mut rng);
        let (x, r) = t.split_at(5);
        let (mut u, mut nodes) = ([0f32; 4], 0u16);
        let mut want = [0f32; 4];
        unsafe {
            assert_eq!(
                kestrel_empc16_eval_f32(
                    nf.as_mut_ptr(),
                    x.as_ptr(),
                    r.as_ptr(),
                    u.as_mut_ptr(),
                    &mut nodes
                ),
                KestrelStatus::Ok
            );
            rnf.control(x, r, &mut want).unwrap();
            assert_eq!(
                u.map(f32::to_bits),
                want.map(f32::to_bits),
                "narrow f32, sample {s}"
            );
            assert_eq!(nodes, kestrel_avr_rt::law::LawInfo::iterations(&rnf));
            let tq = q(&t);
            let tb = bits(&tq);
            let mut uq = [0i32; 4];
            let mut wq = [Q16Mac::from_bits(0); 4];
            assert_eq!(
                kestrel_empc16_eval_q16(
                    nq.as_mut_ptr(),
                    tb.as_ptr(),
                    tb[5..].as_ptr(),
                    uq.as_mut_ptr(),
                    core::ptr::null_mut()
                ),
                KestrelStatus::Ok
            );
            rnq.control(&tq[..5], &tq[5..], &mut wq).unwrap();
            assert_eq!(&uq[..], &bits(&wq)[..], "narrow q16, sample {s}");
            assert_eq!(
                kestrel_empc16_eval_f32(
                    wf.as_mut_ptr(),
                    x.as_ptr(),
                    r.as_ptr(),
                    u.as_mut_ptr(),
                    &mut nodes
                ),
                KestrelStatus::Ok
            );
            rwf.control(x, r, &mut want).unwrap();
            assert_eq!(
                u.map(f32::to_bits),
                want.map(f32::to_bits),
                "wide f32, sample {s}"
            );
        }
    }
}
