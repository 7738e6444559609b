//! Fuzz target `frame`: see `kestrel_fuzz::frame`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::frame(data);
});
