//! `/v1/plan`: the request (robot, stance, obstacles, timing) and the answer.

use serde::{Deserialize, Serialize};

use crate::api::types::domain::Warning;
use crate::api::types::identify::{IdentifyResponse, NoiseJson, ProbeJson};
use crate::api::types::models::ModelInfo;
use crate::api::types::motion::{
    AttemptJson, BasePoseJson, ClearanceJson, JointTrajectoryJson, LimitsAnswer, StrategyJson,
    TimedPointJson,
};
use crate::api::types::objective::{LimitsJson, LoadsJson, ObjectiveJson};
use crate::api::types::robots::RobotJson;
use crate::api::types::shape::ShapeJson;
use crate::api::types::tree::TreeJson;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanRequest {
    pub tree: TreeJson,
    /// What the push is for (shape, clear, reach).
    #[serde(default)]
    pub objective: Option<ObjectiveJson>,
    /// Shorthand for a full `shape` objective.
    #[serde(default)]
    pub target_positions: Option<Vec<Vec<f64>>>,
    /// Loads `model` and `physics` may not exceed (defaults: 40 MPa, 50 N).
    #[serde(default)]
    pub limits: Option<LimitsJson>,
    #[serde(default)]
    pub robot: RobotJson,
    #[serde(default)]
    pub obstacles: Vec<ShapeJson>,
    #[serde(default)]
    pub strategy: StrategyJson,
    /// Planning budget (ms); default and maximum are server limits.
    #[serde(default)]
    pub budget_ms: Option<f64>,
    /// Policy-ranked nodes searched (`model`, `physics`).
    #[serde(default, deserialize_with = "crate::api::json::integer::opt_u64")]
    pub max_candidates: Option<u64>,
    /// Push predictions allowed (`model`, `physics`).
    #[serde(default, deserialize_with = "crate::api::json::integer::opt_u64")]
    pub max_evaluations: Option<u64>,
    /// Seed of the search and of RRT* (plans are reproducible for a seed).
    #[serde(default, deserialize_with = "crate::api::json::integer::opt_u64")]
    pub seed: Option<u64>,
    /// See [`super::predict::ForwardRequest::allow_out_of_domain`].
    #[serde(default)]
    pub allow_out_of_domain: bool,
    /// Probe pushes already observed on this tree (as `/v1/identify`
    /// takes them, e.g. the outcome of the last push while it was held):
    /// the planner identifies the stiffness first and plans with the
    /// estimate, returned as `identification`.
    #[serde(default)]
    pub observations: Vec<ProbeJson>,
    /// Noise of `observations` (defaults: 3 mm, 5 % of force).
    #[serde(default)]
    pub observation_noise: Option<NoiseJson>,
    /// Seconds the push is held before the release (default 2).
    #[serde(default)]
    pub hold_s: Option<f64>,
    /// Tool speed along the push (m/s, default 0.05).
    #[serde(default)]
    pub push_speed: Option<f64>,
    /// Shares (0, 1] of the joints' velocity and acceleration limits.
    #[serde(default)]
    pub velocity_scaling: Option<f64>,
    #[serde(default)]
    pub acceleration_scaling: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct PlanResponse {
    /// `planned` or `no_plan`.
    pub status: &'static str,
    pub strategy: StrategyJson,
    pub node: Option<usize>,
    pub rank: Option<usize>,
    pub push: Option<[f64; 3]>,
    /// `shape`, `clear` or `reach`.
    pub objective: &'static str,
    /// The objective's predicted residual after the push (m): shape, the
    /// largest weighted node distance to the target; clear, the deepest
    /// intrusion into a region grown by the margin (0 when clear); reach,
    /// the node's distance to its region (0 inside).
    pub predicted_error: Option<f64>,
    /// The same residual if nothing is done (m).
    pub no_action_error: f64,
    /// The chosen push's loads as the search predicted them (for `model`,
    /// read from the forward model's positions).
    pub predicted_loads: Option<LoadsJson>,
    /// The chosen push's loads as the simulator gives them (`paper`
    /// included: it reports, never enforces).
    pub simulated_loads: Option<LoadsJson>,
    /// The limits enforced (`null` for `paper`).
    pub limits: Option<LimitsAnswer>,
    /// For `clear`: the clearance the push reaches between branches and
    /// regions (m, negative: overlapping), predicted and simulated.
    pub clearance: Option<ClearanceJson>,
    pub base: BasePoseJson,
    /// The configuration the trajectory starts from.
    pub start: Vec<f64>,
    /// Whether the planner chose `start` (base region, no start given).
    pub start_chosen: bool,
    /// The arm that planned.
    pub robot: String,
    pub joint_names: Vec<String>,
    pub trajectory: Vec<TimedPointJson>,
    pub push_start_index: Option<usize>,
    /// The whole held push (approach, push, hold, release, retreat) as a
    /// ROS 2 `trajectory_msgs/JointTrajectory`, velocity-continuous and
    /// within the joints' limits.
    pub joint_trajectory: Option<JointTrajectoryJson>,
    /// Indices of `joint_trajectory`'s first and last point of the
    /// straight push.
    pub push_start_point: Option<usize>,
    pub push_end_point: Option<usize>,
    pub evaluations: usize,
    pub attempts: Vec<AttemptJson>,
    pub total_ms: f64,
    pub model: ModelInfo,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
    /// With `observations`: the stiffness the plan was made with.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub identification: Option<IdentifyResponse>,
}
