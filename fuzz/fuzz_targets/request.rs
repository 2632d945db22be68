//! See `treemanip::fuzz::request`.
#![no_main]

libfuzzer_sys::fuzz_target!(
    init: treemanip::fuzz::init_request_harness(),
    |data: &[u8]| treemanip::fuzz::request(data)
);
