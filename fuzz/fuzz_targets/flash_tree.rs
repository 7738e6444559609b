//! Fuzz target `flash_tree`: see `kestrel_fuzz::flash_tree`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::flash_tree(data);
});
