//! treemanip's core, after "Towards Robotic Tree Manipulation: Leveraging
//! Graph Representations" (Kim, Lee, Kroemer, Kantor): everything that
//! neither trains a model nor runs one.
//!
//! Layers, each using only those listed before it:
//! - [`seed`]: deriving seeds;
//! - [`tree`]: the tree (nodes, branches, wood), Space Colonization, URDF;
//! - [`sim`]: the quasi-static push simulator;
//! - [`identify`]: branch stiffness from probe pushes, with the simulator as
//!   the observation model;
//! - [`graph`]: the graph encoding and the models' I/O contract;
//!   [`model`]: what a model is trained for (its domain);
//! - [`dataset`]: push episodes collected with the simulator, `.npz` files;
//! - [`geometry`]: shapes placed in the world and their queries;
//! - [`scan`]: trees from point clouds, synthetic scans and their scores;
//! - [`robot`]: any arm from its URDF, in layers (model, kinematics, arm,
//!   collision, motion, catalog);
//! - [`planner`]: the paper's Algorithm 1, with the contact policy and the
//!   forward model behind small traits ([`planner::ContactPolicy`],
//!   [`planner::Predictor`]) that `treemanip-infer` implements.
//!
//! Units are SI everywhere: metres, radians, N·m/rad for joint stiffness,
//! N·m·s/rad for joint damping.

pub mod dataset;
pub mod geometry;
pub mod graph;
pub mod identify;
pub mod model;
pub mod planner;
pub mod robot;
pub mod scan;
pub mod seed;
pub mod sim;
pub mod tree;
