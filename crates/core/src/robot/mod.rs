//! The robot side: any arm from its URDF, its ⊔ pusher tool, kinematics,
//! collision checking against the tree, and the motion that carries out a
//! push (RRT* approach, straight push, timed controller trajectories).
//!
//! Layers, each using only those listed before it (no file imports one in
//! its own or a later layer that imports it back; `tests/it/architecture.rs`
//! checks that no import circle exists):
//!
//! 1. [`model`]: what an arm is, read from files: the URDF chain, link
//!    geometry and fitted shapes, SRDF, sampled self-collision pairs, the
//!    ⊔ tool, a robot description and its import from a URDF.
//! 2. [`kinematics`]: inverse kinematics: the numerical solver for any
//!    chain, the UR closed form and its detection.
//! 3. [`arm`]: [`Arm`], a description made ready to plan with (forward and
//!    inverse kinematics of the tool, limits, self-motion, reach), the
//!    tool's straight lines by IK steps and the base stances they score.
//! 4. [`collision`]: the arm against itself, the tree, obstacles and the
//!    ground; clearance bounds for conservative advancement.
//! 5. [`motion`]: RRT* in joint space, the planning scene, one push's
//!    motion (the paper's Algorithm 1, lines 4-8: approach, push, retreat),
//!    trajectory timing (TOPP-RA, jerk limits) and ROS 2 messages.
//! 6. [`ur5`] (the built-in UR5 and its description), [`catalog`] (arms
//!    by name: the built-in one, shipped descriptions, URDFs) and
//!    [`check`] (what `treemanip robot check` reports on an arm).
//!
//! How each part works and what it measures: `docs/robot.md`.

pub mod arm;
pub mod catalog;
pub mod check;
pub mod collision;
pub mod kinematics;
pub mod model;
pub mod motion;
pub mod ur5;

pub use arm::{Arm, BaseStance, PROBE_PUSHES, UR5_REACH};
