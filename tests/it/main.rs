//! The integration tests: one test binary (one link of burn, tract and
//! ort instead of one per file), a module per area. Shared helpers, the
//! server launcher and HTTP client among them, live in [`common`].

mod ablations;
mod architecture;
mod cli_trees;
mod common;
mod dataset;
mod deploy;
mod onnx_parity;
mod planner;
mod readme_examples;
mod robot_arms;
mod robot_bare_arms;
mod server_faults;
mod server_models;
mod tasks;
mod training;
