//! One period of the 50 Hz rate loop for C (kestrel-avr-rt's `RateLoop`,
//! exactly as the Rust firmware composes it): gyro sample, reference and
//! throttle in; four pulses out, always within their limits.

use crate::empc;
use crate::fgm;
use crate::slot;
use crate::status::{KestrelStatus, code};
use crate::tables::{Design, KestrelDesign, KestrelEmpc16Tables, ValueScalar};
use crate::{KESTREL_NU, KESTREL_NX, KESTREL_NY};
use core::ffi::c_void;
use kestrel_avr_rt::control::{GyroCheck, Mixer, RateLoop};
use kestrel_avr_rt::cycles::{CycleBudget, CycleClock, Deadline};
use kestrel_avr_rt::fgm16::Fgm16Deadline;
use kestrel_avr_rt::frame::Command;
use kestrel_avr_rt::kalman16::Kalman16;
use kestrel_avr_rt::law::LawInfo;
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_avr_rt::output::{PwmLimits, SafeOutput};
use kestrel_core::{ControlLaw, Error, Matrix};

/// Words of a rate loop's state.
pub const KESTREL_RATE_LOOP_WORDS: usize = 311;

/// The rate loop in f32 (caller-owned; initialise it with
/// `kestrel_rate_loop_init_fgm_f32` or `kestrel_rate_loop_init_empc_f32`).
#[repr(C)]
pub struct KestrelRateLoopF32 {
    _opaque: [u64; KESTREL_RATE_LOOP_WORDS],
}

/// The rate loop in Q15.16; see `KestrelRateLoopF32`.
#[repr(C)]
pub struct KestrelRateLoopQ16 {
    _opaque: [u64; KESTREL_RATE_LOOP_WORDS],
}

/// The loop's limits and failsafe (`kestrel_loop_config_default` fills
/// in the thesis's values, the Rust firmware's).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KestrelLoopConfig {
    /// Lowest ESC pulse, microseconds.
    pub esc_min: u16,
    /// Highest ESC pulse.
    pub esc_max: u16,
    /// Lowest servo pulse.
    pub servo_min: u16,
    /// Highest servo pulse.
    pub servo_max: u16,
    /// The failsafe's ESC pulse (clamped to the limits).
    pub safe_esc: u16,
    /// The failsafe's servo pulse (clamped to the limits).
    pub safe_servo: u16,
    /// The gyro check's full scale, rad/s: a reading at or beyond it is
    /// a sensor fault at once.
    pub gyro_full_scale: f32,
    /// Repeats of a bit-identical reading that make an axis stuck; 0: no
    /// gyro check.
    pub gyro_stuck_periods: u8,
    /// The fast gradient's cycle budget: clock cycles from the start of
    /// the step to the end of the law's last iteration (asked every 4th
    /// iteration, with the step's clock); a solve that would overrun stops
    /// early with its current iterate, inside the input box, and reports
    /// fewer iterations. 0, or no clock: every iteration runs. The Rust
    /// firmware gives 240000 (15 ms at 16 MHz).
    pub fgm_cycle_budget: u32,
}

/// One period's input.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KestrelRateInput {
    /// The gyro sample (p, q, r), rad/s.
    pub gyro: [f32; 3],
    /// The rate references (p, q, r), rad/s.
    pub reference: [f32; 3],
    /// The collective throttle, microseconds.
    pub throttle: f32,
    /// 1: a fresh sample and command this period; 0: none arrived (the
    /// loop holds, then goes to the failsafe; the other fields are
    /// ignored).
    pub fresh: u8,
}

/// One period's output.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct KestrelRateOutput {
    /// ESC 1-3 and the servo, microseconds, within the configured limits
    /// whatever happened (the failsafe's pulses on any fault).
    pub pwm: [u16; 4],
    /// `KESTREL_FLAG_*` bits.
    pub flags: u8,
    /// Law iterations (fast gradient) or tree nodes (explicit law).
    pub iterations: u16,
    /// Cycles of the estimator stage (0 without a clock).
    pub kalman_cycles: u32,
    /// Cycles of the law (0 without a clock).
    pub solver_cycles: u32,
}

/// A cycle counter the loop reads around its stages (optional).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct KestrelClock {
    /// Returns the current count (wrapping); NULL: no timing.
    pub now: Option<unsafe extern "C" fn(ctx: *mut c_void) -> u32>,
    /// Passed to `now`.
    pub ctx: *mut c_void,
}

impl CycleClock for KestrelClock {
    fn now(&self) -> u32 {
        match self.now {
            // SAFETY: the C side's function with its own context.
            Some(f) => unsafe { f(self.ctx) },
            None => 0,
        }
    }
}

/// The fast gradient's deadline for one step: none, or a cycle budget on
/// the step's clock.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Budget {
    /// Every iteration runs.
    Off,
    /// kestrel-avr-rt's budget, asked every 4th iteration (the firmware's).
    On(CycleBudget<KestrelClock, 4>),
}

impl Deadline for Budget {
    const STRIDE: u16 = 4;
    fn expired(&mut self) -> bool {
        match self {
            Budget::Off => false,
            Budget::On(b) => b.expired(),
        }
    }
}

/// The rate loop's law: the fast gradient or the explicit MPC.
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)] // the state is caller-owned, sized for the larger
pub(crate) enum LoopLaw<S: ValueScalar> {
    /// kestrel-avr-rt's `Fgm16Law` with a deadline.
    Fgm(Fgm16Deadline<fgm::Law<S>, Budget>),
    /// kestrel-avr-rt's `Empc16Law`.
    Empc(empc::Law<S>),
}

impl<S: ValueScalar> ControlLaw for LoopLaw<S> {
    type Scalar = S;
    fn nx(&self) -> usize {
        match self {
            LoopLaw::Fgm(l) => l.nx(),
            LoopLaw::Empc(l) => l.nx(),
        }
    }
    fn nr(&self) -> usize {
        match self {
            LoopLaw::Fgm(l) => l.nr(),
            LoopLaw::Empc(l) => l.nr(),
        }
    }
    fn nu(&self) -> usize {
        match self {
            LoopLaw::Fgm(l) => l.nu(),
            LoopLaw::Empc(l) => l.nu(),
        }
    }
    fn control(&mut self, x: &[S], r: &[S], u: &mut [S]) -> Result<(), Error> {
        match self {
            LoopLaw::Fgm(l) => l.control(x, r, u),
            LoopLaw::Empc(l) => l.control(x, r, u),
        }
    }
}

impl<S: ValueScalar> LawInfo for LoopLaw<S> {
    fn iterations(&self) -> u16 {
        match self {
            LoopLaw::Fgm(l) => l.iterations(),
            LoopLaw::Empc(l) => l.iterations(),
        }
    }
    fn restart(&mut self) {
        match self {
            LoopLaw::Fgm(l) => l.restart(),
            LoopLaw::Empc(l) => l.restart(),
        }
    }
}

/// The loop in `S`, with its fast gradient's cycle budget.
pub(crate) struct Loop<S: ValueScalar> {
    /// kestrel-avr-rt's loop.
    pub(crate) inner:
        RateLoop<S, Kalman16<S, KESTREL_NX, KESTREL_NU, KESTREL_NY>, LoopLaw<S>, KESTREL_NU>,
    /// `KestrelLoopConfig.fgm_cycle_budget`.
    pub(crate) budget: u32,
}

/// The loop of the checked design with `law`, as the firmware builds it:
/// identity mixer with the design's offsets, throttle into the ESCs.
pub(crate) fn build<S: ValueScalar>(
    d: &Design,
    law: LoopLaw<S>,
    config: &KestrelLoopConfig,
) -> Result<Loop<S>, KestrelStatus> {
    let limits = PwmLimits {
        esc_min: config.esc_min,
        esc_max: config.esc_max,
        servo_min: config.servo_min,
        servo_max: config.servo_max,
    };
    if limits.esc_min > limits.esc_max || limits.servo_min > limits.servo_max {
        return Err(KestrelStatus::InvalidTable);
    }
    let safe = SafeOutput {
        esc: config.safe_esc,
        servo: config.safe_servo,
    };
    let (offset, bias) = d.mixer_and_bias::<S>()?;
    let one = S::from_f32_fast(1.0);
    let mixer = Mixer::<S, KESTREL_NU> {
        m: Matrix::from_fn(|i, j| if i == j { one } else { S::ZERO }),
        offset,
        throttle_gain: [one, one, one, S::ZERO],
    };
    let filter = Kalman16::new(d.kalman16()?);
    let mut l = RateLoop::new(filter, law, bias, mixer, limits, safe)?;
    let budget = config.fgm_cycle_budget;
    if config.gyro_stuck_periods > 0 {
        if !config.gyro_full_scale.is_finite() || config.gyro_full_scale <= 0.0 {
            return Err(KestrelStatus::InvalidTable);
        }
        l.gyro_check = Some(GyroCheck::new(
            config.gyro_full_scale,
            config.gyro_stuck_periods,
        ));
    }
    Ok(Loop { inner: l, budget })
}

unsafe fn init_fgm<S: ValueScalar, O>(
    out: *mut O,
    design: *const KestrelDesign,
    config: *const KestrelLoopConfig,
) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    unsafe {
        slot::init(out, || {
            let config = config.as_ref().ok_or(KestrelStatus::NullPointer)?;
            let d = Design::new(design, Some(S::FORMAT))?;
            let law = Fgm16Deadline {
                law: fgm::law(&d)?,
                deadline: Budget::Off,
            };
            build::<S>(&d, LoopLaw::Fgm(law), config)
        })
    }
}

unsafe fn init_empc<S: ValueScalar, O>(
    out: *mut O,
    design: *const KestrelDesign,
    tables: *const KestrelEmpc16Tables,
    config: *const KestrelLoopConfig,
) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    unsafe {
        slot::init(out, || {
            let config = config.as_ref().ok_or(KestrelStatus::NullPointer)?;
            let d = Design::new(design, Some(S::FORMAT))?;
            build::<S>(&d, LoopLaw::Empc(empc::law(tables)?), config)
        })
    }
}

unsafe fn step<S: ValueScalar, O>(
    state: *mut O,
    input: *const KestrelRateInput,
    clock: *const KestrelClock,
    out: *mut KestrelRateOutput,
) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    let r = unsafe {
        slot::get::<Loop<S>, O>(state).and_then(|l| {
            let input = input.as_ref().ok_or(KestrelStatus::NullPointer)?;
            if out.is_null() {
                return Err(KestrelStatus::NullPointer);
            }
            let cmd = Command {
                gyro: input.gyro,
                reference: input.reference,
                throttle: input.throttle,
            };
            let fresh = (input.fresh != 0).then_some(&cmd);
            let none = KestrelClock {
                now: None,
                ctx: core::ptr::null_mut(),
            };
            let clock = clock.as_ref().unwrap_or(&none);
            if let LoopLaw::Fgm(f) = &mut l.inner.law {
                f.deadline = match (l.budget, clock.now) {
                    (0, _) | (_, None) => Budget::Off,
                    (b, Some(_)) => Budget::On(CycleBudget::new(*clock, b)),
                };
            }
            let p = l.inner.period(fresh, clock);
            out.write(KestrelRateOutput {
                pwm: p.pwm,
                flags: p.status,
                iterations: p.iterations,
                kalman_cycles: p.kalman_cycles,
                solver_cycles: p.solver_cycles,
            });
            Ok(())
        })
    };
    code(r)
}

/// Fills `config` with the thesis's values (the Rust firmware's): ESC
/// 1000-2000 us, servo 1200-1800 us, failsafe 1000 us (motors stopped)
/// and 1500 us (servo centred), gyro check at 34.9 rad/s (2000 deg/s)
/// with 10 repeats (200 ms at 50 Hz), no cycle budget (set
/// `fgm_cycle_budget` for one). `KESTREL_STATUS_NULL_POINTER` for NULL.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_loop_config_default(
    config: *mut KestrelLoopConfig,
) -> KestrelStatus {
    if config.is_null() {
        return KestrelStatus::NullPointer;
    }
    let limits = PwmLimits::default();
    let safe = SafeOutput::default();
    let check = GyroCheck::default();
    // SAFETY: not NULL, a writable config (the contract).
    unsafe {
        config.write(KestrelLoopConfig {
            esc_min: limits.esc_min,
            esc_max: limits.esc_max,
            servo_min: limits.servo_min,
            servo_max: limits.servo_max,
            safe_esc: safe.esc,
            safe_servo: safe.servo,
            gyro_full_scale: check.full_scale,
            gyro_stuck_periods: check.stuck_periods,
            fgm_cycle_budget: 0,
        })
    };
    KestrelStatus::Ok
}

/// Initialises `rate_loop` with the fast gradient law: the design
/// (`values_format` f32) and the limits in `config`. The loop starts in
/// the failsafe (its pulses) until its first fresh, finite input.
///
/// Returns `KESTREL_STATUS_NULL_POINTER`, `KESTREL_STATUS_BAD_SIZE`,
/// `KESTREL_STATUS_BAD_CHECKSUM`, `KESTREL_STATUS_BAD_FORMAT`, `KESTREL_STATUS_NON_FINITE` or
/// `KESTREL_STATUS_INVALID_TABLE` (also for crossed limits or a gyro check
/// without a positive full scale); the loop is then not initialised.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_rate_loop_init_fgm_f32(
    rate_loop: *mut KestrelRateLoopF32,
    design: *const KestrelDesign,
    config: *const KestrelLoopConfig,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { init_fgm::<f32, _>(rate_loop, design, config) }
}

/// Initialises `rate_loop` with the explicit law of `tables` (which must
/// outlive the loop) and the design's filter, mixer offsets and bias;
/// returns as `kestrel_rate_loop_init_fgm_f32` and
/// `kestrel_empc16_init_f32`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_rate_loop_init_empc_f32(
    rate_loop: *mut KestrelRateLoopF32,
    design: *const KestrelDesign,
    tables: *const KestrelEmpc16Tables,
    config: *const KestrelLoopConfig,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { init_empc::<f32, _>(rate_loop, design, tables, config) }
}

/// One period: failsafe decision (and gyro check), bias removal, Kalman
/// measurement update, the law, Kalman time update, mixer, saturation.
/// The failsafe is active from init until the first fresh, finite
/// input; one period without a fresh input holds the last pulses, two or
/// more give the failsafe's; after a failsafe the first good input
/// restarts the estimator at the state 0 and clears the law's memory.
/// Writes `*out` (the pulses are within the limits whatever the input:
/// a non-finite input or result gives the failsafe's pulses and flags).
/// `clock` may be NULL (no cycle counts). Returns `KESTREL_STATUS_OK`, or
/// `KESTREL_STATUS_NULL_POINTER` / `KESTREL_STATUS_NOT_INITIALISED` without touching
/// `*out`: write the safe pulses yourself then.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_rate_loop_step_f32(
    rate_loop: *mut KestrelRateLoopF32,
    input: *const KestrelRateInput,
    clock: *const KestrelClock,
    out: *mut KestrelRateOutput,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { step::<f32, _>(rate_loop, input, clock, out) }
}

/// `kestrel_rate_loop_init_fgm_f32` in Q15.16 (`values_format` Q16).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_rate_loop_init_fgm_q16(
    rate_loop: *mut KestrelRateLoopQ16,
    design: *const KestrelDesign,
    config: *const KestrelLoopConfig,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { init_fgm::<Q16Mac, _>(rate_loop, design, config) }
}

/// `kestrel_rate_loop_init_empc_f32` in Q15.16 (`values_format` Q16).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_rate_loop_init_empc_q16(
    rate_loop: *mut KestrelRateLoopQ16,
    design: *const KestrelDesign,
    tables: *const KestrelEmpc16Tables,
    config: *const KestrelLoopConfig,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { init_empc::<Q16Mac, _>(rate_loop, design, tables, config) }
}

/// `kestrel_rate_loop_step_f32` for the Q15.16 loop (the same f32
/// input and output: the conversion is the firmware's).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_rate_loop_step_q16(
    rate_loop: *mut KestrelRateLoopQ16,
    input: *const KestrelRateInput,
    clock: *const KestrelClock,
    out: *mut KestrelRateOutput,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { step::<Q16Mac, _>(rate_loop, input, clock, out) }
}
