//! Fuzz target `ss`: see `kestrel_fuzz::ss`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::ss(data);
});
