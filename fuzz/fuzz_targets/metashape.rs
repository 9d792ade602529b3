#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| hairrecon_fuzz::metashape(data));
