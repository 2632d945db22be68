//! A tree as every endpoint takes it: `positions`, `parents`, `radius`, optional `stiffness` (SI units; checked into a core tree by [`crate::api::tree_json`]).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::types::schema::Vec3;

/// Node 0 is the fixed root. `radius` (m) and `stiffness` (K_s, N·m/rad)
/// belong to the branch ending at each node; the root's entry is ignored
/// (null). Without `stiffness`, K_s = E π r⁴ / (2 ℓ) with E = 5 GPa.
/// Branch lengths come from the positions.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = Tree)]
pub struct TreeJson {
    /// Node positions (m).
    #[schema(value_type = Vec<Vec3>, min_items = 2, max_items = 512)]
    pub positions: Vec<Vec<f64>>,
    /// Each node's parent (null for the root).
    #[serde(deserialize_with = "crate::api::json::integer::vec_opt_usize")]
    #[schema(max_items = 512, minimum = 0, maximum = 511)]
    pub parents: Vec<Option<usize>>,
    /// The radius of the branch ending at each node (m).
    #[schema(max_items = 512)]
    pub radius: Vec<Option<f64>>,
    /// The stiffness of the branch ending at each node (N·m/rad).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(max_items = 512)]
    pub stiffness: Option<Vec<Option<f64>>>,
}
