//! `/v1/forward` and `/v1/policy`.

use serde::{Deserialize, Serialize};
use treemanip_core::planner::Candidate;
use utoipa::ToSchema;

use crate::api::types::domain::Warning;
use crate::api::types::models::ModelInfo;
use crate::api::types::schema::Vec3;
use crate::api::types::tree::TreeJson;

/// One action (`contact_node` + `push`) or many on the same tree
/// (`contact_nodes` + `pushes`).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ForwardRequest {
    pub tree: TreeJson,
    /// One action: the contacted node (not the root)...
    #[serde(default, deserialize_with = "crate::api::json::integer::opt_usize")]
    #[schema(minimum = 1, maximum = 511)]
    pub contact_node: Option<usize>,
    /// ...and the gripper displacement T (m).
    #[serde(default)]
    #[schema(value_type = Option<Vec3>)]
    pub push: Option<Vec<f64>>,
    /// Many actions on the same tree: contact nodes...
    #[serde(default, deserialize_with = "crate::api::json::integer::opt_vec_usize")]
    #[schema(min_items = 1, max_items = 256, minimum = 1, maximum = 511)]
    pub contact_nodes: Option<Vec<usize>>,
    /// ...and their pushes, one per contact node (m).
    #[serde(default)]
    #[schema(value_type = Option<Vec<Vec3>>, min_items = 1, max_items = 256)]
    pub pushes: Option<Vec<Vec<f64>>>,
    /// Answer for trees (and pushes) outside the model's training domain
    /// too, with `warnings`, instead of refusing them with 422
    /// `out_of_domain`.
    #[serde(default)]
    #[schema(default = false)]
    pub allow_out_of_domain: bool,
    /// Deadline (ms), capped by the server's request timeout (10 s by
    /// default): a request whose model job is still queued when it passes
    /// is answered 504 `timeout`.
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0)]
    pub timeout_ms: Option<f64>,
    /// Which forward model answers: `forward_path` (the default where it
    /// is loaded: it reads the push's path, any tree size) or
    /// `forward_gnn` (the paper's, on the fully connected graph, at most
    /// 64 nodes); `GET /v1/models` lists what is loaded.
    #[serde(default)]
    #[schema(examples("forward_path", "forward_gnn"))]
    pub model: Option<String>,
}

/// One set of per-node values per action, in the request's order.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ForwardResponse {
    /// Per action, per node: predicted Δp (m). Single precision, as the
    /// model computes: 7 significant digits, and half the bytes of doubles
    /// (64 pushes on a 500-node tree are 192,000 numbers).
    #[schema(value_type = Vec<Vec<Vec3>>)]
    pub displacements: Vec<Vec<[f32; 3]>>,
    /// Per action, per node: predicted p + Δp (m), single precision (a
    /// tenth of a micrometre on a 1 m tree).
    #[schema(value_type = Vec<Vec<Vec3>>)]
    pub positions: Vec<Vec<[f32; 3]>>,
    pub model: ModelInfo,
    /// Present when the answer is given outside the model's domain (or for
    /// a tree size it is not evaluated on).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PolicyRequest {
    pub tree: TreeJson,
    /// Where each node should end up (m).
    #[schema(value_type = Vec<Vec3>, max_items = 512)]
    pub target_positions: Vec<Vec<f64>>,
    /// As `/v1/forward`'s.
    #[serde(default)]
    #[schema(default = false)]
    pub allow_out_of_domain: bool,
    /// As `/v1/forward`'s.
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0)]
    pub timeout_ms: Option<f64>,
}

#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct PolicyResponse {
    /// Every non-root node, by affordance, descending.
    pub candidates: Vec<CandidateJson>,
    pub model: ModelInfo,
    /// As `/v1/forward`'s.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
}

/// One node to push and how, from the contact policy: its share of the
/// affordance over the pushable nodes, the push T (m), its rank (1 = most
/// promising).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
#[schema(as = Candidate)]
pub struct CandidateJson {
    #[schema(minimum = 1)]
    pub node: usize,
    #[schema(minimum = 0, maximum = 1)]
    pub affordance: f64,
    #[schema(value_type = Vec3)]
    pub push: [f64; 3],
    #[schema(minimum = 1)]
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
