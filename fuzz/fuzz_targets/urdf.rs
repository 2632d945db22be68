//! See `treemanip_server::fuzz::urdf`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| treemanip_server::fuzz::urdf(data));
