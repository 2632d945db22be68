//! See `treemanip_server::fuzz::npz`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| treemanip_server::fuzz::npz(data));
