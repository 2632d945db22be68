//! `POST /v1/plan`: turns the JSON request into a [`planner::Query`] and
//! the [`planner::Plan`] into JSON; the planning is in [`treemanip_core::planner`].

use std::time::Duration;

use axum::extract::State;
use serde::{Deserialize, Serialize};
use serde_json::json;

use super::AppState;
use super::domain::{self, Warning};
use super::error::ApiError;
use super::json::ApiJson;
use super::objective::{LimitsJson, LoadsJson, ObjectiveJson, limits, objective};
use super::observations::{IdentifyResponse, ProbeJson, identify_config, probes};
use super::shape::{OBSTACLE, ShapeJson, shape};
use super::state::ModelInfo;
use super::tree_json::TreeJson;
use super::validate::{joints, near_point, within_turn};
use treemanip_core::geometry::shape::Shape;
use treemanip_core::graph::Task;
use treemanip_core::identify::Noise;
use treemanip_core::planner::base::{BasePose, BaseRegion};
use treemanip_core::planner::{self, Attempt, Predictor, Query, Stance, Strategy};
use treemanip_core::robot::motion::execution::ExecutionOptions;
use treemanip_core::robot::motion::trajectory::TimedPoint;

/// Obstacles a request may list.
pub const MAX_OBSTACLES: usize = 64;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseRegionJson {
    pub min: Vec<f64>,
    pub max: Vec<f64>,
    #[serde(default)]
    pub yaw: Option<Vec<f64>>,
}

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotJson {
    /// Which arm plans (`GET /v1/robots`); default the server's default
    /// robot (the built-in `ur5` unless `--robot` was given).
    #[serde(default)]
    pub name: Option<String>,
    /// Arm base position (m); default (−0.5, 0, 0.1).
    #[serde(default)]
    pub base: Option<Vec<f64>>,
    /// The fixed base's orientation [roll, pitch, yaw] (rad, the URDF's
    /// convention); default upright, facing +x. Roll π hangs the arm.
    #[serde(default)]
    pub base_rpy: Option<Vec<f64>>,
    /// A box the planner may place the base in (instead of `base`).
    #[serde(default)]
    pub base_region: Option<BaseRegionJson>,
    /// Start joint configuration (rad, or m for prismatic joints), one
    /// value per joint of the arm; default the arm's home.
    #[serde(default)]
    pub start: Option<Vec<f64>>,
}

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
    pub strategy: Strategy,
    /// Planning budget (ms); default and maximum are server limits.
    #[serde(default)]
    pub budget_ms: Option<f64>,
    /// Policy-ranked nodes searched (`model`, `physics`).
    #[serde(default, deserialize_with = "super::json::integer::opt_u64")]
    pub max_candidates: Option<u64>,
    /// Push predictions allowed (`model`, `physics`).
    #[serde(default, deserialize_with = "super::json::integer::opt_u64")]
    pub max_evaluations: Option<u64>,
    /// Seed of the search and of RRT* (plans are reproducible for a seed).
    #[serde(default, deserialize_with = "super::json::integer::opt_u64")]
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
    pub observation_noise: Option<Noise>,
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
    pub strategy: Strategy,
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
    pub limits: Option<treemanip_core::planner::Limits>,
    /// For `clear`: the clearance the push reaches between branches and
    /// regions (m, negative: overlapping), predicted and simulated.
    pub clearance: Option<treemanip_core::planner::Clearance>,
    pub base: BasePose,
    /// The configuration the trajectory starts from.
    pub start: Vec<f64>,
    /// Whether the planner chose `start` (base region, no start given).
    pub start_chosen: bool,
    /// The arm that planned.
    pub robot: String,
    pub joint_names: Vec<String>,
    pub trajectory: Vec<TimedPoint>,
    pub push_start_index: Option<usize>,
    /// The whole held push (approach, push, hold, release, retreat) as a
    /// ROS 2 `trajectory_msgs/JointTrajectory`, velocity-continuous and
    /// within the joints' limits.
    pub joint_trajectory: Option<treemanip_core::robot::motion::ros::JointTrajectory>,
    /// Indices of `joint_trajectory`'s first and last point of the
    /// straight push.
    pub push_start_point: Option<usize>,
    pub push_end_point: Option<usize>,
    pub evaluations: usize,
    pub attempts: Vec<Attempt>,
    pub total_ms: f64,
    pub model: ModelInfo,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
    /// With `observations`: the stiffness the plan was made with.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub identification: Option<IdentifyResponse>,
}

fn invalid(field: &str, message: impl Into<String>) -> ApiError {
    ApiError::invalid_field(field, message)
}

/// `robot.base_rpy`, checked (default upright).
fn base_rpy(robot: &RobotJson) -> Result<[f64; 3], ApiError> {
    let Some(v) = &robot.base_rpy else {
        return Ok([0.0; 3]);
    };
    match v.as_slice() {
        [r, p, y] if [r, p, y].iter().all(|a| within_turn(**a)) => Ok([*r, *p, *y]),
        _ => Err(invalid(
            "robot.base_rpy",
            "`robot.base_rpy` must be [roll, pitch, yaw], finite, within ±2π rad",
        )),
    }
}

/// Where the arm stands: a fixed base, a base region, or `None` for the
/// robot's own default base ([`treemanip_core::robot::Arm::default_base`]).
pub(crate) fn stance(robot: &RobotJson) -> Result<Option<Stance>, ApiError> {
    match (&robot.base, &robot.base_region) {
        (Some(_), Some(_)) => Err(invalid(
            "robot.base_region",
            "give either `robot.base` or `robot.base_region`, not both",
        )),
        (Some(b), None) => {
            let p = near_point(b, "robot.base")?;
            let [roll, pitch, yaw] = base_rpy(robot)?;
            Ok(Some(Stance::Fixed(
                BasePose {
                    position: [p.x, p.y, p.z],
                    yaw,
                    roll,
                    pitch,
                }
                .isometry(),
            )))
        }
        (None, None) if robot.base_rpy.is_some() => Err(invalid(
            "robot.base_rpy",
            "`robot.base_rpy` orients a fixed base: give `robot.base` with it",
        )),
        (None, None) => Ok(None),
        (None, Some(_)) if robot.base_rpy.is_some() => Err(invalid(
            "robot.base_rpy",
            "`robot.base_rpy` orients a fixed base; a base region chooses its own heading (`robot.base_region.yaw`)",
        )),
        (None, Some(region)) => {
            let min = near_point(&region.min, "robot.base_region.min")?.coords;
            let max = near_point(&region.max, "robot.base_region.max")?.coords;
            if (0..3).any(|k| min[k] > max[k]) {
                return Err(invalid(
                    "robot.base_region",
                    "`robot.base_region.min` must not exceed `max` in any coordinate",
                ));
            }
            let yaw = match &region.yaw {
                None => None,
                Some(y) => match y.as_slice() {
                    [lo, hi] if within_turn(*lo) && within_turn(*hi) && lo <= hi => {
                        Some((*lo, *hi))
                    }
                    _ => {
                        return Err(invalid(
                            "robot.base_region.yaw",
                            "`robot.base_region.yaw` must be [low, high] within ±2π rad",
                        ));
                    }
                },
            };
            Ok(Some(Stance::Region(BaseRegion { min, max, yaw })))
        }
    }
}

fn obstacles(list: &[ShapeJson]) -> Result<Vec<Shape>, ApiError> {
    if list.len() > MAX_OBSTACLES {
        return Err(invalid(
            "obstacles",
            format!(
                "{} obstacles; at most {MAX_OBSTACLES} are accepted",
                list.len()
            ),
        ));
    }
    list.iter()
        .map(|o| shape(o, "obstacles", &OBSTACLE))
        .collect()
}

/// The request's timing of the controller's trajectory.
fn execution_options(request: &PlanRequest) -> Result<ExecutionOptions, ApiError> {
    let mut options = ExecutionOptions::default();
    let in_range = |value: Option<f64>, lo: f64, hi: f64, field: &str| match value {
        None => Ok(None),
        Some(v) if v.is_finite() && v > lo && v <= hi => Ok(Some(v)),
        Some(v) => Err(invalid(
            field,
            format!("`{field}` must be in ({lo}, {hi}], not {v}"),
        )),
    };
    if let Some(v) = in_range(request.push_speed, 0.0, 0.5, "push_speed")? {
        options.push_speed = v;
    }
    if let Some(v) = in_range(request.velocity_scaling, 0.0, 1.0, "velocity_scaling")? {
        options.velocity_scaling = v;
    }
    if let Some(v) = in_range(
        request.acceleration_scaling,
        0.0,
        1.0,
        "acceleration_scaling",
    )? {
        options.acceleration_scaling = v;
    }
    match request.hold_s {
        None => {}
        Some(v) if v.is_finite() && (0.0..=600.0).contains(&v) => options.hold_s = v,
        Some(v) => {
            return Err(invalid(
                "hold_s",
                format!("`hold_s` must be between 0 and 600 s, not {v}"),
            ));
        }
    }
    Ok(options)
}

/// A request count within `1..=max`, or its default.
fn count(value: Option<u64>, default: usize, max: usize, field: &str) -> Result<usize, ApiError> {
    match value {
        None => Ok(default.min(max)),
        Some(v) if v >= 1 && v <= max as u64 => Ok(v as usize),
        Some(_) => Err(
            invalid(field, format!("`{field}` must be between 1 and {max}"))
                .with_details(json!({ "field": field, "max": max })),
        ),
    }
}

pub async fn plan(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<PlanRequest>,
) -> Result<axum::Json<PlanResponse>, ApiError> {
    let policy = state.model_for(Task::Policy)?;
    let forward = match request.strategy {
        Strategy::Model => Some(state.model_for(Task::Forward)?),
        _ => None,
    };
    let tree = request.tree.to_tree(state.limits.max_nodes)?;
    let objective = objective(
        request.objective.as_ref(),
        request.target_positions.as_deref(),
        &tree,
    )?;
    let load_limits = limits(request.limits.as_ref())?;
    let warnings = domain::check(&policy, &tree, &[], request.allow_out_of_domain)?;
    let max_ms = state.limits.max_plan_budget.as_secs_f64() * 1e3;
    let budget_ms = request.budget_ms.unwrap_or(max_ms.min(2000.0));
    if !(budget_ms.is_finite() && budget_ms > 0.0 && budget_ms <= max_ms) {
        return Err(ApiError::invalid_argument(format!(
            "`budget_ms` must be positive and at most {max_ms:.0}"
        ))
        .with_details(json!({ "field": "budget_ms", "max": max_ms })));
    }
    let mut query = Query::with_objective(tree, objective);
    query.limits = Some(load_limits);
    let stance = stance(&request.robot)?;
    let planner = state
        .robots
        .get(request.robot.name.as_deref(), "robot.name")?;
    query.stance = stance.unwrap_or_else(|| Stance::Fixed(planner.robot().default_base()));
    query.start = request
        .robot
        .start
        .as_deref()
        .map(|q| joints(q, "robot.start", planner.robot()))
        .transpose()?;
    query.obstacles = obstacles(&request.obstacles)?;
    query.strategy = request.strategy;
    query.budget = Duration::from_secs_f64(budget_ms / 1e3);
    let nodes = query.tree.len().saturating_sub(1).max(1);
    query.max_candidates = count(
        request.max_candidates,
        planner::DEFAULT_CANDIDATES,
        nodes,
        "max_candidates",
    )?;
    query.max_evaluations = Some(count(
        request.max_evaluations,
        query.evaluations(),
        state.limits.max_plan_evaluations,
        "max_evaluations",
    )?);
    query.seed = request.seed.unwrap_or(1);
    query.execution = execution_options(&request)?;
    let config = identify_config(request.observation_noise, None, "observation_")?;
    query.observations = probes(&query.tree, &request.observations, &config, "observations")?;
    query.identify = config;
    let info = ModelInfo::of(&policy, &state);
    let response = state
        .run_blocking("/v1/plan", move || {
            let plan = planner.plan(
                &query,
                &*policy,
                forward.as_deref().map(|m| m as &dyn Predictor),
            )?;
            Ok(PlanResponse {
                identification: plan.identification.as_ref().map(IdentifyResponse::from),
                ..response(plan, planner.robot(), info, warnings)
            })
        })
        .await?;
    Ok(axum::Json(response))
}

fn response(
    plan: planner::Plan,
    arm: &treemanip_core::robot::Arm,
    model: ModelInfo,
    warnings: Vec<Warning>,
) -> PlanResponse {
    for a in &plan.attempts {
        let outcome = serde_json::to_value(a.outcome)
            .ok()
            .and_then(|v| v.as_str().map(str::to_owned))
            .unwrap_or_default();
        ::metrics::counter!("treemanip_plan_attempts_total", "outcome" => outcome).increment(1);
    }
    let status = if plan.plan.is_some() {
        "planned"
    } else {
        "no_plan"
    };
    ::metrics::counter!("treemanip_plans_total", "status" => status).increment(1);
    let chosen = plan.plan;
    let limits = plan.limits;
    PlanResponse {
        objective: plan.objective,
        clearance: plan.clearance,
        predicted_loads: plan
            .predicted_loads
            .map(|l| LoadsJson::new(&l, limits.as_ref())),
        simulated_loads: plan
            .simulated_loads
            .map(|l| LoadsJson::new(&l, limits.as_ref())),
        limits,
        status,
        strategy: plan.strategy,
        node: chosen.as_ref().map(|p| p.node),
        rank: chosen.as_ref().map(|p| p.rank),
        push: chosen.as_ref().map(|p| [p.push.x, p.push.y, p.push.z]),
        predicted_error: plan.predicted_error,
        no_action_error: plan.no_action_error,
        base: plan.base,
        start: plan.start.to_vec(),
        start_chosen: plan.start_chosen,
        robot: arm.name().to_owned(),
        joint_names: arm.joint_names().map(str::to_owned).collect(),
        push_start_index: chosen.as_ref().map(|p| p.push_start_index),
        push_start_point: chosen
            .as_ref()
            .and_then(|p| p.execution.as_ref())
            .map(|e| e.push_start_point),
        push_end_point: chosen
            .as_ref()
            .and_then(|p| p.execution.as_ref())
            .map(|e| e.push_end_point),
        joint_trajectory: chosen
            .as_ref()
            .and_then(|p| p.execution.as_ref())
            .map(|e| e.joint_trajectory.clone()),
        trajectory: chosen.map(|p| p.trajectory).unwrap_or_default(),
        evaluations: plan.evaluations,
        attempts: plan.attempts,
        total_ms: plan.total_ms,
        model,
        warnings,
        identification: None,
    }
}
