//! A tree as every endpoint takes it: `positions`, `parents`, `radius`, optional `stiffness` (SI units; checked into a core tree by [`crate::api::tree_json`]).

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TreeJson {
    pub positions: Vec<Vec<f64>>,
    #[serde(deserialize_with = "crate::api::json::integer::vec_opt_usize")]
    pub parents: Vec<Option<usize>>,
    pub radius: Vec<Option<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<Vec<Option<f64>>>,
}
