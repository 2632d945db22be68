//! `/v1/plan`'s `objective`, `limits` and the loads an answer reports.

use serde::{Deserialize, Serialize};
use treemanip_core::planner::Limits;
use treemanip_core::sim::loads::PushLoads;
use utoipa::ToSchema;

use crate::api::types::schema::Vec3;
use crate::api::types::shape::ShapeJson;

/// What the push is for (docs/tasks.md).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
#[schema(as = Objective)]
pub enum ObjectiveJson {
    /// Move the tree toward target positions.
    Shape {
        /// Where each node should end up (m).
        #[schema(value_type = Vec<Vec3>, max_items = 512)]
        target_positions: Vec<Vec<f64>>,
        /// One per node, ≥ 0; 0 ignores a node; at least one non-root
        /// node weighted. Residual: the largest weighted node distance.
        #[serde(default)]
        #[schema(max_items = 512, minimum = 0)]
        weights: Option<Vec<f64>>,
    },
    /// Keep every branch `margin` away from every region.
    Clear {
        #[schema(min_items = 1, max_items = 16)]
        regions: Vec<ShapeJson>,
        /// Clearance every branch must keep from every region (m).
        #[serde(default)]
        #[schema(minimum = 0, maximum = 2, default = 0.01)]
        margin: Option<f64>,
    },
    /// Bring one node into a region.
    Reach {
        /// The node to bring into the region (not the root).
        #[serde(deserialize_with = "crate::api::json::integer::usize")]
        #[schema(minimum = 1, maximum = 9007199254740991_u64)]
        node: usize,
        region: ShapeJson,
    },
}

/// Loads `model` and `physics` may not exceed; a missing member takes its
/// default.
#[derive(Debug, Clone, Default, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LimitsJson {
    /// Bending stress at a branch's base (Pa); default 40 MPa, a
    /// green-wood modulus of rupture of about 60 MPa (USDA Wood Handbook,
    /// Table 5-3a) divided by 1.5.
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0, default = 40000000.0)]
    pub max_stress: Option<f64>,
    /// Gripper force (N); default 50 N, the range of the UR5e wrist
    /// force/torque sensor.
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0, default = 50.0)]
    pub max_contact_force: Option<f64>,
}

/// A push's loads as the response reports them.
#[derive(Debug, Clone, Serialize, ToSchema)]
#[schema(as = Loads)]
pub struct LoadsJson {
    /// The largest bending stress at a branch's base (Pa).
    pub peak_stress: f64,
    /// The branch (its node) where it occurs.
    #[schema(required = true)]
    pub peak_node: Option<usize>,
    /// Magnitude of the gripper's force on the branch (N).
    pub contact_force: f64,
    /// 1 − load / limit for each limit (> 0 within it); absent without
    /// limits.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub margin: Option<LoadMarginJson>,
}

impl LoadsJson {
    pub fn new(loads: &PushLoads, limits: Option<&Limits>) -> Self {
        Self {
            peak_stress: loads.peak_stress,
            peak_node: loads.peak_node,
            contact_force: loads.contact_force,
            margin: limits.map(|l| {
                let m = l.margin(loads);
                LoadMarginJson {
                    stress: m.stress,
                    contact_force: m.contact_force,
                }
            }),
        }
    }
}

/// How a push's loads compare with the limits: 1 − load / limit (> 0:
/// within the limit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, ToSchema)]
#[schema(as = LoadMargin)]
pub struct LoadMarginJson {
    pub stress: f64,
    pub contact_force: f64,
}
