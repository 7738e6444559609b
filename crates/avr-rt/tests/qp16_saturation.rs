//! The saturation branches of kestrel-avr-rt's `qp16` AVR assembly on the
//! ATmega2560 (simavr, 16 MHz): crafted inputs for the rounded sum
//! (`mac_round`), the rows routine (`rows_round`, its general rounding and
//! its shift-25 path), the 16-bit rows routine of `w_unc`
//! (`Row16::apply_all`, `Row16::add_all`) and the per-set kernel's pass
//! loops (`qp16::probe`: members' residuals, multipliers, the point and
//! most-violated scan), compiled into the test program in
//! `tests/qp16_saturation/avr` (the pinned nightly) and run in simavr. Every
//! AVR result must equal the host's run of the same function bit for bit,
//! and the host's must equal an independent `i128` computation of the
//! exact value, rounded half up and saturated. Each case is classified by
//! that computation (saturated up or down, exactly at a limit, a tie that
//! rounds up across or onto a limit), and the test checks that every
//! routine reached every class its arithmetic allows (docs/avr-qp.md says
//! why the others cannot happen). Boundary cases: the largest term counts
//! (255 for the rounded sum, 63 for the carry-counting rows routine, 31
//! for the 16-bit rows) and one past them (the wrappers then take the
//! portable path: the same bits, no error), shifts clamped at both ends.
//! Skipped when simavr, avr-gcc or rustup is missing, unless
//! `KESTREL_REQUIRE_AVR` is set (then it fails).

use kestrel_avr_rt::host::{assert_no_miscompile, avr_cargo_build, simavr, tools_present};
use kestrel_avr_rt::mac::Row16;
use kestrel_avr_rt::qp16::probe::{self, PassVar};
use kestrel_avr_rt::qp16::{mac_round, rows_round};
use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

#[path = "qp16_saturation/cases.rs"]
mod cases;
use cases::{Case, Class, Routine, cases};

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `bulk` then `tail` in `n` entries (as the AVR program's `fill`).
fn fill(n: usize, bulk: i32, tail: &[i32]) -> Vec<i32> {
    assert!(tail.len() <= n);
    let cut = n - tail.len();
    (0..n)
        .map(|i| if i < cut { bulk } else { tail[i - cut] })
        .collect()
}

/// The rows case's data and `r` (as the AVR program builds them).
fn rows_data(k: usize, rb: i32, rt: &[i32], db: &[i32], dt: &[i32]) -> (Vec<i32>, Vec<i32>) {
    let t = rt.len();
    let r = fill(k, rb, rt);
    let mut data = Vec::new();
    for (i, d) in db.iter().enumerate() {
        data.extend(fill(k, *d, &dt[i * t..(i + 1) * t]));
    }
    (data, r)
}

/// `round(x / 2^s)` half up (exact) and whether it was a tie.
fn round_half_up(x: i128, s: u32) -> (i128, bool) {
    if s == 0 {
        return (x, false);
    }
    let q = x >> s;
    let rem = x - (q << s);
    let half = 1i128 << (s - 1);
    (q + i128::from(rem >= half), rem == half)
}

fn sat(x: i128) -> i32 {
    x.clamp(i32::MIN.into(), i32::MAX.into()) as i32
}

fn row16_host<const N: usize>(rows: &[(Vec<i16>, u8, u8)], v: &[i32], acc: &[i32]) -> Vec<i32> {
    let v: [i32; N] = v.try_into().unwrap();
    let rows: Vec<Row16<N>> = rows
        .iter()
        .map(|(c, s, st)| Row16::new(c.as_slice().try_into().unwrap(), *s, *st))
        .collect();
    let mut out: Vec<i32> = rows
        .iter()
        .map(|r| Row16::apply_all(&[*r], &v)[0])
        .collect();
    for (r, a) in rows.iter().zip(acc) {
        let mut o = [*a];
        Row16::add_all(&[*r], &v, &mut o);
        out.push(o[0]);
    }
    out
}

fn members_host<const N: usize>(var: &[PassVar]) -> Vec<i32> {
    let (mask, q, r) = probe::members::<N>(var.try_into().unwrap());
    [mask as i32, q as i32].into_iter().chain(r).collect()
}

fn stars_host<const N: usize>(var: &[PassVar], out: &[i32], limit: i32) -> Vec<i32> {
    let mut var: [PassVar; N] = var.try_into().unwrap();
    let cand = probe::stars(&mut var, out.try_into().unwrap(), limit);
    std::iter::once(cand as i32)
        .chain(var.iter().map(|v| v.star))
        .collect()
}

fn scan_host<const N: usize>(var: &[PassVar], out: &[i32], k: usize, tol: i32) -> Vec<i32> {
    let mut var: [PassVar; N] = var.try_into().unwrap();
    let (best, code) = probe::scan(&mut var, out.try_into().unwrap(), k, tol);
    [best as i32, i32::from(code)]
        .into_iter()
        .chain(var.iter().flat_map(|v| [v.w, v.nu]))
        .collect()
}

/// Calls `$f::<N>` for the runtime length `$n` (the lengths the cases use).
macro_rules! by_len {
    ($n:expr, $f:ident ( $($a:expr),* )) => {
        match $n {
            1 => $f::<1>($($a),*),
            2 => $f::<2>($($a),*),
            3 => $f::<3>($($a),*),
            4 => $f::<4>($($a),*),
            8 => $f::<8>($($a),*),
            24 => $f::<24>($($a),*),
            31 => $f::<31>($($a),*),
            32 => $f::<32>($($a),*),
            n => panic!("no case length {n}"),
        }
    };
}

impl Case {
    /// The library's answer on the host (the portable code).
    fn host(&self) -> Vec<i32> {
        match self {
            Case::Mac {
                n,
                ab,
                at,
                bb,
                bt,
                shift,
            } => vec![mac_round(&fill(*n, *ab, at), &fill(*n, *bb, bt), *shift)],
            Case::Rows {
                k,
                shift,
                rb,
                rt,
                db,
                dt,
            } => {
                let (data, r) = rows_data(*k, *rb, rt, db, dt);
                let mut out = vec![0; db.len()];
                rows_round(&data, &r, *shift, &mut out);
                out
            }
            Case::Row16 { rows, v, acc } => by_len!(v.len(), row16_host(rows, v, acc)),
            Case::Members(var) => by_len!(var.len(), members_host(var)),
            Case::Stars(var, out, limit) => by_len!(var.len(), stars_host(var, out, *limit)),
            Case::Scan(var, out, k, tol) => by_len!(var.len(), scan_host(var, out, *k, *tol)),
        }
    }

    /// The independent answer (`i128` exact values, rounded half up,
    /// saturated), recording each rounded quantity's class.
    fn reference(&self, seen: &mut BTreeSet<(Routine, Class)>) -> Vec<i32> {
        let mut note = |r: Routine, c: Option<Class>| {
            if let Some(c) = c {
                seen.insert((r, c));
            }
        };
        match self {
            Case::Mac {
                n,
                ab,
                at,
                bb,
                bt,
                shift,
            } => {
                let (a, b) = (fill(*n, *ab, at), fill(*n, *bb, bt));
                let x: i128 = a.iter().zip(&b).map(|(p, q)| *p as i128 * *q as i128).sum();
                let s = u32::from((*shift).clamp(16, 46));
                let (r, tie) = round_half_up(x, s);
                if *n <= 255 {
                    note(Routine::Mac, Class::of(r, tie));
                }
                vec![sat(r)]
            }
            Case::Rows {
                k,
                shift,
                rb,
                rt,
                db,
                dt,
            } => {
                if *k == 0 {
                    return vec![0; db.len()];
                }
                let (data, r) = rows_data(*k, *rb, rt, db, dt);
                let s = u32::from((*shift).clamp(16, 46));
                let routine = if s == 25 {
                    Routine::Rows25
                } else {
                    Routine::Rows
                };
                data.chunks(*k)
                    .map(|row| {
                        let x: i128 = row
                            .iter()
                            .zip(&r)
                            .map(|(p, q)| *p as i128 * *q as i128)
                            .sum();
                        let (v, tie) = round_half_up(x as i64 as i128, s); // modulo 2^64
                        if *k <= 63 {
                            note(routine, Class::of(v, tie));
                        }
                        sat(v)
                    })
                    .collect()
            }
            Case::Row16 { rows, v, acc } => {
                let mut apply = Vec::new();
                let mut add = Vec::new();
                for ((c, shift, start), a) in rows.iter().zip(acc) {
                    let x: i128 = c
                        .iter()
                        .zip(v)
                        .skip(*start as usize)
                        .map(|(p, q)| *p as i128 * *q as i128)
                        .sum();
                    let (r, tie) = round_half_up(x, u32::from((*shift).min(48)));
                    let total = r + *a as i128;
                    if v.len() <= 31 {
                        note(Routine::Apply, Class::of(r, tie));
                        note(Routine::Add, Class::of(total, tie));
                    }
                    apply.push(sat(r));
                    add.push(sat(total));
                }
                apply.into_iter().chain(add).collect()
            }
            Case::Members(var) => {
                let (mut mask, mut out) = (0, Vec::new());
                for (j, v) in var.iter().enumerate() {
                    if v.pos != 0 {
                        mask |= 1 << j;
                        let b = if v.code & 1 == 1 { v.hi } else { v.lo };
                        let x = v.unc as i128 - b as i128;
                        note(Routine::Members, Class::of(x, false));
                        out.push(sat(x));
                    }
                }
                let q = out.len() as i32;
                out.resize(var.len(), 0);
                [mask, q].into_iter().chain(out).collect()
            }
            Case::Stars(var, out, limit) => {
                let (mut cand, mut q, mut stars) = (0, 0, Vec::new());
                for (j, v) in var.iter().enumerate() {
                    if v.pos == 0 {
                        stars.push(v.star);
                        continue;
                    }
                    let star = out[q];
                    q += 1;
                    stars.push(star);
                    if v.code >= 2 {
                        continue;
                    }
                    let signed = if v.code == 1 {
                        star as i128
                    } else {
                        let x = -(star as i128);
                        note(Routine::Stars, Class::of(x, false));
                        x
                    };
                    if sat(signed) < *limit {
                        cand |= 1 << j;
                    }
                }
                std::iter::once(cand).chain(stars).collect()
            }
            Case::Scan(var, out, k, tol) => {
                let (mut best, mut code, mut worst) = (var.len() as i32, 0, *tol as i128);
                let mut q = *k;
                let mut wn = Vec::new();
                for (j, x) in var.iter().enumerate() {
                    if x.pos != 0 {
                        wn.extend([if x.code & 1 == 1 { x.hi } else { x.lo }, x.star]);
                        continue;
                    }
                    let ve = x.unc as i128 - out[q] as i128;
                    q += 1;
                    note(Routine::ScanPoint, Class::of(ve, false));
                    let v = sat(ve) as i128;
                    wn.extend([v as i32, x.nu]);
                    let (d, side) = if v > x.hi as i128 {
                        let d = v - x.hi as i128;
                        note(Routine::ScanAbove, Class::of(d, false));
                        (d, 1)
                    } else if v < x.lo as i128 {
                        let d = x.lo as i128 - v;
                        note(Routine::ScanBelow, Class::of(d, false));
                        (d, 0)
                    } else {
                        continue;
                    };
                    let d = sat(d) as i128;
                    if d > worst {
                        worst = d;
                        best = j as i32;
                        code = side | if x.lo == x.hi { 2 } else { 0 };
                    }
                }
                [best, code].into_iter().chain(wn).collect()
            }
        }
    }
}

/// Builds the AVR program over `generated`; the ELF's copy.
fn build(root: &Path, generated: &Path) -> PathBuf {
    let target = root.join("avr/target");
    let status = avr_cargo_build(root)
        .args(["--target", "avr-none", "-Zbuild-std=core", "--target-dir"])
        .arg(&target)
        .env(
            "CARGO_TARGET_AVR_NONE_RUSTFLAGS",
            "-C target-cpu=atmega2560",
        )
        .env("KESTREL_SAT_GENERATED", generated)
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/qp16_saturation/avr"))
        .status()
        .expect("run rustup/cargo");
    assert!(status.success(), "tests/qp16_saturation/avr build failed");
    let elf = target.join("avr-none/release/kestrel-avr-qp16-saturation.elf");
    let copy = generated.with_extension("elf");
    std::fs::copy(&elf, &copy).unwrap();
    // The pinned nightly's two AVR miscompilations (docs/avr-qp.md).
    assert_no_miscompile(&copy, |f| f == "main");
    copy
}

#[test]
fn host_equals_the_exact_rounded_saturated_value_and_every_branch_is_reached() {
    let cases = cases();
    let mut seen = BTreeSet::new();
    for (id, case) in cases.iter().enumerate() {
        assert_eq!(
            case.host(),
            case.reference(&mut seen),
            "case {id}: {case:?}"
        );
    }
    let missing: Vec<_> = Routine::required()
        .into_iter()
        .filter(|rc| !seen.contains(rc))
        .collect();
    assert!(missing.is_empty(), "classes not reached: {missing:?}");
}

#[test]
fn qp16_saturation_on_the_avr_equals_the_host() {
    if !tools_present("qp16_saturation", &["avr-gcc", "simavr", "rustup"]) {
        return;
    }
    let cases = cases();
    let root = repo_root();
    let dir = root.join("avr/target/qp16-saturation-gen");
    std::fs::create_dir_all(&dir).unwrap();
    let mut values = 0;
    // One program per group of routines (all cases in one would put code
    // beyond 128 kB of flash and the operands in more than the 8 kB of RAM).
    for group in 0..3 {
        let mine: Vec<(usize, &Case)> = cases
            .iter()
            .enumerate()
            .filter(|(_, c)| c.group() == group)
            .collect();
        let mut g = String::from(
            "// @generated by kestrel-avr-rt's tests/qp16_saturation.rs; do not edit.\nfn cases() {\n",
        );
        for (id, case) in &mine {
            writeln!(g, "    {}", case.call(*id)).unwrap();
        }
        g.push_str("}\n");
        let file = dir.join(format!("generated-{group}.rs"));
        std::fs::write(&file, g).unwrap();
        let elf = build(&root, &file);
        let run = simavr(&elf, Duration::from_secs(120)).expect("run simavr");
        assert!(
            run.ended,
            "group {group}: simavr did not end: {:#?}",
            run.lines
        );
        let lines = run.lines;
        assert!(lines.iter().any(|l| l == "INIT"), "{lines:#?}");
        assert!(lines.iter().any(|l| l == "END"), "{lines:#?}");
        let got: Vec<&String> = lines.iter().filter(|l| l.starts_with("C ")).collect();
        assert_eq!(got.len(), mine.len(), "group {group}: {lines:#?}");
        for (line, (id, case)) in got.iter().zip(&mine) {
            let want = case.host();
            let expect = want.iter().fold(format!("C {id}"), |mut s, v| {
                write!(s, " {}", *v as u32).unwrap();
                s
            });
            assert_eq!(line.as_str(), expect, "case {id}: {case:?}");
            values += want.len();
        }
    }
    println!(
        "qp16 saturation: {} cases, {values} values equal on the AVR and the host",
        cases.len()
    );
}
