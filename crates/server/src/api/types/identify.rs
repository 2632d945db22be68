//! `/v1/identify` and `/v1/identify/probes`: probes, requests and answers.

use serde::{Deserialize, Serialize};
use treemanip_core::identify::probes::ProbeRequest;
use treemanip_core::identify::{FitReport, Noise, Prior, Rejected, Scale, Status};
use treemanip_core::sim::ContactModel;

use crate::api::types::robots::RobotJson;
use crate::api::types::tree::TreeJson;

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
        deserialize_with = "crate::api::json::integer::usize"
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
    pub robot: Option<RobotJson>,
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

/// One observed probe push.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeJson {
    #[serde(deserialize_with = "crate::api::json::integer::usize")]
    pub contact_node: usize,
    /// Gripper displacement T (m).
    pub push: Vec<f64>,
    #[serde(default)]
    pub contact: ContactModel,
    /// Per node, where it was seen while the push was held (m), or null.
    pub observed_positions: Vec<Option<Vec<f64>>>,
    /// The force the gripper applied to the branch (N), as `/v1/simulate`
    /// reports `contact_force`; a wrist sensor reads the opposite sign.
    #[serde(default)]
    pub contact_force: Option<Vec<f64>>,
}

/// The estimate, per node (null at the root).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct IdentifyResponse {
    /// Estimated K_s (N·m/rad).
    pub stiffness: Vec<Option<f64>>,
    /// 90 % interval of each K_s (N·m/rad).
    pub interval: Vec<Option<[f64; 2]>>,
    pub status: Vec<Option<Status>>,
    /// `absolute` when a contact force fixed the level; `relative`: the
    /// estimate keeps the prior's level (its mean ln K_s).
    pub scale: Scale,
    /// The request's tree with the estimate as its `stiffness`, ready for
    /// the other endpoints.
    pub tree: TreeJson,
    pub fit: FitReport,
    pub rejected: Vec<Rejected>,
}

fn default_count() -> usize {
    ProbeRequest::default().count
}

fn default_push_length() -> f64 {
    ProbeRequest::default().push_length
}
