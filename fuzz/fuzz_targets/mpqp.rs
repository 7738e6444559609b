//! Fuzz target `mpqp`: see `kestrel_fuzz::mpqp`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::mpqp(data);
});
