//! The fast gradient solve: the firmware's law (kestrel-avr-rt's
//! `Fgm16Law`: set-up in the loop's scalar, iterations in Q15.16 with
//! 16-bit rows) with a caller-owned state, and kestrel-fgm's reference
//! solver (`FgmTables::solve_with`, everything in the scalar) without one.

use crate::slot::{self, read_array, write_array};
use crate::status::{KestrelStatus, code};
use crate::tables::{Design, KestrelDesign, ValueScalar};
use crate::{KESTREL_FGM_T, KESTREL_NP, KESTREL_NU, KESTREL_NX, KESTREL_NZ};
use kestrel_avr_rt::fgm16::Fgm16Law;
use kestrel_avr_rt::law::LawInfo;
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_fgm::{FgmWorkspace, Start};

/// Words of a fast gradient law's state.
pub const KESTREL_FGM16_WORDS: usize = 90;

/// The firmware's fast gradient law in f32 (caller-owned; initialise it
/// with `kestrel_fgm16_init_f32`). Holds a copy of the tables.
#[repr(C)]
pub struct KestrelFgm16F32 {
    _opaque: [u64; KESTREL_FGM16_WORDS],
}

/// The firmware's fast gradient law in Q15.16; see `KestrelFgm16F32`.
#[repr(C)]
pub struct KestrelFgm16Q16 {
    _opaque: [u64; KESTREL_FGM16_WORDS],
}

/// The law of a design, in `S`.
pub(crate) type Law<S> = Fgm16Law<S, KESTREL_NZ, KESTREL_NP, KESTREL_FGM_T, KESTREL_NU>;

/// [`law`] written into `dst` (its own frame: no copy of the law in its
/// callers' frames).
#[inline(never)]
pub(crate) fn law_into<S: ValueScalar>(
    d: &Design,
    dst: &mut core::mem::MaybeUninit<Law<S>>,
) -> Result<(), KestrelStatus> {
    dst.write(law::<S>(d)?);
    Ok(())
}

/// The fast gradient law of the checked design `d`.
#[inline(always)]
pub(crate) fn law<S: ValueScalar>(d: &Design) -> Result<Law<S>, KestrelStatus> {
    let (m16, betas) = d.fgm16()?;
    Ok(Law::<S>::new(
        d.fgm()?,
        m16,
        betas,
        KESTREL_NX,
        d.warm,
        d.iterations,
    )?)
}

unsafe fn init<S: ValueScalar, O>(out: *mut O, design: *const KestrelDesign) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    unsafe {
        slot::init_with(out, |dst| {
            law_into::<S>(&Design::new(design, Some(S::FORMAT))?, dst)
        })
    }
}

unsafe fn solve<S: ValueScalar, O>(
    state: *mut O,
    theta: *const S,
    z: *mut S,
    iterations: *mut u16,
) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    let r = unsafe {
        slot::get::<Law<S>, O>(state).and_then(|law| {
            let theta: [S; KESTREL_NP] = read_array(theta)?;
            let sol = law.solve(&theta)?;
            write_array(z, &sol);
            if !iterations.is_null() {
                iterations.write(law.iterations());
            }
            Ok(())
        })
    };
    code(r)
}

unsafe fn solve_ref<S: ValueScalar>(
    design: *const KestrelDesign,
    theta: *const S,
    z_warm: *const S,
    z: *mut S,
) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    let r = unsafe {
        Design::new(design, Some(S::FORMAT)).and_then(|d| {
            let t = d.fgm::<S>()?;
            let theta: [S; KESTREL_NP] = read_array(theta)?;
            let warm: Option<[S; KESTREL_NZ]> = if z_warm.is_null() {
                None
            } else {
                Some(read_array(z_warm)?)
            };
            let start = match &warm {
                Some(w) => Start::Warm(w),
                None => Start::Cold,
            };
            let mut ws = FgmWorkspace::new();
            let sol = t.solve_with(&theta, start, usize::from(d.iterations), &mut ws)?;
            if z.is_null() {
                return Err(KestrelStatus::NullPointer);
            }
            write_array(z, &sol);
            Ok(())
        })
    };
    code(r)
}

/// Initialises `law` from the design (`values_format` must be
/// `KESTREL_FORMAT_F32`): kestrel-avr-rt's `Fgm16Law` with the design's
/// iteration count and warm/cold start.
///
/// Returns `KESTREL_STATUS_NULL_POINTER`, `KESTREL_STATUS_BAD_SIZE`,
/// `KESTREL_STATUS_BAD_CHECKSUM`, `KESTREL_STATUS_BAD_FORMAT`, `KESTREL_STATUS_NON_FINITE`
/// (non-finite set-up data) or `KESTREL_STATUS_INVALID_TABLE` (an `M` row not in
/// Q1.15, no iterations); the law is then not initialised.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_fgm16_init_f32(
    law: *mut KestrelFgm16F32,
    design: *const KestrelDesign,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { init::<f32, _>(law, design) }
}

/// Solves the box QP for `theta[KESTREL_NP]` (`[x; p_ref, q_ref, r_ref,
/// throttle]`) and writes the solution `z[KESTREL_NZ]` (the first
/// `KESTREL_NU` are the input moves; `z` may be NULL) and the iterations
/// run (`iterations`, may be NULL). `KESTREL_STATUS_NON_FINITE` for a
/// non-finite theta, `KESTREL_STATUS_INFEASIBLE` for an empty box.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_fgm16_solve_f32(
    law: *mut KestrelFgm16F32,
    theta: *const f32,
    z: *mut f32,
    iterations: *mut u16,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { solve::<f32, _>(law, theta, z, iterations) }
}

/// `kestrel_fgm16_init_f32` for the Q15.16 law (`values_format` must be
/// `KESTREL_FORMAT_Q16`).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_fgm16_init_q16(
    law: *mut KestrelFgm16Q16,
    design: *const KestrelDesign,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { init::<Q16Mac, _>(law, design) }
}

/// `kestrel_fgm16_solve_f32` in Q15.16 (`int32_t` raw bits).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_fgm16_solve_q16(
    law: *mut KestrelFgm16Q16,
    theta: *const i32,
    z: *mut i32,
    iterations: *mut u16,
) -> KestrelStatus {
    // SAFETY: the C contract; Q16Mac is a transparent i32.
    unsafe { solve::<Q16Mac, _>(law, theta.cast(), z.cast(), iterations) }
}

/// kestrel-fgm's solver (`FgmTables::solve_with`, all arithmetic in f32)
/// on the design's set-up data (`values`, format f32) with its iteration
/// count: cold from the box centre, or warm from `z_warm[KESTREL_NZ]`
/// when not NULL. Writes `z[KESTREL_NZ]`. Stateless: reads the tables at
/// every call (the reference the 16-bit law is measured against; about
/// 700 bytes of stack).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_fgm_solve_f32(
    design: *const KestrelDesign,
    theta: *const f32,
    z_warm: *const f32,
    z: *mut f32,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { solve_ref::<f32>(design, theta, z_warm, z) }
}

/// `kestrel_fgm_solve_f32` in Q15.16 (`int32_t` raw bits, format Q16).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_fgm_solve_q16(
    design: *const KestrelDesign,
    theta: *const i32,
    z_warm: *const i32,
    z: *mut i32,
) -> KestrelStatus {
    // SAFETY: the C contract; Q16Mac is a transparent i32.
    unsafe { solve_ref::<Q16Mac>(design, theta.cast(), z_warm.cast(), z.cast()) }
}
