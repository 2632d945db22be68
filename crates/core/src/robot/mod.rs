//! The robot side: any arm from its URDF ([`arm`], [`description`],
//! [`catalog`]; the built-in UR5 with its ⊔ gripper in [`ur5`]), inverse
//! kinematics, collision checking against the tree, RRT*, the paper's
//! Algorithm 1 and trajectories a controller executes.

pub mod arm;
pub mod catalog;
pub mod chain;
pub mod collision;
pub mod description;
pub mod dh;
pub mod execution;
pub mod ik;
pub mod ik_numeric;
pub mod import;
pub mod joint_vector;
pub mod link_geometry;
pub mod mesh_fit;
pub mod plan;
pub mod ros;
pub mod rrt;
pub mod scene;
pub mod self_collision;
pub mod srdf;
pub mod timing;
pub mod trajectory;
pub mod ur5;
pub mod ur_kinematics;

pub use arm::{Arm, BaseStance, PROBE_PUSHES, UR5_REACH};
