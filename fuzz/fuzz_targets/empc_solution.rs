//! Fuzz target `empc_solution`: see `kestrel_fuzz::empc_solution`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::empc_solution(data);
});
