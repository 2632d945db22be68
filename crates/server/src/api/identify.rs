//! `POST /v1/identify` (branch stiffness from observed probe pushes) and
//! `POST /v1/identify/probes` (which pushes to probe next). The work is
//! `treemanip_core::identify`; this file only translates.

use axum::extract::State;
use serde::{Deserialize, Serialize};
use serde_json::json;
use treemanip_core::identify::probes::{ProbeRequest, choose_probes};
use treemanip_core::identify::{Noise, Posterior, Prior, identify as run_identify};
use treemanip_core::planner::Stance;
use treemanip_core::sim::{ContactModel, MAX_PUSH_LENGTH};

use super::AppState;
use super::error::ApiError;
use super::json::ApiJson;
use super::observations::{IdentifyResponse, ProbeJson, identify_config, probes};
use super::tree_json::TreeJson;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdentifyRequest {
    /// The tree; its `stiffness`, when given, is the prior mean (else the
    /// radius formula).
    pub tree: TreeJson,
    pub probes: Vec<ProbeJson>,
    /// Measurement noise (defaults: 3 mm, 5 % of force).
    #[serde(default)]
    pub noise: Option<Noise>,
    /// Prior spreads on ln K_s (defaults: 0.5 per branch, 1.0 overall).
    #[serde(default)]
    pub prior: Option<Prior>,
}

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

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbesRequest {
    pub tree: TreeJson,
    /// Probes already observed: the proposal starts from what they taught.
    #[serde(default)]
    pub probes: Vec<ProbeJson>,
    /// How many probes to propose (1–20, default 5).
    #[serde(
        default = "default_count",
        deserialize_with = "super::json::integer::usize"
    )]
    pub count: usize,
    /// Length of each proposed push (m, default 0.08).
    #[serde(default = "default_push_length")]
    pub push_length: f64,
    #[serde(default)]
    pub contact: ContactModel,
    /// Measurement noise (defaults: 3 mm, 5 % of force).
    #[serde(default)]
    pub noise: Option<Noise>,
    /// Prior spreads on ln K_s (defaults: 0.5 per branch, 1.0 overall).
    #[serde(default)]
    pub prior: Option<Prior>,
    /// Where the arm stands (as `/v1/plan` takes it): only pushes it can
    /// make are proposed. Without it, every push is a candidate.
    #[serde(default)]
    pub robot: Option<super::plan::RobotJson>,
}

fn default_count() -> usize {
    ProbeRequest::default().count
}

fn default_push_length() -> f64 {
    ProbeRequest::default().push_length
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ProposedProbeJson {
    pub contact_node: usize,
    pub push: [f64; 3],
    pub contact: ContactModel,
    /// Expected information gain about ln K_s (nats), given the probes
    /// proposed before it.
    pub information_gain: f64,
    /// Variance it is expected to remove from the predicted positions of
    /// the paper's pushes (m², summed over coordinates, averaged over
    /// pushes), given the probes proposed before it: what it is chosen by.
    pub prediction_variance_reduction: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ProbesResponse {
    pub probes: Vec<ProposedProbeJson>,
}

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
        contact: request.contact,
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
                        contact: c.contact,
                        information_gain: c.information_gain,
                        prediction_variance_reduction: c.prediction_variance_reduction,
                    })
                    .collect(),
            })
        })
        .await?;
    Ok(axum::Json(response))
}
