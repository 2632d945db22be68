//! The integration tests: one test binary (one link of burn, tract and
//! ort instead of one per file), a module per area. Shared helpers, the
//! server launcher and HTTP client among them, live in [`common`].

mod ablations;
mod architecture;
mod batching;
mod cli_trees;
mod common;
mod dataset;
mod deploy;
mod fuzz_corpus;
mod graph_encoding;
mod identify;
mod oip_v2;
mod onnx_parity;
mod openapi_spec;
mod planner;
mod readme_examples;
mod robot_arms;
mod robot_chain;
mod robot_collision;
mod robot_description;
mod robot_geometry;
mod robot_model;
mod robot_plan;
mod robot_ros;
mod robot_rrt;
mod robot_timing;
mod robot_ur_kinematics;
mod sca;
mod schemathesis;
mod server_adversarial;
mod server_basics;
mod server_faults;
mod server_identify;
mod server_models;
mod server_tasks;
mod sim_convergence;
mod sim_loads;
mod sim_physics;
mod sim_reference;
mod tasks;
mod training;
mod tree_model;
mod urdf_python;
mod urdf_roundtrip;
mod viewer;
