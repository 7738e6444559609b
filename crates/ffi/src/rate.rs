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
use core::mem::MaybeUninit;
use kestrel_avr_rt::control::{GyroCheck, Mixer, RateLoop};
use kestrel_avr_rt::cycles::{CycleBudget, CycleClock, Deadline};
use kestrel_avr_rt::fgm16::Fgm16Deadline;
use kestrel_avr_rt::frame::Command;
use kestrel_avr_rt::kalman16::Kalman16;
use kestrel_avr_rt::law::LawInfo;
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_avr_rt::output::{PwmLimits, SafeOutput};
use kestrel_core::{ControlLaw, Error, Matrix};

/// Words of the fast gradient rate loop's state (`KestrelRateLoopF32`,
/// `KestrelRateLoopQ16`).
pub const KESTREL_RATE_LOOP_WORDS: usize = 145;

/// Words of the explicit-law rate loop's state (`KestrelRateLoopEmpcF32`,
/// `KestrelRateLoopEmpcQ16`): the law's value cache of
/// `KESTREL_EMPC_CACHE_ROWS` rows is most of it.
pub const KESTREL_RATE_LOOP_EMPC_WORDS: usize = 312;

/// The fast gradient rate loop in f32 (caller-owned; initialise it with
/// `kestrel_rate_loop_init_fgm_f32`, step it with
/// `kestrel_rate_loop_step_f32`).
#[repr(C)]
pub struct KestrelRateLoopF32 {
    _opaque: [u64; KESTREL_RATE_LOOP_WORDS],
}

/// The fast gradient rate loop in Q15.16; see `KestrelRateLoopF32`.
#[repr(C)]
pub struct KestrelRateLoopQ16 {
    _opaque: [u64; KESTREL_RATE_LOOP_WORDS],
}

/// The explicit-law rate loop in f32 (caller-owned; initialise it with
/// `kestrel_rate_loop_init_empc_f32`, step it with
/// `kestrel_rate_loop_step_empc_f32`).
#[repr(C)]
pub struct KestrelRateLoopEmpcF32 {
    _opaque: [u64; KESTREL_RATE_LOOP_EMPC_WORDS],
}

/// The explicit-law rate loop in Q15.16; see `KestrelRateLoopEmpcF32`.
#[repr(C)]
pub struct KestrelRateLoopEmpcQ16 {
    _opaque: [u64; KESTREL_RATE_LOOP_EMPC_WORDS],
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

/// The fast gradient law of the loop, with its deadline.
pub(crate) type FgmLaw<S> = Fgm16Deadline<fgm::Law<S>, Budget>;

/// A law the loop runs: it is told the step's cycle budget.
pub(crate) trait StepLaw: ControlLaw + LawInfo {
    /// Sets the deadline of the coming step (`budget` 0: none).
    fn arm(&mut self, budget: u32, clock: &KestrelClock);
}

impl<S: ValueScalar> StepLaw for FgmLaw<S> {
    fn arm(&mut self, budget: u32, clock: &KestrelClock) {
        self.deadline = match (budget, clock.now) {
            (0, _) | (_, None) => Budget::Off,
            (b, Some(_)) => Budget::On(CycleBudget::new(*clock, b)),
        };
    }
}

impl<S: ValueScalar> StepLaw for empc::Law<S> {
    fn arm(&mut self, _budget: u32, _clock: &KestrelClock) {}
}

/// The loop's handle on its law, which lives beside the `RateLoop` in the
/// state (built there in place, never moved through the stack): a
/// pointer set from the state's own address before every use, so a state
/// copied by the caller stays valid.
pub(crate) struct LawAt<L>(*mut L);

impl<L: StepLaw> ControlLaw for LawAt<L> {
    type Scalar = L::Scalar;
    // SAFETY (every method): the pointer is set from the live state's
    // `law` field just before the loop uses it (`build`, `step`), and no
    // other reference to that field is live meanwhile.
    fn nx(&self) -> usize {
        unsafe { (*self.0).nx() }
    }
    fn nr(&self) -> usize {
        unsafe { (*self.0).nr() }
    }
    fn nu(&self) -> usize {
        unsafe { (*self.0).nu() }
    }
    fn control(
        &mut self,
        x: &[L::Scalar],
        r: &[L::Scalar],
        u: &mut [L::Scalar],
    ) -> Result<(), Error> {
        unsafe { (*self.0).control(x, r, u) }
    }
}

impl<L: StepLaw> LawInfo for LawAt<L> {
    fn iterations(&self) -> u16 {
        // SAFETY: as for `ControlLaw`.
        unsafe { (*self.0).iterations() }
    }
    fn restart(&mut self) {
        // SAFETY: as for `ControlLaw`.
        unsafe { (*self.0).restart() }
    }
}

/// kestrel-avr-rt's loop around the law at a `LawAt`.
pub(crate) type Inner<S, L> =
    RateLoop<S, Kalman16<S, KESTREL_NX, KESTREL_NU, KESTREL_NY>, LawAt<L>, KESTREL_NU>;

/// The loop in `S` with the law `L`, and its fast gradient's cycle budget.
pub(crate) struct Loop<S: ValueScalar, L> {
    /// kestrel-avr-rt's loop, running the law below.
    pub(crate) inner: Inner<S, L>,
    /// The law.
    pub(crate) law: L,
    /// `KestrelLoopConfig.fgm_cycle_budget`.
    pub(crate) budget: u32,
}

/// Writes the fast gradient law of `d` into `dst`.
fn fgm_law<S: ValueScalar>(
    d: &Design,
    dst: &mut MaybeUninit<FgmLaw<S>>,
) -> Result<(), KestrelStatus> {
    let p = dst.as_mut_ptr();
    // SAFETY: fields of the writable `dst`, as `MaybeUninit` (same layout).
    unsafe {
        fgm::law_into::<S>(d, &mut *(&raw mut (*p).law).cast())?;
        (&raw mut (*p).deadline).write(Budget::Off);
    }
    Ok(())
}

/// The loop of the checked design, as the firmware builds it (identity
/// mixer with the design's offsets, throttle into the ESCs), written in
/// place: first the law by `law` into its field (its own frame, gone
/// before the rest), then the small `RateLoop` around it.
#[inline(never)]
fn build<S: ValueScalar, L: StepLaw<Scalar = S>>(
    d: &Design,
    config: &KestrelLoopConfig,
    law: impl FnOnce(&mut MaybeUninit<L>) -> Result<(), KestrelStatus>,
    dst: &mut MaybeUninit<Loop<S, L>>,
) -> Result<(), KestrelStatus> {
    let p = dst.as_mut_ptr();
    // SAFETY: `p` is the caller's writable state; the field pointer is
    // only written through.
    let law_at = unsafe { &raw mut (*p).law };
    // SAFETY: a field of the state, as `MaybeUninit` (same layout).
    law(unsafe { &mut *law_at.cast::<MaybeUninit<L>>() })?;
    // SAFETY: as above, the other fields.
    unsafe {
        rate_loop::<S, L>(d, config, LawAt(law_at), &mut *(&raw mut (*p).inner).cast())?;
        (&raw mut (*p).budget).write(config.fgm_cycle_budget);
    }
    Ok(())
}

/// Writes the `RateLoop` around the law at `law` (written) into `dst`:
/// config checks, mixer, bias and filter, in the order of the firmware.
#[inline(never)]
fn rate_loop<S: ValueScalar, L: StepLaw<Scalar = S>>(
    d: &Design,
    config: &KestrelLoopConfig,
    law: LawAt<L>,
    dst: &mut MaybeUninit<Inner<S, L>>,
) -> Result<(), KestrelStatus> {
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
    if config.gyro_stuck_periods > 0 {
        if !config.gyro_full_scale.is_finite() || config.gyro_full_scale <= 0.0 {
            return Err(KestrelStatus::InvalidTable);
        }
        l.gyro_check = Some(GyroCheck::new(
            config.gyro_full_scale,
            config.gyro_stuck_periods,
        ));
    }
    dst.write(l);
    Ok(())
}

unsafe fn init_fgm<S: ValueScalar, O>(
    out: *mut O,
    design: *const KestrelDesign,
    config: *const KestrelLoopConfig,
) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    unsafe {
        slot::init_with(out, |dst: &mut MaybeUninit<Loop<S, FgmLaw<S>>>| {
            let config = config.as_ref().ok_or(KestrelStatus::NullPointer)?;
            let d = Design::new(design, Some(S::FORMAT))?;
            build(&d, config, |law| fgm_law::<S>(&d, law), dst)
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
        slot::init_with(out, |dst: &mut MaybeUninit<Loop<S, empc::Law<S>>>| {
            let config = config.as_ref().ok_or(KestrelStatus::NullPointer)?;
            let d = Design::new(design, Some(S::FORMAT))?;
            build(&d, config, |law| empc::law_into::<S>(tables, law), dst)
        })
    }
}

unsafe fn step<S: ValueScalar, L: StepLaw<Scalar = S>, O>(
    state: *mut O,
    input: *const KestrelRateInput,
    clock: *const KestrelClock,
    out: *mut KestrelRateOutput,
) -> KestrelStatus {
    // SAFETY: the C contract of the callers.
    let r = unsafe {
        slot::get::<Loop<S, L>, O>(state).and_then(|l| {
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
            l.law.arm(l.budget, clock);
            l.inner.law = LawAt(&raw mut l.law);
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
    rate_loop: *mut KestrelRateLoopEmpcF32,
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
    unsafe { step::<f32, FgmLaw<f32>, _>(rate_loop, input, clock, out) }
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
    rate_loop: *mut KestrelRateLoopEmpcQ16,
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
    unsafe { step::<Q16Mac, FgmLaw<Q16Mac>, _>(rate_loop, input, clock, out) }
}

/// `kestrel_rate_loop_step_f32` for the explicit-law loop (`iterations`:
/// the tree nodes visited).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_rate_loop_step_empc_f32(
    rate_loop: *mut KestrelRateLoopEmpcF32,
    input: *const KestrelRateInput,
    clock: *const KestrelClock,
    out: *mut KestrelRateOutput,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { step::<f32, empc::Law<f32>, _>(rate_loop, input, clock, out) }
}

/// `kestrel_rate_loop_step_empc_f32` for the Q15.16 explicit-law loop.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn kestrel_rate_loop_step_empc_q16(
    rate_loop: *mut KestrelRateLoopEmpcQ16,
    input: *const KestrelRateInput,
    clock: *const KestrelClock,
    out: *mut KestrelRateOutput,
) -> KestrelStatus {
    // SAFETY: the C contract.
    unsafe { step::<Q16Mac, empc::Law<Q16Mac>, _>(rate_loop, input, clock, out) }
}
