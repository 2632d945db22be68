//! treemanip-core's integration tests: one test binary, a module per area.
//! They build without the server, the inference engines and the trainer
//! (`cargo test -p treemanip-core`).

mod common;
mod graph_encoding;
mod identify;
mod robot_chain;
mod robot_check;
mod robot_collision;
mod robot_description;
mod robot_geometry;
mod robot_mimic;
mod robot_model;
mod robot_plan;
mod robot_reach;
mod robot_ros;
mod robot_rrt;
mod robot_timing;
mod robot_ur_kinematics;
mod sca;
mod sim_convergence;
mod sim_loads;
mod sim_physics;
mod sim_reference;
mod tree_crop;
mod tree_model;
mod urdf_python;
mod urdf_roundtrip;
