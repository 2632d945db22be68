//! Geometry shared by the robot, the planner and the server: one place for
//! the conversions into parry's types and the queries built on them.
//!
//! - [`convert`]: nalgebra vectors and isometries as parry's `Vec3` and
//!   `Pose` (parry 0.31 has its own math types);
//! - [`shape`]: [`shape::Shape`], the solids around a tree (an objective's
//!   regions, obstacles): parry conversion, bounding box, signed distance;
//! - [`segment`]: closest points of two segments (every capsule query);
//! - [`aabb`]: axis-aligned boxes, the prefilter of every query;
//! - [`world_shape`]: capsules, boxes and cylinders placed in the world,
//!   whether two touch and their distance;
//! - [`segment_box`]: a segment's distance to a box, in closed form;
//! - [`principal`]: the principal directions of a point set.

pub mod aabb;
pub mod convert;
pub mod principal;
pub mod segment;
pub mod segment_box;
pub mod shape;
pub mod world_shape;
