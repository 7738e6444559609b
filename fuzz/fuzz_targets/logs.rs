//! Fuzz target `logs`: see `kestrel_fuzz::logs`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::logs(data);
});
