//! kestrel-empc's candidate-list point location on the ATmega2560: the
//! `u16` / `f32` tables written by `locate::list_bytes` into 4 kB chunks
//! of program memory, read through `locate::FlashLists` by
//! `kestrel_empc::evaluate_lists` in `avr/locate-bench` (built with the
//! pinned nightly), run in simavr at 16 MHz. Every answer (law, nodes,
//! hyperplanes tested, output bits) is compared with the host's evaluation
//! of the same tables, and the cycles (Timer1) are printed, one
//! `LOCATE-AVR-REPORT {json}` line per problem: at the worst parameter a
//! host search found (random points, then a climb maximising the
//! hyperplanes evaluated, also inside the longest list's leaf) and at 64
//! random parameters in the box, beside the builder's worst-case count
//! (extrapolated to cycles by a least-squares line through the measured
//! cycles against hyperplanes evaluated); `ten_rows_ram_flash` calibrates:
//! cycles of 10 affine rows in RAM, of reading as many numbers from
//! flash, of 10 rows evaluated from flash.
//!
//! The 75-region problem (`testing::scaled_thesis(1, 2, 1)`) runs by
//! default, in `f32` and in Q15.16 (`mac::Q16Mac` numbers: the answers
//! must equal the host's emulation bit for bit); the 1,075-region one (kestrel-empc's
//! `tests/data/locate-1075.mpqp.json`, 174 kB of tables) is `#[ignore]`d
//! (about a minute): `cargo test -p kestrel-avr-rt --test locate_avr --
//! --ignored`. Skipped when simavr, avr-gcc, avr-size or rustup is
//! missing, unless `KESTREL_REQUIRE_AVR` is set (then it fails).

use kestrel_avr_rt::host::{
    assert_no_miscompile, avr_cargo_build, avr_size, simavr, tools_present,
};
use kestrel_avr_rt::locate::{list_bytes, list_bytes_with};
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_core::formats::MpqpProblem;
use kestrel_empc::locate::{ListStats, LocateSettings, build_lists};
use kestrel_empc::{ListSlices, Outputs, Settings, evaluate_lists, solve};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Duration;

/// Chunk size of the flash table (2^12 bytes, as the firmware's chunked tables).
const CHUNK_BITS: u8 = 12;
/// One AVR build and simulation at a time (one target directory).
static AVR_LOCK: Mutex<()> = Mutex::new(());
/// Random parameters measured besides the worst ones.
const RANDOM: usize = 64;

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Whether the AVR tools are here (a missing one fails under `KESTREL_REQUIRE_AVR`).
fn tools() -> bool {
    tools_present("locate_avr", &["avr-gcc", "simavr", "avr-size", "rustup"])
}

struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
    fn in_box(&mut self, t: &ListSlices<'_, f32>) -> Vec<f32> {
        (0..t.n_params)
            .map(|j| t.theta_lb[j] + (t.theta_ub[j] - t.theta_lb[j]) * self.uniform())
            .collect()
    }
}

/// The leaf of `th` (a host walk of the tables' tree, for the search).
fn leaf_of(t: &ListSlices<'_, f32>, th: &[f32]) -> usize {
    let w = t.n_params + 1;
    let row = |r: u16| -> f32 {
        if r == kestrel_empc::NO_ROW {
            return 0.0;
        }
        let g = &t.rows[r as usize * w..(r as usize + 1) * w];
        th.iter().zip(g).fold(g[t.n_params], |a, (x, c)| a + c * x)
    };
    let mut code = t.root;
    while code & kestrel_empc::LEAF == 0 {
        let [h, le, gt] = t.nodes[code as usize];
        let [r1, r2] = t.hyperplanes[h as usize];
        code = if row(r1) <= row(r2) { le } else { gt };
    }
    (code & !kestrel_empc::LEAF) as usize
}

/// Hyperplanes evaluated at `th` (tree path plus region tests).
fn cost(t: &ListSlices<'_, f32>, th: &[f32]) -> usize {
    let mut s = vec![0.0f32; t.n_params];
    let mut z = vec![0.0f32; t.n_outputs];
    let e = evaluate_lists(t, th, &mut s, &mut z).unwrap();
    usize::from(e.steps) + usize::from(e.tests)
}

/// Climbs from `start` to a parameter evaluating more hyperplanes
/// (`keep`: which points may be taken).
fn climb(
    t: &ListSlices<'_, f32>,
    rng: &mut Rng,
    start: Vec<f32>,
    keep: &dyn Fn(&[f32]) -> bool,
    steps: usize,
) -> (Vec<f32>, usize) {
    let (mut best, mut c) = (start.clone(), cost(t, &start));
    for k in 0..steps {
        let scale = 0.2 * (1.0 - k as f32 / steps as f32) + 0.002;
        let cand: Vec<f32> = best
            .iter()
            .enumerate()
            .map(|(j, v)| {
                let span = t.theta_ub[j] - t.theta_lb[j];
                (v + scale * span * (rng.uniform() - 0.5)).clamp(t.theta_lb[j], t.theta_ub[j])
            })
            .collect();
        if keep(&cand) {
            let cc = cost(t, &cand);
            if cc >= c {
                (best, c) = (cand, cc);
            }
        }
    }
    (best, c)
}

/// The worst parameters found: overall, and inside the longest list's leaf.
fn worst_parameters(t: &ListSlices<'_, f32>, rng: &mut Rng) -> Vec<Vec<f32>> {
    let longest = (0..t.leaves.len())
        .max_by_key(|&l| t.leaves[l][1] - t.leaves[l][0])
        .unwrap();
    let (mut all, mut inside) = ((Vec::new(), 0), (None, 0));
    for _ in 0..20_000 {
        let th = rng.in_box(t);
        let c = cost(t, &th);
        if leaf_of(t, &th) == longest && c > inside.1 {
            inside = (Some(th.clone()), c);
        }
        if c > all.1 {
            all = (th, c);
        }
    }
    let mut out = vec![climb(t, rng, all.0, &|_| true, 20_000).0];
    if let Some(th) = inside.0 {
        out.push(climb(t, rng, th, &|x| leaf_of(t, x) == longest, 20_000).0);
    }
    out
}

/// Writes the generated file and the chunks into `dir`.
fn generate(
    dir: &Path,
    t: &ListSlices<'_, f32>,
    thetas: &[Vec<f32>],
    fixed: Option<&ListSlices<'_, Q16Mac>>,
) {
    std::fs::create_dir_all(dir).unwrap();
    let (bytes, layout) = match fixed {
        Some(q) => list_bytes_with(q, |v: Q16Mac| v.0.to_le_bytes()),
        None => list_bytes(t),
    };
    let size = 1usize << CHUNK_BITS;
    let chunks: Vec<&[u8]> = bytes.chunks(size).collect();
    let mut s =
        String::from("// @generated by kestrel-avr-rt's tests/locate_avr.rs; do not edit.\n");
    let ty = if fixed.is_some() {
        "kestrel_avr_rt::mac::Q16Mac"
    } else {
        "f32"
    };
    writeln!(s, "type S = {ty};\nconst LAYOUT: ListLayout = {layout:?};").unwrap();
    writeln!(
        s,
        "const P: usize = {};\nconst K: usize = {};",
        t.n_params, t.n_outputs
    )
    .unwrap();
    for (i, c) in chunks.iter().enumerate() {
        let f = dir.join(format!("chunk{i}.bin"));
        std::fs::write(&f, c).unwrap();
        writeln!(
            s,
            "#[unsafe(link_section = \".text.kestrel_tables\")]\n#[used]\nstatic C{i}: [u8; {}] = *include_bytes!({:?});",
            c.len(),
            f.display()
        )
        .unwrap();
    }
    let list: Vec<String> = (0..chunks.len())
        .map(|i| format!("kestrel_avr_rt::far_table!(C{i})"))
        .collect();
    writeln!(
        s,
        "const N_CHUNKS: usize = {};\nconst CHUNK_BYTES: u32 = {size};\nfn chunks() -> [kestrel_avr_rt::progmem::FarTable; N_CHUNKS] {{\n    [{}]\n}}",
        chunks.len(),
        list.join(", ")
    )
    .unwrap();
    writeln!(s, "static THETAS: [[S; P]; {}] = [", thetas.len()).unwrap();
    for th in thetas {
        let v: Vec<String> = th
            .iter()
            .map(|x| match fixed {
                Some(_) => format!("kestrel_avr_rt::mac::Q16Mac({})", q16(*x).0),
                None => format!("f32::from_bits({:#x})", x.to_bits()),
            })
            .collect();
        writeln!(s, "    [{}],", v.join(", ")).unwrap();
    }
    s.push_str("];\n");
    std::fs::write(dir.join("generated.rs"), s).unwrap();
}

/// `x` in Q15.16.
fn q16(x: f32) -> Q16Mac {
    kestrel_core::Scalar::from_f64(f64::from(x))
}

/// Builds avr/locate-bench over `generated` with the pinned nightly; the ELF.
fn build(generated: &Path) -> PathBuf {
    let root = repo_root();
    let mut cmd = avr_cargo_build(&root);
    cmd.env("KESTREL_LOCATE_GENERATED", generated);
    let status = cmd
        .current_dir(root.join("avr/locate-bench"))
        .status()
        .expect("run rustup/cargo");
    assert!(status.success(), "avr/locate-bench build failed");
    let elf = root.join("avr/target/avr-none/release/kestrel-avr-locate-bench.elf");
    let copy = generated.with_file_name("bench.elf");
    std::fs::copy(&elf, &copy).unwrap();
    // The pinned nightly's two AVR miscompilations (docs/avr-qp.md).
    assert_no_miscompile(&copy, |f| f == "main");
    copy
}

/// simavr's USART0 lines; a run that does not end within `limit` fails.
fn simulate(elf: &Path, limit: Duration) -> Vec<String> {
    let run = simavr(elf, limit).expect("run simavr");
    assert!(run.ended, "simavr did not end within {limit:?}");
    run.lines
}

fn flash_bytes(elf: &Path) -> u64 {
    avr_size(elf).expect("avr-size").flash
}

/// Builds the lists of `problem`, runs them on the AVR and checks/prints.
fn measure(name: &str, problem: &MpqpProblem, fixed: bool) {
    let solution = solve(problem, &Settings::default()).unwrap();
    let settings = LocateSettings {
        outputs: Outputs::First(4),
        ..LocateSettings::default()
    };
    let c = build_lists(problem, &solution, &settings, &mut |_| {}).unwrap();
    let stats: &ListStats = &c.stats;
    let single = c.tables.narrow().expect("u16 tables").cast::<f32>();
    let t = single.tables();
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    let mut thetas = worst_parameters(&t, &mut rng);
    let n_worst = thetas.len();
    for _ in 0..RANDOM {
        thetas.push(rng.in_box(&t));
    }
    let quantised = c.tables.narrow().expect("u16 tables").cast::<Q16Mac>();
    let q = quantised.tables();
    let name = &format!("{name}-{}", if fixed { "q16" } else { "f32" });
    if fixed {
        // The host's Q15.16 answers first (a failure here is the host's).
        let (mut sq, mut zq) = (vec![Q16Mac(0); t.n_params], vec![Q16Mac(0); t.n_outputs]);
        for th in &thetas {
            let thq: Vec<Q16Mac> = th.iter().map(|x| q16(*x)).collect();
            evaluate_lists(&q, &thq, &mut sq, &mut zq).unwrap();
        }
    }
    let dir = repo_root().join(format!("avr/target/locate-bench-gen/{name}"));
    generate(&dir, &t, &thetas, fixed.then_some(&q));
    let (flash, lines) = {
        let _guard = AVR_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        let elf = build(&dir.join("generated.rs"));
        let flash = flash_bytes(&elf);
        (flash, simulate(&elf, Duration::from_secs(600)))
    };
    assert!(flash <= 256 * 1024, "{name}: {flash} B of flash");
    assert!(lines.iter().any(|l| l == "INIT 0"), "{name}: {lines:#?}");
    assert!(lines.iter().any(|l| l == "END"), "{name}: {lines:#?}");
    let cal = lines
        .iter()
        .find_map(|l| l.strip_prefix("CAL "))
        .unwrap_or("? ?");
    let rows: Vec<Vec<u32>> = lines
        .iter()
        .filter_map(|l| l.strip_prefix("L "))
        .map(|l| {
            assert!(!l.contains("ERR"), "{name}: evaluation error: {l}");
            l.split_whitespace().map(|v| v.parse().unwrap()).collect()
        })
        .collect();
    assert_eq!(rows.len(), thetas.len(), "{name}: {lines:#?}");
    let (mut s, mut z) = (vec![0.0f32; t.n_params], vec![0.0f32; t.n_outputs]);
    let (mut sq, mut zq) = (vec![Q16Mac(0); t.n_params], vec![Q16Mac(0); t.n_outputs]);
    let mut cycles = Vec::new();
    let (mut equal_bits, mut same_law_as_f32, mut max_diff_f32) = (0, 0, 0.0f64);
    for (i, (th, r)) in thetas.iter().zip(&rows).enumerate() {
        assert_eq!(r[0] as usize, i);
        let e = evaluate_lists(&t, th, &mut s, &mut z).unwrap();
        // The host's answer in the AVR's scalar, and its output bits.
        let (want, bits): (_, Vec<u32>) = if fixed {
            let thq: Vec<Q16Mac> = th.iter().map(|x| q16(*x)).collect();
            let eq = evaluate_lists(&q, &thq, &mut sq, &mut zq).unwrap();
            for (o, v) in z.iter().enumerate() {
                let avr = f64::from(r[5 + o] as i32) / 65536.0;
                max_diff_f32 = max_diff_f32.max((avr - f64::from(*v)).abs());
            }
            same_law_as_f32 += usize::from(eq.law == e.law);
            (eq, zq.iter().map(|v| v.0 as u32).collect())
        } else {
            for (o, v) in z.iter().enumerate() {
                let avr = f32::from_bits(r[5 + o]);
                max_diff_f32 = max_diff_f32.max(f64::from((avr - v).abs()));
            }
            same_law_as_f32 += 1;
            (e, z.iter().map(|v| v.to_bits()).collect())
        };
        assert_eq!(
            (r[1], r[2], r[3]),
            (
                u32::from(want.law),
                u32::from(want.steps),
                u32::from(want.tests)
            ),
            "{name}: parameter {i}: law, nodes, hyperplanes"
        );
        equal_bits += usize::from(bits[..] == r[5..]);
        cycles.push((r[4], usize::from(want.steps) + usize::from(want.tests)));
    }
    // f32 on the AVR: the host's bits (avr-libc rounds as IEEE); Q15.16:
    // the host's emulation of the MAC.
    assert_eq!(equal_bits, thetas.len(), "{name}: output bits");
    if !fixed {
        assert!(max_diff_f32 == 0.0, "{name}: {max_diff_f32}");
    }
    let worst = cycles[..n_worst].iter().max_by_key(|c| c.0).unwrap();
    let random = &cycles[n_worst..];
    let (min, max) = (
        random.iter().map(|c| c.0).min().unwrap(),
        random.iter().map(|c| c.0).max().unwrap(),
    );
    let mean = random.iter().map(|c| f64::from(c.0)).sum::<f64>() / random.len() as f64;
    // Cycles against hyperplanes evaluated, least squares over every
    // measured parameter (fixed part: box, outputs; slope: one hyperplane,
    // one or two rows), extrapolated to the builder's worst case.
    let n = cycles.len() as f64;
    let (sx, sy) = cycles
        .iter()
        .fold((0.0, 0.0), |(a, b), c| (a + c.1 as f64, b + f64::from(c.0)));
    let (mx, my) = (sx / n, sy / n);
    let (sxy, sxx) = cycles.iter().fold((0.0, 0.0), |(a, b), c| {
        let dx = c.1 as f64 - mx;
        (a + dx * (f64::from(c.0) - my), b + dx * dx)
    });
    let per = sxy / sxx;
    let fixed = my - per * mx;
    println!(
        "LOCATE-AVR-REPORT {{\"problem\": \"{name}\", \"regions\": {}, \"table_bytes\": {}, \"flash\": {flash}, \"worst_case_mul_adds\": {}, \"worst_case_hyperplanes\": {}, \"max_leaf_regions\": {}, \"worst_found\": {{\"cycles\": {}, \"hyperplanes\": {}}}, \"random\": {{\"n\": {}, \"min\": {min}, \"mean\": {mean:.0}, \"max\": {max}}}, \"cycles_per_hyperplane\": {per:.0}, \"fixed_cycles\": {fixed:.0}, \"bound_cycles_est\": {:.0}, \"equal_bits\": {equal_bits}, \"of\": {}, \"same_law_as_f32\": {same_law_as_f32}, \"max_output_diff_from_f32\": {max_diff_f32:.2e}, \"ten_rows_ram_flash\": \"{cal}\"}}",
        stats.regions,
        list_bytes(&t).0.len(),
        stats.worst_case.mul_adds,
        stats.worst_case_hyperplanes,
        stats.max_leaf_regions,
        worst.0,
        worst.1,
        random.len(),
        fixed + per * stats.worst_case_hyperplanes as f64,
        thetas.len(),
    );
}

#[test]
fn lists_on_the_avr_75_regions() {
    if !tools() {
        return;
    }
    let problem = kestrel_empc::testing::scaled_thesis(1, 2, 1);
    measure("p75", &problem, false);
    measure("p75", &problem, true);
}

#[test]
#[ignore = "about a minute: the 1,075-region problem (174 kB of tables) in simavr"]
fn lists_on_the_avr_1075_regions() {
    if !tools() {
        return;
    }
    let path = repo_root().join("crates/empc/tests/data/locate-1075.mpqp.json");
    // f32 only: the Q15.16 build of these tables stops in simavr after
    // its calibration line, at its first evaluation (no panic: the
    // handler would send PANIC; the host's emulation completes). Open.
    measure("p1075", &MpqpProblem::read(&path).unwrap(), false);
}

/// Any `kestrel.mpqp.v1` problem named by `KESTREL_LOCATE_AVR_PROBLEM`
/// (skipped without it), e.g. the 1,395-region one, whose 234 kB of
/// tables may not fit beside the program.
#[test]
#[ignore = "needs KESTREL_LOCATE_AVR_PROBLEM"]
fn lists_on_the_avr_from_a_file() {
    let Some(path) = std::env::var_os("KESTREL_LOCATE_AVR_PROBLEM") else {
        println!("KESTREL_LOCATE_AVR_PROBLEM not set");
        return;
    };
    if !tools() {
        return;
    }
    let path = PathBuf::from(path);
    let name = path
        .file_stem()
        .unwrap()
        .to_string_lossy()
        .replace('.', "-");
    measure(&name, &MpqpProblem::read(&path).unwrap(), false);
}
