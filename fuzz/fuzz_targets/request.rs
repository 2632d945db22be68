//! See `treemanip::fuzz::request`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| treemanip::fuzz::request(data));
