//! treemanip-server's integration tests: one test binary, a module per
//! area, each against a real `treemanip-server` process. They build
//! without burn and tract (`cargo test -p treemanip-server`).

mod batching;
mod common;
mod fuzz_corpus;
mod oip_v2;
mod openapi_spec;
mod schemathesis;
mod server_adversarial;
mod server_basics;
mod server_identify;
mod server_large_trees;
mod server_robots;
mod server_scans;
mod server_tasks;
mod viewer;
