//! A guard against two miscompilations of the pinned nightly's LLVM AVR
//! backend (docs/avr-qp.md, "Two compiler bugs"), found in `avr-objdump -d`
//! output by a linear scan of each function:
//!
//! 1. **Incoming stack arguments read one byte low on the ATmega2560.** A
//!    `call` there pushes a 3-byte return address; LLVM addresses a
//!    function's stack arguments as if it were 2 bytes. Every Y-relative
//!    access above a function's pushes and frame (the prologue's `push`es,
//!    `in r28, 0x3d`, then `sbiw r28, F` or `subi r28` / `sbci r29`) is such
//!    a read or write, so any is reported.
//! 2. **A multiply's `r0` overwritten by a frame access's SREG save.** LLVM
//!    may leave a product byte in `r0` (its fixed temporary) while a frame
//!    access beyond `Y+63` saves SREG there (`in r0, 0x3f`), then read `r0`
//!    as the product. Reported: a `MUL` whose `r0` is next read (not as the
//!    `out 0x3f, r0` restore) only after an `in r0, 0x3f`; rewriting `r0`
//!    first (`mov r0, ..`, a load, another `MUL`) ends the watch.
//!
//! The scan follows the listing's order (branches are not followed; labels,
//! `ret` and `reti` reset it), so code inlined into a function is reported
//! under that function's symbol.

use std::fmt;
use std::path::Path;
use std::process::Command;

/// Which of the two miscompilations a [`MiscompileHit`] is, and where.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MiscompileBug {
    /// Bug 1: a Y-relative access to the function's incoming stack
    /// arguments (or, as LLVM sees it, its return address), one byte low on
    /// the ATmega2560.
    StackArgument {
        /// Address of the access.
        access: u32,
        /// Bytes above the function's pushes and frame: LLVM puts the
        /// return address at 1-2 and the arguments from 3; on the
        /// ATmega2560 the return address takes 1-3.
        above_frame: u32,
    },
    /// Bug 2: a multiply's `r0` read after an SREG save overwrote it.
    R0AfterSregSave {
        /// Address of the `MUL`.
        mul: u32,
        /// Address of the first `in r0, 0x3f` after it.
        sreg_save: u32,
        /// Address of the instruction that reads `r0`.
        read: u32,
    },
}

/// One place where the listing shows one of the two bugs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MiscompileHit {
    /// The function's symbol as `avr-objdump` prints it (mangled; code
    /// inlined into it is reported under its name).
    pub function: String,
    /// The bug and its addresses.
    pub bug: MiscompileBug,
    /// The access (bug 1) or the read of `r0` (bug 2), as disassembled.
    pub instruction: String,
}

impl MiscompileHit {
    /// Whether the hit is in code LLVM compiled: a Rust-mangled symbol
    /// (`_R...` or `_ZN...`) or a name `unmangled_rust` accepts, the
    /// program's `#[no_mangle]` Rust functions (`main` for a firmware built
    /// by cargo, `kestrel_*` for kestrel-ffi's exports in a C program).
    /// avr-gcc's code (a C program, libgcc, avr-libc) addresses stack
    /// arguments right, so bug 1 there is a false alarm.
    pub fn in_rust(&self, unmangled_rust: impl Fn(&str) -> bool) -> bool {
        is_rust_mangled(&self.function) || unmangled_rust(&self.function)
    }
}

impl fmt::Display for MiscompileHit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.bug {
            MiscompileBug::StackArgument {
                access,
                above_frame,
            } => write!(
                f,
                "{}: `{}` at {access:#x} accesses the byte {above_frame} above its pushes and \
                 frame, an incoming stack argument (bug 1: LLVM AVR addresses stack arguments \
                 for a 2-byte return address; the ATmega2560's is 3 bytes, so the read is one \
                 byte low)",
                self.function, self.instruction
            ),
            MiscompileBug::R0AfterSregSave {
                mul,
                sreg_save,
                read,
            } => write!(
                f,
                "{}: the MUL at {mul:#x} leaves a product byte in r0, `in r0, 0x3f` at \
                 {sreg_save:#x} overwrites it (a frame access beyond Y+63 saving SREG) and \
                 `{}` at {read:#x} reads it (bug 2: LLVM AVR does not keep r0 live across the \
                 SREG save)",
                self.function, self.instruction
            ),
        }
    }
}

/// Both bugs in `avr-objdump -d <elf>` output: every hit, in listing
/// order, in every function (C and library functions included: see
/// [`MiscompileHit::in_rust`]).
///
/// # Errors
/// When `avr-objdump` does not run or fails on `elf`.
pub fn miscompile_scan(elf: &Path) -> std::io::Result<Vec<MiscompileHit>> {
    Ok(scan_disassembly(&disassemble(elf)?))
}

/// A scan's result; `None` (with a note) when `avr-objdump` is missing
/// and `KESTREL_REQUIRE_AVR` is not set.
///
/// # Panics
/// When the scan failed otherwise, or `avr-objdump` is missing while
/// `KESTREL_REQUIRE_AVR` is set.
pub(super) fn scanned<T>(what: &str, elf: &Path, result: std::io::Result<T>) -> Option<T> {
    match result {
        Ok(v) => Some(v),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            assert!(
                std::env::var_os("KESTREL_REQUIRE_AVR").is_none(),
                "KESTREL_REQUIRE_AVR is set but avr-objdump is not installed"
            );
            println!(
                "{what} of {} skipped: avr-objdump not installed",
                elf.display()
            );
            None
        }
        Err(e) => panic!("{what} of {}: {e}", elf.display()),
    }
}

/// `avr-objdump -d <elf>`'s listing.
pub(super) fn disassemble(elf: &Path) -> std::io::Result<String> {
    let out = Command::new("avr-objdump").arg("-d").arg(elf).output()?;
    if !out.status.success() {
        return Err(std::io::Error::other(format!(
            "avr-objdump -d {}: {}",
            elf.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// Fails the calling test when the pinned nightly miscompiled Rust code
/// of `elf` ([`miscompile_scan`]; Rust code as [`MiscompileHit::in_rust`]
/// with `unmangled_rust`). Hits elsewhere are counted, not failed on.
/// Without `avr-objdump` the check is skipped with a note, unless
/// `KESTREL_REQUIRE_AVR` is set.
///
/// # Panics
/// On a hit in Rust code, naming the function and the bug; when
/// `avr-objdump` fails, or is missing while `KESTREL_REQUIRE_AVR` is set.
pub fn assert_no_miscompile(elf: &Path, unmangled_rust: impl Fn(&str) -> bool) {
    let Some(hits) = scanned("miscompile scan", elf, miscompile_scan(elf)) else {
        return;
    };
    let (rust, other): (Vec<_>, Vec<_>) = hits.iter().partition(|h| h.in_rust(&unmangled_rust));
    if let Some(first) = other.first() {
        println!(
            "note: {} place(s) outside Rust code match the scan's patterns, not failed on \
             (first: {first})",
            other.len()
        );
    }
    let list: Vec<String> = rust.iter().map(|h| format!("  {h}")).collect();
    assert!(
        list.is_empty(),
        "{}: the pinned nightly's LLVM AVR backend miscompiled {} place(s) of Rust code \
         (docs/avr-qp.md, the two compiler bugs); change the source so the pattern goes away:\n{}",
        elf.display(),
        list.len(),
        list.join("\n")
    );
}

/// Both bugs in the text of an `avr-objdump -d` listing ([`miscompile_scan`]
/// without running the tool).
pub fn scan_disassembly(listing: &str) -> Vec<MiscompileHit> {
    let mut hits = Vec::new();
    for (name, body) in functions(listing) {
        stack_arguments(name, &body, &mut hits);
        r0_after_sreg_save(name, &body, &mut hits);
    }
    hits.sort_by_key(|h| match h.bug {
        MiscompileBug::StackArgument { access, .. } => access,
        MiscompileBug::R0AfterSregSave { read, .. } => read,
    });
    hits
}

/// One disassembled instruction: address, mnemonic, operands (comment
/// removed).
struct Insn<'a> {
    addr: u32,
    op: &'a str,
    args: Vec<&'a str>,
}

impl Insn<'_> {
    fn text(&self) -> String {
        format!("{} {}", self.op, self.args.join(", "))
            .trim_end()
            .to_string()
    }

    fn arg(&self, i: usize) -> &str {
        self.args.get(i).copied().unwrap_or("")
    }
}

/// The listing's functions (`<addr> <name>:` labels) with their
/// instructions (`addr:\tbytes\tmnemonic\toperands ; comment`).
fn functions(listing: &str) -> Vec<(&str, Vec<Insn<'_>>)> {
    let mut out: Vec<(&str, Vec<Insn<'_>>)> = Vec::new();
    for line in listing.lines() {
        if let Some(name) = label(line) {
            out.push((name, Vec::new()));
        } else if let (Some(insn), Some((_, body))) = (instruction(line), out.last_mut()) {
            body.push(insn);
        }
    }
    out
}

pub(super) fn label(line: &str) -> Option<&str> {
    let (addr, rest) = line.trim().split_once(' ')?;
    u32::from_str_radix(addr, 16).ok()?;
    rest.strip_prefix('<')?.strip_suffix(">:")
}

fn instruction(line: &str) -> Option<Insn<'_>> {
    let (addr, rest) = line.split_once(':')?;
    let addr = u32::from_str_radix(addr.trim(), 16).ok()?;
    let mut fields = rest.split('\t').skip(1);
    let _bytes = fields.next()?;
    let op = fields.next()?.trim();
    let args = fields.next().unwrap_or("");
    let args = args.split(';').next().unwrap_or("").trim();
    let args = if args.is_empty() {
        Vec::new()
    } else {
        args.split(',').map(str::trim).collect()
    };
    (!op.is_empty()).then_some(Insn { addr, op, args })
}

/// A number as avr-objdump prints an operand (`0x3f`, `63`, `-2`).
fn imm(s: &str) -> Option<i64> {
    match s.strip_prefix("0x") {
        Some(h) => i64::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

/// Rust's v0 (`_R...`) or legacy (`_ZN...17h<hash>E`) mangling.
fn is_rust_mangled(name: &str) -> bool {
    name.starts_with("_R")
        || (name.starts_with("_ZN") && name.contains("17h") && name.ends_with('E'))
}

/// Bug 1: Y-relative accesses above the pushes and frame of a function
/// whose prologue points Y at its frame.
fn stack_arguments(name: &str, body: &[Insn<'_>], hits: &mut Vec<MiscompileHit>) {
    let pushes = body.iter().take_while(|i| i.op == "push").count();
    let mut rest = &body[pushes..];
    match rest {
        [a, ..] if a.op == "in" && a.arg(0) == "r28" && a.arg(1) == "0x3d" => {
            rest = &rest[2.min(rest.len())..]
        }
        _ => return,
    }
    let frame = match rest {
        [a, b, ..] if a.op == "subi" && a.arg(0) == "r28" && b.op == "sbci" => {
            let v = imm(a.arg(1)).unwrap_or(0) | imm(b.arg(1)).unwrap_or(0) << 8;
            rest = &rest[2..];
            v
        }
        [a, ..] if a.op == "sbiw" && a.arg(0) == "r28" => {
            rest = &rest[1..];
            imm(a.arg(1)).unwrap_or(0)
        }
        _ => 0,
    };
    let limit = pushes as i64 + frame;
    // Y's offset from the frame pointer inside a window that moves it (a
    // frame access beyond Y+63: SREG saved, Y moved, access, Y moved back,
    // SREG restored), measured from the window's start.
    let mut adj = 0i64;
    let mut subi: Option<i64> = None;
    for i in rest {
        match (i.op, i.arg(0), i.arg(1)) {
            ("ret" | "reti", ..) | ("in", "r0", "0x3f") | ("out", "0x3f" | "0x3d", _) => adj = 0,
            ("adiw", "r28", k) => adj += imm(k).unwrap_or(0),
            ("sbiw", "r28", k) => adj -= imm(k).unwrap_or(0),
            ("subi", "r28", k) => subi = imm(k),
            ("sbci", "r29", k) if subi.is_some() => {
                let v = subi.take().unwrap_or(0) | imm(k).unwrap_or(0) << 8;
                adj -= if v >= 0x8000 { v - 0x1_0000 } else { v };
            }
            _ => {
                let above = i
                    .args
                    .iter()
                    .filter_map(|a| a.strip_prefix("Y+")?.parse::<i64>().ok())
                    .map(|q| adj + q - limit)
                    .max();
                if let Some(above) = above.filter(|&a| a > 0) {
                    hits.push(MiscompileHit {
                        function: name.to_string(),
                        bug: MiscompileBug::StackArgument {
                            access: i.addr,
                            above_frame: above as u32,
                        },
                        instruction: i.text(),
                    });
                }
            }
        }
    }
}

/// Mnemonics whose first operand is written without being read.
const WRITE_ONLY: [&str; 11] = [
    "mov", "movw", "ldi", "ld", "ldd", "lds", "lpm", "elpm", "in", "pop", "ser",
];

/// Multiplies: the product goes to `r1:r0`.
const MUL: [&str; 6] = ["mul", "muls", "mulsu", "fmul", "fmuls", "fmulsu"];

/// How an instruction uses `r0`: (reads it, writes it).
fn r0_use(i: &Insn<'_>) -> (bool, bool) {
    let is_r0 = |k: usize| i.args.get(k) == Some(&"r0");
    if MUL.contains(&i.op) {
        return (is_r0(0) || is_r0(1), true);
    }
    if (i.op == "lpm" || i.op == "elpm") && i.args.is_empty() {
        return (false, true); // `lpm` alone loads r0
    }
    if i.op == "eor" && is_r0(0) && is_r0(1) {
        return (false, true); // clr r0
    }
    let first_written = WRITE_ONLY.contains(&i.op);
    let reads = (0..i.args.len()).any(|k| is_r0(k) && !(k == 0 && first_written));
    (reads, is_r0(0))
}

/// Bug 2: a `MUL` whose `r0` is read only after `in r0, 0x3f`.
fn r0_after_sreg_save(name: &str, body: &[Insn<'_>], hits: &mut Vec<MiscompileHit>) {
    // (the MUL, the first SREG save after it) while r0 holds its product.
    let mut watch: Option<(u32, Option<u32>)> = None;
    for i in body {
        if i.op == "in" && i.arg(0) == "r0" && i.arg(1) == "0x3f" {
            if let Some((_, save @ None)) = &mut watch {
                *save = Some(i.addr);
            }
            continue;
        }
        if i.op == "out" && i.arg(0) == "0x3f" && i.arg(1) == "r0" {
            continue; // the SREG restore itself
        }
        let (reads, writes) = r0_use(i);
        if reads {
            if let Some((mul, Some(sreg_save))) = watch {
                hits.push(MiscompileHit {
                    function: name.to_string(),
                    bug: MiscompileBug::R0AfterSregSave {
                        mul,
                        sreg_save,
                        read: i.addr,
                    },
                    instruction: i.text(),
                });
            }
            watch = None;
        }
        if writes {
            watch = MUL.contains(&i.op).then_some((i.addr, None));
        }
        if i.op == "ret" || i.op == "reti" {
            watch = None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A function as `avr-objdump -d` prints it: `lines` are
    /// `mnemonic operands` at consecutive 2-byte addresses from `base`.
    fn listing(name: &str, base: u32, lines: &[&str]) -> String {
        let mut s = format!("\n{base:08x} <{name}>:\n");
        for (k, l) in lines.iter().enumerate() {
            let (op, args) = l.split_once(' ').unwrap_or((l, ""));
            let addr = base + 2 * k as u32;
            s += &format!("{addr:8x}:\t00 00       \t{op}\t{args}\t; comment\n");
        }
        s
    }

    /// kestrel-qp's `solve_mustar` inlined into the firmware's `main`
    /// (build `qp,hil-faults` at b1206c4), verbatim but shortened.
    const SOLVE_MUSTAR: &str = "\
00002b8e <main>:
   10fb6:\tf4 02       \tmuls\tr31, r20
   10fb8:\t11 24       \teor\tr1, r1
   10fba:\t0f b6       \tin\tr0, 0x3f\t; 63
   10fbc:\tcb 54       \tsubi\tr28, 0x4B\t; 75
   10fbe:\tdc 4f       \tsbci\tr29, 0xFC\t; 252
   10fc0:\t4e ad       \tldd\tr20, Y+62\t; 0x3e
   10fc2:\t5f ad       \tldd\tr21, Y+63\t; 0x3f
   10fc4:\tc5 5b       \tsubi\tr28, 0xB5\t; 181
   10fc6:\td3 40       \tsbci\tr29, 0x03\t; 3
   10fc8:\t0f be       \tout\t0x3f, r0\t; 63
   10fca:\t46 17       \tcp\tr20, r22
   10fd2:\t10 f0       \tbrcs\t.+4      \t; 0x10fd8 <main+0xe44a>
   10fd8:\t0f b6       \tin\tr0, 0x3f\t; 63
   10fe6:\t0f be       \tout\t0x3f, r0\t; 63
   10ffc:\t29 0f       \tadd\tr18, r25
   10ffe:\t20 0d       \tadd\tr18, r0
   11000:\t33 27       \teor\tr19, r19
";

    #[test]
    fn a_product_byte_read_after_an_sreg_save_is_bug_2() {
        let hits = scan_disassembly(SOLVE_MUSTAR);
        let want = MiscompileBug::R0AfterSregSave {
            mul: 0x10fb6,
            sreg_save: 0x10fba,
            read: 0x10ffe,
        };
        assert_eq!(hits.len(), 1, "{hits:?}");
        assert_eq!((hits[0].function.as_str(), hits[0].bug), ("main", want));
        assert_eq!(hits[0].instruction, "add r18, r0");
        // `main` is Rust in a cargo-built firmware, C in a C program.
        assert!(hits[0].in_rust(|f| f == "main") && !hits[0].in_rust(|_| false));
        let text = hits[0].to_string();
        assert!(text.contains("bug 2") && text.contains("0x10ffe"), "{text}");
    }

    #[test]
    fn r0_rewritten_or_only_restored_after_the_save_is_not_bug_2() {
        let save = [
            "muls r31, r20",
            "eor r1, r1",
            "in r0, 0x3f",
            "subi r28, 0x4B",
            "sbci r29, 0xFC",
            "ldd r20, Y+62",
            "subi r28, 0xB5",
            "sbci r29, 0x03",
            "out 0x3f, r0",
        ];
        let f = "_RNvCs1_4demo1f";
        let cases: [&[&str]; 6] = [
            &[],                              // only the restore reads r0
            &["mov r0, r24", "add r18, r0"],  // rewritten, then read
            &["ld r0, Z+", "add r18, r0"],    // loaded, then read
            &["eor r0, r0", "add r18, r0"],   // cleared, then read
            &["mul r24, r22", "add r18, r0"], // a new product
            &["ret", "add r18, r0"],          // another path
        ];
        for tail in cases {
            let text = listing(f, 0x100, &[&save[..], tail].concat());
            assert_eq!(scan_disassembly(&text), [], "{tail:?}");
        }
        // Read before the save: the product was used in time.
        let early = [
            "mul r30, r20",
            "mov r24, r0",
            "in r0, 0x3f",
            "out 0x3f, r0",
            "add r18, r1",
        ];
        assert_eq!(scan_disassembly(&listing(f, 0x100, &early)), []);
        // The control: the same save then a read is a hit, also as a MUL operand.
        for read in ["add r18, r0", "movw r24, r0", "mul r0, r24", "push r0"] {
            let text = listing(f, 0x100, &[&save[..], &[read]].concat());
            let hits = scan_disassembly(&text);
            assert_eq!(hits.len(), 1, "{read}");
            assert_eq!(hits[0].instruction, read);
        }
        // A new function label ends the watch.
        let split = listing(f, 0x100, &save) + &listing("_RNvCs1_4demo1g", 0x200, &["add r18, r0"]);
        assert_eq!(scan_disassembly(&split), []);
    }

    /// The minimal reproduction's `f(a: u32, b: u32, c: u32, d: u32, e: u8,
    /// g: u8)`: four pushes, no frame, `g` read at `Y+7`.
    const STACK_ARG: [&str; 13] = [
        "push r8",
        "push r10",
        "push r28",
        "push r29",
        "in r28, 0x3d",
        "in r29, 0x3e",
        "ldd r24, Y+7",
        "add r24, r8",
        "pop r29",
        "pop r28",
        "pop r10",
        "pop r8",
        "ret",
    ];

    #[test]
    fn a_read_above_the_pushes_and_frame_is_bug_1() {
        let text = listing("_RNvCs1_7h12_min1f", 0x200, &STACK_ARG);
        let hits = scan_disassembly(&text);
        let want = MiscompileBug::StackArgument {
            access: 0x20c,
            above_frame: 3,
        };
        assert_eq!(hits.len(), 1, "{hits:?}");
        assert_eq!(hits[0].bug, want);
        assert_eq!(hits[0].instruction, "ldd r24, Y+7");
        assert!(hits[0].in_rust(|_| false) && hits[0].to_string().contains("bug 1"));
        // The same code from avr-gcc (a C function) is reported, not Rust.
        let c = scan_disassembly(&listing("sum6", 0x200, &STACK_ARG));
        assert!(c.len() == 1 && !c[0].in_rust(|f| f == "main"));
        // H11's `mac`: 18 pushes, a 0x840-byte frame, `shift` read through
        // a window moving Y by 0x819: 0x857 - 0x852 = 5 above.
        let mut mac = vec!["push r2"; 18];
        mac.extend([
            "in r28, 0x3d",
            "in r29, 0x3e",
            "subi r28, 0x40",
            "sbci r29, 0x08",
            "std Y+1, r24",
            "in r0, 0x3f",
            "subi r28, 0xE7",
            "sbci r29, 0xF7",
            "ldd r24, Y+62",
            "subi r28, 0x19",
            "sbci r29, 0x08",
            "out 0x3f, r0",
        ]);
        let hits = scan_disassembly(&listing("_RNvCs1_3sat3mac", 0x400, &mac));
        assert_eq!(hits.len(), 1, "{hits:?}");
        assert!(matches!(
            hits[0].bug,
            MiscompileBug::StackArgument { above_frame: 5, .. }
        ));
    }

    #[test]
    fn frame_and_register_argument_accesses_are_not_bug_1() {
        // No frame pointer: register arguments only, Y not set up.
        let regs = [
            "push r28",
            "push r29",
            "movw r28, r24",
            "ldd r24, Y+9",
            "add r24, r22",
            "pop r29",
            "pop r28",
            "ret",
        ];
        assert_eq!(
            scan_disassembly(&listing("_RNvCs1_4demo4regs", 0x100, &regs)),
            []
        );
        // A small frame: its last byte (`Y+2 + 8 = Y+10` with 2 pushes) is in range.
        let small = [
            "push r28",
            "push r29",
            "in r28, 0x3d",
            "in r29, 0x3e",
            "sbiw r28, 0x08",
            "std Y+8, r24",
            "ldd r25, Y+10",
            "adiw r28, 0x08",
            "out 0x3d, r28",
            "pop r29",
            "pop r28",
            "ret",
        ];
        assert_eq!(
            scan_disassembly(&listing("_RNvCs1_4demo5small", 0x100, &small)),
            []
        );
        // A large frame's window reaching its top byte exactly (2 pushes +
        // 0x840 = Y+0x842: Y moved by 0x804, then Y+62); one more is a hit.
        let large = |q: &'static str| {
            let mut v = vec!["push r28", "push r29", "in r28, 0x3d", "in r29, 0x3e"];
            v.extend(["subi r28, 0x40", "sbci r29, 0x08", "in r0, 0x3f"]);
            v.extend(["subi r28, 0xFC", "sbci r29, 0xF7", q, "subi r28, 0x04"]);
            v.extend(["sbci r29, 0x08", "out 0x3f, r0", "ret"]);
            scan_disassembly(&listing("_RNvCs1_4demo5large", 0x100, &v))
        };
        assert_eq!(large("ldd r24, Y+62"), []);
        assert!(matches!(
            large("ldd r24, Y+63")[..],
            [MiscompileHit {
                bug: MiscompileBug::StackArgument { above_frame: 1, .. },
                ..
            }]
        ));
    }

    #[test]
    fn symbols_are_told_rust_or_not_and_missing_files_are_errors() {
        assert!(is_rust_mangled("_RNvCs1_4demo1f"));
        assert!(is_rust_mangled("_ZN4core3fmt5write17h0123456789abcdefE"));
        assert!(!is_rust_mangled("__mulsf3") && !is_rust_mangled("memcpy"));
        assert!(!is_rust_mangled("_ZN3foo3barEv"));
        assert!(miscompile_scan(Path::new("/nonexistent.elf")).is_err());
    }
}
