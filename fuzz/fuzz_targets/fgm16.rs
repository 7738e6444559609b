//! Fuzz target `fgm16`: see `kestrel_fuzz::fgm16`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::fgm16(data);
});
