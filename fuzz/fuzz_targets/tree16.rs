//! Fuzz target `tree16`: see `kestrel_fuzz::tree16`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::tree16(data);
});
