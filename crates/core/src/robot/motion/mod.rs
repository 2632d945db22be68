//! The arm's motion for a push (layer 5 of [`crate::robot`]).
//!
//! - [`rrt`]: RRT* and lazy RRT* in joint space, shortcutting;
//! - [`scene`]: the planning scene (arm, tree, obstacles) as RRT*'s
//!   validator;
//! - [`push_motion`]: the paper's Algorithm 1, lines 4-8, for one push:
//!   reach the pre-contact pose, the straight push, the held tree;
//! - [`trajectory`]: the viewer's trapezoidal timing of a path;
//! - [`topp`]: time-optimal path parameterisation (TOPP-RA), jerk limits;
//! - [`execution`]: the controller trajectory of a planned push;
//! - [`ros`]: ROS 2 `trajectory_msgs/JointTrajectory` shapes.

pub mod execution;
pub mod push_motion;
pub mod ros;
pub mod rrt;
pub mod scene;
pub mod topp;
pub mod trajectory;
