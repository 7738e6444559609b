//! kestrel-ffi from C (issue 25): the C programs of `examples/c` built by
//! the system C compiler against the host staticlib of kestrel-ffi
//! (`cargo build -p kestrel-ffi`, `target/<profile>/libkestrel_ffi.a`), its
//! header `crates/ffi/include/kestrel.h` and the tables of `kestrel export
//! --lang c` (`kestrel_design.h`/`.c`, written here by the export's library
//! function `kestrel_tricopter::firmware::c_tables::generate_c_tables` for
//! the committed design), run at 10^4 random inputs and compared with the
//! Rust library bit for bit: the rate loop, the 16-bit Kalman filter, the
//! fast gradient law and the explicit law (`kestrel export --lang c --empc`)
//! of kestrel-avr-rt built in Rust exactly as the Rust firmware builds them
//! from its tables (`avr/firmware/src/generated.rs`, `generated_empc.rs`),
//! in f32 and in Q15.16. Bad tables (wrong checksum, wrong sizes, NULL
//! pointers, uninitialised states) give their error codes, tested from C
//! (`examples/c/check.c errors`).
//!
//! The AVR half (`ffi_c/avr.rs`, `avr_example_in_simavr`) builds
//! `avr/c-example` with avr-gcc for the ATmega2560 against kestrel-ffi's
//! `avr-none` staticlib and runs it in simavr; it is skipped (with a
//! message) when avr-gcc or simavr is missing.
//!
//! The C compiler is the system's `cc` (or `$CC`), run as a process: the
//! `cc` crate is made for build scripts (it reads cargo's build-script
//! environment), and a test that compiles two C files needs nothing of it.

use kestrel_avr_rt::control::{GyroCheck, Mixer, RateLoop};
use kestrel_avr_rt::cycles::CycleClock;
use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16};
use kestrel_avr_rt::fgm16::Fgm16Law;
use kestrel_avr_rt::frame::Command;
use kestrel_avr_rt::kalman16::Kalman16;
use kestrel_avr_rt::law::LawInfo;
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_avr_rt::output::{PwmLimits, RtScalar, SafeOutput};
use kestrel_core::{Error, Matrix, StateEstimator};
use kestrel_fgm::{FgmTables, FgmWorkspace, Start};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command as Process, Stdio};
use std::sync::OnceLock;

#[allow(dead_code)]
mod generated {
    include!("../../avr/firmware/src/generated.rs");
}

#[allow(dead_code)]
mod generated_empc {
    include!("../../avr/firmware/src/generated_empc.rs");
}
use generated::*;

mod ffi_c {
    pub mod avr;
}

/// Random inputs per comparison.
const N: usize = 10_000;

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `target/<profile>` of this test binary (`target/<profile>/deps/ffi_c-*`).
fn profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test binary path");
    exe.parent()
        .and_then(Path::parent)
        .expect("target/<profile>/deps")
        .to_path_buf()
}

/// A scratch folder of this test under the target folder.
fn work_dir(name: &str) -> PathBuf {
    let d = profile_dir().join("ffi_c").join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// kestrel-ffi's host staticlib, built by cargo in this test's profile
/// (once per test binary).
fn host_staticlib() -> &'static Path {
    static LIB: OnceLock<PathBuf> = OnceLock::new();
    LIB.get_or_init(|| {
        let dir = profile_dir();
        let profile = match dir.file_name().and_then(|n| n.to_str()) {
            Some("debug") => "dev".to_string(),
            Some(p) => p.to_string(),
            None => panic!("no profile folder in {}", dir.display()),
        };
        let target_dir = dir.parent().expect("target folder");
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let status = Process::new(cargo)
            .args([
                "build",
                "--quiet",
                "-p",
                "kestrel-ffi",
                "--profile",
                &profile,
            ])
            .arg("--target-dir")
            .arg(target_dir)
            .current_dir(repo_root())
            .env_remove("CARGO_TARGET_DIR")
            .status()
            .expect("run cargo");
        assert!(status.success(), "cargo build -p kestrel-ffi failed");
        let lib = dir.join("libkestrel_ffi.a");
        assert!(lib.exists(), "{} missing", lib.display());
        lib
    })
}

/// The committed design (once per test binary).
fn design() -> &'static kestrel_tricopter::firmware::FirmwareDesign {
    static D: OnceLock<kestrel_tricopter::firmware::FirmwareDesign> = OnceLock::new();
    D.get_or_init(|| kestrel_tricopter::codegen::firmware::design(&repo_root()).expect("design"))
}

/// `kestrel_design.h` and `kestrel_design.c` of the committed design, as
/// `kestrel export --lang c` writes them, in `dir`.
fn write_design(dir: &Path) {
    let c = kestrel_tricopter::firmware::c_tables::generate_c_tables(design()).expect("C tables");
    std::fs::write(dir.join("kestrel_design.h"), c.header).unwrap();
    std::fs::write(dir.join("kestrel_design.c"), c.source).unwrap();
}

/// `kestrel_empc.h` and `kestrel_empc.c` (`kestrel export --lang c
/// --empc`): the design's explicit law, in `dir`.
fn write_empc(dir: &Path) {
    let c = kestrel_tricopter::firmware::c_tables::generate_c_empc_of(design()).expect("C tables");
    std::fs::write(dir.join("kestrel_empc.h"), c.header).unwrap();
    std::fs::write(dir.join("kestrel_empc.c"), c.source).unwrap();
}

/// `examples/c/check.c`, built once per test binary.
fn check_exe() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| build_c("check"))
}

/// Compiles `examples/c/<name>.c` with the exported tables and the host
/// staticlib (in a folder of its own); returns the executable.
fn build_c(name: &str) -> PathBuf {
    let dir = work_dir(&format!("host-{name}"));
    write_design(&dir);
    let mut sources = vec![dir.join("kestrel_design.c")];
    if name == "check" {
        write_empc(&dir);
        sources.push(dir.join("kestrel_empc.c"));
    }
    let root = repo_root();
    let exe = dir.join(name);
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let out = Process::new(&cc)
        .args([
            "-std=c99",
            "-O2",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-pedantic",
        ])
        .arg("-I")
        .arg(root.join("crates/ffi/include"))
        .arg("-I")
        .arg(&dir)
        .arg("-o")
        .arg(&exe)
        .arg(root.join(format!("examples/c/{name}.c")))
        .args(&sources)
        .arg(host_staticlib())
        .args(["-lm", "-lpthread", "-ldl"])
        .output()
        .unwrap_or_else(|e| panic!("run {cc}: {e}"));
    assert!(
        out.status.success(),
        "{cc} {name}.c failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    exe
}

/// Runs `exe args` with `input` on its standard input; its standard output.
fn run(exe: &Path, args: &[&str], input: &str) -> (i32, String) {
    let mut child = Process::new(exe)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("run {}: {e}", exe.display()));
    let mut stdin = child.stdin.take().unwrap();
    let input = input.to_string();
    let writer = std::thread::spawn(move || stdin.write_all(input.as_bytes()));
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap().unwrap();
    assert!(
        out.stderr.is_empty(),
        "{} {args:?} wrote to stderr:\n{}",
        exe.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8(out.stdout).unwrap(),
    )
}

/// Compares the C program's lines with the Rust lines; panics with the
/// first differences.
fn assert_same_lines(what: &str, c: &str, rust: &[String]) {
    let c: Vec<&str> = c.lines().collect();
    assert_eq!(c.len(), rust.len(), "{what}: line count");
    let diffs: Vec<String> = c
        .iter()
        .zip(rust)
        .enumerate()
        .filter(|(_, (a, b))| **a != b.as_str())
        .map(|(k, (a, b))| format!("line {k}: C `{a}`, Rust `{b}`"))
        .collect();
    assert!(
        diffs.is_empty(),
        "{what}: {} of {} lines differ, first: {:#?}",
        diffs.len(),
        c.len(),
        &diffs[..diffs.len().min(5)]
    );
    println!("{what}: {} results equal bit for bit", c.len());
}

// ---------------------------------------------------------------- the Rust library

/// kestrel.h's `KestrelStatus` code of a run-time result (kestrel-ffi's
/// mapping; `KESTREL_STATUS_OTHER` for a variant it has no code for).
fn code(r: Result<(), Error>) -> i32 {
    match r {
        Ok(()) => 0,
        Err(Error::DimensionMismatch { .. }) => 2,
        Err(Error::NonFinite) => 6,
        Err(Error::Infeasible) => 7,
        Err(Error::InvalidArgument(_)) => 8,
        Err(Error::OutOfRange) => 9,
        Err(Error::Singular) => 10,
        Err(Error::NotPositiveDefinite) => 11,
        Err(Error::Unbounded) => 12,
        Err(Error::NotConverged) => 13,
        Err(e) => panic!("no kestrel.h code for {e:?}"),
    }
}

/// A scalar of the loop with the table value type the firmware reads.
trait Scalar: RtScalar + std::fmt::Debug {
    /// Table value `i` (`VALUES_F32` or `VALUES_Q16` of generated.rs).
    fn value(i: usize) -> Self;
    /// The raw bits the C program prints.
    fn bits(self) -> u32;
}

impl Scalar for f32 {
    fn value(i: usize) -> Self {
        VALUES_F32[i]
    }
    fn bits(self) -> u32 {
        self.to_bits()
    }
}

impl Scalar for Q16Mac {
    fn value(i: usize) -> Self {
        Q16Mac::from_bits(VALUES_Q16[i])
    }
    fn bits(self) -> u32 {
        self.to_bits() as u32
    }
}

fn va<S: Scalar, const K: usize>(at: usize) -> [S; K] {
    std::array::from_fn(|i| S::value(at + i))
}

fn vm<S: Scalar, const R: usize, const C: usize>(at: usize) -> Matrix<S, R, C> {
    Matrix::from_fn(|i, j| S::value(at + C * i + j))
}

/// kestrel-fgm's tables as the firmware reads them (avr/firmware/src/main.rs).
fn fgm_tables<S: Scalar>() -> FgmTables<S, NZ, NP, FGM_T> {
    FgmTables {
        m: vm(FGM_M),
        k_theta: vm(FGM_K),
        k0: va(FGM_K0),
        lo_theta: vm(FGM_LO),
        lo0: va(FGM_LO0),
        hi_theta: vm(FGM_HI),
        hi0: va(FGM_HI0),
        d: va(FGM_D),
        d_inv: va(FGM_DINV),
        betas: va(FGM_BETAS),
        iterations: FGM_ITERATIONS,
        warm_iterations: FGM_ITERATIONS,
        shift: 0,
    }
}

type Law<S> = Fgm16Law<S, NZ, NP, FGM_T, 4>;

fn fgm16_law<S: Scalar>() -> Law<S> {
    Law::<S>::new(
        fgm_tables(),
        FGM16_M,
        FGM16_BETAS,
        NX,
        FGM_WARM,
        FGM_LOOP_ITERATIONS as u16,
    )
    .expect("the firmware's law")
}

type Loop<S> = RateLoop<S, Kalman16<S, NX, 4, 3>, Law<S>, 4>;

/// The firmware's rate loop (its main.rs), with the gyro check.
fn rate_loop<S: Scalar>() -> Loop<S> {
    rate_loop_with(fgm16_law())
}

/// The firmware's rate loop with the law `law`.
fn rate_loop_with<S: Scalar, L>(law: L) -> RateLoop<S, Kalman16<S, NX, 4, 3>, L, 4>
where
    L: kestrel_core::ControlLaw<Scalar = S> + LawInfo,
{
    let one = S::from_f32_fast(1.0);
    let mixer = Mixer::<S, 4> {
        m: Matrix::from_fn(|i, j| if i == j { one } else { S::ZERO }),
        offset: va(MIX_OFFSET),
        throttle_gain: [one, one, one, S::ZERO],
    };
    let mut l = RateLoop::new(
        Kalman16::new(KF16),
        law,
        va(BIAS),
        mixer,
        PwmLimits::default(),
        SafeOutput::default(),
    )
    .expect("the firmware's loop");
    l.gyro_check = Some(GyroCheck::default());
    l
}

struct NoClock;
impl CycleClock for NoClock {
    fn now(&self) -> u32 {
        0
    }
}

// ---------------------------------------------------------------- random inputs

fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}

/// A value in `[-a, a]`, now and then a special one (NaN, infinities, a
/// railed gyro) when `specials`.
fn value(r: &mut Xoshiro256PlusPlus, a: f32, specials: bool) -> f32 {
    if specials {
        match r.random_range(0..400) {
            0 => return f32::NAN,
            1 => return f32::INFINITY,
            2 => return -f32::INFINITY,
            3 => return 40.0 * a,
            _ => {}
        }
    }
    r.random_range(-a..=a)
}

/// Random periods: (fresh, gyro, reference, throttle); now and then no
/// fresh sample (hold, failsafe, recovery), a non-finite or railed value,
/// or a repeated gyro reading (the stuck-sensor check).
fn loop_inputs(seed: u64) -> Vec<(bool, Command)> {
    let mut r = rng(seed);
    let mut last = [0.0f32; 3];
    (0..N)
        .map(|_| {
            let fresh = r.random_range(0..50) != 0;
            let gyro = if r.random_range(0..200) == 0 {
                last
            } else {
                std::array::from_fn(|_| value(&mut r, 4.0, true))
            };
            last = gyro;
            let cmd = Command {
                gyro,
                reference: std::array::from_fn(|_| value(&mut r, 2.0, false)),
                throttle: r.random_range(1000.0..=2000.0),
            };
            (fresh, cmd)
        })
        .collect()
}

fn hex_line(words: impl IntoIterator<Item = u32>) -> String {
    let mut s = String::new();
    for (i, w) in words.into_iter().enumerate() {
        let _ = write!(s, "{}{w:08x}", if i > 0 { " " } else { "" });
    }
    s.push('\n');
    s
}

// ---------------------------------------------------------------- host tests

fn check_loop<S: Scalar, L>(
    exe: &Path,
    mode: &str,
    seed: u64,
    mut l: RateLoop<S, Kalman16<S, NX, 4, 3>, L, 4>,
) where
    L: kestrel_core::ControlLaw<Scalar = S> + LawInfo,
{
    let inputs = loop_inputs(seed);
    let stdin: String = inputs
        .iter()
        .map(|(fresh, c)| {
            let mut w = vec![u32::from(*fresh)];
            w.extend(c.gyro.iter().chain(&c.reference).map(|v| v.to_bits()));
            w.push(c.throttle.to_bits());
            hex_line(w)
        })
        .collect();
    let (status, out) = run(exe, &[mode], &stdin);
    assert_eq!(status, 0, "{mode}");
    let rust: Vec<String> = inputs
        .iter()
        .map(|(fresh, c)| {
            let p = l.period(fresh.then_some(c), &NoClock);
            format!(
                "0 {} {} {} {} {} {}",
                p.pwm[0], p.pwm[1], p.pwm[2], p.pwm[3], p.status, p.iterations
            )
        })
        .collect();
    // The inputs reach the failsafe paths, not only the law.
    let flagged = rust
        .iter()
        .filter(|l| l.split(' ').nth(5) != Some("0"))
        .count();
    assert!(flagged > N / 100, "{mode}: only {flagged} flagged periods");
    assert_same_lines(&format!("{mode} ({flagged} periods flagged)"), &out, &rust);
}

#[test]
fn rate_loop_f32_equals_rust() {
    check_loop(check_exe(), "loop-f32", 1, rate_loop::<f32>());
}

#[test]
fn rate_loop_q16_equals_rust() {
    check_loop(check_exe(), "loop-q16", 2, rate_loop::<Q16Mac>());
}

#[test]
fn rate_loop_empc_f32_equals_rust() {
    check_loop(
        check_exe(),
        "loop-empc-f32",
        12,
        rate_loop_with(empc16_law::<f32>()),
    );
}

#[test]
fn rate_loop_empc_q16_equals_rust() {
    check_loop(
        check_exe(),
        "loop-empc-q16",
        13,
        rate_loop_with(empc16_law::<Q16Mac>()),
    );
}

/// Random values of `S` in `[-a, a]` (Q15.16: the bits of a random value).
fn random_s<S: Scalar>(r: &mut Xoshiro256PlusPlus, a: f32) -> S {
    S::from_f32_fast(value(r, a, false))
}

fn check_kalman<S: Scalar>(exe: &Path, mode: &str, seed: u64) {
    let mut r = rng(seed);
    let inputs: Vec<([S; 3], [S; 4])> = (0..N)
        .map(|_| {
            (
                std::array::from_fn(|_| random_s(&mut r, 3.0)),
                std::array::from_fn(|_| random_s(&mut r, 300.0)),
            )
        })
        .collect();
    let stdin: String = inputs
        .iter()
        .map(|(y, u)| hex_line(y.iter().chain(u).map(|v| v.bits())))
        .collect();
    let (status, out) = run(exe, &[mode], &stdin);
    assert_eq!(status, 0, "{mode}");
    let mut f = Kalman16::<S, NX, 4, 3>::new(KF16);
    let rust: Vec<String> = inputs
        .iter()
        .map(|(y, u)| {
            let mut s = String::new();
            let a = code(f.measurement_update(y));
            let _ = write!(s, "{a} {}", hex_line(f.estimate().iter().map(|v| v.bits())));
            s.pop();
            let b = code(f.time_update(u));
            let _ = write!(
                s,
                " {b} {}",
                hex_line(f.estimate().iter().map(|v| v.bits()))
            );
            s.pop();
            s
        })
        .collect();
    assert_same_lines(mode, &out, &rust);
}

#[test]
fn kalman16_f32_equals_rust() {
    check_kalman::<f32>(check_exe(), "kalman-f32", 3);
}

#[test]
fn kalman16_q16_equals_rust() {
    check_kalman::<Q16Mac>(check_exe(), "kalman-q16", 4);
}

/// Random law parameters: states, rate references, throttle.
fn thetas<S: Scalar>(seed: u64) -> Vec<[S; NP]> {
    let mut r = rng(seed);
    (0..N)
        .map(|_| {
            std::array::from_fn(|j| match j {
                j if j < NX => random_s(&mut r, 30.0),
                j if j < NP - 1 => random_s(&mut r, 2.0),
                _ => S::from_f32_fast(r.random_range(1000.0..=2000.0)),
            })
        })
        .collect()
}

fn z_line<S: Scalar>(r: Result<[S; NZ], Error>) -> String {
    let (c, z) = match r {
        Ok(z) => (0, z),
        Err(e) => (code(Err(e)), [S::ZERO; NZ]),
    };
    let mut s = format!("{c} {}", hex_line(z.iter().map(|v| v.bits())));
    s.pop();
    s
}

fn check_fgm16<S: Scalar>(exe: &Path, mode: &str, seed: u64) {
    let thetas = thetas::<S>(seed);
    let stdin: String = thetas
        .iter()
        .map(|t| hex_line(t.iter().map(|v| v.bits())))
        .collect();
    let (status, out) = run(exe, &[mode], &stdin);
    assert_eq!(status, 0, "{mode}");
    let mut law = fgm16_law::<S>();
    let rust: Vec<String> = thetas
        .iter()
        .map(|t| {
            let r = law.solve(t);
            let it = if r.is_ok() { law.iterations() } else { 0 };
            format!("{} {it}", z_line(r))
        })
        .collect();
    assert_same_lines(mode, &out, &rust);
}

#[test]
fn fgm16_f32_equals_rust() {
    check_fgm16::<f32>(check_exe(), "fgm16-f32", 5);
}

#[test]
fn fgm16_q16_equals_rust() {
    check_fgm16::<Q16Mac>(check_exe(), "fgm16-q16", 6);
}

fn check_fgm_reference<S: Scalar>(exe: &Path, mode: &str, seed: u64) {
    let thetas = thetas::<S>(seed);
    let stdin: String = thetas
        .iter()
        .map(|t| hex_line(t.iter().map(|v| v.bits())))
        .collect();
    let (status, out) = run(exe, &[mode], &stdin);
    assert_eq!(status, 0, "{mode}");
    let tables = fgm_tables::<S>();
    let mut ws = FgmWorkspace::new();
    let rust: Vec<String> = thetas
        .iter()
        .map(|t| z_line(tables.solve_with(t, Start::Cold, FGM_LOOP_ITERATIONS, &mut ws)))
        .collect();
    assert_same_lines(mode, &out, &rust);
}

#[test]
fn fgm_reference_f32_equals_rust() {
    check_fgm_reference::<f32>(check_exe(), "fgm-f32", 7);
}

#[test]
fn fgm_reference_q16_equals_rust() {
    check_fgm_reference::<Q16Mac>(check_exe(), "fgm-q16", 8);
}

/// The firmware's `empc` law: EMPC16 of generated_empc.rs.
fn empc16_law<S: Scalar>() -> Empc16Law<S, &'static [u8], NP, 4, { generated_empc::EMPC16_ROWS }> {
    let tree = Tree16::new(&generated_empc::EMPC16[..], generated_empc::EMPC16_LAYOUT).unwrap();
    Empc16Law::new(tree, NX).unwrap()
}

fn check_empc<S: Scalar>(exe: &Path, mode: &str, seed: u64) {
    use kestrel_core::ControlLaw;
    let thetas = thetas::<S>(seed);
    let stdin: String = thetas
        .iter()
        .map(|t| hex_line(t.iter().map(|v| v.bits())))
        .collect();
    let (status, out) = run(exe, &[mode], &stdin);
    assert_eq!(status, 0, "{mode}");
    // The firmware's `empc` build: EMPC16 of generated_empc.rs.
    let tree = Tree16::new(&generated_empc::EMPC16[..], generated_empc::EMPC16_LAYOUT).unwrap();
    let mut law = Empc16Law::<S, _, NP, 4, { generated_empc::EMPC16_ROWS }>::new(tree, NX).unwrap();
    let rust: Vec<String> = thetas
        .iter()
        .map(|t| {
            let mut u = [S::ZERO; 4];
            let r = law.control(&t[..NX], &t[NX..], &mut u);
            let nodes = if r.is_ok() { law.iterations() } else { 0 };
            let u = if r.is_ok() { u } else { [S::ZERO; 4] };
            let mut s = format!("{} {}", code(r), hex_line(u.iter().map(|v| v.bits())));
            s.pop();
            format!("{s} {nodes}")
        })
        .collect();
    assert_same_lines(mode, &out, &rust);
}

#[test]
fn empc16_f32_equals_rust() {
    check_empc::<f32>(check_exe(), "empc-f32", 10);
}

#[test]
fn empc16_q16_equals_rust() {
    check_empc::<Q16Mac>(check_exe(), "empc-q16", 11);
}

#[test]
fn bad_tables_give_error_codes_from_c() {
    let (status, out) = run(check_exe(), &["errors"], "");
    print!("{out}");
    let ok = out.lines().filter(|l| l.starts_with("ok ")).count();
    assert_eq!(status, 0, "failures in examples/c/check.c errors:\n{out}");
    assert!(!out.contains("FAIL"), "{out}");
    assert!(ok >= 40, "only {ok} checks ran:\n{out}");
}

/// 200 periods as text lines (`-`: no fresh sample) and the Rust loop's
/// `pwm1 pwm2 pwm3 servo flags` for them.
fn text_periods() -> (String, Vec<String>) {
    let mut stdin = String::new();
    let mut l = rate_loop::<f32>();
    let mut rust = Vec::new();
    let mut r = rng(9);
    for k in 0..200 {
        let cmd = Command {
            gyro: std::array::from_fn(|_| r.random_range(-2.0f32..2.0)),
            reference: if k < 100 { [0.0; 3] } else { [1.0, -1.0, 0.5] },
            throttle: 1500.0,
        };
        let fresh = k != 150;
        if fresh {
            // `{}` of an f32 is the shortest text that reads back to it.
            let _ = writeln!(
                stdin,
                "{} {} {} {} {} {} {}",
                cmd.gyro[0],
                cmd.gyro[1],
                cmd.gyro[2],
                cmd.reference[0],
                cmd.reference[1],
                cmd.reference[2],
                cmd.throttle
            );
        } else {
            stdin.push_str("-\n");
        }
        let p = l.period(fresh.then_some(&cmd), &NoClock);
        rust.push(format!(
            "{} {} {} {} {}",
            p.pwm[0], p.pwm[1], p.pwm[2], p.pwm[3], p.status
        ));
    }
    (stdin, rust)
}

/// The example itself: text in, pulses out, the same as the Rust loop.
#[test]
fn rate_loop_example_prints_the_rust_pulses() {
    let exe = build_c("rate_loop");
    let (stdin, rust) = text_periods();
    let (status, out) = run(&exe, &[], &stdin);
    assert_eq!(status, 0);
    assert_same_lines("examples/c/rate_loop.c", &out, &rust);
}

/// The C++ wrapper of kestrel-ffi's README (its ```cpp block, compiled as
/// it stands) with the same main loop as `examples/c/rate_loop.c`.
#[test]
fn cpp_wrapper_of_the_readme_gives_the_rust_pulses() {
    let root = repo_root();
    let readme = std::fs::read_to_string(root.join("crates/ffi/README.md")).unwrap();
    let start = readme
        .find("```cpp\n")
        .expect("a ```cpp block in crates/ffi/README.md")
        + 7;
    let len = readme[start..].find("```").expect("the block's end");
    let wrapper = &readme[start..start + len];
    let dir = work_dir("cpp");
    write_design(&dir);
    let source = format!(
        "{wrapper}\n#include <cstdio>\n#include \"kestrel_design.h\"\n\
         int main() {{\n\
             KestrelLoopConfig config;\n\
             kestrel_loop_config_default(&config);\n\
             static RateLoop loop(kestrel_design_f32(), config);\n\
             char line[256];\n\
             while (std::fgets(line, sizeof line, stdin)) {{\n\
                 KestrelRateInput in{{}};\n\
                 in.fresh = std::sscanf(line, \"%f %f %f %f %f %f %f\", &in.gyro[0], &in.gyro[1],\n\
                     &in.gyro[2], &in.reference[0], &in.reference[1], &in.reference[2], &in.throttle) == 7;\n\
                 KestrelRateOutput out{{}};\n\
                 if (loop.step(in, out) != KESTREL_STATUS_OK) return 1;\n\
                 std::printf(\"%u %u %u %u %u\\n\", out.pwm[0], out.pwm[1], out.pwm[2], out.pwm[3], out.flags);\n\
             }}\n\
             return 0;\n\
         }}\n"
    );
    std::fs::write(dir.join("loop.cpp"), source).unwrap();
    let include = [
        "-I".to_string() + &root.join("crates/ffi/include").display().to_string(),
        "-I".to_string() + &dir.display().to_string(),
    ];
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let cxx = std::env::var("CXX").unwrap_or_else(|_| "c++".into());
    let object = dir.join("kestrel_design.o");
    let out = Process::new(&cc)
        .args(["-std=c99", "-O2", "-c"])
        .args(&include)
        .arg("-o")
        .arg(&object)
        .arg(dir.join("kestrel_design.c"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let exe = dir.join("loop");
    let out = Process::new(&cxx)
        .args(["-std=c++17", "-O2", "-Wall", "-Wextra", "-Werror"])
        .args(&include)
        .arg("-o")
        .arg(&exe)
        .arg(dir.join("loop.cpp"))
        .arg(&object)
        .arg(host_staticlib())
        .args(["-lm", "-lpthread", "-ldl"])
        .output()
        .unwrap_or_else(|e| panic!("run {cxx}: {e}"));
    assert!(
        out.status.success(),
        "{cxx} failed on the README's wrapper:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (stdin, rust) = text_periods();
    let (status, out) = run(&exe, &[], &stdin);
    assert_eq!(status, 0);
    assert_same_lines("crates/ffi/README.md's C++ wrapper", &out, &rust);
}
