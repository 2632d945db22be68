//! `POST /v1/plan`: the paper's Algorithm 1. The contact policy ranks the
//! nodes; for each in turn the planner looks for a collision-free UR5
//! trajectory that reaches the node's pre-contact pose and carries out its
//! predicted push; the first one found is returned.

use std::time::Duration;

use axum::extract::State;
use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};
use serde_json::json;

use super::AppState;
use super::domain::{self, Warning};
use super::error::ApiError;
use super::json::ApiJson;
use super::predict::{ModelInfo, targets, vector3};
use super::tree_json::TreeJson;
use crate::graph::Task;
use crate::infer::models::rank_candidates;
use crate::robot::Ur5;
use crate::robot::collision::CollisionModel;
use crate::robot::plan::{Attempt, PlanError, PlanOptions, PushCandidate, plan_push};
use crate::robot::trajectory::TimedPoint;
use crate::robot::ur5::{self, JOINT_NAMES};

#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotJson {
    /// Arm base position (m), identity orientation; default (−0.5, 0, 0.1).
    #[serde(default)]
    pub base: Option<Vec<f64>>,
    /// Start joint configuration (rad); default the paper's home pose.
    #[serde(default)]
    pub start: Option<Vec<f64>>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanRequest {
    pub tree: TreeJson,
    pub target_positions: Vec<Vec<f64>>,
    #[serde(default)]
    pub robot: RobotJson,
    /// Planning budget (ms) over all candidates; default and maximum are
    /// server limits.
    #[serde(default)]
    pub budget_ms: Option<f64>,
    /// RRT* seed (plans are reproducible for a given seed).
    #[serde(default, deserialize_with = "super::json::integer::opt_u64")]
    pub seed: Option<u64>,
    /// See [`super::predict::ForwardRequest::allow_out_of_domain`].
    #[serde(default)]
    pub allow_out_of_domain: bool,
}

#[derive(Debug, Clone, Serialize)]
pub struct PlanResponse {
    /// `planned` or `no_plan`.
    pub status: &'static str,
    pub node: Option<usize>,
    pub rank: Option<usize>,
    pub push: Option<[f64; 3]>,
    pub joint_names: [&'static str; 6],
    pub trajectory: Vec<TimedPoint>,
    pub push_start_index: Option<usize>,
    pub attempts: Vec<Attempt>,
    pub total_ms: f64,
    pub model: ModelInfo,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
}

fn joints(values: &[f64]) -> Result<[f64; 6], ApiError> {
    let q = <[f64; 6]>::try_from(values).map_err(|_| {
        ApiError::invalid_argument(format!(
            "`robot.start` must have 6 joint angles, it has {}",
            values.len()
        ))
        .with_details(json!({ "field": "robot.start" }))
    })?;
    if !q
        .iter()
        .all(|v| v.is_finite() && v.abs() <= 2.0 * std::f64::consts::TAU)
    {
        return Err(ApiError::invalid_argument(
            "`robot.start` must be finite angles within ±4π rad",
        )
        .with_details(json!({ "field": "robot.start" })));
    }
    Ok(q)
}

pub async fn plan(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<PlanRequest>,
) -> Result<axum::Json<PlanResponse>, ApiError> {
    let model = state.model_for(Task::Policy)?;
    let tree = request.tree.to_tree(state.limits.max_nodes)?;
    let targets = targets(&request.target_positions, &tree)?;
    let warnings = domain::check(&model, &tree, &[], request.allow_out_of_domain)?;
    let max_ms = state.limits.max_plan_budget.as_secs_f64() * 1e3;
    let budget_ms = request.budget_ms.unwrap_or(max_ms.min(2000.0));
    if !(budget_ms.is_finite() && budget_ms > 0.0 && budget_ms <= max_ms) {
        return Err(ApiError::invalid_argument(format!(
            "`budget_ms` must be positive and at most {max_ms:.0}"
        ))
        .with_details(json!({ "field": "budget_ms", "max": max_ms })));
    }
    let base = match &request.robot.base {
        Some(b) => {
            let v: Vector3<f64> = vector3(b, "robot.base")?;
            if v.norm() > 5.0 {
                return Err(ApiError::invalid_argument(
                    "`robot.base` is more than 5 m from the tree root",
                )
                .with_details(json!({ "field": "robot.base" })));
            }
            Isometry3::translation(v.x, v.y, v.z)
        }
        None => ur5::default_base(),
    };
    let start = match &request.robot.start {
        Some(q) => joints(q)?,
        None => ur5::HOME,
    };
    let seed = request.seed.unwrap_or(1);
    let info = ModelInfo::of(&model, &state);
    let response = state
        .run_blocking("/v1/plan", move || {
            let ranked = rank_candidates(&model, &tree, &targets)
                .map_err(|e| ApiError::internal(format!("inference failed: {e}")))?;
            let candidates: Vec<PushCandidate> = ranked
                .iter()
                .map(|c| PushCandidate {
                    node: c.node,
                    push: Vector3::from(c.push),
                })
                .collect();
            let collision = CollisionModel::new(Ur5::default().with_base(base));
            let mut options = PlanOptions::default();
            options.rrt.seed = seed;
            options.budget = Some(Duration::from_secs_f64(budget_ms / 1e3));
            let report = plan_push(&collision, &tree, &candidates, &start, &options).map_err(
                |e| match e {
                    PlanError::StartInCollision => ApiError::invalid_argument(
                        "the start configuration collides with the tree, the ground or itself",
                    )
                    .with_details(json!({ "field": "robot.start" })),
                },
            )?;
            for a in &report.attempts {
                let outcome = serde_json::to_value(a.outcome)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_owned))
                    .unwrap_or_default();
                ::metrics::counter!("treemanip_plan_attempts_total", "outcome" => outcome)
                    .increment(1);
            }
            let status = if report.plan.is_some() {
                "planned"
            } else {
                "no_plan"
            };
            ::metrics::counter!("treemanip_plans_total", "status" => status).increment(1);
            let plan = report.plan;
            Ok(PlanResponse {
                status,
                node: plan.as_ref().map(|p| p.node),
                rank: plan.as_ref().map(|p| p.rank),
                push: plan.as_ref().map(|p| [p.push.x, p.push.y, p.push.z]),
                joint_names: JOINT_NAMES,
                push_start_index: plan.as_ref().map(|p| p.push_start_index),
                trajectory: plan.map(|p| p.trajectory).unwrap_or_default(),
                attempts: report.attempts,
                total_ms: report.total_ms,
                model: info,
                warnings,
            })
        })
        .await?;
    Ok(axum::Json(response))
}
