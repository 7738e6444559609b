//! kestrel-avr-rt's fixed-point dual active-set solver (`qp16`) on the
//! ATmega2560: the tables of the tricopter thesis-sized problem (`n = 4`,
//! 9 parameters) and of the larger one (`n = 16`), built on the host,
//! compiled into `avr/qp-bench` (the pinned nightly) and run in simavr at
//! 16 MHz. At every parameter the program solves cold, then warm from the
//! previous solve's active set; every answer (iterations, active-set size,
//! solution bits, or the error and the fallback's bits) must equal the
//! host's run of the same code bit for bit, and the Timer1 cycles are
//! printed, one `QP-AVR-REPORT {json}` line per problem: at the worst
//! parameters a host search found (most iterations among 20,000 random
//! ones), at the certified worst-case region's parameter of the thesis-sized
//! problem (`kestrel qp certify`, written into `CERTIFIED_WORST` below) and
//! at 64 random parameters in the box. Skipped when simavr, avr-gcc,
//! avr-size or rustup is missing, unless `KESTREL_REQUIRE_AVR` is set
//! (then it fails).

use kestrel_avr_rt::host::{avr_cargo_build, avr_size, missing_tools, simavr};
use kestrel_avr_rt::qp16::{Qp16Error, Qp16Settings, Qp16Solver, Qp16Start, Qp16Tables, theta_q16};
use kestrel_core::formats::MpqpProblem;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Duration;

/// One AVR build and simulation at a time (one target directory).
static AVR_LOCK: Mutex<()> = Mutex::new(());
/// Random parameters measured besides the worst ones.
const RANDOM: usize = 64;

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn tools() -> bool {
    let missing = missing_tools(&["avr-gcc", "simavr", "avr-size", "rustup"]);
    if missing.is_empty() {
        return true;
    }
    assert!(
        std::env::var_os("KESTREL_REQUIRE_AVR").is_none(),
        "KESTREL_REQUIRE_AVR is set but {missing:?} not installed"
    );
    println!("qp_avr skipped: {missing:?} not installed");
    false
}

struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn problem(name: &str) -> MpqpProblem {
    MpqpProblem::read(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data")
            .join(name),
    )
    .unwrap()
}

/// The host's run of the bench's sequence: per parameter and mode (cold,
/// warm) the expected line after `Q i mode`, without the cycles.
fn host_lines<const N: usize, const P: usize>(
    t: &Qp16Tables<N, P>,
    thetas: &[[i32; P]],
) -> Vec<(String, Vec<u32>)> {
    let mut s = Qp16Solver::<N>::new();
    let mut out = Vec::new();
    for th in thetas {
        for start in [Qp16Start::Cold, Qp16Start::Warm] {
            let (head, w) = match s.solve(t, th, start) {
                Ok(info) => (
                    format!("{} {}", info.iterations, info.active),
                    *s.solution(),
                ),
                Err(e) => {
                    let code = match e {
                        Qp16Error::InvalidBounds => 1,
                        Qp16Error::Infeasible => 2,
                        Qp16Error::IterationLimit => 3,
                    };
                    (format!("ERR {code}"), s.fallback())
                }
            };
            out.push((head, w.iter().map(|v| *v as u32).collect()));
        }
    }
    out
}

/// Builds avr/qp-bench over `generated`; the ELF's copy.
fn build(generated: &Path) -> PathBuf {
    let root = repo_root();
    let mut cmd = avr_cargo_build(&root);
    cmd.env("KESTREL_QP_GENERATED", generated);
    let status = cmd
        .current_dir(root.join("avr/qp-bench"))
        .status()
        .expect("run rustup/cargo");
    assert!(status.success(), "avr/qp-bench build failed");
    let elf = root.join("avr/target/avr-none/release/kestrel-avr-qp-bench.elf");
    let copy = generated.with_file_name("bench.elf");
    std::fs::copy(&elf, &copy).unwrap();
    copy
}

fn stats(c: &[u32]) -> String {
    let (min, max) = (c.iter().min().unwrap(), c.iter().max().unwrap());
    let mean = c.iter().map(|&v| f64::from(v)).sum::<f64>() / c.len() as f64;
    format!(
        "{{\"n\": {}, \"min\": {min}, \"mean\": {mean:.0}, \"max\": {max}}}",
        c.len()
    )
}

/// Runs `thetas` (the first `named` of them named in the report) on the
/// AVR, checks every answer against the host and prints the report.
fn measure<const N: usize, const P: usize>(name: &str, file: &str, named: &[(&str, Vec<f64>)]) {
    let p = problem(file);
    let (t, scaling) = Qp16Tables::<N, P>::from_mpqp(&p, Qp16Settings::default()).unwrap();
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    let lo: Vec<f64> = p.theta_lb.iter().copied().collect();
    let hi: Vec<f64> = p.theta_ub.iter().copied().collect();
    let mut random = || -> Vec<f64> {
        (0..P)
            .map(|j| lo[j] + (hi[j] - lo[j]) * rng.uniform())
            .collect()
    };
    // The most iterations among 20,000 random parameters (cold).
    let mut s = Qp16Solver::<N>::new();
    let mut worst = (0u16, vec![0.0; P]);
    for _ in 0..20_000 {
        let th = random();
        if let Ok(i) = s.solve(&t, &theta_q16::<P>(&th), Qp16Start::Cold)
            && i.iterations > worst.0
        {
            worst = (i.iterations, th);
        }
    }
    let mut labels: Vec<String> = vec![format!("most iterations found ({})", worst.0)];
    let mut thetas: Vec<[i32; P]> = vec![theta_q16::<P>(&worst.1)];
    for (label, th) in named {
        labels.push((*label).to_string());
        thetas.push(theta_q16::<P>(th));
    }
    let n_named = thetas.len();
    for _ in 0..RANDOM {
        thetas.push(theta_q16::<P>(&random()));
    }
    let want = host_lines(&t, &thetas);
    let dir = repo_root().join(format!("avr/target/qp-bench-gen/{name}"));
    std::fs::create_dir_all(&dir).unwrap();
    let mut g = String::from("// @generated by kestrel-avr-rt's tests/qp_avr.rs; do not edit.\n");
    writeln!(g, "const N: usize = {N};\nconst P: usize = {P};").unwrap();
    g.push_str(&t.to_rust("TABLES"));
    writeln!(g, "static THETAS: [[i32; P]; {}] = [", thetas.len()).unwrap();
    for th in &thetas {
        writeln!(g, "    {th:?},").unwrap();
    }
    g.push_str("];\n");
    std::fs::write(dir.join("generated.rs"), g).unwrap();
    let (flash, run) = {
        let _guard = AVR_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        let elf = build(&dir.join("generated.rs"));
        let size = avr_size(&elf).expect("avr-size");
        (
            size,
            simavr(&elf, Duration::from_secs(300)).expect("run simavr"),
        )
    };
    assert!(run.ended, "{name}: simavr did not end: {:#?}", run.lines);
    let lines = run.lines;
    assert!(
        lines.iter().any(|l| l == &format!("INIT {N} {P}")),
        "{name}: {lines:#?}"
    );
    assert!(lines.iter().any(|l| l == "END"), "{name}: {lines:#?}");
    let rows: Vec<Vec<String>> = lines
        .iter()
        .filter_map(|l| l.strip_prefix("Q "))
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect();
    assert_eq!(rows.len(), want.len(), "{name}: {lines:#?}");
    let (mut cold, mut warm) = (Vec::new(), Vec::new());
    let mut named_cycles = Vec::new();
    for (k, (r, (head, bits))) in rows.iter().zip(&want).enumerate() {
        let (i, mode) = (k / 2, k % 2);
        assert_eq!(r[0], i.to_string());
        assert_eq!(r[1], mode.to_string());
        let got_head = format!("{} {}", r[2], r[3]);
        assert_eq!(&got_head, head, "{name}: parameter {i} mode {mode}");
        let cycles: u32 = r[4].parse().unwrap();
        let got_bits: Vec<u32> = r[5..].iter().map(|v| v.parse().unwrap()).collect();
        assert_eq!(
            &got_bits, bits,
            "{name}: parameter {i} mode {mode}: solution bits"
        );
        if i < n_named {
            named_cycles.push(format!(
                "{{\"theta\": \"{}\", \"mode\": \"{}\", \"result\": \"{head}\", \"cycles\": {cycles}}}",
                labels[i],
                if mode == 0 { "cold" } else { "warm" }
            ));
        } else if mode == 0 {
            cold.push(cycles);
        } else {
            warm.push(cycles);
        }
    }
    let cal = lines
        .iter()
        .find_map(|l| l.strip_prefix("CAL "))
        .unwrap_or("?");
    println!(
        "QP-AVR-REPORT {{\"problem\": \"{name}\", \"n\": {N}, \"p\": {P}, \"flash\": {}, \"ram_static\": {}, \"table_bytes\": {}, \"var_shift\": {}, \"obj_shift\": {}, \"bits\": [{}, {}, {}], \"named\": [{}], \"random_cold\": {}, \"random_warm_after_cold\": {}, \"equal_bits\": {}, \"cal_mac1_mac9_recip_row\": \"{cal}\"}}",
        flash.flash,
        flash.ram,
        std::mem::size_of::<Qp16Tables<N, P>>(),
        scaling.var_shift,
        scaling.obj_shift,
        t.p_bits,
        t.l_bits,
        t.nu_bits,
        named_cycles.join(", "),
        stats(&cold),
        stats(&warm),
        rows.len(),
    );
}

/// The certified worst-case region's parameter of the thesis-sized problem
/// (from `kestrel qp certify`, /work/coord/h1-bench.md); `None` until known.
const CERTIFIED_WORST: Option<[f64; 9]> = None;

#[test]
fn qp16_on_the_avr_thesis_sized() {
    if !tools() {
        return;
    }
    let named: Vec<(&str, Vec<f64>)> = CERTIFIED_WORST
        .iter()
        .map(|t| ("certified worst-case region", t.to_vec()))
        .collect();
    measure::<4, 9>("thesis", "qp16-thesis.mpqp.json", &named);
}

#[test]
fn qp16_on_the_avr_larger() {
    if !tools() {
        return;
    }
    measure::<16, 9>("larger", "qp16-larger.mpqp.json", &[]);
}
