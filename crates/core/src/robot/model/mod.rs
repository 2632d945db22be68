//! What an arm is, read from files (layer 1 of [`crate::robot`]).
//!
//! - [`urdf_chain`]: the serial chain of a URDF, its joints, forward
//!   kinematics and Jacobian;
//! - [`joint_vector`]: a joint configuration on the stack;
//! - [`mesh_fit`]: capsules and cylinders fitted to collision meshes;
//! - [`link_geometry`]: each link's collision shapes, from the URDF's
//!   primitives or fitted to its meshes;
//! - [`srdf`]: MoveIt's `<disable_collisions>` pairs;
//! - [`self_pairs`]: link pairs that never or always touch, sampled;
//! - [`tool`]: the ⊔ pusher tool's dimensions and boxes;
//! - [`tool_mount`]: where the ⊔ tool goes on a bare URDF (the last
//!   joint's axis, or a named frame);
//! - [`description`]: a robot description (`robots/*.toml`);
//! - [`import`]: a description from a URDF.

pub mod description;
pub mod import;
pub mod joint_vector;
pub mod link_geometry;
pub mod mesh_fit;
pub mod self_pairs;
pub mod srdf;
pub mod tool;
pub mod tool_mount;
pub mod urdf_chain;
