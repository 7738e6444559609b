//! Fuzz target `csv_log`: see `kestrel_fuzz::csv_log`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = kestrel_fuzz::csv_log(data);
});
