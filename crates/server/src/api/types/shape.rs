//! The one shape schema of requests: a region of an objective or an obstacle (checked by [`crate::api::shape::shape`]).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::types::schema::Vec3;

/// A region of space or an obstacle (m, within 5 m of the root; sizes
/// positive, at most 2 m for an objective's region and 5 m for an
/// obstacle). The same schema and validator for both
/// (`crates/server/src/api/shape.rs`).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
#[schema(as = Shape)]
pub enum ShapeJson {
    /// A ball.
    Sphere {
        #[schema(value_type = Vec3)]
        centre: Vec<f64>,
        #[schema(exclusive_minimum = 0.0, maximum = 5.0)]
        radius: f64,
    },
    /// A box turned about the vertical axis.
    Box {
        #[schema(value_type = Vec3)]
        centre: Vec<f64>,
        #[schema(value_type = Vec3)]
        half_extents: Vec<f64>,
        /// Rotation about the vertical axis (rad).
        #[serde(default)]
        yaw: f64,
    },
    /// The points within `radius` of the segment a–b (a line of sight, a
    /// branch).
    Capsule {
        #[schema(value_type = Vec3)]
        a: Vec<f64>,
        #[schema(value_type = Vec3)]
        b: Vec<f64>,
        #[schema(exclusive_minimum = 0.0, maximum = 5.0)]
        radius: f64,
    },
}
