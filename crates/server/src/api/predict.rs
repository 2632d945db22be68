//! `POST /v1/forward` and `POST /v1/policy`: the learned models.

use axum::extract::State;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use serde_json::json;

use super::AppState;
use super::domain::{self, Warning};
use super::error::ApiError;
use super::json::ApiJson;
use super::state::ModelInfo;
use super::tree_json::TreeJson;
use super::validate::{check_contact, check_push, request_timeout, targets, vector3};
use treemanip_core::graph::Task;
use treemanip_core::planner::Candidate;
use treemanip_core::tree::Tree;
use treemanip_infer::models::{predict_displacements, rank_candidates};

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForwardRequest {
    pub tree: TreeJson,
    /// One action: the contacted node...
    #[serde(default, deserialize_with = "super::json::integer::opt_usize")]
    pub contact_node: Option<usize>,
    /// ...and the gripper displacement T (m).
    #[serde(default)]
    pub push: Option<Vec<f64>>,
    /// Many actions on the same tree: contact nodes...
    #[serde(default, deserialize_with = "super::json::integer::opt_vec_usize")]
    pub contact_nodes: Option<Vec<usize>>,
    /// ...and their pushes, one per contact node.
    #[serde(default)]
    pub pushes: Option<Vec<Vec<f64>>>,
    /// Answer for trees and pushes outside the model's domain too (with
    /// warnings) instead of refusing them with 422 `out_of_domain`.
    #[serde(default)]
    pub allow_out_of_domain: bool,
    /// Deadline (ms, capped by the server's request timeout): a request
    /// still queued for the model when it passes is answered 504.
    #[serde(default)]
    pub timeout_ms: Option<f64>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ForwardResponse {
    /// Per action, per node: predicted Δp (m).
    pub displacements: Vec<Vec<[f64; 3]>>,
    /// Per action, per node: predicted p + Δp (m).
    pub positions: Vec<Vec<[f64; 3]>>,
    pub model: ModelInfo,
    /// Why the answer may be less trustworthy than usual (empty: omitted).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
}

/// The request's (contact node, push) pairs, each push at most `max_push`
/// (m) long.
fn actions(
    request: &ForwardRequest,
    tree: &Tree,
    max_actions: usize,
    max_push: f64,
) -> Result<Vec<(usize, Vector3<f64>)>, ApiError> {
    let single = request.contact_node.is_some() || request.push.is_some();
    let many = request.contact_nodes.is_some() || request.pushes.is_some();
    match (single, many) {
        (true, true) => Err(ApiError::invalid_argument(
            "give either `contact_node` + `push` or `contact_nodes` + `pushes`, not both",
        )),
        (false, false) => Err(ApiError::invalid_argument(
            "missing the action: give `contact_node` and `push` (or `contact_nodes` and `pushes`)",
        )),
        (true, false) => {
            let (Some(node), Some(push)) = (request.contact_node, &request.push) else {
                return Err(ApiError::invalid_argument(
                    "`contact_node` and `push` go together",
                ));
            };
            Ok(vec![(
                check_contact(node, tree, "contact_node")?,
                check_push(vector3(push, "push")?, "push", max_push)?,
            )])
        }
        (false, true) => {
            let (Some(nodes), Some(pushes)) = (&request.contact_nodes, &request.pushes) else {
                return Err(ApiError::invalid_argument(
                    "`contact_nodes` and `pushes` go together",
                ));
            };
            if nodes.len() != pushes.len() {
                return Err(ApiError::invalid_argument(format!(
                    "{} contact nodes but {} pushes",
                    nodes.len(),
                    pushes.len()
                ))
                .with_details(json!({ "field": "pushes" })));
            }
            if nodes.is_empty() {
                return Err(ApiError::invalid_argument("`contact_nodes` is empty"));
            }
            if nodes.len() > max_actions {
                return Err(ApiError::too_large(format!(
                    "{} actions in one call; this server accepts at most {max_actions}",
                    nodes.len()
                ))
                .with_details(json!({ "field": "pushes", "max_actions": max_actions })));
            }
            nodes
                .iter()
                .zip(pushes)
                .enumerate()
                .map(|(k, (&node, push))| {
                    let field = format!("pushes[{k}]");
                    Ok((
                        check_contact(node, tree, &format!("contact_nodes[{k}]"))?,
                        check_push(vector3(push, &field)?, &field, max_push)?,
                    ))
                })
                .collect()
        }
    }
}

pub async fn forward(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<ForwardRequest>,
) -> Result<axum::Json<ForwardResponse>, ApiError> {
    let model = state.model_for(Task::Forward)?;
    let tree = request.tree.to_tree(state.limits.max_nodes)?;
    let actions = actions(
        &request,
        &tree,
        state.limits.max_actions,
        model.card.max_push(),
    )?;
    let lengths: Vec<(usize, f64)> = actions.iter().map(|(j, t)| (*j, t.norm())).collect();
    let warnings = domain::check(&model, &tree, &lengths, request.allow_out_of_domain)?;
    ::metrics::histogram!("treemanip_actions_per_request", "route" => "/v1/forward")
        .record(actions.len() as f64);
    let info = ModelInfo::of(&model, &state);
    let timeout = request_timeout(request.timeout_ms)?;
    let response = state
        .run_model_work("/v1/forward", timeout, move |control| {
            let predicted = predict_displacements(&model, &tree, &actions, &control)?;
            let xyz = |v: Vector3<f64>| [v.x, v.y, v.z];
            Ok(ForwardResponse {
                positions: predicted
                    .iter()
                    .map(|d| {
                        d.iter()
                            .zip(tree.positions())
                            .map(|(d, p)| xyz(p.coords + d))
                            .collect()
                    })
                    .collect(),
                displacements: predicted
                    .iter()
                    .map(|d| d.iter().map(|v| xyz(*v)).collect())
                    .collect(),
                model: info,
                warnings,
            })
        })
        .await?;
    Ok(axum::Json(response))
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PolicyRequest {
    pub tree: TreeJson,
    /// Where each node should end up (m).
    pub target_positions: Vec<Vec<f64>>,
    /// See [`ForwardRequest::allow_out_of_domain`].
    #[serde(default)]
    pub allow_out_of_domain: bool,
    /// See [`ForwardRequest::timeout_ms`].
    #[serde(default)]
    pub timeout_ms: Option<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct PolicyResponse {
    /// Every non-root node, by affordance, descending.
    pub candidates: Vec<Candidate>,
    pub model: ModelInfo,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
}

pub async fn policy(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<PolicyRequest>,
) -> Result<axum::Json<PolicyResponse>, ApiError> {
    let model = state.model_for(Task::Policy)?;
    let tree = request.tree.to_tree(state.limits.max_nodes)?;
    let targets = targets(&request.target_positions, &tree)?;
    let warnings = domain::check(&model, &tree, &[], request.allow_out_of_domain)?;
    let info = ModelInfo::of(&model, &state);
    let timeout = request_timeout(request.timeout_ms)?;
    let response = state
        .run_model_work("/v1/policy", timeout, move |control| {
            let candidates = rank_candidates(&model, &tree, &targets, &control)?;
            Ok(PolicyResponse {
                candidates,
                model: info,
                warnings,
            })
        })
        .await?;
    Ok(axum::Json(response))
}
