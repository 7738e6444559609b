//! kestrel-avr-rt's fixed-point dual active-set solver (`qp16`) on the
//! ATmega2560: the tables of the tricopter thesis-sized problem (`n = 4`,
//! 9 parameters) and of the larger one (`n = 16`), built on the host,
//! compiled into `avr/qp-bench` (the pinned nightly) and run in simavr at
//! 16 MHz; every answer (iterations, active-set size,
//! solution bits, or the error and the fallback's bits) must equal the
//! host's run of the same code bit for bit, and the Timer1 cycles are
//! printed, one `QP-AVR-REPORT {json}` line per problem: at the worst
//! parameters a host search found (most iterations among 20,000 random
//! ones), at the certified worst-case regions' interior points of the
//! thesis-sized problem (kestrel-empc's certification: cold, and warm from
//! the previous period's set for a 5 % parameter step) and at 64 random
//! parameters in the box (24 for the larger problem). Each parameter is
//! solved warm from the previous parameter's final set, then cold, by both
//! kernels (`Qp16Solver`; `Qp16SetSolver` where its per-set tables exist). Skipped when simavr, avr-gcc,
//! avr-size or rustup is missing, unless `KESTREL_REQUIRE_AVR` is set
//! (then it fails).

use kestrel_avr_rt::host::{
    assert_no_miscompile, avr_cargo_build, avr_size, simavr, tools_present,
};
use kestrel_avr_rt::qp16::{
    Qp16Error, Qp16Info, Qp16SetSolver, Qp16SetTables, Qp16Settings, Qp16Solver, Qp16Start,
    Qp16Tables, theta_q16,
};
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::certify::{CertifySettings, certify};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Duration;

/// One AVR build and simulation at a time (one target directory).
static AVR_LOCK: Mutex<()> = Mutex::new(());
// Random parameters measured besides the worst ones: 64, and 24 for the
// larger problem (the parameters sit in the AVR's 8 kB of RAM beside its
// 3 kB of tables and the solver's factor).

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Whether the AVR tools are here (a missing one fails under `KESTREL_REQUIRE_AVR`).
fn tools() -> bool {
    tools_present("qp_avr", &["avr-gcc", "simavr", "avr-size", "rustup"])
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

/// The host's run of the bench's sequence: per parameter and mode (warm,
/// cold; per-set warm, cold) the expected line after `Q i mode`, without
/// the cycles.
fn host_lines<const N: usize, const P: usize, const S: usize, const E: usize>(
    t: &Qp16Tables<N, P>,
    sets: Option<&Qp16SetTables<N, S, E>>,
    thetas: &[[i32; P]],
) -> Vec<(String, Vec<u32>)> {
    let mut s = Qp16Solver::<N>::new();
    let mut ps = Qp16SetSolver::<N>::new();
    let mut out = Vec::new();
    // Warm from the previous parameter's final set, then cold.
    let modes: &[u32] = if sets.is_some() {
        &[1, 0, 3, 2]
    } else {
        &[1, 0]
    };
    for th in thetas {
        for &mode in modes {
            let start = if mode % 2 == 0 {
                Qp16Start::Cold
            } else {
                Qp16Start::Warm
            };
            let r: Result<Qp16Info, Qp16Error> = match (mode < 2, sets) {
                (false, Some(st)) => ps.solve(t, st, th, start),
                _ => s.solve(t, th, start),
            };
            let (head, w) = match r {
                Ok(info) => (
                    format!("{} {}", info.iterations, info.active),
                    if mode < 2 {
                        *s.solution()
                    } else {
                        *ps.solution()
                    },
                ),
                Err(e) => {
                    let code = match e {
                        Qp16Error::InvalidBounds => 1,
                        Qp16Error::Infeasible => 2,
                        Qp16Error::IterationLimit => 3,
                    };
                    (
                        format!("ERR {code}"),
                        if mode < 2 {
                            s.fallback()
                        } else {
                            ps.fallback()
                        },
                    )
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
    // KESTREL_QP_PROFILE=1: cycles per solver phase (a `PHASES` line).
    if std::env::var_os("KESTREL_QP_PROFILE").is_some() {
        cmd.args(["--features", "profile"]);
    }
    let status = cmd
        .current_dir(root.join("avr/qp-bench"))
        .status()
        .expect("run rustup/cargo");
    assert!(status.success(), "avr/qp-bench build failed");
    let elf = root.join("avr/target/avr-none/release/kestrel-avr-qp-bench.elf");
    let copy = generated.with_file_name("bench.elf");
    std::fs::copy(&elf, &copy).unwrap();
    // The pinned nightly's two AVR miscompilations (docs/avr-qp.md).
    assert_no_miscompile(&copy, |f| f == "main");
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
fn measure<const N: usize, const P: usize, const S: usize, const E: usize>(
    name: &str,
    file: &str,
    named: &[(&str, Vec<f64>)],
    count: usize,
) {
    let p = problem(file);
    let (t, scaling) = Qp16Tables::<N, P>::from_mpqp(&p, Qp16Settings::default()).unwrap();
    // The per-set kernel's tables where they exist (S = 2^N).
    let sets = t.set_tables::<S, E>().ok();
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
    for _ in 0..count {
        thetas.push(theta_q16::<P>(&random()));
    }
    let want = host_lines(&t, sets.as_ref(), &thetas);
    let n_modes = if sets.is_some() { 4 } else { 2 };
    let dir = repo_root().join(format!("avr/target/qp-bench-gen/{name}"));
    std::fs::create_dir_all(&dir).unwrap();
    let mut g = String::from("// @generated by kestrel-avr-rt's tests/qp_avr.rs; do not edit.\n");
    writeln!(g, "const N: usize = {N};\nconst P: usize = {P};").unwrap();
    g.push_str(&t.to_rust("TABLES"));
    match &sets {
        Some(st) => {
            g.push_str("const SETS: bool = true;\n");
            g.push_str(&st.to_rust("SET_TABLES"));
        }
        None => {
            writeln!(g, "const SETS: bool = false;\nstatic SET_TABLES: kestrel_avr_rt::qp16::Qp16SetTables<{N}, 1, 0> = kestrel_avr_rt::qp16::Qp16SetTables {{ offset: [0], data: [], minv_bits: 16, w_bits: 16 }};").unwrap();
        }
    }
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
    // Random parameters' cycles per mode; the named ones listed.
    let mut random: Vec<Vec<u32>> = vec![Vec::new(); n_modes];
    let mut named_cycles = Vec::new();
    let mut by_iter = std::collections::BTreeMap::new();
    let mode_names = ["cold", "warm", "per-set cold", "per-set warm"];
    let order: &[usize] = if n_modes == 4 { &[1, 0, 3, 2] } else { &[1, 0] };
    for (k, (r, (head, bits))) in rows.iter().zip(&want).enumerate() {
        let (i, mode) = (k / n_modes, order[k % n_modes]);
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
                labels[i], mode_names[mode]
            ));
        } else {
            if mode % 2 == 0 {
                by_iter
                    .entry(format!("{} {}", mode_names[mode], r[2]))
                    .or_insert_with(Vec::new)
                    .push(cycles);
            }
            random[mode].push(cycles);
        }
    }
    let per_iter: Vec<String> = by_iter
        .iter()
        .map(|(k, v): (&String, &Vec<u32>)| format!("\"{k}\": {}", stats(v)))
        .collect();
    for l in lines.iter().filter(|l| l.starts_with("PHASES")) {
        println!("{name}: {l}");
    }
    let cal = lines
        .iter()
        .find_map(|l| l.strip_prefix("CAL "))
        .unwrap_or("?");
    println!(
        "QP-AVR-REPORT {{\"problem\": \"{name}\", \"n\": {N}, \"p\": {P}, \"flash\": {}, \"ram_static\": {}, \"table_bytes\": {}, \"var_shift\": {}, \"obj_shift\": {}, \"bits\": [{}, {}, {}], \"named\": [{}], \"random\": {{{}}}, \"random_cold_by_iterations\": {{{}}}, \"equal_bits\": {}, \"cal_mac1_mac9_recip_row\": \"{cal}\"}}",
        flash.flash,
        flash.ram,
        std::mem::size_of::<Qp16Tables<N, P>>(),
        scaling.var_shift,
        scaling.obj_shift,
        t.p_bits,
        t.l_bits,
        t.nu_bits,
        named_cycles.join(", "),
        random
            .iter()
            .enumerate()
            .map(|(m, c)| format!("\"{}\": {}", mode_names[m], stats(c)))
            .collect::<Vec<_>>()
            .join(", "),
        per_iter.join(", "),
        rows.len(),
    );
}

/// The certified worst-case regions' interior points (kestrel-empc's
/// certification of kestrel-qp's decisions, which this kernel shares):
/// cold (most iterations, most flops) and warm from the previous period's
/// optimal set for steps up to [`WARM_STEP`] of each box width (each as
/// the pair `theta_prev`, `theta`: the bench solves `theta` warm from
/// `theta_prev`'s final set).
fn certified(file: &str) -> Vec<(String, Vec<f64>)> {
    let settings = CertifySettings {
        warm_step: Some(WARM_STEP),
        warm_any_order: true,
        ..CertifySettings::default()
    };
    let c = certify(&problem(file), &settings, &mut |_| {}).expect("certification");
    println!(
        "{file}: certified cold worst {} iterations ({} regions), warm (step {WARM_STEP}, any order) worst {} iterations",
        c.cold.worst_iterations,
        c.cold.regions,
        c.warm.as_ref().map_or(0, |w| w.worst_iterations)
    );
    let mut out = Vec::new();
    for (label, r) in [
        ("certified cold worst iterations", &c.cold.worst),
        ("certified cold worst flops", &c.cold.worst_flops_region),
    ] {
        if let Some(r) = r {
            out.push((format!("{label} ({})", r.iterations), r.theta.clone()));
        }
    }
    if let Some(w) = &c.warm {
        for (label, r) in [
            ("certified warm worst iterations", &w.worst),
            ("certified warm worst flops", &w.worst_flops_region),
        ] {
            if let Some(r) = r
                && let Some(prev) = &r.theta_prev
            {
                out.push((format!("{label}: previous theta"), prev.clone()));
                out.push((format!("{label} ({})", r.iterations), r.theta.clone()));
            }
        }
    }
    out
}

/// The warm start's certified parameter step (fraction of each box width).
const WARM_STEP: f64 = 0.05;

#[test]
fn qp16_on_the_avr_thesis_sized() {
    if !tools() {
        return;
    }
    let named = certified("qp16-thesis.mpqp.json");
    let named: Vec<(&str, Vec<f64>)> = named.iter().map(|(l, t)| (l.as_str(), t.clone())).collect();
    measure::<4, 9, 16, 128>("thesis", "qp16-thesis.mpqp.json", &named, 64);
}

#[test]
fn qp16_on_the_avr_larger() {
    if !tools() {
        return;
    }
    measure::<16, 9, 1, 0>("larger", "qp16-larger.mpqp.json", &[], 24);
}
