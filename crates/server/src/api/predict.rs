//! `POST /v1/forward` and `POST /v1/policy`: the learned models.

use crate::api::types::error::PostErrors;
use axum::extract::State;
use nalgebra::Vector3;
use serde_json::json;

use super::AppState;
use super::domain;
use super::error::ApiError;
use super::json::ApiJson;
use super::state::ModelInfo;
use super::validate::{check_contact, check_push, request_timeout, targets, vector3};
use crate::api::types::{ForwardRequest, ForwardResponse, PolicyRequest, PolicyResponse};
use treemanip_core::graph::Task;
use treemanip_core::tree::Tree;
use treemanip_infer::models::{predict_displacements, rank_candidates};

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

/// Predicted node displacements under one or many pushes (GNN forward model).
///
/// Either one action (`contact_node` + `push`) or many on the same tree
/// (`contact_nodes` + `pushes`, at most the server's max actions). The answer
/// holds one set of per-node values per action. Pushes longer than the
/// model's card allows (`domain.domain.push_length.max` in `/v1/models`:
/// twice the longest trained push, 0.3 m for the shipped model trained on
/// 0.05–0.15 m) are refused (422) rather than extrapolated.
#[utoipa::path(post, path = "/v1/forward", tag = "models",
    request_body = ForwardRequest,
    responses(
    (status = 200, description = "Predictions.", body = ForwardResponse),
    PostErrors,
))]
pub async fn forward(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<ForwardRequest>,
) -> Result<axum::Json<ForwardResponse>, ApiError> {
    let nodes = request.tree.positions.len();
    let model = match request.model.as_deref() {
        None => state.forward_model_for(nodes)?,
        Some(name) if name.starts_with("forward_") => state.model_by_name(name)?,
        Some(name) => {
            return Err(ApiError::invalid_field(
                "model",
                format!("`{name}` is not a forward model (forward_path, forward_gnn, ...)"),
            ));
        }
    };
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
            let xyz = |v: Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
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

/// Which node to push, and how, to move the tree toward a target (GNN contact
/// policy).
///
/// Every non-root node, ranked by affordance (a softmax over the tree's
/// nodes, renormalised over the pushable ones, so the list sums to 1), with
/// the push T the policy proposes for it.
#[utoipa::path(post, path = "/v1/policy", tag = "models",
    request_body = PolicyRequest,
    responses(
    (status = 200, description = "Ranked candidates.", body = PolicyResponse),
    PostErrors,
))]
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
                candidates: candidates.iter().map(Into::into).collect(),
                model: info,
                warnings,
            })
        })
        .await?;
    Ok(axum::Json(response))
}
