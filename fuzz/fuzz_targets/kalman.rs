//! Fuzz target `kalman`: see `kestrel_fuzz::kalman`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::kalman(data);
});
