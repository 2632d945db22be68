//! treemanip: learning how trees deform when a robot pushes them, after
//! "Towards Robotic Tree Manipulation: Leveraging Graph Representations"
//! (Kim, Lee, Kroemer, Kantor).
//!
//! This crate trains, exports and evaluates the models (`nn`, `eval`) and
//! holds the offline `treemanip` CLI. The layers below it are crates of
//! their own (ARCHITECTURE.md), re-exported here under their old names so
//! that one path reaches everything: [`tree`], [`sim`], [`graph`],
//! [`model`], [`dataset`], [`robot`], [`planner`] (`treemanip-core`),
//! [`infer`] (`treemanip-infer`) and [`api`] (`treemanip-server`).
//!
//! Units are SI everywhere: metres, radians, N·m/rad for joint stiffness,
//! N·m·s/rad for joint damping.

pub use treemanip_core::{
    dataset, geometry, graph, identify, model, planner, robot, scan, seed, sim, tree,
};
pub use treemanip_infer as infer;
pub use treemanip_server::{api, fuzz};

#[cfg(feature = "train")]
pub mod eval;
#[cfg(feature = "train")]
pub mod nn;
