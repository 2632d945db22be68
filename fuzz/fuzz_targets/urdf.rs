//! See `treemanip::fuzz::urdf`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| treemanip::fuzz::urdf(data));
