//! A link-time check that run-time code has no panic path: every panic in
//! Rust ends in `core::panicking` (a bounds check, `unwrap`, `Ord::clamp`'s
//! assertion, a division by zero), so an image none of whose functions
//! calls a panic function has none. The linker drops everything
//! unreferenced, so a panic function present in the image is reached from
//! some call site, which the scan names.

use super::miscompile::{disassemble, label, scanned};
use std::fmt;
use std::path::Path;

/// A call or jump from a function to a panic function.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PanicCall {
    /// Address of the instruction.
    pub address: u32,
    /// The calling function's (mangled) symbol.
    pub caller: String,
    /// The panic function's (mangled) symbol.
    pub target: String,
}

impl fmt::Display for PanicCall {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:#x} in {} calls {}",
            self.address, self.caller, self.target
        )
    }
}

/// Whether a (mangled) symbol is one of core's panic functions:
/// `core::panicking::*` and the out-of-line failure paths of core
/// (`slice_index_fail`, `len_mismatch_fail`, `unwrap_failed`, ...).
pub fn is_panic_function(symbol: &str) -> bool {
    symbol.contains("4core")
        && (symbol.contains("9panicking")
            || symbol.ends_with("_fail")
            || symbol.ends_with("_failed")
            || symbol.contains("_fail17h")
            || symbol.contains("_failed17h"))
}

/// Calls and jumps to panic functions in an `avr-objdump -d` listing,
/// from functions that are not panic functions themselves (the panic
/// machinery calling itself is not a path into it).
pub fn scan_panic_calls(listing: &str) -> Vec<PanicCall> {
    let mut caller: Option<&str> = None;
    let mut out = Vec::new();
    for line in listing.lines() {
        if let Some(name) = label(line) {
            caller = Some(name);
            continue;
        }
        let Some(caller) = caller.filter(|c| !is_panic_function(c)) else {
            continue;
        };
        let Some((addr, rest)) = line.split_once(':') else {
            continue;
        };
        let Ok(address) = u32::from_str_radix(addr.trim(), 16) else {
            continue;
        };
        let mut fields = rest.split('\t').skip(2);
        let op = fields.next().unwrap_or("").trim();
        if !matches!(op, "call" | "jmp" | "rcall" | "rjmp") {
            continue;
        }
        let target = rest
            .rsplit_once('<')
            .and_then(|(_, t)| t.strip_suffix('>'))
            .map(|t| t.split('+').next().unwrap_or(t));
        if let Some(target) = target.filter(|t| is_panic_function(t)) {
            out.push(PanicCall {
                address,
                caller: caller.to_string(),
                target: target.to_string(),
            });
        }
    }
    out
}

/// [`scan_panic_calls`] on `avr-objdump -d <elf>`.
///
/// # Errors
/// When `avr-objdump` does not run or fails on `elf`.
pub fn panic_calls(elf: &Path) -> std::io::Result<Vec<PanicCall>> {
    Ok(scan_panic_calls(&disassemble(elf)?))
}

/// Fails the calling test when `elf` has a panic path ([`panic_calls`]),
/// naming each call site's function. Without `avr-objdump` the check is
/// skipped with a note, unless `KESTREL_REQUIRE_AVR` is set.
///
/// # Panics
/// On a panic path; when `avr-objdump` fails, or is missing while
/// `KESTREL_REQUIRE_AVR` is set.
pub fn assert_no_panic_path(elf: &Path) {
    let Some(calls) = scanned("panic-path scan", elf, panic_calls(elf)) else {
        return;
    };
    let list: Vec<String> = calls.iter().map(|c| format!("  {c}")).collect();
    assert!(
        list.is_empty(),
        "{}: {} call(s) into core's panic functions (run-time code must have no panic path: \
         no unchecked indexing, unwrap or Ord::clamp with run-time bounds):\n{}",
        elf.display(),
        list.len(),
        list.join("\n")
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    const LISTING: &str = "
00001000 <_RNvNtCs1_14kestrel_avr_rt3fgm4step>:
    1000:\t0e 94 04 4e \tcall\t0x9c08\t; 0x9c08 <_RNvNtCseHSBXm2hA5S_4core9panicking18panic_bounds_check>
    1004:\t08 95       \tret

00001006 <main>:
    1006:\t0c 94 06 4e \tjmp\t0x9c0c\t; 0x9c0c <_RNvNtNtCseHSBXm2hA5S_4core5slice5index16slice_index_fail>
    100a:\t0e 94 10 00 \tcall\t0x20\t; 0x20 <_RNvCs1_7kestrel4safe>

00009c08 <_RNvNtCseHSBXm2hA5S_4core9panicking18panic_bounds_check>:
    9c08:\t0e 94 04 4e \tcall\t0x9c10\t; 0x9c10 <_RNvNtCseHSBXm2hA5S_4core9panicking9panic_fmt>
";

    #[test]
    fn finds_calls_into_core_panics_from_other_functions_only() {
        let calls = scan_panic_calls(LISTING);
        assert_eq!(calls.len(), 2, "{calls:?}");
        assert_eq!(calls[0].address, 0x1000);
        assert_eq!(calls[0].caller, "_RNvNtCs1_14kestrel_avr_rt3fgm4step");
        assert!(calls[0].target.ends_with("18panic_bounds_check"));
        assert_eq!(calls[1].caller, "main");
        assert!(calls[1].target.ends_with("16slice_index_fail"));
        assert!(scan_panic_calls("00000000 <main>:\n 0:\t08 95\tret\n").is_empty());
    }

    #[test]
    fn panic_functions_by_name() {
        assert!(is_panic_function(
            "_RNvNtCseHSBXm2hA5S_4core9panicking9panic_fmt"
        ));
        assert!(is_panic_function("_RNvNtCs1_4core6option13unwrap_failed"));
        assert!(is_panic_function(
            "_ZN4core9panicking5panic17h0123456789abcdefE"
        ));
        assert!(!is_panic_function("_RNvCs1_7kestrel4safe"));
        assert!(!is_panic_function("main"));
    }
}
