//! The stationary Kalman step with 16-bit coefficients
//! (kestrel-avr-rt's `Kalman16`, the firmware's estimator): f32 and
//! Q15.16 at the interface, the same Q15.16 arithmetic inside.

use crate::slot::{self, read_array, write_array};
use crate::status::{KestrelStatus, code};
use crate::tables::{Design, KestrelDesign};
use crate::{KESTREL_NU, KESTREL_NX, KESTREL_NY};
use kestrel_avr_rt::kalman16::Kalman16;
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_avr_rt::output::RtScalar;
use kestrel_core::StateEstimator;

/// Words of a Kalman state.
pub const KESTREL_KALMAN16_WORDS: usize = 32;

/// A stationary Kalman filter working in f32 (caller-owned; initialise it
/// with `kestrel_kalman16_init_f32`; any alignment of `uint64_t` will do).
/// It holds a copy of the tables: the design may be discarded after init.
#[repr(C)]
pub struct KestrelKalman16F32 {
    _opaque: [u64; KESTREL_KALMAN16_WORDS],
}

/// A stationary Kalman filter working in Q15.16 (`int32_t` raw bits);
/// see `KestrelKalman16F32`.
#[repr(C)]
pub struct KestrelKalman16Q16 {
    _opaque: [u64; KESTREL_KALMAN16_WORDS],
}

type Filter<S> = Kalman16<S, KESTREL_NX, KESTREL_NU, KESTREL_NY>;

unsafe fn init<S: RtScalar, O>(out: *mut O, design: *const KestrelDesign) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    unsafe {
        slot::init(out, || {
            let d = Design::new(design, None)?;
            Ok(Filter::<S>::new(d.kalman16()?))
        })
    }
}

unsafe fn measure<S: RtScalar, O>(state: *mut O, y: *const S, x: *mut S) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    let r = unsafe {
        slot::get::<Filter<S>, O>(state).and_then(|f| {
            let y: [S; KESTREL_NY] = read_array(y)?;
            f.measurement_update(&y)?;
            write_state(f, x);
            Ok(())
        })
    };
    code(r)
}

unsafe fn predict<S: RtScalar, O>(state: *mut O, u: *const S, x: *mut S) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    let r = unsafe {
        slot::get::<Filter<S>, O>(state).and_then(|f| {
            let u: [S; KESTREL_NU] = read_array(u)?;
            f.time_update(&u)?;
            write_state(f, x);
            Ok(())
        })
    };
    code(r)
}

unsafe fn reset<S: RtScalar, O>(state: *mut O, x0: *const S) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    let r = unsafe {
        slot::get::<Filter<S>, O>(state).and_then(|f| {
            let x0: [S; KESTREL_NX] = read_array(x0)?;
            Ok(f.reset(&x0)?)
        })
    };
    code(r)
}

/// Writes the estimate to `x` (optional).
unsafe fn write_state<S: RtScalar>(f: &Filter<S>, x: *mut S) {
    let mut v = [S::ZERO; KESTREL_NX];
    for (o, e) in v.iter_mut().zip(f.estimate()) {
        *o = *e;
    }
    // SAFETY: the callers' contract on `x`.
    unsafe { write_array(x, &v) };
}

/// Initialises `state` from the design's `kalman16` rows, at the state
/// 0. Checks the design (sizes, checksum) but not its `values_format`.
///
/// Returns `KESTREL_STATUS_NULL_POINTER`, `KESTREL_STATUS_BAD_SIZE`,
/// `KESTREL_STATUS_BAD_CHECKSUM`, `KESTREL_STATUS_BAD_FORMAT` (unknown format code),
/// `KESTREL_STATUS_INVALID_TABLE` (a row shift above 40); the state is then not
/// initialised.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_kalman16_init_f32(
    state: *mut KestrelKalman16F32,
    design: *const KestrelDesign,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { init::<f32, _>(state, design) }
}

/// The measurement update with `y[KESTREL_NY]` (the rates with the gyro
/// bias removed): `x^ = x + M (y - y0 - C x)`; writes the estimate to
/// `x[KESTREL_NX]` unless `x` is NULL. `KESTREL_STATUS_NON_FINITE` for a
/// non-finite `y` (the state is unchanged).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_kalman16_measure_f32(
    state: *mut KestrelKalman16F32,
    y: *const f32,
    x: *mut f32,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { measure::<f32, _>(state, y, x) }
}

/// The time update with the applied input `u[KESTREL_NU]`:
/// `x+ = x^ + (A - I) x^ + B u`; writes the prediction to `x[KESTREL_NX]`
/// unless `x` is NULL.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_kalman16_predict_f32(
    state: *mut KestrelKalman16F32,
    u: *const f32,
    x: *mut f32,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { predict::<f32, _>(state, u, x) }
}

/// Sets the state to `x0[KESTREL_NX]`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_kalman16_reset_f32(
    state: *mut KestrelKalman16F32,
    x0: *const f32,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { reset::<f32, _>(state, x0) }
}

/// `kestrel_kalman16_init_f32` for the Q15.16 filter.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_kalman16_init_q16(
    state: *mut KestrelKalman16Q16,
    design: *const KestrelDesign,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { init::<Q16Mac, _>(state, design) }
}

/// `kestrel_kalman16_measure_f32` in Q15.16 (`int32_t` raw bits).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_kalman16_measure_q16(
    state: *mut KestrelKalman16Q16,
    y: *const i32,
    x: *mut i32,
) -> KestrelStatus {
    // SAFETY: the C contract; Q16Mac is a transparent i32.
    unsafe { measure::<Q16Mac, _>(state, y.cast(), x.cast()) }
}

/// `kestrel_kalman16_predict_f32` in Q15.16 (`int32_t` raw bits).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_kalman16_predict_q16(
    state: *mut KestrelKalman16Q16,
    u: *const i32,
    x: *mut i32,
) -> KestrelStatus {
    // SAFETY: the C contract; Q16Mac is a transparent i32.
    unsafe { predict::<Q16Mac, _>(state, u.cast(), x.cast()) }
}

/// `kestrel_kalman16_reset_f32` in Q15.16 (`int32_t` raw bits).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_kalman16_reset_q16(
    state: *mut KestrelKalman16Q16,
    x0: *const i32,
) -> KestrelStatus {
    // SAFETY: the C contract; Q16Mac is a transparent i32.
    unsafe { reset::<Q16Mac, _>(state, x0.cast()) }
}
