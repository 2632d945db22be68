//! The one shape schema of requests: a region of an objective or an obstacle (checked by [`crate::api::shape::shape`]).

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeJson {
    Sphere {
        centre: Vec<f64>,
        radius: f64,
    },
    Box {
        centre: Vec<f64>,
        half_extents: Vec<f64>,
        #[serde(default)]
        yaw: f64,
    },
    Capsule {
        a: Vec<f64>,
        b: Vec<f64>,
        radius: f64,
    },
}
