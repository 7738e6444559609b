//! Host-side tools for firmware built on this crate (feature `std`): the
//! pinned AVR nightly's `cargo build` for a crate under `avr/`, a run of an
//! ELF in simavr (ATmega2560 at 16 MHz) with its USART0 lines, the flash
//! and RAM sizes `avr-size` reports, which of the tools are installed, and
//! a scan of an ELF for the pinned nightly's two known miscompilations
//! ([`miscompile_scan`], [`assert_no_miscompile`]) and for panic paths,
//! calls into core's panic functions ([`panic_calls`],
//! [`assert_no_panic_path`]). The hardware-in-the-loop tests of the
//! workspace use them.
//!
//! ```no_run
//! use kestrel_avr_rt::host::{avr_cargo_build, avr_size, missing_tools, simavr};
//! use std::path::Path;
//! use std::time::Duration;
//!
//! let root = Path::new(".");
//! assert!(missing_tools(&["simavr", "avr-size", "rustup"]).is_empty());
//! let status = avr_cargo_build(root).current_dir(root.join("avr/firmware")).status().unwrap();
//! assert!(status.success());
//! let elf = root.join("avr/target/avr-none/release/kestrel-avr-firmware.elf");
//! let run = simavr(&elf, Duration::from_secs(30)).unwrap();
//! println!("{} lines, ended: {}, flash {} B", run.lines.len(), run.ended, avr_size(&elf).unwrap().flash);
//! ```

mod miscompile;
mod panics;

pub use miscompile::{
    MiscompileBug, MiscompileHit, assert_no_miscompile, miscompile_scan, scan_disassembly,
};
pub use panics::{
    PanicCall, assert_no_panic_path, is_panic_function, panic_calls, scan_panic_calls,
};
use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Environment variables of a host `cargo` that would leak into the AVR
/// build (another toolchain, target directory, target or flags).
const CARGO_ENV: [&str; 9] = [
    "RUSTUP_TOOLCHAIN",
    "CARGO_TARGET_DIR",
    "CARGO_BUILD_TARGET",
    "RUSTC",
    "RUSTDOC",
    "RUSTC_WRAPPER",
    "RUSTFLAGS",
    "CARGO_ENCODED_RUSTFLAGS",
    "CARGO",
];

/// The pinned nightly's channel from `avr/rust-toolchain.toml` under the
/// workspace `root`.
pub fn avr_channel(root: &Path) -> std::io::Result<String> {
    let toml = std::fs::read_to_string(root.join("avr/rust-toolchain.toml"))?;
    toml.lines()
        .find_map(|l| l.trim().strip_prefix("channel"))
        .and_then(|l| l.split('"').nth(1))
        .map(str::to_string)
        .ok_or_else(|| {
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                "no channel = \"...\" in avr/rust-toolchain.toml",
            )
        })
}

/// `rustup run <pinned nightly> cargo build --release --quiet`, with the
/// calling cargo's environment removed; set its `current_dir` to the AVR
/// crate and add features, `--target-dir` or `RUSTFLAGS` as needed.
/// Without a readable `avr/rust-toolchain.toml` the command names the
/// channel `missing-avr-toolchain`, so running it fails with that name.
pub fn avr_cargo_build(root: &Path) -> Command {
    let channel = avr_channel(root).unwrap_or_else(|_| "missing-avr-toolchain".into());
    let mut cmd = Command::new("rustup");
    cmd.args(["run", &channel, "cargo", "build", "--release", "--quiet"]);
    for var in CARGO_ENV {
        cmd.env_remove(var);
    }
    cmd
}

/// What simavr printed of a run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SimavrRun {
    /// The USART0 lines (simavr's colour escapes and trailing `.`
    /// removed, empty lines dropped), stdout then stderr.
    pub lines: Vec<String>,
    /// False when the run was stopped at the time limit (a crashed program
    /// leaves simavr waiting for a debugger).
    pub ended: bool,
}

/// Runs `elf` in simavr (`-m atmega2560 -f 16000000`) for at most `limit`.
pub fn simavr(elf: &Path, limit: Duration) -> std::io::Result<SimavrRun> {
    let mut child = Command::new("simavr")
        .args(["-m", "atmega2560", "-f", "16000000"])
        .arg(elf)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()?;
    let read = |r: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut s = String::new();
            if let Some(mut r) = r {
                let _ = r.read_to_string(&mut s);
            }
            s
        })
    };
    let out = read(
        child
            .stdout
            .take()
            .map(|s| Box::new(s) as Box<dyn Read + Send>),
    );
    let err = read(
        child
            .stderr
            .take()
            .map(|s| Box::new(s) as Box<dyn Read + Send>),
    );
    let start = Instant::now();
    let mut ended = true;
    while child.try_wait()?.is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            ended = false;
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let text = out.join().unwrap_or_default() + &err.join().unwrap_or_default();
    Ok(SimavrRun {
        lines: uart_lines(&text),
        ended,
    })
}

/// simavr's UART output as lines: each wrapped in colour escapes and
/// ended with a `.`, both removed; empty lines dropped.
pub fn uart_lines(text: &str) -> Vec<String> {
    text.lines()
        .map(|l| {
            let mut s = String::new();
            let mut esc = false;
            for c in l.chars() {
                match (esc, c) {
                    (false, '\x1b') => esc = true,
                    (true, 'm') => esc = false,
                    (true, _) => {}
                    (false, c) => s.push(c),
                }
            }
            s.trim().trim_end_matches('.').to_string()
        })
        .filter(|l| !l.is_empty())
        .collect()
}

/// Memory use of an ELF as `avr-size` reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AvrSize {
    /// Program memory: text + data bytes.
    pub flash: u64,
    /// Static RAM: data + bss bytes.
    pub ram: u64,
}

/// Runs `avr-size` on `elf`.
pub fn avr_size(elf: &Path) -> std::io::Result<AvrSize> {
    let out = Command::new("avr-size").arg(elf).output()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let f: Vec<u64> = text
        .lines()
        .nth(1)
        .unwrap_or("")
        .split_whitespace()
        .take(3)
        .filter_map(|v| v.parse().ok())
        .collect();
    match f[..] {
        [text, data, bss] => Ok(AvrSize {
            flash: text + data,
            ram: data + bss,
        }),
        _ => Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("avr-size {}: unexpected output {text:?}", elf.display()),
        )),
    }
}

/// The tools of `tools` that do not run here (each tried with
/// `--version`, simavr with `--help`).
pub fn missing_tools<'a>(tools: &[&'a str]) -> Vec<&'a str> {
    tools
        .iter()
        .copied()
        .filter(|t| {
            let arg = if *t == "simavr" {
                "--help"
            } else {
                "--version"
            };
            Command::new(t)
                .arg(arg)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .status()
                .is_err()
        })
        .collect()
}

/// Whether every tool of `tools` runs here, for a test named `test` that
/// needs them: a missing tool skips the test (printing which) unless
/// `KESTREL_REQUIRE_AVR` is set, as in CI, where it fails the test.
///
/// # Panics
/// When a tool is missing and `KESTREL_REQUIRE_AVR` is set.
pub fn tools_present(test: &str, tools: &[&str]) -> bool {
    let missing = missing_tools(tools);
    if missing.is_empty() {
        return true;
    }
    assert!(
        std::env::var_os("KESTREL_REQUIRE_AVR").is_none(),
        "KESTREL_REQUIRE_AVR is set but {missing:?} not installed"
    );
    println!("{test} skipped: {missing:?} not installed");
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uart_lines_drop_escapes_dots_and_blank_lines() {
        let text = "\x1b[32mLOOP 1 2.\x1b[0m\n\n  \x1b[32mREPORT {\"a\": 1}.\x1b[0m  \n";
        assert_eq!(uart_lines(text), ["LOOP 1 2", "REPORT {\"a\": 1}"]);
    }

    #[test]
    fn the_pinned_channel_is_read_and_a_missing_file_is_an_error() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let channel = avr_channel(&root).unwrap();
        assert!(channel.starts_with("nightly"), "{channel}");
        assert!(avr_channel(Path::new("/nonexistent")).is_err());
        assert_eq!(
            missing_tools(&["kestrel-no-such-tool"]),
            ["kestrel-no-such-tool"]
        );
    }
}
