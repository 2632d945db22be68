//! The robot side: the UR5 with its ⊔ gripper, inverse kinematics, collision
//! checking against the tree, RRT* and the paper's Algorithm 1.

pub mod chain;
pub mod collision;
pub mod description;
pub mod dh;
pub mod execution;
pub mod ik;
pub mod ik_numeric;
pub mod link_geometry;
pub mod mesh_fit;
pub mod plan;
pub mod ros;
pub mod rrt;
pub mod scene;
pub mod self_collision;
pub mod timing;
pub mod trajectory;
pub mod ur5;
pub mod ur_kinematics;

pub use ur5::Ur5;
