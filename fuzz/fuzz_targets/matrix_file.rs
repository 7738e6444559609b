//! Fuzz target `matrix_file`: see `kestrel_fuzz::matrix_file`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::matrix_file(data);
});
