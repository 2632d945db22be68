//! `/v1/forward` and `/v1/policy`.

use serde::{Deserialize, Serialize};
use treemanip_core::planner::Candidate;

use crate::api::types::domain::Warning;
use crate::api::types::models::ModelInfo;
use crate::api::types::tree::TreeJson;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForwardRequest {
    pub tree: TreeJson,
    /// One action: the contacted node...
    #[serde(default, deserialize_with = "crate::api::json::integer::opt_usize")]
    pub contact_node: Option<usize>,
    /// ...and the gripper displacement T (m).
    #[serde(default)]
    pub push: Option<Vec<f64>>,
    /// Many actions on the same tree: contact nodes...
    #[serde(default, deserialize_with = "crate::api::json::integer::opt_vec_usize")]
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
    pub candidates: Vec<CandidateJson>,
    pub model: ModelInfo,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
}

/// One node to push and how, from the contact policy: its share of the
/// affordance over the pushable nodes, the push T (m), its rank (1 = most
/// promising).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CandidateJson {
    pub node: usize,
    pub affordance: f64,
    pub push: [f64; 3],
    pub rank: usize,
}

impl From<&Candidate> for CandidateJson {
    fn from(c: &Candidate) -> Self {
        Self {
            node: c.node,
            affordance: c.affordance,
            push: c.push,
            rank: c.rank,
        }
    }
}
