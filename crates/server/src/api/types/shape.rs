//! The one shape schema of the wire: a region of an objective, an
//! obstacle (both checked by [`crate::api::shape::shape`]) and every
//! collision shape of an arm's links in `/v1/robot/link-poses`' answer.

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use treemanip_core::geometry::shape::Shape;
use utoipa::ToSchema;

use crate::api::types::schema::{Quaternion, Vec3};

/// A shape (m, rad): a ball, a box, a capsule or a cylinder. In a request
/// (a region or an obstacle) its points lie within 5 m of the root and its
/// sizes are positive, at most 2 m for an objective's region and 5 m for an
/// obstacle. The same schema and validator for both
/// (`crates/server/src/api/shape.rs`), and the same schema for the links'
/// shapes the server answers with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
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
    /// A box about its centre, turned by `yaw` about the vertical axis or
    /// by `rotation` (not both).
    Box {
        #[schema(value_type = Vec3)]
        centre: Vec<f64>,
        #[schema(value_type = Vec3)]
        half_extents: Vec<f64>,
        /// Rotation about the vertical axis (rad).
        #[serde(default, skip_serializing_if = "is_zero")]
        #[schema(default = 0.0)]
        yaw: f64,
        /// Any rotation, as a quaternion.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        #[schema(value_type = Option<Quaternion>)]
        rotation: Option<Vec<f64>>,
    },
    /// The points within `radius` of the segment a–b (a line of sight, a
    /// branch, an arm's link).
    Capsule {
        #[schema(value_type = Vec3)]
        a: Vec<f64>,
        #[schema(value_type = Vec3)]
        b: Vec<f64>,
        #[schema(exclusive_minimum = 0.0, maximum = 5.0)]
        radius: f64,
    },
    /// A cylinder about its centre, along the z axis of `rotation`
    /// (default: vertical).
    Cylinder {
        #[schema(value_type = Vec3)]
        centre: Vec<f64>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        #[schema(value_type = Option<Quaternion>)]
        rotation: Option<Vec<f64>>,
        #[schema(exclusive_minimum = 0.0, maximum = 5.0)]
        radius: f64,
        /// Half its length along its axis (m).
        #[schema(exclusive_minimum = 0.0, maximum = 5.0)]
        half_length: f64,
    },
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

fn xyz(v: &nalgebra::Vector3<f64>) -> Vec<f64> {
    vec![v.x, v.y, v.z]
}

fn quaternion(pose: &Isometry3<f64>) -> Option<Vec<f64>> {
    let q = pose.rotation.quaternion();
    Some(vec![q.i, q.j, q.k, q.w])
}

/// A core shape as the server answers it (a link's, in its frame).
impl From<&Shape> for ShapeJson {
    fn from(shape: &Shape) -> Self {
        match shape {
            Shape::Sphere { centre, radius } => ShapeJson::Sphere {
                centre: xyz(&centre.coords),
                radius: *radius,
            },
            Shape::Box { pose, half_extents } => ShapeJson::Box {
                centre: xyz(&pose.translation.vector),
                half_extents: xyz(half_extents),
                yaw: 0.0,
                rotation: quaternion(pose),
            },
            Shape::Capsule { a, b, radius } => ShapeJson::Capsule {
                a: xyz(&a.coords),
                b: xyz(&b.coords),
                radius: *radius,
            },
            Shape::Cylinder {
                pose,
                radius,
                half_length,
            } => ShapeJson::Cylinder {
                centre: xyz(&pose.translation.vector),
                rotation: quaternion(pose),
                radius: *radius,
                half_length: *half_length,
            },
        }
    }
}
