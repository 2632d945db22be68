//! `POST /v1/identify` (branch stiffness from observed probe pushes) and
//! `POST /v1/identify/probes` (which pushes to probe next). The work is
//! `treemanip_core::identify`; this file only translates.

use crate::api::types::error::PostErrors;
use axum::extract::State;
use serde_json::json;
use treemanip_core::identify::probes::{ProbeRequest, choose_probes};
use treemanip_core::identify::{Posterior, identify as run_identify};
use treemanip_core::planner::Stance;
use treemanip_core::sim::MAX_PUSH_LENGTH;

use super::AppState;
use super::error::ApiError;
use super::json::ApiJson;
use super::observations::{identify_config, probes};
use crate::api::types::{
    IdentifyRequest, IdentifyResponse, ProbesRequest, ProbesResponse, ProposedProbeJson,
};

/// Branch stiffness from observed probe pushes.
///
/// Each probe is a push the arm made and held, with where the tree's nodes
/// were seen while it was held (null for nodes not seen) and, optionally, the
/// contact force: the force the gripper applied to the branch, as
/// /v1/simulate reports `contact_force` (a wrist force/torque sensor reads
/// the opposite sign). The tree's `stiffness`, when given, is the prior mean,
/// else the radius formula. The fit is the maximum a posteriori of ln K_s
/// with the simulator as the observation model and the prior ln K ~ N(ln
/// K_prior, σ²I + σ_g²11ᵀ) (σ = 0.4, σ_g = 1.0 by default); intervals are 90
/// % (Laplace). Positions fix only stiffness ratios (a push at node j depends
/// on the branches on the path root → j, and a global factor moves nothing):
/// without a force `scale` is `relative` and the estimate keeps the prior's
/// level (its mean ln K_s); with a force it is `absolute`. A branch is
/// `identified` when the posterior σ of its ln K_s is at most 0.15, `weak`
/// when probed but less certain (typically stiff trunk branches),
/// `unobserved` when on no probe's path. Probes whose slot hold slid to a
/// fork (`hold_switched`) or that the simulator cannot reproduce are left out
/// and listed in `rejected`. The returned `tree` carries the estimate, ready
/// for the other endpoints.
#[utoipa::path(post, path = "/v1/identify", tag = "stiffness",
    request_body = IdentifyRequest,
    responses(
    (status = 200, description = "The estimate.", body = IdentifyResponse),
    PostErrors,
))]
pub async fn identify(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<IdentifyRequest>,
) -> Result<axum::Json<IdentifyResponse>, ApiError> {
    let tree = request.tree.to_tree(state.limits.max_nodes)?;
    let config = identify_config(request.noise, request.prior, "")?;
    if request.probes.is_empty() {
        return Err(ApiError::invalid_argument(
            "`probes` is empty: identification needs at least one observed push (POST /v1/identify/probes proposes some)",
        )
        .with_details(json!({ "field": "probes" })));
    }
    let probes = probes(&tree, &request.probes, &config, "probes")?;
    let response = state
        .run_blocking("/v1/identify", move || {
            Ok(IdentifyResponse::from(&run_identify(
                &tree, &probes, &config,
            )))
        })
        .await?;
    Ok(axum::Json(response))
}

/// The next probe pushes that most reduce the stiffness uncertainty.
///
/// Candidates are pushes of `push_length` at the tree's leaves, in four
/// directions across the leaf's branch; each is scored by its expected
/// information gain about ln K_s (nats) under the posterior of the probes
/// already made (`probes`, optional), and `count` are picked greedily, each
/// counting the ones before it. Reachability by an arm is not checked here:
/// plan each with /v1/plan's robot settings.
#[utoipa::path(post, path = "/v1/identify/probes", tag = "stiffness",
    request_body = ProbesRequest,
    responses(
    (status = 200, description = "Proposed probes, best first.", body = ProbesResponse),
    PostErrors,
))]
pub async fn propose(
    State(state): State<AppState>,
    ApiJson(request): ApiJson<ProbesRequest>,
) -> Result<axum::Json<ProbesResponse>, ApiError> {
    let tree = request.tree.to_tree(state.limits.max_nodes)?;
    let config = identify_config(request.noise, request.prior, "")?;
    if !(1..=20).contains(&request.count) {
        return Err(ApiError::invalid_field("count", "`count` must be 1 to 20"));
    }
    let length = request.push_length;
    if !(length.is_finite() && length > 0.0 && length <= MAX_PUSH_LENGTH) {
        return Err(ApiError::invalid_field(
            "push_length",
            format!("`push_length` must be in (0, {MAX_PUSH_LENGTH}] m"),
        ));
    }
    let observed = probes(&tree, &request.probes, &config, "probes")?;
    let ask = ProbeRequest {
        count: request.count,
        push_length: length,
        contact: request.contact.into(),
    };
    let robot_name = request.robot.as_ref().and_then(|r| r.name.as_deref());
    let planner = state.robots.get(robot_name, "robot.name")?;
    let arm = match &request.robot {
        None => None,
        Some(robot) => {
            let start = robot
                .start
                .as_deref()
                .map(|q| super::validate::joints(q, "robot.start", planner.robot()))
                .transpose()?;
            let stance = super::plan::stance(robot)?
                .unwrap_or_else(|| Stance::Fixed(planner.robot().default_base()));
            Some((stance, start))
        }
    };
    let response = state
        .run_blocking("/v1/identify/probes", move || {
            let posterior = if observed.is_empty() {
                Posterior::prior(&tree, &config)
            } else {
                run_identify(&tree, &observed, &config).posterior
            };
            let chosen = match &arm {
                None => choose_probes(&tree, &posterior, &ask, &config, &|_| true),
                Some((stance, start)) => {
                    let reachable = planner.reach_test(&tree, &[], stance, *start);
                    choose_probes(&tree, &posterior, &ask, &config, &reachable)
                }
            };
            Ok(ProbesResponse {
                probes: chosen
                    .iter()
                    .map(|c| ProposedProbeJson {
                        contact_node: c.push.node,
                        push: [c.push.vector.x, c.push.vector.y, c.push.vector.z],
                        contact: c.contact.into(),
                        information_gain: c.information_gain,
                        prediction_variance_reduction: c.prediction_variance_reduction,
                    })
                    .collect(),
            })
        })
        .await?;
    Ok(axum::Json(response))
}
