//! See `treemanip::fuzz::npz`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| treemanip::fuzz::npz(data));
