//! Fuzz target `thetas`: see `kestrel_fuzz::thetas`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::thetas(data);
});
