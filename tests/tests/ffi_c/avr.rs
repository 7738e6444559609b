//! The AVR half of the test: `avr/c-example` built by avr-gcc for the
//! ATmega2560 against kestrel-ffi's `avr-none` staticlib (the pinned
//! nightly) and the exported tables in flash, with the fast gradient and
//! with the explicit law, f32 and Q15.16, run in simavr at 16 MHz.
//! Every period's pulses are checked against their limits and against
//! kestrel-avr-rt's rate loop on the host (the same fixed input sequence;
//! equal in every period: pulses, flags and iterations), the
//! bad-table codes from flash are checked, and the cycles per stage
//! (Timer1, as the Rust firmware counts them), flash, RAM and the peak
//! stack (painted) are printed
//! (and one `C-AVR-REPORT {json}` line per build). Skipped when avr-gcc,
//! simavr, avr-size, make or rustup is missing, unless `KESTREL_REQUIRE_AVR`
//! is set (then it fails).

use crate::{
    NoClock, Scalar, empc16_law, fgm16_law, rate_loop_with, repo_root, write_design, write_empc,
};
use kestrel_avr_rt::control::RateLoop;
use kestrel_avr_rt::cycles::CycleStats;
use kestrel_avr_rt::frame::{Command, status};
use kestrel_avr_rt::host::{simavr, tools_present};
use kestrel_avr_rt::kalman16::Kalman16;
use kestrel_avr_rt::law::LawInfo;
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_core::ControlLaw;
use std::path::Path;
use std::process::Command as Process;
use std::time::{Duration, Instant};

/// Periods of the fixed sequence (`PERIODS` in avr/c-example/main.c).
const PERIODS: usize = 300;
/// The reference steps here (`STEP_AT`).
const STEP_AT: usize = 100;

/// The inputs of avr/c-example/main.c, in the same integer arithmetic.
fn inputs() -> Vec<(bool, Command)> {
    let mut seed: u32 = 0x2545_F491;
    let mut rate = [2048i32; 3];
    let step = [1024i32, -1024, 512];
    (0..PERIODS)
        .map(|k| {
            let mut cmd = Command {
                gyro: [0.0; 3],
                reference: [0.0; 3],
                throttle: 1500.0,
            };
            for i in 0..3 {
                let r = if k < STEP_AT { 0 } else { step[i] };
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                let noise = (seed >> 26) as i32 - 32;
                cmd.gyro[i] = (rate[i] + noise) as f32 * (1.0 / 1024.0);
                cmd.reference[i] = r as f32 * (1.0 / 1024.0);
                rate[i] += (r - rate[i]) / 8;
            }
            if k == 250 {
                cmd.gyro[1] = f32::NAN;
            }
            (!matches!(k, 150 | 200 | 201), cmd)
        })
        .collect()
}

/// Builds the example for `law` (`fgm` or `empc`) and `scalar` (`f32` or
/// `q16`); the ELF.
fn build(law: &str, scalar: &str, design: &Path) -> std::path::PathBuf {
    let root = repo_root();
    let out = Process::new("make")
        .arg("-C")
        .arg(root.join("avr/c-example"))
        .arg(format!("SCALAR={scalar}"))
        .arg(format!("LAW={law}"))
        .arg(format!("DESIGN={}", design.display()))
        .output()
        .expect("run make");
    assert!(
        out.status.success(),
        "make -C avr/c-example LAW={law} SCALAR={scalar} failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    root.join(if law == "fgm" {
        format!("avr/target/c-example/kestrel-c-example-{scalar}.elf")
    } else {
        format!("avr/target/c-example/kestrel-c-example-{law}-{scalar}.elf")
    })
}

/// Runs the ELF in simavr (at most 30 s: a crashed program leaves simavr
/// waiting for a debugger); its USART0 lines, and whether it ended.
fn simulate(elf: &Path) -> (Vec<String>, bool) {
    let run = simavr(elf, Duration::from_secs(30)).expect("run simavr");
    (run.lines, run.ended)
}

/// Flash (text + data) and RAM (data + bss) bytes.
fn avr_size(elf: &Path) -> (u64, u64) {
    let size = kestrel_avr_rt::host::avr_size(elf).expect("avr-size");
    (size.flash, size.ram)
}

fn json(s: &CycleStats) -> String {
    format!(
        "{{\"min\": {}, \"mean\": {:.1}, \"max\": {}}}",
        s.min,
        s.mean().unwrap_or(0.0),
        s.max
    )
}

/// One line `P k status pwm1 pwm2 pwm3 servo flags iterations kalman solver step`.
struct Period {
    status: u32,
    pwm: [u16; 4],
    flags: u8,
    iterations: u16,
    cycles: [u32; 3],
}

fn parse_period(l: &str) -> (usize, Period) {
    let v: Vec<u64> = l
        .split_whitespace()
        .skip(1)
        .map(|x| x.parse().unwrap_or_else(|_| panic!("bad line `{l}`")))
        .collect();
    assert_eq!(v.len(), 11, "bad line `{l}`");
    (
        v[0] as usize,
        Period {
            status: v[1] as u32,
            pwm: [v[2] as u16, v[3] as u16, v[4] as u16, v[5] as u16],
            flags: v[6] as u8,
            iterations: v[7] as u16,
            cycles: [v[8] as u32, v[9] as u32, v[10] as u32],
        },
    )
}

/// Flies the build of `law_name` and `scalar` and checks it against
/// `host`, the same loop with `law` on the host.
fn check_scalar<S: Scalar, L: ControlLaw<Scalar = S> + LawInfo>(
    law_name: &str,
    scalar: &str,
    mut host: RateLoop<S, Kalman16<S, { crate::NX }, 4, 3>, L, 4>,
    design: &Path,
    tolerance: u16,
) {
    let elf = build(law_name, scalar, design);
    // The pinned nightly's AVR miscompilations (docs/avr-qp.md) in the
    // ELF's Rust half: kestrel-ffi's exports and every mangled function.
    kestrel_avr_rt::host::assert_no_miscompile(&elf, |f| f.starts_with("kestrel_"));
    let scalar = &format!("{law_name} {scalar}");
    let started = Instant::now();
    let (lines, ended) = simulate(&elf);
    let sim_time = started.elapsed();
    assert!(
        ended,
        "{scalar}: simavr did not end within 30 s (a crash?): {:#?}",
        &lines[lines.len().saturating_sub(8)..]
    );
    let init = lines
        .iter()
        .find(|l| l.starts_with("INIT"))
        .unwrap_or_else(|| panic!("{scalar}: no INIT line in {lines:#?}"));
    assert!(init.starts_with("INIT 0 "), "{scalar}: {init}");
    assert!(
        lines.iter().any(|l| l == "END"),
        "{scalar}: the program did not finish: {:#?}",
        &lines[lines.len().saturating_sub(5)..]
    );
    let periods: Vec<Period> = lines
        .iter()
        .filter(|l| l.starts_with("P "))
        .enumerate()
        .map(|(k, l)| {
            let (i, p) = parse_period(l);
            assert_eq!(i, k, "{scalar}: period numbers");
            p
        })
        .collect();
    assert_eq!(periods.len(), PERIODS, "{scalar}: periods");
    let errors: Vec<&String> = lines.iter().filter(|l| l.starts_with("E ")).collect();
    assert_eq!(errors.len(), 5, "{scalar}: bad-table checks {errors:#?}");
    for e in &errors {
        assert!(e.starts_with("E ok "), "{scalar}: {e}");
    }

    let (mut kal, mut sol, mut step) = (CycleStats::new(), CycleStats::new(), CycleStats::new());
    let mut max_diff = 0u16;
    let mut exact = 0;
    for (k, ((fresh, cmd), p)) in inputs().iter().zip(&periods).enumerate() {
        assert_eq!(p.status, 0, "{scalar}: step status at period {k}");
        for w in &p.pwm[..3] {
            assert!(
                (1000..=2000).contains(w),
                "{scalar}: ESC pulse {w} at period {k}"
            );
        }
        assert!(
            (1200..=1800).contains(&p.pwm[3]),
            "{scalar}: servo pulse {} at period {k}",
            p.pwm[3]
        );
        let h = host.period(fresh.then_some(cmd), &NoClock);
        assert_eq!(p.flags, h.status, "{scalar}: flags at period {k}");
        assert_eq!(
            p.iterations, h.iterations,
            "{scalar}: iterations at period {k}"
        );
        let d = p
            .pwm
            .iter()
            .zip(h.pwm)
            .map(|(a, b)| a.abs_diff(b))
            .max()
            .unwrap();
        max_diff = max_diff.max(d);
        exact += usize::from(d == 0);
        if p.flags & (status::FAILSAFE | status::HOLD) == 0 {
            kal.add(p.cycles[0]);
            sol.add(p.cycles[1]);
            step.add(p.cycles[2]);
        }
    }
    assert!(
        max_diff <= tolerance,
        "{scalar}: pulses differ from the Rust library's by up to {max_diff} us"
    );
    let flag = |k: usize| periods[k].flags;
    assert_eq!(
        flag(150),
        status::HOLD,
        "{scalar}: one missing sample holds"
    );
    assert_ne!(
        flag(201) & status::TIMEOUT,
        0,
        "{scalar}: two missing: failsafe"
    );
    assert_eq!(flag(202), 0, "{scalar}: recovery");
    assert_ne!(flag(250) & status::NON_FINITE, 0, "{scalar}: NaN gyro");
    let (flash, ram) = avr_size(&elf);
    // The peak stack: main.c paints the free RAM at start-up and reports
    // how far down from RAMEND it was written.
    let stack: u64 = lines
        .iter()
        .find_map(|l| l.strip_prefix("STACK "))
        .unwrap_or_else(|| panic!("{scalar}: no STACK line"))
        .parse()
        .expect("STACK bytes");
    assert!(
        ram + stack <= 8192,
        "{scalar}: {ram} B static + {stack} B stack beyond the 8 kB of RAM"
    );
    let m = |s: &CycleStats| format!("{}/{:.0}/{}", s.min, s.mean().unwrap_or(0.0), s.max);
    println!(
        "C on the ATmega2560, {scalar}: kalman {} cycles, solver {} cycles, whole step {} cycles (min/mean/max over {} periods); flash {flash} B, RAM {ram} B (static), peak stack {stack} B; pulses equal to the Rust library's in {exact} of {PERIODS} periods (max difference {max_diff} us); simavr {:.1} s",
        m(&kal),
        m(&sol),
        m(&step),
        step.count,
        sim_time.as_secs_f64()
    );
    println!(
        "C-AVR-REPORT {{\"build\": \"{scalar}\", \"kalman\": {}, \"solver\": {}, \"step\": {}, \"flash\": {flash}, \"ram\": {ram}, \"stack\": {stack}, \"exact_periods\": {exact}, \"max_pwm_diff\": {max_diff}}}",
        json(&kal),
        json(&sol),
        json(&step)
    );
}

#[test]
fn avr_example_in_simavr() {
    // CI (scripts/test.sh installs the tools) sets KESTREL_REQUIRE_AVR=1.
    if !tools_present(
        "avr_example_in_simavr",
        &["avr-gcc", "simavr", "avr-size", "make", "rustup"],
    ) {
        return;
    }
    let design = crate::work_dir("avr-design");
    write_design(&design);
    write_empc(&design);
    check_scalar(
        "fgm",
        "f32",
        rate_loop_with::<f32, _>(fgm16_law()),
        &design,
        0,
    );
    check_scalar(
        "fgm",
        "q16",
        rate_loop_with::<Q16Mac, _>(fgm16_law()),
        &design,
        0,
    );
    check_scalar(
        "empc",
        "f32",
        rate_loop_with::<f32, _>(empc16_law()),
        &design,
        0,
    );
    check_scalar(
        "empc",
        "q16",
        rate_loop_with::<Q16Mac, _>(empc16_law()),
        &design,
        0,
    );
}
