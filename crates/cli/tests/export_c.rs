//! End-to-end tests of `kestrel export --lang c`: the C tables hold the
//! Rust tables' numbers bit for bit (parsed back, and as the C compiler
//! reads them), carry kestrel-ffi's design checksum, compile with the
//! host C compiler and avr-gcc, and bad inputs are refused as with
//! `--lang rust`, without writing anything.

mod common;

use common::{MODEL, kestrel, temp_dir};
use std::path::{Path, PathBuf};
use std::process::Command;

fn dir(name: &str) -> PathBuf {
    let d = temp_dir("export-c").join(name);
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// `kestrel export --lang c` of the model with `extra` flags into `out`;
/// the header and the source.
fn export_c(out: &Path, extra: &[&str]) -> (String, String) {
    let mut args = vec!["export", "--model", MODEL, "--lang", "c"];
    args.extend(extra);
    args.extend(["--out", out.to_str().unwrap()]);
    let (ok, _, err) = kestrel(&args);
    assert!(ok, "{err}");
    (
        std::fs::read_to_string(out.join("kestrel_design.h")).unwrap(),
        std::fs::read_to_string(out.join("kestrel_design.c")).unwrap(),
    )
}

/// The text between `{` after `start` and the matching `}`, comments removed.
fn braced<'a>(src: &'a str, start: &str) -> &'a str {
    let at = src.find(start).unwrap_or_else(|| panic!("{start}"));
    let open = at + src[at..].find('{').unwrap();
    let mut depth = 0;
    for (i, ch) in src[open..].char_indices() {
        match ch {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    return &src[open + 1..open + i];
                }
            }
            _ => {}
        }
    }
    panic!("unbalanced {start}");
}

/// The text of the Rust array `start ... = [` up to its `];`.
fn bracketed<'a>(src: &'a str, start: &str) -> &'a str {
    let s = &src[src.find(start).unwrap_or_else(|| panic!("{start}"))..];
    &s[s.find("= [").unwrap() + 3..s.find("];").unwrap()]
}

/// The numbers of an initializer or a Rust array literal, in order (`f`
/// suffixes and `Row16::new` dropped).
fn numbers(body: &str) -> Vec<String> {
    body.replace("kestrel_avr_rt::kalman16::Row16::new", "")
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '.' || c == '-' || c == '+'))
        .filter(|s| !s.is_empty())
        .map(|s| s.trim_end_matches('f').to_string())
        .collect()
}

fn f32_bits(v: &[String]) -> Vec<u32> {
    v.iter()
        .map(|s| s.parse::<f32>().unwrap_or_else(|_| panic!("{s}")).to_bits())
        .collect()
}

/// `#define KESTREL_DESIGN_NAME V` of the header.
fn define(h: &str, name: &str) -> String {
    let key = format!("#define KESTREL_DESIGN_{name} ");
    let at = h.find(&key).unwrap_or_else(|| panic!("{name}")) + key.len();
    h[at..].lines().next().unwrap().trim().to_string()
}

/// `pub const NAME: T = V;` of the Rust source.
fn rust_const(src: &str, name: &str) -> String {
    let at = src.find(&format!("pub const {name}: ")).unwrap();
    let line = src[at..].lines().next().unwrap();
    line.split("= ")
        .nth(1)
        .unwrap()
        .trim_end_matches(';')
        .to_string()
}

/// CRC-16/CCITT-FALSE, written here from its definition (polynomial
/// 0x1021, initial 0xFFFF, no reflection, no final XOR).
fn crc16(data: &[u8]) -> u16 {
    let mut crc = 0xFFFFu16;
    for &b in data {
        crc ^= u16::from(b) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// The Rust tables' bytes in kestrel-ffi's layout, from `generated.rs`:
/// (values f32, values Q16, kalman16, fgm16).
fn rust_table_bytes(rs: &str) -> [Vec<u8>; 4] {
    let f: Vec<u8> = f32_bits(&numbers(bracketed(rs, "pub const VALUES_F32")))
        .iter()
        .flat_map(|b| b.to_le_bytes())
        .collect();
    let q: Vec<u8> = numbers(bracketed(rs, "pub const VALUES_Q16"))
        .iter()
        .flat_map(|s| s.parse::<i32>().unwrap().to_le_bytes())
        .collect();
    // KF16: each row `([c...], shift, start)`, y0 after the C rows.
    let ny: usize = rust_const(rs, "NP").parse::<usize>().unwrap()
        - rust_const(rs, "NX").parse::<usize>().unwrap()
        - 1;
    let kf = &rs[rs.find("pub const KF16").unwrap()..];
    let rows = |block: &str| -> Vec<u8> {
        let mut b = Vec::new();
        for l in block.lines().filter(|l| l.contains("Row16::new([")) {
            let v = numbers(&l[l.find("([").unwrap()..]);
            let (c, tail) = v.split_at(v.len() - 2);
            b.extend(
                c.iter()
                    .flat_map(|s| s.parse::<i16>().unwrap().to_le_bytes()),
            );
            b.extend(tail.iter().map(|s| s.parse::<u8>().unwrap()));
        }
        b
    };
    let block = |name: &str| {
        let s = &kf[kf.find(&format!("    {name}: ")).unwrap()..];
        s[..s.find("],\n").unwrap() + 2].to_string()
    };
    let mut k = rows(&block("c"));
    let y0 = block("y0");
    let y0 = numbers(&y0[y0.find('[').unwrap()..]);
    assert_eq!(y0.len(), ny);
    k.extend(
        y0.iter()
            .flat_map(|s| s.parse::<i32>().unwrap().to_le_bytes()),
    );
    for name in ["m", "a", "b"] {
        k.extend(rows(&block(name)));
    }
    let fg = &rs[rs.find("pub const FGM16_M").unwrap()..];
    let mut g = rows(&fg[..fg.find("];").unwrap()]);
    g.extend(
        numbers(bracketed(rs, "pub const FGM16_BETAS"))
            .iter()
            .flat_map(|s| s.parse::<i16>().unwrap().to_le_bytes()),
    );
    [f, q, k, g]
}

/// The C tables' bytes from the source text (the same order).
fn c_table_bytes(c: &str) -> [Vec<u8>; 4] {
    let f = f32_bits(&numbers(braced(c, "kestrel_design_values_f32[")))
        .iter()
        .flat_map(|b| b.to_le_bytes())
        .collect();
    let q = numbers(braced(c, "kestrel_design_values_q16["))
        .iter()
        .flat_map(|s| s.parse::<i32>().unwrap().to_le_bytes())
        .collect();
    // Rows: coefficients int16_t, shift and start uint8_t; y0 int32_t.
    let rows16 = |v: &[String], len: usize| -> Vec<u8> {
        let mut b = Vec::new();
        for r in v.chunks(len + 2) {
            b.extend(
                r[..len]
                    .iter()
                    .flat_map(|s| s.parse::<i16>().unwrap().to_le_bytes()),
            );
            b.extend(r[len..].iter().map(|s| s.parse::<u8>().unwrap()));
        }
        b
    };
    let kf = numbers(braced(c, "kestrel_design_kalman16 KESTREL"));
    let (nx, nu, ny) = (5, 4, 3);
    let mut k = rows16(&kf[..ny * (nx + 2)], nx);
    let mut at = ny * (nx + 2);
    k.extend(
        kf[at..at + ny]
            .iter()
            .flat_map(|s| s.parse::<i32>().unwrap().to_le_bytes()),
    );
    at += ny;
    for len in [ny, nx, nu] {
        k.extend(rows16(&kf[at..at + nx * (len + 2)], len));
        at += nx * (len + 2);
    }
    assert_eq!(at, kf.len());
    let fg = numbers(braced(c, "kestrel_design_fgm16 KESTREL"));
    let nz = 4;
    let mut g = rows16(&fg[..nz * (nz + 2)], nz);
    g.extend(
        fg[nz * (nz + 2)..]
            .iter()
            .flat_map(|s| s.parse::<i16>().unwrap().to_le_bytes()),
    );
    [f, q, k, g]
}

/// kestrel-ffi's checksum of the tables with the value table of `format`.
fn checksum(t: &[Vec<u8>; 4], format: u8, warm: u8, iterations: u16) -> u16 {
    let mut b = t[usize::from(format)].clone();
    b.extend(&t[2]);
    b.extend(&t[3]);
    b.extend([format, warm]);
    b.extend(iterations.to_le_bytes());
    crc16(&b)
}

fn hex16(s: &str) -> u16 {
    u16::from_str_radix(s.trim_start_matches("0x").trim_end_matches('u'), 16).unwrap()
}

#[test]
fn thesis_tables_in_c_equal_the_rust_tables_bit_for_bit() {
    let out = dir("thesis");
    let (h, c) = export_c(&out, &[]);
    // The default design is the firmware's (`kestrel codegen` checks
    // generated.rs against the same generator).
    let rs = std::fs::read_to_string(repo("avr/firmware/src/generated.rs")).unwrap();
    let (rust, ct) = (rust_table_bytes(&rs), c_table_bytes(&c));
    for (i, name) in ["values_f32", "values_q16", "kalman16", "fgm16"]
        .iter()
        .enumerate()
    {
        assert_eq!(rust[i], ct[i], "{name}");
    }
    let lens: Vec<usize> = ct.iter().map(Vec::len).collect();
    assert_eq!(lens, [608, 608, 198, 42]);
    for (c_name, rust_name) in [
        ("NX", "NX"),
        ("NZ", "NZ"),
        ("NP", "NP"),
        ("FGM_T", "FGM_T"),
        ("FGM_ITERATIONS", "FGM_ITERATIONS"),
        ("FGM_LOOP_ITERATIONS", "FGM_LOOP_ITERATIONS"),
        ("N_VALUES", "N_VALUES"),
        ("OFF_FGM_M", "FGM_M"),
        ("OFF_FGM_K", "FGM_K"),
        ("OFF_FGM_K0", "FGM_K0"),
        ("OFF_FGM_LO", "FGM_LO"),
        ("OFF_FGM_LO0", "FGM_LO0"),
        ("OFF_FGM_HI", "FGM_HI"),
        ("OFF_FGM_HI0", "FGM_HI0"),
        ("OFF_FGM_D", "FGM_D"),
        ("OFF_FGM_DINV", "FGM_DINV"),
        ("OFF_FGM_BETAS", "FGM_BETAS"),
        ("OFF_MIX_OFFSET", "MIX_OFFSET"),
        ("OFF_BIAS", "BIAS"),
    ] {
        assert_eq!(define(&h, c_name), rust_const(&rs, rust_name), "{c_name}");
    }
    assert_eq!(
        define(&h, "FGM_WARM"),
        if rust_const(&rs, "FGM_WARM") == "true" {
            "1"
        } else {
            "0"
        }
    );
    // The checksums are kestrel-ffi's, recomputed here from the parsed tables.
    let iterations: u16 = rust_const(&rs, "FGM_LOOP_ITERATIONS").parse().unwrap();
    let (f, q) = (
        hex16(&define(&h, "CHECKSUM_F32")),
        hex16(&define(&h, "CHECKSUM_Q16")),
    );
    assert_eq!(f, checksum(&rust, 0, 0, iterations));
    assert_eq!(q, checksum(&rust, 1, 0, iterations));
    // Any one changed byte of any table changes it.
    for t in 0..4 {
        let mut bad = rust.clone();
        let at = bad[t].len() / 2;
        bad[t][at] ^= 0x10;
        let format = if t == 1 { 1 } else { 0 };
        assert_ne!(
            checksum(&bad, format, 0, iterations),
            [f, q][usize::from(format)],
            "table {t}"
        );
    }
}

#[test]
fn checksum_changes_with_the_design() {
    let base = export_c(&dir("base"), &[]).0;
    let jacobi = export_c(&dir("jacobi"), &["--preconditioner", "jacobi"]).0;
    let warm = export_c(&dir("warm"), &["--warm-iterations", "5"]).0;
    let sums = |h: &str| (define(h, "CHECKSUM_F32"), define(h, "CHECKSUM_Q16"));
    assert_ne!(sums(&base).0, sums(&jacobi).0);
    assert_ne!(sums(&base).1, sums(&jacobi).1);
    assert_ne!(sums(&base).0, sums(&warm).0);
    assert_eq!(define(&warm, "FGM_WARM"), "1");
    assert_eq!(define(&warm, "FGM_LOOP_ITERATIONS"), "5");
}

/// Whether `tool` runs (`tool --version`).
fn have(tool: &str) -> bool {
    Command::new(tool)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Runs `cmd`, panicking with its output unless it succeeds; its stdout.
fn run(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap_or_else(|e| panic!("{cmd:?}: {e}"));
    assert!(
        out.status.success(),
        "{cmd:?}:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// kestrel-ffi's header, when it is there (crates/ffi/include/kestrel.h).
fn ffi_include() -> Option<PathBuf> {
    let d = repo("crates/ffi/include");
    d.join("kestrel.h").exists().then_some(d)
}

/// A C program that prints, as hex, the bytes of the four tables as the
/// compiler laid them out, and (with kestrel.h) the KestrelDesign fields.
const DUMP_C: &str = r#"
#include <stdio.h>
#include "kestrel_design.h"
static void dump(const char *name, const void *p, unsigned long n) {
    const unsigned char *b = (const unsigned char *)p;
    unsigned long i;
    printf("%s ", name);
    for (i = 0; i < n; i++) printf("%02x", b[i]);
    printf("\n");
}
int main(void) {
    dump("values_f32", kestrel_design_values_f32, sizeof kestrel_design_values_f32);
    dump("values_q16", kestrel_design_values_q16, sizeof kestrel_design_values_q16);
    dump("kalman16", &kestrel_design_kalman16, KESTREL_DESIGN_KALMAN16_BYTES);
    dump("fgm16", &kestrel_design_fgm16, KESTREL_DESIGN_FGM16_BYTES);
#if KESTREL_DESIGN_ABI
    {
        KestrelDesign d[4];
        int i;
        d[0] = kestrel_design_f32();
        d[1] = kestrel_design_q16();
        d[2] = kestrel_design_f32_tables;
        d[3] = kestrel_design_q16_tables;
        for (i = 0; i < 4; i++) {
            printf("design %d %d %d %u %u %u\n", i, d[i].values_format, d[i].fgm_warm,
                   (unsigned)d[i].fgm_iterations, (unsigned)d[i].checksum,
                   (unsigned)(d[i].values.flash + d[i].kalman16.flash + d[i].fgm16.flash));
            dump("values", d[i].values.data, d[i].values.len);
            dump("kalman16", d[i].kalman16.data, d[i].kalman16.len);
            dump("fgm16", d[i].fgm16.data, d[i].fgm16.len);
        }
    }
#endif
    return 0;
}
"#;

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len() / 2)
        .map(|i| u8::from_str_radix(&s[2 * i..2 * i + 2], 16).unwrap())
        .collect()
}

#[test]
fn c_compilers_build_the_tables_and_read_the_same_bits() {
    let out = dir("compile");
    let (h, _) = export_c(&out, &[]);
    let rs = std::fs::read_to_string(repo("avr/firmware/src/generated.rs")).unwrap();
    let rust = rust_table_bytes(&rs);
    let sums = [
        hex16(&define(&h, "CHECKSUM_F32")),
        hex16(&define(&h, "CHECKSUM_Q16")),
    ];
    let iterations: u16 = rust_const(&rs, "FGM_LOOP_ITERATIONS").parse().unwrap();
    let ffi = ffi_include();
    if ffi.is_none() {
        println!(
            "note: crates/ffi/include/kestrel.h missing: compiled with KESTREL_DESIGN_NO_ABI only"
        );
    }
    let mut variants: Vec<Vec<String>> = vec![vec!["-DKESTREL_DESIGN_NO_ABI".into()]];
    if let Some(i) = &ffi {
        variants.push(vec![format!("-I{}", i.display())]);
    }
    if !have("cc") {
        println!("note: no host C compiler (cc): C build not checked");
    } else {
        std::fs::write(out.join("dump.c"), DUMP_C).unwrap();
        for flags in &variants {
            let exe = out.join("dump");
            // The tables alone, as a firmware would compile them.
            run(Command::new("cc")
                .args(["-c", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"])
                .args(flags)
                .arg(out.join("kestrel_design.c"))
                .arg("-o")
                .arg(out.join("kestrel_design.o")));
            run(Command::new("cc")
                .args(["-std=c99", "-Wall", "-Werror"])
                .args(flags)
                .arg(format!("-I{}", out.display()))
                .arg(out.join("dump.c"))
                .arg(out.join("kestrel_design.c"))
                .arg("-o")
                .arg(&exe));
            let text = run(&mut Command::new(&exe));
            let lines: Vec<(&str, &str)> = text.lines().filter_map(|l| l.split_once(' ')).collect();
            for (i, name) in ["values_f32", "values_q16", "kalman16", "fgm16"]
                .iter()
                .enumerate()
            {
                assert_eq!(lines[i].0, *name);
                assert_eq!(unhex(lines[i].1), rust[i], "{name} as compiled");
            }
            if flags[0] == "-DKESTREL_DESIGN_NO_ABI" {
                assert!(!text.contains("design "), "{text}");
                continue;
            }
            // KestrelDesign: f32 and q16 from the functions and the constants.
            let designs: Vec<&str> = text.lines().filter(|l| l.starts_with("design ")).collect();
            assert_eq!(designs.len(), 4, "{text}");
            for (k, d) in designs.iter().enumerate() {
                // design k format warm iterations checksum flash
                let f: Vec<u32> = d[7..].split(' ').map(|s| s.parse().unwrap()).collect();
                let format = (k % 2) as u8;
                assert_eq!((f[0], f[1]), (k as u32, u32::from(format)));
                assert_eq!((f[2], f[3]), (0, u32::from(iterations)));
                assert_eq!(f[4], u32::from(sums[k % 2]), "design {k} checksum");
                assert_eq!(f[5], 0, "no flash addresses off the AVR");
                let at = 4 + 4 * k + 1;
                let bytes: Vec<Vec<u8>> = (0..3).map(|j| unhex(lines[at + j].1)).collect();
                assert_eq!(bytes[0], rust[k % 2]);
                assert_eq!((&bytes[1], &bytes[2]), (&rust[2], &rust[3]));
                assert_eq!(checksum(&rust, format, 0, iterations), sums[k % 2]);
            }
        }
    }
    // The header from C++ (extern "C", no C-only syntax).
    for cxx in ["c++", "g++", "clang++"] {
        if have(cxx) {
            for flags in &variants {
                run(Command::new(cxx)
                    .args(["-x", "c++", "-fsyntax-only", "-Wall", "-Werror"])
                    .args(flags)
                    .arg(out.join("kestrel_design.h")));
            }
            break;
        }
    }
    if !have("avr-gcc") {
        println!("note: avr-gcc not installed: the AVR build of the C tables is not checked");
        return;
    }
    for flags in &variants {
        run(Command::new("avr-gcc")
            .args(["-mmcu=atmega2560", "-Os", "-c", "-Wall", "-Werror"])
            .args(flags)
            .arg(out.join("kestrel_design.c"))
            .arg("-o")
            .arg(out.join("kestrel_design.avr.o")));
        // Every table in flash (PROGMEM's section).
        let symbols = run(Command::new("avr-objdump")
            .arg("-t")
            .arg(out.join("kestrel_design.avr.o")));
        for name in [
            "kestrel_design_values_f32",
            "kestrel_design_values_q16",
            "kestrel_design_kalman16",
            "kestrel_design_fgm16",
        ] {
            let line = symbols
                .lines()
                .find(|l| l.ends_with(&format!(" {name}")))
                .unwrap_or_else(|| panic!("{name} in\n{symbols}"));
            assert!(line.contains(".progmem.data"), "{line}");
        }
    }
}

#[test]
fn bad_inputs_are_refused_and_nothing_is_written() {
    let out = dir("refused");
    let o = out.to_str().unwrap();
    // No folder given.
    let (ok, _, err) = kestrel(&["export", "--model", MODEL, "--lang", "c"]);
    assert!(!ok && err.contains("--out"), "{err}");
    // A continuous-time model, a missing model, a mismatched Kalman filter.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(MODEL).unwrap()).unwrap();
    v["ts"] = serde_json::json!(0.0);
    let root = temp_dir("export-c");
    let cont = root.join("continuous.json");
    std::fs::write(&cont, v.to_string()).unwrap();
    let (ok, _, err) = kestrel(&[
        "export",
        "--model",
        cont.to_str().unwrap(),
        "--lang",
        "c",
        "--out",
        o,
    ]);
    assert!(!ok && err.contains("continuous"), "{err}");
    let (ok, _, err) = kestrel(&[
        "export",
        "--model",
        "/nonexistent/m.json",
        "--lang",
        "c",
        "--out",
        o,
    ]);
    assert!(!ok && err.contains("nonexistent"), "{err}");
    let mut m = kestrel_core::formats::SsModel::read(Path::new(MODEL)).unwrap();
    m.a[(1, 1)] *= 0.9;
    let foreign = root.join("foreign.json");
    std::fs::write(&foreign, m.to_json_string()).unwrap();
    let kalman = root.join("foreign-kalman.json");
    let (ok, _, err) = kestrel(&[
        "kalman",
        "--model",
        foreign.to_str().unwrap(),
        "--q",
        "1e-4",
        "--r",
        "1e-4",
        "--out",
        kalman.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let (ok, _, err) = kestrel(&[
        "export",
        "--model",
        MODEL,
        "--kalman",
        kalman.to_str().unwrap(),
        "--lang",
        "c",
        "--out",
        o,
    ]);
    assert!(!ok && err.contains("do not belong together"), "{err}");
    assert!(!out.exists(), "a refused export made {o}");
    // A file as the folder.
    std::fs::write(root.join("file"), "x").unwrap();
    let (ok, _, err) = kestrel(&[
        "export",
        "--model",
        MODEL,
        "--lang",
        "c",
        "--out",
        root.join("file").to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("not a folder"), "{err}");
    // A file the export did not write is kept, and so is the other file.
    export_c(&out, &[]);
    let h = out.join("kestrel_design.h");
    std::fs::write(&h, "/* my own header */\n").unwrap();
    let before = std::fs::read_to_string(out.join("kestrel_design.c")).unwrap();
    let (ok, _, err) = kestrel(&[
        "export",
        "--model",
        MODEL,
        "--lang",
        "c",
        "--preconditioner",
        "jacobi",
        "--out",
        o,
    ]);
    assert!(!ok && err.contains("not written by"), "{err}");
    assert_eq!(
        std::fs::read_to_string(&h).unwrap(),
        "/* my own header */\n"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("kestrel_design.c")).unwrap(),
        before
    );
    // Its own files are replaced.
    std::fs::remove_file(&h).unwrap();
    export_c(&out, &["--preconditioner", "jacobi"]);
    assert_ne!(
        std::fs::read_to_string(out.join("kestrel_design.c")).unwrap(),
        before
    );
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

#[test]
fn rust_stays_the_default() {
    let (ok, out, err) = kestrel(&["export", "--model", MODEL]);
    assert!(ok, "{err}");
    assert_eq!(
        out,
        std::fs::read_to_string(repo("avr/firmware/src/generated.rs")).unwrap()
    );
    let (ok, help, _) = kestrel(&["export", "--help"]);
    assert!(ok && help.contains("--lang") && help.contains("kestrel_design.h"));
}

#[test]
fn an_even_state_count_keeps_kestrel_ffis_byte_layout() {
    use kestrel_tricopter::firmware::c_tables::{c_design, write_c};
    use kestrel_tricopter::firmware::{DesignSettings, FirmwareDesign};
    // The thesis tables cut to 4 states: y0 then starts at byte 30, where
    // an int32_t would be padded to 32; the writer uses 16-bit halves.
    let model = kestrel_core::formats::SsModel::read(Path::new(MODEL)).unwrap();
    let design = FirmwareDesign::from_model(&model, &DesignSettings::default()).unwrap();
    let mut c = c_design(&design).unwrap();
    for r in c.kf_c.iter_mut().chain(c.kf_a.iter_mut()) {
        r.c.pop();
        r.start = r.start.min(4);
    }
    c.kf_m.pop();
    c.kf_a.pop();
    c.kf_b.pop();
    let bytes = c.kalman16_bytes();
    for (name, _, v) in c.macros.iter_mut() {
        match name.as_str() {
            "NX" => *v = 4,
            "KALMAN16_BYTES" => *v = bytes.len(),
            _ => {}
        }
    }
    let t = write_c(&c);
    assert!(t.header.contains("int16_t y0[KESTREL_DESIGN_NY][2];"));
    let out = dir("nx4");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("kestrel_design.h"), &t.header).unwrap();
    std::fs::write(out.join("kestrel_design.c"), &t.source).unwrap();
    std::fs::write(out.join("dump.c"), DUMP_C).unwrap();
    if !have("cc") {
        println!("note: no host C compiler (cc): C build not checked");
        return;
    }
    let exe = out.join("dump");
    run(Command::new("cc")
        .args([
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-DKESTREL_DESIGN_NO_ABI",
        ])
        .arg(format!("-I{}", out.display()))
        .arg(out.join("dump.c"))
        .arg(out.join("kestrel_design.c"))
        .arg("-o")
        .arg(&exe));
    let text = run(&mut Command::new(&exe));
    let kf = text
        .lines()
        .find_map(|l| l.strip_prefix("kalman16 "))
        .unwrap();
    assert_eq!(unhex(kf), bytes);
    assert_eq!(bytes.len(), 3 * 10 + 12 + 4 * 8 + 4 * 10 + 4 * 10);
}

#[test]
fn explicit_law_in_c_equals_the_firmwares_table() {
    let out = dir("empc");
    let mut args = vec!["export", "--model", MODEL, "--lang", "c", "--empc"];
    args.extend(["--out", out.to_str().unwrap()]);
    let (ok, _, err) = kestrel(&args);
    assert!(ok, "{err}");
    let h = std::fs::read_to_string(out.join("kestrel_empc.h")).unwrap();
    let c = std::fs::read_to_string(out.join("kestrel_empc.c")).unwrap();
    let rs = std::fs::read_to_string(repo("avr/firmware/src/generated_empc.rs")).unwrap();
    let rust: Vec<u8> = numbers(bracketed(&rs, "pub const EMPC16:"))
        .iter()
        .map(|s| s.parse().unwrap())
        .collect();
    let bytes: Vec<u8> = numbers(braced(&c, "kestrel_empc_chunk_0["))
        .iter()
        .map(|s| s.parse().unwrap())
        .collect();
    assert_eq!(bytes.len(), 7992);
    assert_eq!(bytes, rust);
    // The layout as generated_empc.rs's EMPC16_LAYOUT.
    let layout = braced(&rs, "pub const EMPC16_LAYOUT");
    let mut tail = Vec::new();
    for (key, name) in [
        ("n_params", "N_PARAMS"),
        ("n_outputs", "N_OUTPUTS"),
        ("n_nodes", "N_NODES"),
        ("n_laws", "N_LAWS"),
        ("n_rows", "N_ROWS"),
        ("root", "ROOT"),
        ("scale", "SCALE"),
    ] {
        let v = layout.split(&format!("{key}: ")).nth(1).unwrap();
        let v: u16 = v.split(',').next().unwrap().trim().parse().unwrap();
        let key = format!("#define KESTREL_EMPC_{name} ");
        let at = h.find(&key).unwrap() + key.len();
        assert_eq!(h[at..].lines().next().unwrap(), v.to_string(), "{name}");
        if name == "SCALE" {
            tail.push(v as u8);
        } else {
            tail.extend(v.to_le_bytes());
        }
    }
    assert!(layout.contains("wide: false") && h.contains("#define KESTREL_EMPC_WIDE 0\n"));
    tail.push(0);
    // kestrel-ffi's KestrelEmpc16Tables checksum, recomputed here.
    let mut all = rust.clone();
    all.extend(tail);
    let want = format!("#define KESTREL_EMPC_CHECKSUM 0x{:04X}u", crc16(&all));
    assert!(h.contains(&want), "{want}");
    // Host and AVR builds, with kestrel.h when it is there.
    let mut variants: Vec<Vec<String>> = vec![vec!["-DKESTREL_EMPC_NO_ABI".into()]];
    if let Some(i) = ffi_include() {
        variants.push(vec![format!("-I{}", i.display())]);
    }
    for flags in &variants {
        if have("cc") {
            run(Command::new("cc")
                .args(["-c", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"])
                .args(flags)
                .arg(out.join("kestrel_empc.c"))
                .arg("-o")
                .arg(out.join("kestrel_empc.o")));
        } else {
            println!("note: no host C compiler (cc): C build not checked");
        }
        if have("avr-gcc") {
            run(Command::new("avr-gcc")
                .args(["-mmcu=atmega2560", "-Os", "-c", "-Wall", "-Werror"])
                .args(flags)
                .arg(out.join("kestrel_empc.c"))
                .arg("-o")
                .arg(out.join("kestrel_empc.avr.o")));
            let symbols = run(Command::new("avr-objdump")
                .arg("-t")
                .arg(out.join("kestrel_empc.avr.o")));
            let line = symbols
                .lines()
                .find(|l| l.ends_with(" kestrel_empc_chunk_0"))
                .unwrap();
            assert!(line.contains(".progmem.data"), "{line}");
        } else {
            println!(
                "note: avr-gcc not installed: the AVR build of the explicit law is not checked"
            );
        }
    }
    // Only with --lang c.
    let (ok, _, err) = kestrel(&["export", "--model", MODEL, "--empc"]);
    assert!(!ok && err.contains("--lang c"), "{err}");
}
