//! treemanip: learning how trees deform when a robot pushes them, after
//! "Towards Robotic Tree Manipulation: Leveraging Graph Representations"
//! (Kim, Lee, Kroemer, Kantor).
//!
//! Units are SI everywhere: metres, radians, N·m/rad for joint stiffness,
//! N·m·s/rad for joint damping.

pub mod api;
pub mod dataset;
pub mod eval;
pub mod fuzz;
pub mod graph;
pub mod infer;
pub mod nn;
pub mod planner;
pub mod robot;
pub mod seed;
pub mod sim;
pub mod tree;
