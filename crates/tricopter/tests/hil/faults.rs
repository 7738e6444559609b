//! HIL fault injection: the `hil-faults` firmware build (avr/firmware,
//! feature `hil-faults`: src/faults.rs) flown in simavr against the
//! nonlinear plant, hovering (rate references zero, the hover throttle),
//! with one fault per flight of [`FLIGHT`] periods starting at [`K0`]:
//!
//! - sensor faults change the gyro reading the host sends (stuck at the
//!   reading of period `K0`, NaN, +inf, railed at the full scale);
//! - link faults drop or corrupt bursts of command frames;
//! - actuator faults change what the plant receives (motor 2 at half
//!   thrust, the servo stuck), the firmware sees only their effect;
//! - firmware faults are requested with a fault frame (a hang, which the
//!   watchdog resets; a solver slowed beyond its time budget: in the
//!   fast-gradient builds each iteration takes longer and the solver's
//!   cycle budget stops the iterations early; in the explicit-MPC build
//!   the law's call takes longer, within the period).
//!
//! For each: the replies' pulses within the limits in every period, no
//! missed deadline (`OVERRUN` in a reply or a period over 320,000 cycles),
//! the failsafe engaging and releasing when the specification
//! (`kestrel_avr_rt::output`, `control::GyroCheck`) says, and the peak
//! body rate, attitude change and height lost. `KESTREL_HIL_REPORT=1`
//! prints one `HIL-FAULT {json}` line per flight; the table in
//! docs/avr-rt.md ("HIL fault injection") comes from
//! `cargo test -p kestrel-tricopter --test hil faults -- --nocapture`.

use super::{CYCLES_PER_PERIOD, build_firmware, design, read_frames, wait_boot};
use avr_tester::AvrTester;
use kestrel_avr_rt::frame::{Boot, Command, Frame, FrameDecoder, Kind, MAX_FRAME, Reply, status};
use kestrel_avr_rt::output::{PwmLimits, SafeOutput};
use kestrel_tricopter::closed_loop::{NonlinearPlant, RatePlant};
use kestrel_tricopter_model::{PlantConfig, idx};
use std::path::Path;

/// Periods per flight (3 s).
const FLIGHT: usize = 150;
/// The period the fault starts in (1 s).
const K0: usize = 50;
/// The firmware's gyro full scale (`GyroCheck::default`), rad/s.
const FULL_SCALE: f32 = 34.9;
/// Fault-request op codes (avr/firmware/src/faults.rs).
const HANG: u8 = 1;
const STALL: u8 = 2;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Inject {
    /// No fault (the reference for the aircraft's columns).
    None,
    /// The gyro repeats its reading of period K0 for `len` periods.
    GyroStuck,
    /// Gyro p is NaN for `len` periods.
    GyroNaN,
    /// Gyro r is +inf for `len` periods.
    GyroInf,
    /// Gyro q reads +full scale for `len` periods.
    GyroRailed,
    /// `len` command frames dropped.
    DropBurst,
    /// `len` command frames corrupted (one bit of the payload).
    CorruptBurst,
    /// Motor 2 gives half its thrust from K0 on (its rotor speed, linear
    /// in the pulse above 1000 us, scaled by 1/sqrt(2)).
    MotorHalfThrust,
    /// The servo stays at its pulse of period K0 from K0 on.
    ServoStuck,
    /// The main loop hangs at K0; the watchdog resets the MCU.
    WatchdogReset,
    /// The solve of period K0 takes this many cycles more per iteration
    /// (fast gradient) or in all (explicit MPC); `true`: enough to end
    /// after the next tick without the solver's budget.
    SolverStall(u32, bool),
}

struct Scenario {
    name: &'static str,
    inject: Inject,
    /// Periods the fault lasts (to the end of the flight for actuator faults).
    len: usize,
}

/// What one faulted flight gave.
#[derive(Debug)]
struct Outcome {
    /// Every reply, in order (one per tick the firmware served; a late
    /// reply arrives in the next window).
    replies: Vec<Reply>,
    /// The replies of each 20 ms window.
    windows: Vec<Vec<Reply>>,
    /// Windows in which a boot frame arrived.
    boots: Vec<usize>,
    /// Time of the watchdog reset after the start of window K0 (us,
    /// within 10 us; the watchdog scenario).
    reset_us: Option<u64>,
    /// The servo pulses on the pin from window K0 on: start after the
    /// start of window K0 and width (us; the watchdog scenario).
    servo_pulses: Vec<(u64, u64)>,
    /// Largest |p|, |q|, |r| over the flight from K0 on (rad/s).
    peak_rate: f64,
    /// Largest |roll|, |pitch| change from period K0 on (rad).
    peak_tilt: f64,
    /// Height lost from period K0 to the end of the flight (m).
    height_lost: f64,
}

/// The servo pulses on its pin (OC4A, PH3) from samples of its level
/// (avr-tester 0.6 reaches ports A to H, not the ESCs' port L; the output
/// watchdog, the failsafe and the reset write all four outputs together).
#[derive(Debug, Default)]
struct PulseMeter {
    high_since: Option<u64>,
    /// Every complete pulse: start and width (us).
    pulses: Vec<(u64, u64)>,
}

/// Whether a measured servo pulse is the safe one (within the 10 us steps).
fn is_safe_servo(width_us: u64) -> bool {
    width_us.abs_diff(u64::from(SafeOutput::default().servo)) <= 10
}

impl PulseMeter {
    fn sample(&mut self, avr: &mut AvrTester, t_us: u64) {
        let high = avr.pins().ph3().is_high();
        match (high, self.high_since) {
            (true, None) => self.high_since = Some(t_us),
            (false, Some(t0)) => {
                self.high_since = None;
                self.pulses.push((t0, t_us - t0));
            }
            _ => {}
        }
    }
}

fn fault_frame(op: u8, arg: u32) -> Vec<u8> {
    let mut p = [0u8; 5];
    p[0] = op;
    p[1..].copy_from_slice(&arg.to_le_bytes());
    let mut wire = [0u8; MAX_FRAME];
    let n = Frame::new(Kind::Bench, 0, &p)
        .unwrap()
        .encode(&mut wire)
        .unwrap();
    wire[..n].to_vec()
}

/// Runs `cycles` simulated cycles; returns whether the MCU was reset
/// meanwhile. simavr's reset sets its cycle count back to 0, which
/// avr-simulator 0.6.4's `step` subtracts the count before the instruction
/// from: a wrapped, huge step (overflow checks are off for avr-simulator
/// in the root Cargo.toml, else a panic), counted here as one cycle.
fn run_cycles(avr: &mut AvrTester, cycles: u64) -> bool {
    let (mut left, mut reset) = (cycles, false);
    while left > 0 {
        let mut step = avr.run().as_cycles();
        if step > 1 << 40 {
            reset = true;
            step = 1;
        }
        left = left.saturating_sub(step);
    }
    reset
}

fn fly(elf: &Path, sc: &Scenario) -> Outcome {
    let mut avr = AvrTester::atmega2560().with_clock_of_16_mhz().load(elf);
    let mut dec = FrameDecoder::new();
    wait_boot(&mut avr, &mut dec);
    let mut plant = NonlinearPlant::hovering(PlantConfig::default(), [0.0; 3], 11).unwrap();
    let throttle = design().trim.hover_throttle as f32;
    let in_fault = |k: usize| (K0..K0 + sc.len).contains(&k);
    let mut pwm = SafeOutput::default().pwm(&PwmLimits::default());
    let mut windows = Vec::with_capacity(FLIGHT);
    let mut reset_us = None;
    let mut meter = PulseMeter::default();
    let mut boots = Vec::new();
    let mut stuck = [0.0f32; 3];
    let mut servo_stuck = 1500.0;
    let (mut peak_rate, mut peak_tilt) = (0.0f64, 0.0f64);
    let (mut att0, mut z0) = ([0.0; 2], 0.0);
    for k in 0..FLIGHT {
        let gyro = plant.measure().map(|g| g as f32);
        if k == K0 {
            stuck = gyro;
            let x = plant.0.state();
            att0 = [x[idx::PHI], x[idx::THETA]];
            z0 = x[idx::Z];
        }
        let mut cmd = Command {
            gyro,
            reference: [0.0; 3],
            throttle,
        };
        let on = in_fault(k);
        match sc.inject {
            Inject::GyroStuck if on => cmd.gyro = stuck,
            Inject::GyroNaN if on => cmd.gyro[0] = f32::NAN,
            Inject::GyroInf if on => cmd.gyro[2] = f32::INFINITY,
            Inject::GyroRailed if on => cmd.gyro[1] = FULL_SCALE,
            _ => {}
        }
        let mut wire = [0u8; MAX_FRAME];
        let n = Frame::new(Kind::Command, k as u8, &cmd.to_payload())
            .unwrap()
            .encode(&mut wire)
            .unwrap();
        match sc.inject {
            Inject::DropBurst if on => {}
            Inject::CorruptBurst if on => {
                wire[9] ^= 0x04;
                avr.uart0().write(&wire[..n]);
            }
            _ => avr.uart0().write(&wire[..n]),
        }
        if k == K0 {
            match sc.inject {
                Inject::WatchdogReset => avr.uart0().write(&*fault_frame(HANG, 0)),
                Inject::SolverStall(c, _) => avr.uart0().write(&*fault_frame(STALL, c)),
                _ => {}
            }
        }
        let firmware_fault = matches!(sc.inject, Inject::WatchdogReset | Inject::SolverStall(..));
        if firmware_fault && (K0..K0 + 8).contains(&k) {
            // The servo pulses on its pin, measured in 10 us steps (the
            // outputs while the main loop is hung or late are the
            // hardware's and the output watchdog's, not a reply's).
            for step in 0..2000 {
                if run_cycles(&mut avr, 160) {
                    reset_us.get_or_insert(((k - K0) * 20_000 + step * 10) as u64);
                }
                meter.sample(&mut avr, ((k - K0) * 20_000 + step * 10) as u64);
            }
        } else if sc.inject == Inject::WatchdogReset && k >= K0 {
            run_cycles(&mut avr, CYCLES_PER_PERIOD);
        } else {
            avr.run_for(CYCLES_PER_PERIOD);
        }
        let frames = read_frames(&mut avr, &mut dec);
        if frames.iter().any(|f| Boot::from_frame(f).is_ok()) {
            boots.push(k);
            // From the reset on the outputs are the safe pulses (init_hw).
            pwm = SafeOutput::default().pwm(&PwmLimits::default());
        }
        // The last reply of the window sets the pulses.
        let replies: Vec<Reply> = frames
            .iter()
            .filter_map(|f| Reply::from_frame(f).ok())
            .collect();
        if let Some(r) = replies.last() {
            pwm = r.pwm;
        }
        if firmware_fault && (K0..K0 + 8).contains(&k) {
            // The window's last pulse on the pin: the safe pulses, or the
            // last reply's (held by the hardware while the loop hangs).
            if meter.pulses.last().is_some_and(|&(_, w)| is_safe_servo(w)) {
                pwm = SafeOutput::default().pwm(&PwmLimits::default());
            }
        }
        windows.push(replies);
        if k == K0 {
            servo_stuck = f64::from(pwm[3]);
        }
        let mut applied = pwm.map(f64::from);
        if k >= K0 {
            match sc.inject {
                Inject::MotorHalfThrust => {
                    applied[1] = 1000.0 + (applied[1] - 1000.0).max(0.0) / 2f64.sqrt()
                }
                Inject::ServoStuck => applied[3] = servo_stuck,
                _ => {}
            }
        }
        plant.advance(&applied).unwrap();
        if k >= K0 {
            let x = plant.0.state();
            for i in [idx::P, idx::Q, idx::R] {
                peak_rate = peak_rate.max(x[i].abs());
            }
            peak_tilt = peak_tilt
                .max((x[idx::PHI] - att0[0]).abs())
                .max((x[idx::THETA] - att0[1]).abs());
        }
    }
    let height_lost = plant.0.state()[idx::Z] - z0;
    Outcome {
        replies: windows.concat(),
        windows,
        boots,
        reset_us,
        servo_pulses: meter.pulses,
        peak_rate,
        peak_tilt,
        height_lost,
    }
}

/// The measured row of the fault table.
#[derive(Debug)]
struct Row {
    periods: usize,
    no_reply: usize,
    out_of_range: usize,
    missed: usize,
    /// First failsafe period from K0, in ms after the fault started.
    engaged_ms: Option<usize>,
    /// First period without failsafe after it engaged, in ms after the
    /// fault ended (after the reboot for the watchdog).
    released_ms: Option<usize>,
}

fn row(o: &Outcome, sc: &Scenario) -> Row {
    let limits = PwmLimits::default();
    let mut r = Row {
        periods: o.windows.len(),
        no_reply: o.windows.len().saturating_sub(o.replies.len()),
        out_of_range: 0,
        missed: 0,
        engaged_ms: None,
        released_ms: None,
    };
    let esc = |w: u16| (limits.esc_min..=limits.esc_max).contains(&w);
    for rep in &o.replies {
        let servo = (limits.servo_min..=limits.servo_max).contains(&rep.pwm[3]);
        if !rep.pwm[..3].iter().all(|&w| esc(w)) || !servo {
            r.out_of_range += 1;
        }
        // Each OVERRUN reports one tick that came while the firmware was
        // still busy with the period before.
        if rep.status & status::OVERRUN != 0 {
            r.missed += 1;
        }
    }
    // Failsafe timing by window (the reply a window brought).
    let fs = |w: &Vec<Reply>| w.iter().any(|r| r.status & status::FAILSAFE != 0);
    let end = K0 + sc.len;
    if sc.inject == Inject::WatchdogReset {
        // From the pin: the first safe pulse after the hang (the output
        // watchdog), and the first controlled one after the reset.
        let p = &o.servo_pulses;
        let on = p.iter().position(|&(_, w)| is_safe_servo(w));
        r.engaged_ms = on.map(|i| (p[i].0 / 1000) as usize);
        let back = on.and_then(|i| p[i..].iter().find(|&&(_, w)| !is_safe_servo(w)));
        r.released_ms = back
            .zip(o.reset_us)
            .map(|(&(t, _), reset)| (t.saturating_sub(reset) / 1000) as usize);
        return r;
    }
    let on = (K0..FLIGHT).find(|&k| fs(&o.windows[k]));
    r.engaged_ms = on.map(|k| (k - K0) * 20);
    r.released_ms = on
        .and_then(|k0| (k0..FLIGHT).find(|&k| !o.windows[k].is_empty() && !fs(&o.windows[k])))
        .map(|k| k.saturating_sub(end) * 20);
    r
}

/// The scenarios; the solver stalls are `within` (the solve still ends
/// within its budget) and `past` (without the budget it would end past the
/// next tick) cycles, per iteration in the fast-gradient builds; `past` is
/// not flown in the explicit-MPC build (no iterations to cut: its bounded
/// tree walk cannot overrun by itself).
fn scenarios(within: u32, past: Option<u32>) -> Vec<Scenario> {
    let s = |name, inject, len| Scenario { name, inject, len };
    vec![
        s("none (reference)", Inject::None, 0),
        s("gyro stuck", Inject::GyroStuck, 25),
        s("gyro NaN", Inject::GyroNaN, 5),
        s("gyro +inf", Inject::GyroInf, 5),
        s("gyro railed (+full scale)", Inject::GyroRailed, 25),
        s("5 frames dropped", Inject::DropBurst, 5),
        s("5 frames corrupted", Inject::CorruptBurst, 5),
        s(
            "motor 2 at half thrust",
            Inject::MotorHalfThrust,
            FLIGHT - K0,
        ),
        s("servo stuck", Inject::ServoStuck, FLIGHT - K0),
        s("watchdog reset (main loop hung)", Inject::WatchdogReset, 1),
        s(
            "solver slowed, within its budget",
            Inject::SolverStall(within, false),
            1,
        ),
    ]
    .into_iter()
    .chain(past.map(|c| {
        s(
            "solver slowed past the next tick (budget cuts it)",
            Inject::SolverStall(c, true),
            1,
        )
    }))
    .collect()
}

fn fmt_ms(v: Option<usize>) -> String {
    v.map_or("-".to_string(), |ms| format!("{ms} ms"))
}

/// Flies every scenario with the firmware built with `features`, prints
/// the table and checks the specification; `stalls`: the solver stalls
/// (within the budget, past the next tick) in cycles per iteration (fast
/// gradient) or in all (explicit MPC).
fn check_faults(features: &[&str], label: &str, stalls: (u32, Option<u32>)) {
    let elf = build_firmware(features, false);
    let mut flown = Vec::new();
    println!(
        "| {label}: fault | periods | no reply | pulses out of range | missed deadlines | failsafe engaged (after fault start) | released (after fault end) | peak rate (rad/s) | peak roll/pitch change (deg) | height lost (m) |"
    );
    for sc in scenarios(stalls.0, stalls.1) {
        let o = fly(&elf, &sc);
        let r = row(&o, &sc);
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {:.2} | {:.1} | {:.2} |",
            sc.name,
            r.periods,
            r.no_reply,
            r.out_of_range,
            r.missed,
            fmt_ms(r.engaged_ms),
            fmt_ms(r.released_ms),
            o.peak_rate,
            o.peak_tilt.to_degrees(),
            o.height_lost
        );
        if std::env::var_os("KESTREL_HIL_REPORT").is_some() {
            println!(
                "HIL-FAULT {{\"build\": \"{label}\", \"fault\": \"{}\", \"periods\": {}, \"no_reply\": {}, \"out_of_range\": {}, \"missed\": {}, \"engaged_ms\": {}, \"released_ms\": {}, \"peak_rate\": {:.4}, \"peak_tilt\": {:.4}, \"height_lost\": {:.4}}}",
                sc.name,
                r.periods,
                r.no_reply,
                r.out_of_range,
                r.missed,
                r.engaged_ms.map_or(-1, |v| v as i64),
                r.released_ms.map_or(-1, |v| v as i64),
                o.peak_rate,
                o.peak_tilt,
                o.height_lost
            );
        }
        flown.push((sc, o, r));
    }
    for (sc, o, r) in &flown {
        assert_spec(sc, o, r, label);
    }
}

/// The specified behaviour under each fault.
fn assert_spec(sc: &Scenario, o: &Outcome, r: &Row, label: &str) {
    let safe = SafeOutput::default().pwm(&PwmLimits::default());
    let name = format!("{label} {}", sc.name);
    assert_eq!(r.out_of_range, 0, "{name}: pulses out of range");
    assert_eq!(r.missed, 0, "{name}: missed deadlines");
    // Every tick answered but the hung ones (replies[k] is tick k; a
    // dropped or corrupted frame's period answers the last good command).
    if sc.inject != Inject::WatchdogReset {
        assert_eq!(o.replies.len(), FLIGHT, "{name}: every tick answered");
        let link = matches!(sc.inject, Inject::DropBurst | Inject::CorruptBurst);
        for (k, rep) in o.replies.iter().enumerate() {
            if !link || !(K0..K0 + sc.len).contains(&k) {
                assert_eq!(rep.cmd_seq, k as u8, "{name}: reply {k} late");
            }
        }
    }
    let st = |k: usize| o.replies[k].status;
    let pw = |k: usize| o.replies[k].pwm;
    match sc.inject {
        Inject::GyroStuck | Inject::GyroRailed => {
            // Stuck: the tenth repeat of the reading of K0 engages;
            // railed: at once. Released by the first live reading.
            let engage = if sc.inject == Inject::GyroStuck {
                K0 + 10
            } else {
                K0
            };
            assert_eq!(st(engage - 1), 0, "{name}: flown until the check");
            for k in engage..K0 + sc.len {
                assert_eq!(st(k), status::FAILSAFE, "{name} at {k}");
                assert_eq!(pw(k), safe, "{name}");
            }
            assert_eq!(st(K0 + sc.len), 0, "{name}: released when live");
        }
        Inject::GyroNaN | Inject::GyroInf => {
            for k in K0..K0 + sc.len {
                assert_eq!(st(k), status::FAILSAFE | status::NON_FINITE, "{name}");
                assert_eq!(pw(k), safe, "{name}");
            }
            assert_eq!(st(K0 + sc.len), 0, "{name}: released");
        }
        Inject::DropBurst | Inject::CorruptBurst => {
            assert_eq!(st(K0), status::HOLD, "{name}: one period held");
            assert_eq!(pw(K0), pw(K0 - 1), "{name}: held");
            for k in K0 + 1..K0 + sc.len {
                assert_eq!(st(k), status::FAILSAFE | status::TIMEOUT, "{name} at {k}");
                assert_eq!(pw(k), safe, "{name}");
            }
            assert_eq!(st(K0 + sc.len), 0, "{name}: released");
        }
        Inject::None | Inject::MotorHalfThrust | Inject::ServoStuck => {
            // Not visible to the firmware as a fault: flown on.
            assert!(
                o.replies.iter().all(|r| r.status == 0),
                "{name}: no failsafe"
            );
        }
        Inject::SolverStall(c, past) => {
            let late = o.replies[K0];
            // Fast gradient: the certified count in every other period;
            // the explicit MPC reports its tree walk's nodes.
            let certified = o.replies[K0 - 1].iterations;
            let per_iteration = !label.starts_with("empc");
            let run = u32::from(late.iterations);
            let extra = if per_iteration { c * run } else { c };
            assert!(
                late.solver_cycles >= extra,
                "{name}: the stall was in the solver stage"
            );
            if per_iteration {
                assert!(
                    o.replies
                        .iter()
                        .enumerate()
                        .all(|(k, r)| k == K0 || r.iterations == certified),
                    "{name}: the certified count in the other periods"
                );
                if past {
                    // The budget cut the solve: fewer iterations (at least
                    // one), the period on time.
                    assert!(
                        (1..certified).contains(&late.iterations),
                        "{name}: {} of {certified} iterations",
                        late.iterations
                    );
                } else {
                    assert_eq!(late.iterations, certified, "{name}: not cut");
                }
            }
            // The output watchdog stays quiet: one late period is not two
            // periods without outputs.
            assert!(o.servo_pulses.len() >= 7, "{name}: servo pulses measured");
            assert!(
                o.servo_pulses.iter().all(|&(_, w)| !is_safe_servo(w)),
                "{name}: safe pulses on the pin {:?}",
                o.servo_pulses
            );
            assert!(late.period_cycles < CYCLES_PER_PERIOD as u32, "{name}");
            assert!(o.replies.iter().all(|r| r.status == 0), "{name}");
            if std::env::var_os("KESTREL_HIL_REPORT").is_some() {
                println!(
                    "HIL-FAULT-STALL {{\"build\": \"{label}\", \"fault\": \"{}\", \"iterations\": {}, \"certified\": {certified}, \"solver_cycles\": {}, \"period_cycles\": {}}}",
                    sc.name, late.iterations, late.solver_cycles, late.period_cycles
                );
            }
        }
        Inject::WatchdogReset => {
            // The hang at K0: no reply until the reset (64 ms after the
            // watchdog's last restart, at the end of period K0 - 1), then
            // a boot frame; the outputs are the safe pulses from the reset
            // until a valid command, then every tick is answered.
            assert_eq!(o.boots.len(), 1, "{name}: one reboot");
            let reset = o.reset_us.expect("a watchdog reset") / 1000;
            assert!((40..=80).contains(&reset), "{name}: reset at {reset} ms");
            // The output watchdog: the held pulses through the two periods
            // the loop did not write, then the safe ones (written 15 ms
            // into the second; on the servo pin from the next period, on
            // the ESCs' within 2.5 ms), before the reset.
            let on = r.engaged_ms.expect("safe pulses on the pin");
            assert!(
                on <= 45 && (on as u64) < reset,
                "{name}: safe pulses at {on} ms"
            );
            let b = o.boots[0];
            for k in K0..b {
                assert!(o.windows[k].is_empty(), "{name}: hung at {k}");
            }
            let answered: Vec<&Reply> = o.windows[b..].iter().flatten().collect();
            // One tick per window from the boot's on; the last one's reply
            // may come after the flight (the ticks' new phase).
            assert!(
                (FLIGHT - b - 1..=FLIGHT - b).contains(&answered.len()),
                "{name}: every tick after the boot ({} replies)",
                answered.len()
            );
            let back = answered.iter().position(|r| r.status == 0).unwrap();
            for r in &answered[..back] {
                assert_ne!(r.status & status::FAILSAFE, 0, "{name}");
                assert_eq!(r.pwm, safe, "{name}");
            }
            assert!(answered[back..].iter().all(|r| r.status == 0), "{name}");
            assert!(r.released_ms.unwrap() <= 60, "{name}: released");
        }
    }
}

/// The fast gradient's stalls per iteration: 2,000 cycles more for each
/// of the certified 27 iterations (54k more, the solve still inside the
/// firmware's budget of 240,000 cycles after the tick); 8,000 more
/// (216k more in all: without the budget the period would end about
/// 23 ms after its tick).
const FGM_STALLS: (u32, Option<u32>) = (2_000, Some(8_000));

#[test]
fn hil_faults_f32() {
    check_faults(&["hil-faults"], "f32", FGM_STALLS);
}

#[test]
fn hil_faults_fixed_q16_mac() {
    check_faults(&["fixed-mac", "hil-faults"], "fixed-mac", FGM_STALLS);
}

/// The explicit MPC (about 8,000 solver cycles, a 28,000-cycle period):
/// 200k more still ends inside the period. Its tree walk is bounded by the
/// tree's depth (13 levels; 7,846 cycles at most in flight), so it has no
/// iterations to cut and no overrun of its own: the scenario past the next
/// tick is not flown.
#[test]
fn hil_faults_empc_fixed_q16_mac() {
    check_faults(
        &["empc", "fixed-mac", "hil-faults"],
        "empc fixed-mac",
        (200_000, None),
    );
}

/// The exact MPC by kestrel-qp in f32 (feature `qp`: at most 127k solver
/// cycles at any parameter of the box, 4 active-set changes; 44k in the
/// hover flights): 150k more still ends inside the period. Its iterations
/// are bounded by the solver's cap (16; at the cap the law answers its
/// bounded fallback), so the scenario past the next tick is not flown.
#[test]
fn hil_faults_qp_f32() {
    check_faults(&["qp", "hil-faults"], "qp f32", (150_000, None));
}
