//! The rate loop through the C functions equals kestrel-avr-rt's
//! `RateLoop` built as the Rust firmware builds it, bit for bit, on
//! random inputs with missing samples, non-finite and railed readings;
//! every pulse within its limits.

use super::equal::{f32_tables, q16_tables};
use super::fixtures::{Owned, Rng, empc_tables, generated as g, generated_empc as ge, ram};
use crate::*;
use core::ffi::c_void;
use kestrel_avr_rt::control::{GyroCheck, LawInfo, Mixer, RateLoop};
use kestrel_avr_rt::cycles::CycleClock;
use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16};
use kestrel_avr_rt::fgm16::Fgm16Law;
use kestrel_avr_rt::frame::Command;
use kestrel_avr_rt::kalman16::Kalman16;
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_avr_rt::output::{PwmLimits, RtScalar, SafeOutput};
use kestrel_core::{ControlLaw, Matrix};

const PERIODS: usize = 10_000;

/// A counter that steps by 7 at every read, from C (through its context).
unsafe extern "C" fn count(ctx: *mut c_void) -> u32 {
    // SAFETY: the context is a live `u32` (the tests' own).
    unsafe {
        let c = ctx.cast::<u32>();
        *c = c.read().wrapping_add(7);
        c.read()
    }
}

/// The same counter for the reference loop.
struct Count(core::cell::Cell<u32>);
impl CycleClock for Count {
    fn now(&self) -> u32 {
        self.0.set(self.0.get().wrapping_add(7));
        self.0.get()
    }
}

/// The firmware's loop around `law` (main.rs).
fn reference<S: RtScalar, L: ControlLaw<Scalar = S> + LawInfo>(
    v: impl Fn(usize) -> S,
    law: L,
) -> RateLoop<S, Kalman16<S, 5, 4, 3>, L, 4> {
    let one = S::from_f32_fast(1.0);
    let mixer = Mixer::<S, 4> {
        m: Matrix::from_fn(|i, j| if i == j { one } else { S::ZERO }),
        offset: core::array::from_fn(|i| v(g::MIX_OFFSET + i)),
        throttle_gain: [one, one, one, S::ZERO],
    };
    let bias = core::array::from_fn(|i| v(g::BIAS + i));
    let filter = Kalman16::<S, 5, 4, 3>::new(g::KF16);
    let mut l = RateLoop::new(
        filter,
        law,
        bias,
        mixer,
        PwmLimits::default(),
        SafeOutput::default(),
    )
    .unwrap();
    l.gyro_check = Some(GyroCheck::default());
    l
}

/// A period's input: mostly fresh, some missing, non-finite, railed or
/// repeated (stuck) readings.
fn input(rng: &mut Rng, last: &KestrelRateInput) -> KestrelRateInput {
    let mut i = KestrelRateInput {
        gyro: [rng.sym(3.0), rng.sym(3.0), rng.sym(3.0)],
        reference: [rng.sym(2.0), rng.sym(2.0), rng.sym(2.0)],
        throttle: 1000.0 + 800.0 * rng.unit(),
        fresh: 1,
    };
    let roll = rng.unit();
    if roll < 0.02 {
        i.fresh = 0;
    } else if roll < 0.025 {
        i.gyro[1] = f32::NAN;
    } else if roll < 0.03 {
        i.gyro[2] = 40.0;
    } else if roll < 0.05 {
        i.gyro = last.gyro;
    } else if roll < 0.055 {
        i.throttle = f32::INFINITY;
    }
    i
}

/// Runs `PERIODS` periods through `step` and the reference, comparing.
fn run<S: RtScalar, L: ControlLaw<Scalar = S> + LawInfo>(
    mut reference: RateLoop<S, Kalman16<S, 5, 4, 3>, L, 4>,
    mut step: impl FnMut(&KestrelRateInput, &KestrelClock, &mut KestrelRateOutput) -> KestrelStatus,
    seed: u64,
) {
    let mut rng = Rng(seed);
    let mut counter = 0u32;
    let ref_clock = Count(core::cell::Cell::new(0));
    let clock = KestrelClock {
        now: Some(count),
        ctx: (&raw mut counter).cast(),
    };
    let mut last = input(
        &mut rng,
        &KestrelRateInput {
            gyro: [0.0; 3],
            reference: [0.0; 3],
            throttle: 0.0,
            fresh: 0,
        },
    );
    let limits = PwmLimits::default();
    let mut failsafes = 0;
    for p in 0..PERIODS {
        let i = input(&mut rng, &last);
        let mut out = KestrelRateOutput::default();
        assert_eq!(step(&i, &clock, &mut out), KestrelStatus::Ok);
        let cmd = Command {
            gyro: i.gyro,
            reference: i.reference,
            throttle: i.throttle,
        };
        let want = reference.period((i.fresh == 1).then_some(&cmd), &ref_clock);
        assert_eq!(out.pwm, want.pwm, "period {p}");
        assert_eq!(out.flags, want.status, "period {p}");
        assert_eq!(out.iterations, want.iterations, "period {p}");
        assert_eq!(
            (out.kalman_cycles, out.solver_cycles),
            (want.kalman_cycles, want.solver_cycles)
        );
        for (k, pw) in out.pwm.iter().enumerate() {
            let (lo, hi) = if k < 3 {
                (limits.esc_min, limits.esc_max)
            } else {
                (limits.servo_min, limits.servo_max)
            };
            assert!((lo..=hi).contains(pw), "period {p}: pulse {k} = {pw}");
        }
        failsafes += usize::from(out.flags & KESTREL_FLAG_FAILSAFE != 0);
        last = i;
    }
    // The faults were exercised, and most periods flew.
    assert!(
        failsafes > PERIODS / 100 && failsafes < PERIODS / 4,
        "{failsafes} failsafe periods"
    );
    assert_eq!(counter, ref_clock.0.get());
}

fn config() -> KestrelLoopConfig {
    let mut c = core::mem::MaybeUninit::uninit();
    // SAFETY: a writable config.
    unsafe {
        assert_eq!(
            kestrel_loop_config_default(c.as_mut_ptr()),
            KestrelStatus::Ok
        );
        c.assume_init()
    }
}

#[test]
fn fast_gradient_loop_equals_the_firmware_loop_f32_and_q16() {
    let k = g::FGM_LOOP_ITERATIONS as u16;
    let owned = Owned::new(KESTREL_FORMAT_F32);
    let d = owned.design();
    let mut l = std::boxed::Box::new(core::mem::MaybeUninit::<KestrelRateLoopF32>::zeroed());
    // SAFETY (all unsafe calls below): valid pointers to live values.
    assert_eq!(
        unsafe { kestrel_rate_loop_init_fgm_f32(l.as_mut_ptr(), &d, &config()) },
        KestrelStatus::Ok
    );
    let law = Fgm16Law::<f32, 4, 9, 1, 4>::new(
        f32_tables(),
        g::FGM16_M,
        g::FGM16_BETAS,
        5,
        g::FGM_WARM,
        k,
    )
    .unwrap();
    run(
        reference(|i| g::VALUES_F32[i], law),
        |i, c, o| unsafe { kestrel_rate_loop_step_f32(l.as_mut_ptr(), i, c, o) },
        1,
    );

    let owned = Owned::new(KESTREL_FORMAT_Q16);
    let d = owned.design();
    let mut l = std::boxed::Box::new(core::mem::MaybeUninit::<KestrelRateLoopQ16>::zeroed());
    assert_eq!(
        unsafe { kestrel_rate_loop_init_fgm_q16(l.as_mut_ptr(), &d, &config()) },
        KestrelStatus::Ok
    );
    let law = Fgm16Law::<Q16Mac, 4, 9, 1, 4>::new(
        q16_tables(),
        g::FGM16_M,
        g::FGM16_BETAS,
        5,
        g::FGM_WARM,
        k,
    )
    .unwrap();
    run(
        reference(|i| Q16Mac::from_bits(g::VALUES_Q16[i]), law),
        |i, c, o| unsafe { kestrel_rate_loop_step_q16(l.as_mut_ptr(), i, c, o) },
        2,
    );
}

#[test]
fn explicit_loop_equals_the_firmware_loop_f32_and_q16() {
    let narrow = [ram(&ge::EMPC16)];
    let t = empc_tables(&narrow, &[&ge::EMPC16], ge::EMPC16_LAYOUT, 0);
    let tree = Tree16::new(&ge::EMPC16[..], ge::EMPC16_LAYOUT).unwrap();

    let owned = Owned::new(KESTREL_FORMAT_F32);
    let d = owned.design();
    let mut l = std::boxed::Box::new(core::mem::MaybeUninit::<KestrelRateLoopEmpcF32>::zeroed());
    // SAFETY (all unsafe calls below): valid pointers to live values.
    assert_eq!(
        unsafe { kestrel_rate_loop_init_empc_f32(l.as_mut_ptr(), &d, &t, &config()) },
        KestrelStatus::Ok
    );
    let law = Empc16Law::<f32, _, 9, 4, { ge::EMPC16_ROWS }>::new(tree, 5).unwrap();
    run(
        reference(|i| g::VALUES_F32[i], law),
        |i, c, o| unsafe { kestrel_rate_loop_step_empc_f32(l.as_mut_ptr(), i, c, o) },
        3,
    );

    let owned = Owned::new(KESTREL_FORMAT_Q16);
    let d = owned.design();
    let mut l = std::boxed::Box::new(core::mem::MaybeUninit::<KestrelRateLoopEmpcQ16>::zeroed());
    assert_eq!(
        unsafe { kestrel_rate_loop_init_empc_q16(l.as_mut_ptr(), &d, &t, &config()) },
        KestrelStatus::Ok
    );
    let law = Empc16Law::<Q16Mac, _, 9, 4, { ge::EMPC16_ROWS }>::new(tree, 5).unwrap();
    run(
        reference(|i| Q16Mac::from_bits(g::VALUES_Q16[i]), law),
        |i, c, o| unsafe { kestrel_rate_loop_step_empc_q16(l.as_mut_ptr(), i, c, o) },
        4,
    );
}

#[test]
fn the_cycle_budget_cuts_the_fast_gradient_short_and_stays_in_limits() {
    let owned = Owned::new(KESTREL_FORMAT_F32);
    let d = owned.design();
    let input = KestrelRateInput {
        gyro: [0.3, -0.2, 0.1],
        reference: [1.0, -1.0, 0.5],
        throttle: 1400.0,
        fresh: 1,
    };
    // Pulses and iterations of a few periods with `budget` on a clock
    // that advances 1000 cycles per read.
    let run = |budget: u32, with_clock: bool| {
        let mut l = std::boxed::Box::new(core::mem::MaybeUninit::<KestrelRateLoopF32>::zeroed());
        let mut cfg = config();
        cfg.fgm_cycle_budget = budget;
        let mut counter = 0u32;
        let clock = KestrelClock {
            now: Some(count_1000),
            ctx: (&raw mut counter).cast(),
        };
        let clock: *const KestrelClock = if with_clock {
            &clock
        } else {
            core::ptr::null()
        };
        // SAFETY: valid pointers to live values.
        unsafe {
            assert_eq!(
                kestrel_rate_loop_init_fgm_f32(l.as_mut_ptr(), &d, &cfg),
                KestrelStatus::Ok
            );
            (0..5)
                .map(|_| {
                    let mut out = KestrelRateOutput::default();
                    assert_eq!(
                        kestrel_rate_loop_step_f32(l.as_mut_ptr(), &input, clock, &mut out),
                        KestrelStatus::Ok
                    );
                    (out.pwm, out.iterations, out.flags)
                })
                .collect::<std::vec::Vec<_>>()
        }
    };
    let full = run(0, true);
    let k = g::FGM_LOOP_ITERATIONS as u16;
    assert!(full.iter().all(|r| r.1 == k && r.2 == 0));
    // A budget never reached, or no clock: the same periods.
    assert_eq!(run(u32::MAX / 2, true), full);
    assert_eq!(run(20_000, false), full);
    // A budget of 5.5 reads (3 of them before the solve): fewer
    // iterations, pulses in the limits.
    for (pwm, it, flags) in run(5_500, true) {
        assert!(it < k && it > 0, "{it} iterations");
        assert_eq!(flags, 0);
        assert!(
            pwm[..3].iter().all(|p| (1000..=2000).contains(p)) && (1200..=1800).contains(&pwm[3])
        );
    }
}

/// A clock that advances 1000 cycles per read.
unsafe extern "C" fn count_1000(ctx: *mut c_void) -> u32 {
    // SAFETY: the context is a live `u32` (the test's own).
    unsafe {
        let c = ctx.cast::<u32>();
        *c = c.read().wrapping_add(1000);
        c.read()
    }
}

#[test]
fn a_copied_loop_state_runs_on_like_the_original() {
    let owned = Owned::new(KESTREL_FORMAT_F32);
    let d = owned.design();
    let mut a = std::boxed::Box::new(core::mem::MaybeUninit::<KestrelRateLoopF32>::zeroed());
    let input = KestrelRateInput {
        gyro: [0.3, -0.2, 0.1],
        reference: [1.0, -1.0, 0.5],
        throttle: 1400.0,
        fresh: 1,
    };
    // SAFETY: valid pointers to live values; the copy is a byte copy of
    // an initialised state (the C caller's memcpy).
    unsafe {
        assert_eq!(
            kestrel_rate_loop_init_fgm_f32(a.as_mut_ptr(), &d, &config()),
            KestrelStatus::Ok
        );
        let mut out = KestrelRateOutput::default();
        for _ in 0..3 {
            kestrel_rate_loop_step_f32(a.as_mut_ptr(), &input, core::ptr::null(), &mut out);
        }
        let mut b = std::boxed::Box::new(core::mem::MaybeUninit::<KestrelRateLoopF32>::uninit());
        core::ptr::copy_nonoverlapping(a.as_ptr(), b.as_mut_ptr(), 1);
        for k in 0..5 {
            let mut oa = KestrelRateOutput::default();
            let mut ob = KestrelRateOutput::default();
            let i = KestrelRateInput {
                gyro: [0.1 * k as f32, 0.2, -0.3],
                ..input
            };
            assert_eq!(
                kestrel_rate_loop_step_f32(a.as_mut_ptr(), &i, core::ptr::null(), &mut oa),
                KestrelStatus::Ok
            );
            assert_eq!(
                kestrel_rate_loop_step_f32(b.as_mut_ptr(), &i, core::ptr::null(), &mut ob),
                KestrelStatus::Ok
            );
            assert_eq!(oa, ob);
            assert!(oa.iterations > 0);
        }
        // The original dropped: the copy runs on its own law.
        *a = core::mem::MaybeUninit::zeroed();
        let mut ob = KestrelRateOutput::default();
        assert_eq!(
            kestrel_rate_loop_step_f32(b.as_mut_ptr(), &input, core::ptr::null(), &mut ob),
            KestrelStatus::Ok
        );
        assert!(ob.iterations > 0);
    }
}
