//! See `treemanip_server::fuzz::tree_json`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| treemanip_server::fuzz::tree_json(data));
