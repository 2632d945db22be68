//! `/v1/plan`'s `objective`, `limits` and the loads an answer reports.

use serde::{Deserialize, Serialize};
use treemanip_core::planner::Limits;
use treemanip_core::sim::loads::PushLoads;

use crate::api::types::shape::ShapeJson;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ObjectiveJson {
    Shape {
        target_positions: Vec<Vec<f64>>,
        #[serde(default)]
        weights: Option<Vec<f64>>,
    },
    Clear {
        regions: Vec<ShapeJson>,
        #[serde(default)]
        margin: Option<f64>,
    },
    Reach {
        #[serde(deserialize_with = "crate::api::json::integer::usize")]
        node: usize,
        region: ShapeJson,
    },
}

/// `limits`: either may be left out for its default.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsJson {
    /// Pa.
    #[serde(default)]
    pub max_stress: Option<f64>,
    /// N.
    #[serde(default)]
    pub max_contact_force: Option<f64>,
}

/// A push's loads as the response reports them.
#[derive(Debug, Clone, Serialize)]
pub struct LoadsJson {
    /// Peak bending stress (Pa) and its branch.
    pub peak_stress: f64,
    pub peak_node: Option<usize>,
    /// Contact force magnitude (N).
    pub contact_force: f64,
    /// 1 − load / limit per limit (> 0: within); absent without limits.
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LoadMarginJson {
    pub stress: f64,
    pub contact_force: f64,
}
