//! `/v1/plan`: the request (robot, stance, obstacles, timing) and the answer.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::types::domain::Warning;
use crate::api::types::identify::{IdentifyResponse, NoiseJson, ProbeJson};
use crate::api::types::models::ModelInfo;
use crate::api::types::motion::{
    AttemptJson, BasePoseJson, ClearanceJson, JointTrajectoryJson, LimitsAnswer, StrategyJson,
    TimedPointJson,
};
use crate::api::types::objective::{LimitsJson, LoadsJson, ObjectiveJson};
use crate::api::types::robots::RobotJson;
use crate::api::types::schema::{Joints, Vec3, string_enum};
use crate::api::types::shape::ShapeJson;
use crate::api::types::tree::TreeJson;

/// Give `objective` or `target_positions` (one of them, 422 otherwise).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PlanRequest {
    pub tree: TreeJson,
    /// What the push is for (shape, clear, reach).
    #[serde(default)]
    pub objective: Option<ObjectiveJson>,
    /// Shorthand for the objective `{"kind": "shape", "target_positions":
    /// ...}`.
    #[serde(default)]
    #[schema(value_type = Option<Vec<Vec3>>, max_items = 512)]
    pub target_positions: Option<Vec<Vec<f64>>>,
    #[serde(default)]
    pub limits: Option<LimitsJson>,
    #[serde(default)]
    pub robot: RobotJson,
    /// Fixed obstacles in the tree's frame (m), within 5 m of the root;
    /// sizes positive and at most 5 m. A sphere is checked as a ball.
    #[serde(default)]
    #[schema(max_items = 512)]
    pub obstacles: Vec<ShapeJson>,
    #[serde(default)]
    pub strategy: StrategyJson,
    /// Planning budget (ms): default 2000, at most the server's limit
    /// (5000).
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0)]
    pub budget_ms: Option<f64>,
    /// Policy-ranked nodes searched (default 4, at most N - 1).
    #[serde(default, deserialize_with = "crate::api::json::integer::opt_u64")]
    #[schema(minimum = 1, maximum = 511)]
    pub max_candidates: Option<u64>,
    /// Push predictions allowed (default: by tree size, since a prediction
    /// costs in proportion to N(N-1): from a fixed base 60 at N = 15, 33 at
    /// N = 20, 21 at N = 25, 16 at N = 30; with a base region 96 up to
    /// N = 22, 48 at N = 30; at most the server's limit, 512). When no
    /// searched push can be carried out, the policy's own reachable pushes
    /// are predicted too: what the search left of the budget, at least 8.
    #[serde(default, deserialize_with = "crate::api::json::integer::opt_u64")]
    #[schema(minimum = 1, maximum = 512)]
    pub max_evaluations: Option<u64>,
    /// Seed of the push search and of RRT* (plans are reproducible for a
    /// seed).
    #[serde(default, deserialize_with = "crate::api::json::integer::opt_u64")]
    #[schema(minimum = 0, maximum = 9007199254740991_u64)]
    pub seed: Option<u64>,
    /// As `/v1/forward`'s.
    #[serde(default)]
    #[schema(default = false)]
    pub allow_out_of_domain: bool,
    /// Probe pushes already observed on this tree (as `/v1/identify`
    /// takes them, e.g. the last push while it was held): the planner
    /// identifies the stiffness first and plans with the estimate
    /// (returned as `identification`).
    #[serde(default)]
    #[schema(max_items = 32)]
    pub observations: Vec<ProbeJson>,
    /// Noise of `observations` (defaults: 3 mm, 5 % of force).
    #[serde(default)]
    pub observation_noise: Option<NoiseJson>,
    /// Seconds the push is held before the release (`joint_trajectory`).
    #[serde(default)]
    #[schema(minimum = 0, maximum = 600, default = 2.0)]
    pub hold_s: Option<f64>,
    /// Tool speed along the straight push (m/s), with 0.25 m/s² ramps;
    /// lowered if a joint would exceed a limit.
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0, maximum = 0.5, default = 0.05)]
    pub push_speed: Option<f64>,
    /// Share of the joints' velocity limits (as MoveIt's).
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0, maximum = 1.0, default = 1.0)]
    pub velocity_scaling: Option<f64>,
    /// Share of the joints' acceleration limits.
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0, maximum = 1.0, default = 1.0)]
    pub acceleration_scaling: Option<f64>,
}

fn plan_status() -> utoipa::openapi::schema::Schema {
    string_enum(&["planned", "no_plan"], None)
}

fn objective_kind() -> utoipa::openapi::schema::Schema {
    string_enum(&["shape", "clear", "reach"], None)
}

/// A plan, or why there is none (`no_plan` is a normal answer, with every
/// push looked at and why it was dropped).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct PlanResponse {
    #[schema(schema_with = plan_status)]
    pub status: &'static str,
    pub strategy: StrategyJson,
    #[schema(required = true)]
    pub node: Option<usize>,
    #[schema(required = true)]
    pub rank: Option<usize>,
    #[schema(required = true, value_type = Option<Vec3>)]
    pub push: Option<[f64; 3]>,
    #[schema(schema_with = objective_kind)]
    pub objective: &'static str,
    /// The objective's predicted residual after the push (m): shape, the
    /// largest weighted node distance to the target; clear, the deepest
    /// intrusion into a region grown by the margin (0 when clear); reach,
    /// the node's distance to its region (0 inside).
    #[schema(required = true)]
    pub predicted_error: Option<f64>,
    /// The same residual if nothing is done (m).
    pub no_action_error: f64,
    /// The chosen push's loads as the search predicted them (for `model`,
    /// read from the forward model's positions).
    #[schema(required = true)]
    pub predicted_loads: Option<LoadsJson>,
    /// The chosen push's loads as the simulator gives them (`paper`
    /// included: it reports, never enforces).
    #[schema(required = true)]
    pub simulated_loads: Option<LoadsJson>,
    /// The limits enforced (`null` for `paper`).
    #[schema(required = true)]
    pub limits: Option<LimitsAnswer>,
    /// Carry the push out as a guarded move: stop where the wrist's force
    /// first reaches this (N). It is the force limit, or where the push's
    /// simulated stress per newton would put the wood at the stress
    /// limit, whichever is lower, so the tree as sent never trips it; a
    /// real tree stiffer than the one sent (a tree extracted from a scan,
    /// above all) stops before it is overloaded. `null` without a plan or
    /// without limits.
    #[schema(required = true)]
    pub guard_contact_force: Option<f64>,
    /// For `clear`: the clearance the push reaches between branches and
    /// regions (m, negative: overlapping), predicted and simulated.
    #[schema(required = true)]
    pub clearance: Option<ClearanceJson>,
    pub base: BasePoseJson,
    /// The configuration the trajectory starts from.
    #[schema(value_type = Joints)]
    pub start: Vec<f64>,
    /// Whether the planner chose `start` (base region, no start given).
    pub start_chosen: bool,
    /// The arm that planned.
    pub robot: String,
    #[schema(min_items = 1, max_items = 8)]
    pub joint_names: Vec<String>,
    /// The approach and the push of `joint_trajectory` as (t, q) points,
    /// up to `push_end_point` (the same timing; kept for clients that
    /// play a plan, such as the viewer). Deprecated: read
    /// `joint_trajectory`, which also holds the hold, the release and the
    /// retreat.
    #[schema(deprecated)]
    pub trajectory: Vec<TimedPointJson>,
    /// `push_start_point`, as an index into `trajectory`. Deprecated with
    /// it.
    #[schema(required = true, deprecated)]
    pub push_start_index: Option<usize>,
    /// The whole held push (approach, push, hold, release, retreat) as a
    /// ROS 2 `trajectory_msgs/JointTrajectory`, velocity-continuous and
    /// within the joints' limits: present in every `planned` answer (a
    /// push that cannot be timed is the attempt outcome `no_trajectory`).
    #[schema(required = true)]
    pub joint_trajectory: Option<JointTrajectoryJson>,
    /// Indices of `joint_trajectory`'s first and last point of the
    /// straight push.
    #[schema(required = true)]
    pub push_start_point: Option<usize>,
    /// Held from there for `hold_s`.
    #[schema(required = true)]
    pub push_end_point: Option<usize>,
    /// Push predictions made by the search.
    pub evaluations: usize,
    pub attempts: Vec<AttemptJson>,
    pub total_ms: f64,
    pub model: ModelInfo,
    /// As `/v1/forward`'s.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
    /// With `observations`: the stiffness the plan was made with.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub identification: Option<IdentifyResponse>,
}
