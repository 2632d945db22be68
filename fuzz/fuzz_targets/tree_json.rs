//! See `treemanip::fuzz::tree_json`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| treemanip::fuzz::tree_json(data));
