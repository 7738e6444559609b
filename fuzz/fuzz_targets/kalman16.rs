//! Fuzz target `kalman16`: see `kestrel_fuzz::kalman16`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::kalman16(data);
});
