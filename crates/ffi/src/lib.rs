#![doc = include_str!("../README.md")]
#![no_std]
// Every exported function takes raw pointers from C and checks them
// itself; they are `unsafe extern "C"` only for the C side's contract.
#![allow(clippy::missing_safety_doc)]

// On hosted targets std provides the panic machinery the staticlib
// needs (no function here panics; see `panic-handler` for no_std targets).
#[cfg(not(any(target_os = "none", target_arch = "avr")))]
extern crate std;

mod bytes;
mod empc;
mod fgm;
mod kalman;
mod rate;
mod slot;
mod status;
mod tables;
#[cfg(test)]
mod tests;

pub use bytes::{KestrelBytes, kestrel_checksum};
pub use empc::{
    KESTREL_EMPC16_WORDS, KestrelEmpc16F32, KestrelEmpc16Q16, kestrel_empc16_eval_f32,
    kestrel_empc16_eval_q16, kestrel_empc16_init_f32, kestrel_empc16_init_q16,
};
pub use fgm::{
    KESTREL_FGM16_WORDS, KestrelFgm16F32, KestrelFgm16Q16, kestrel_fgm_solve_f32,
    kestrel_fgm_solve_q16, kestrel_fgm16_init_f32, kestrel_fgm16_init_q16, kestrel_fgm16_solve_f32,
    kestrel_fgm16_solve_q16,
};
pub use kalman::{
    KESTREL_KALMAN16_WORDS, KestrelKalman16F32, KestrelKalman16Q16, kestrel_kalman16_init_f32,
    kestrel_kalman16_init_q16, kestrel_kalman16_measure_f32, kestrel_kalman16_measure_q16,
    kestrel_kalman16_predict_f32, kestrel_kalman16_predict_q16, kestrel_kalman16_reset_f32,
    kestrel_kalman16_reset_q16,
};
pub use rate::{
    KESTREL_RATE_LOOP_EMPC_WORDS, KESTREL_RATE_LOOP_WORDS, KestrelClock, KestrelLoopConfig,
    KestrelRateInput, KestrelRateLoopEmpcF32, KestrelRateLoopEmpcQ16, KestrelRateLoopF32,
    KestrelRateLoopQ16, KestrelRateOutput, kestrel_loop_config_default,
    kestrel_rate_loop_init_empc_f32, kestrel_rate_loop_init_empc_q16,
    kestrel_rate_loop_init_fgm_f32, kestrel_rate_loop_init_fgm_q16,
    kestrel_rate_loop_step_empc_f32, kestrel_rate_loop_step_empc_q16, kestrel_rate_loop_step_f32,
    kestrel_rate_loop_step_q16,
};
pub use status::{KestrelStatus, status_of};
pub use tables::{KestrelDesign, KestrelEmpc16Tables, KestrelTree16Layout};

/// The version of this C ABI: changes whenever a struct, a function or a
/// table format changes incompatibly. `kestrel_abi_version()` returns it.
pub const KESTREL_ABI_VERSION: u16 = 2;

/// States of the design model (the thesis design; other sizes are
/// `KESTREL_STATUS_BAD_SIZE`).
pub const KESTREL_NX: usize = 5;
/// Inputs: the law's outputs, the Kalman filter's inputs (pwm1-3, servo).
pub const KESTREL_NU: usize = 4;
/// Measured outputs: the three body rates (p, q, r).
pub const KESTREL_NY: usize = 3;
/// Law parameters `theta = [x; p_ref, q_ref, r_ref, throttle]`.
pub const KESTREL_NP: usize = 9;
/// References after the state in `theta`.
pub const KESTREL_NR: usize = KESTREL_NP - KESTREL_NX;
/// Fast gradient decision variables (`N = 2`, `Ns = 1`, four inputs).
pub const KESTREL_NZ: usize = 4;
/// Fast gradient momentum table length.
pub const KESTREL_FGM_T: usize = 1;
/// Values in the design's flat table (`KestrelDesign.values`).
pub const KESTREL_N_VALUES: usize = 152;
/// Bytes of the design's flat table (4 per value).
pub const KESTREL_VALUES_BYTES: usize = 4 * KESTREL_N_VALUES;
/// Bytes of the 16-bit Kalman tables (`KestrelDesign.kalman16`).
pub const KESTREL_KALMAN16_BYTES: usize = 198;
/// Bytes of the fast gradient's 16-bit `M` rows and momentum
/// (`KestrelDesign.fgm16`).
pub const KESTREL_FGM16_BYTES: usize = 42;
/// Rows of the explicit law's value cache: at most this many affine rows
/// in a narrow table; the cache of a wide one.
pub const KESTREL_EMPC_CACHE_ROWS: usize = 256;
/// Pulses: ESC 1-3, then the servo.
pub const KESTREL_N_PWM: usize = 4;

/// `KestrelDesign.values_format`: little-endian IEEE-754 `f32`.
pub const KESTREL_FORMAT_F32: u8 = 0;
/// `KestrelDesign.values_format`: little-endian Q15.16 (`int32_t`
/// raw bits, value = bits / 65536).
pub const KESTREL_FORMAT_Q16: u8 = 1;

/// `KestrelRateOutput.flags`: the failsafe's pulses are out.
pub const KESTREL_FLAG_FAILSAFE: u8 = 1;
/// `KestrelRateOutput.flags`: no fresh input this period, the last
/// pulses are held (first missing period).
pub const KESTREL_FLAG_HOLD: u8 = 2;
/// `KestrelRateOutput.flags`: a non-finite input or result (with
/// `FAILSAFE`).
pub const KESTREL_FLAG_NON_FINITE: u8 = 4;
/// `KestrelRateOutput.flags`: no fresh input for two periods or more
/// (with `FAILSAFE`).
pub const KESTREL_FLAG_TIMEOUT: u8 = 16;

// The flags are the run-time's reply-frame status bits.
const _: () = {
    use kestrel_avr_rt::frame::status;
    assert!(KESTREL_FLAG_FAILSAFE == status::FAILSAFE);
    assert!(KESTREL_FLAG_HOLD == status::HOLD);
    assert!(KESTREL_FLAG_NON_FINITE == status::NON_FINITE);
    assert!(KESTREL_FLAG_TIMEOUT == status::TIMEOUT);
};

/// The ABI version this library was built with (`KESTREL_ABI_VERSION`);
/// compare it with the header's macro at start-up.
#[unsafe(no_mangle)]
pub extern "C" fn kestrel_abi_version() -> u16 {
    KESTREL_ABI_VERSION
}

/// The staticlib's panic handler on no_std targets (feature
/// `panic-handler`): no function of this crate panics (every error is a
/// `KestrelStatus`); this only satisfies the linker, and stops.
#[cfg(all(
    feature = "panic-handler",
    any(target_os = "none", target_arch = "avr")
))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    loop {}
}
