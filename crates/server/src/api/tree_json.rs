//! The tree as clients send it:
//!
//! ```json
//! {"positions": [[x, y, z], …], "parents": [null, 0, 0, 1, …],
//!  "radius": [null, r1, r2, …], "stiffness": [null, k1, k2, …]}
//! ```
//!
//! Positions in metres; `parents[0]` is null (node 0 is the fixed root);
//! `radius` (m) and `stiffness` K_s (N·m/rad) belong to the branch ending at
//! each node, the root's entry ignored (null or a number). Without
//! `stiffness`, K_s = E π r⁴ / (2 ℓ) with the documented E; branch lengths
//! always come from the positions, and damping is K_s / 10.

use serde_json::json;

use super::error::ApiError;
use crate::api::types::TreeJson;
use nalgebra::Point3;
use treemanip_core::tree::{Tree, TreeError, Wood};

impl TreeJson {
    pub fn from_tree(tree: &Tree) -> Self {
        Self {
            positions: tree
                .positions()
                .iter()
                .map(|p| vec![p.x, p.y, p.z])
                .collect(),
            parents: tree.parents().to_vec(),
            radius: tree
                .branches()
                .iter()
                .map(|b| b.map(|b| b.radius))
                .collect(),
            stiffness: Some(
                tree.branches()
                    .iter()
                    .map(|b| b.map(|b| b.stiffness))
                    .collect(),
            ),
        }
    }

    /// Validates and builds the tree; errors name the field and node.
    pub fn to_tree(&self, max_nodes: usize) -> Result<Tree, ApiError> {
        let n = self.positions.len();
        if n > max_nodes {
            return Err(ApiError::too_large(format!(
                "the tree has {n} nodes; this server accepts at most {max_nodes}"
            ))
            .with_details(json!({ "field": "positions", "nodes": n, "max_nodes": max_nodes })));
        }
        let mut positions = Vec::with_capacity(n);
        for (node, p) in self.positions.iter().enumerate() {
            let [x, y, z] = <[f64; 3]>::try_from(p.as_slice()).map_err(|_| {
                ApiError::invalid_tree(format!(
                    "positions[{node}] must have 3 numbers, it has {}",
                    p.len()
                ))
                .with_details(json!({ "field": "positions", "node": node }))
            })?;
            positions.push(Point3::new(x, y, z));
        }
        for (field, len) in [
            ("parents", self.parents.len()),
            ("radius", self.radius.len()),
            ("stiffness", self.stiffness.as_ref().map_or(n, Vec::len)),
        ] {
            if len != n {
                return Err(ApiError::invalid_tree(format!(
                    "`{field}` has {len} entries but `positions` has {n}"
                ))
                .with_details(json!({ "field": field, "expected": n, "got": len })));
            }
        }
        let wood = Wood::default();
        let mut branches = vec![None; n];
        for node in 0..n {
            // Topology errors are reported by Tree::new; skip what it will name.
            let Some(parent) = self.parents[node] else {
                continue;
            };
            if parent >= n {
                continue;
            }
            let Some(radius) = self.radius[node] else {
                return Err(ApiError::invalid_tree(format!(
                    "radius[{node}] is null; every non-root node needs one"
                ))
                .with_details(json!({ "field": "radius", "node": node })));
            };
            let length = (positions[node] - positions[parent]).norm();
            branches[node] = Some(match self.stiffness.as_ref().map(|k| k[node]) {
                None => wood.branch(radius, length),
                Some(Some(k)) => wood.branch_with_stiffness(radius, length, k),
                Some(None) => {
                    return Err(ApiError::invalid_tree(format!(
                        "stiffness[{node}] is null; give every non-root stiffness or leave `stiffness` out"
                    ))
                    .with_details(json!({ "field": "stiffness", "node": node })));
                }
            });
        }
        Tree::new(positions, self.parents.clone(), branches).map_err(tree_error)
    }
}

/// A [`TreeError`] as a 422 naming the field and node.
pub fn tree_error(err: TreeError) -> ApiError {
    let details = match &err {
        TreeError::NodeCount { got, min, max } => {
            json!({ "field": "positions", "got": got, "min": min, "max": max })
        }
        TreeError::LengthMismatch {
            field,
            expected,
            got,
        } => json!({ "field": field, "expected": expected, "got": got }),
        TreeError::NoRoot => json!({ "field": "parents" }),
        TreeError::MultipleRoots { nodes } => json!({ "field": "parents", "nodes": nodes }),
        TreeError::RootNotFirst { node }
        | TreeError::ParentOutOfRange { node, .. }
        | TreeError::Disconnected { node } => json!({ "field": "parents", "node": node }),
        TreeError::Cycle { nodes } => json!({ "field": "parents", "nodes": nodes }),
        TreeError::NonFinite { field, node } | TreeError::NonPositive { field, node, .. } => {
            json!({ "field": field, "node": node })
        }
        TreeError::NegativeDamping { node, .. } => json!({ "field": "stiffness", "node": node }),
        TreeError::MissingBranch { node } => json!({ "field": "radius", "node": node }),
        TreeError::BranchLength { node, .. } => json!({ "field": "positions", "node": node }),
    };
    let status_too_small =
        matches!(err, TreeError::NodeCount { got, .. } if got < treemanip_core::tree::MIN_NODES);
    let error = if matches!(err, TreeError::NodeCount { .. }) && !status_too_small {
        ApiError::too_large(err.to_string())
    } else {
        ApiError::invalid_tree(err.to_string())
    };
    error.with_details(details)
}
