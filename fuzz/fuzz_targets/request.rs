//! See `treemanip_server::fuzz::request`.
#![no_main]

libfuzzer_sys::fuzz_target!(
    init: treemanip_server::fuzz::init_request_harness(),
    |data: &[u8]| treemanip_server::fuzz::request(data)
);
