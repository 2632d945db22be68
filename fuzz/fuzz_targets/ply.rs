//! See `treemanip_server::fuzz::ply`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| treemanip_server::fuzz::ply(data));
