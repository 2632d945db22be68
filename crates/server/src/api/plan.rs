//! `POST /v1/plan`: turns the JSON request into a [`planner::Query`] and
//! the [`planner::Plan`] into JSON; the planning is in [`treemanip_core::planner`].

use crate::api::types::error::PostErrors;
use std::time::Duration;

use axum::extract::State;
use serde_json::json;

use super::AppState;
use super::domain;
use super::error::ApiError;
use super::json::ApiJson;
use super::objective::{limits, objective};
use super::observations::{identify_config, probes};
use super::shape::{OBSTACLE, shape};
use super::state::ModelInfo;
use super::validate::{joints, near_point, within_turn};
use crate::api::types::{
    AttemptJson, ClearanceJson, IdentifyResponse, JointTrajectoryJson, LimitsAnswer, LoadsJson,
    PlanRequest, PlanResponse, RobotJson, ShapeJson, TimedPointJson, Warning,
};
use treemanip_core::geometry::shape::Shape;
use treemanip_core::graph::Task;
use treemanip_core::planner::base::{BasePose, BaseRegion};
use treemanip_core::planner::predict::PhysicsPredictor;
use treemanip_core::planner::{
    self, ContactPolicy, PredictivePolicy, Predictor, Query, Stance, Strategy,
};
use treemanip_core::robot::motion::execution::ExecutionOptions;
use treemanip_core::tree::FULL_GRAPH_MAX_NODES;

/// Obstacles a request may list.
pub const MAX_OBSTACLES: usize = 64;

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

/// An arm's joint trajectory for the push that best serves an objective (a
/// target shape, a region to clear, a region to reach) within load limits.
///
/// What the push is for is `objective` (or its shorthand `target_positions`,
/// a full `shape`; both at once: 422): `shape` (target positions, optional
/// per-node `weights`, 0 ignores a node), `clear` (keep every branch `margin`
/// away from every region: spheres, yawed boxes, capsules such as a line of
/// sight) or `reach` (one node into a region). `predicted_error` and
/// `no_action_error` are the objective's residual in metres: shape, the
/// largest weighted node distance to the target; clear, the deepest intrusion
/// of a branch (a capsule of its radius) into a region grown by the margin, 0
/// when clear; reach, the node's distance to its region, 0 inside. Among
/// pushes that meet `clear` or `reach` the least stressing, then the
/// shortest, is preferred. Pushes are held: objectives and loads are judged
/// in the held state. `limits` (default 40 MPa bending stress, 50 N contact
/// force; docs/tasks.md gives their sources) are enforced by `model` and
/// `physics`: a push predicted over a limit is not executed (`over_limit`;
/// for `model` the loads are read from the forward model's predicted
/// positions and screened at twice the limits), and the push about to be
/// executed is simulated (as its push line must be collision-checked against
/// the deforming tree) and refused if it exceeds a limit; `model` also passes
/// over a push whose simulation misses a `clear` or `reach` objective it was
/// predicted to meet (`missed`). `paper` plans `shape` objectives only, never
/// enforces limits, and reports the simulated loads of its pick. For a full
/// shape the contact policy ranks the nodes and proposes a push for each; for
/// other objectives the tree's geometry does (the branches in a region and
/// their ancestors pushed away from it, the node to reach and its ancestors
/// pushed toward it). With `strategy` `model` (default) or `physics`, the
/// planner searches the push of the top `max_candidates` nodes (cross-entropy
/// method around the policy's push, 5-15 cm, the policy's own push also as it
/// is), keeps what the arm can reach (IK, joint limits, collision-free
/// pre-contact pose, straight push), and scores each by the predicted largest
/// node distance to the target (forward GNN or simulator); the best ones are
/// executed in turn: the straight push against the deforming tree, then RRT*
/// for the approach. A push predicted no better than doing nothing is never
/// executed (`not_helpful`). `paper` is the paper's Algorithm 1: the policy's
/// ranking and pushes as they are. If nothing searched can be carried out,
/// the policy's ranking is walked as in `paper`. With `robot.base_region` the
/// planner also chooses where the arm stands (returned as `base`), and,
/// without `robot.start`, a collision-free tucked start there (`start`,
/// `start_chosen`). `obstacles` (spheres, boxes, capsules) are avoided by every
/// strategy. The plan is a timed joint trajectory: approach, then the
/// straight push from `push_start_index`. `no_plan` is a normal answer, with
/// every push looked at and why it was dropped.
#[utoipa::path(post, path = "/v1/plan", tag = "planning",
    request_body = PlanRequest,
    responses(
    (status = 200, description = "A plan, or why there is none.", body = PlanResponse),
    PostErrors,
))]
pub async fn plan(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<PlanRequest>,
) -> Result<axum::Json<PlanResponse>, ApiError> {
    let policy = state.model_for(Task::Policy)?;
    let forward = match Strategy::from(request.strategy) {
        Strategy::Model => Some(state.forward_model_for(request.tree.positions.len())?),
        _ => None,
    };
    let tree = request.tree.to_tree(state.limits.max_nodes)?;
    let objective = objective(
        request.objective.as_ref(),
        request.target_positions.as_deref(),
        &tree,
    )?;
    let load_limits = limits(request.limits.as_ref())?;
    // Past the policy GNN's size (it reads the fully connected graph) the
    // predictor ranks the nodes itself (`planner::PredictivePolicy`).
    if let Some(forward) = &forward {
        domain::check_size(forward, &tree)?;
    }
    let predictive = tree.len() > FULL_GRAPH_MAX_NODES;
    let warnings = if predictive {
        Vec::new()
    } else {
        domain::check(&policy, &tree, &[], request.allow_out_of_domain)?
    };
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
    query.strategy = request.strategy.into();
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
            let forward = forward.as_deref().map(|m| m as &dyn Predictor);
            let ranking = PredictivePolicy {
                predictor: forward.unwrap_or(&PhysicsPredictor),
            };
            let contact: &dyn ContactPolicy = if predictive { &ranking } else { &*policy };
            let plan = planner.plan(&query, contact, forward)?;
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
    let attempts: Vec<AttemptJson> = plan.attempts.iter().map(AttemptJson::from).collect();
    for a in &attempts {
        ::metrics::counter!("treemanip_plan_attempts_total", "outcome" => a.outcome.name())
            .increment(1);
    }
    let status = if plan.plan.is_some() {
        "planned"
    } else {
        "no_plan"
    };
    ::metrics::counter!("treemanip_plans_total", "status" => status).increment(1);
    let chosen = plan.plan;
    let execution = chosen.as_ref().map(|p| &p.execution);
    let limits = plan.limits;
    PlanResponse {
        guard_contact_force: plan.guard_contact_force,
        objective: plan.objective,
        clearance: plan.clearance.map(ClearanceJson::from),
        predicted_loads: plan
            .predicted_loads
            .map(|l| LoadsJson::new(&l, limits.as_ref())),
        simulated_loads: plan
            .simulated_loads
            .map(|l| LoadsJson::new(&l, limits.as_ref())),
        limits: limits.map(LimitsAnswer::from),
        status,
        strategy: plan.strategy.into(),
        node: chosen.as_ref().map(|p| p.node),
        rank: chosen.as_ref().map(|p| p.rank),
        push: chosen.as_ref().map(|p| [p.push.x, p.push.y, p.push.z]),
        predicted_error: plan.predicted_error,
        no_action_error: plan.no_action_error,
        base: plan.base.into(),
        start: plan.start.to_vec(),
        start_chosen: plan.start_chosen,
        robot: arm.name().to_owned(),
        joint_names: arm.joint_names().map(str::to_owned).collect(),
        push_start_index: execution.map(|e| e.push_start_point),
        push_start_point: execution.map(|e| e.push_start_point),
        push_end_point: execution.map(|e| e.push_end_point),
        joint_trajectory: execution.map(|e| JointTrajectoryJson::from(&e.joint_trajectory)),
        // The approach and the push of the controller's trajectory: the
        // one timing of the plan, in the form the viewer plays.
        trajectory: execution
            .map(|e| {
                e.joint_trajectory.points[..=e.push_end_point]
                    .iter()
                    .map(TimedPointJson::from)
                    .collect()
            })
            .unwrap_or_default(),
        evaluations: plan.evaluations,
        attempts,
        total_ms: plan.total_ms,
        model,
        warnings,
        identification: None,
    }
}
