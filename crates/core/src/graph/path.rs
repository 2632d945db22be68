//! The path encoding: a forward model that reads only the joints a push
//! can move, and answers with their rotations.
//!
//! In the quasi-static model ([`crate::sim`]) a push at node c rotates only
//! the joints on the path from the root to c; every other subtree turns
//! rigidly with its parent, and the stiffness of branches off the path
//! plays no part. So the answer for any tree, however large, is fixed by
//! the path: its rest geometry, its stiffness *ratios* and the push. The
//! path encoding feeds the same graph network as the paper's encoding, on
//! a small graph:
//!
//! - nodes: the root, the path a_1 … a_m (a_m = c) and c's children (the
//!   fork that stops a gripper sliding off the branch's end), in that order;
//! - edges: every ordered pair, with the paper's attributes [Δp, v, b, κ]
//!   ([`super::edge_attributes_with`]), where κ is ln K_s relative to the
//!   mean over the *path's* branches (only path ratios matter; c's children
//!   carry κ = 0);
//! - node n_j = [c_j], global g = [T], as for the paper's forward model.
//!
//! The model's output per node is the rotation vector θ (rad) of the joint
//! at the node's parent (the branch ending at the node), and
//! [`positions_from_rotations`] places every node of the full tree by
//! forward kinematics: rigid subtrees move rigidly by construction, and the
//! cost is O(m² + N) instead of O(N²).

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::{EncodeError, GraphInput, Task, edge_attributes_with};
use crate::sim::deformed_positions;
use crate::tree::Tree;

/// What graph a model reads and what its 3-vector output means.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Encoding {
    /// The paper's: every node of the tree, fully connected; the output is
    /// each node's displacement Δp (m). Costs O(N²); limited to
    /// [`crate::tree::FULL_GRAPH_MAX_NODES`].
    #[default]
    Full,
    /// The root-to-contact path (this module); the output is each path
    /// joint's rotation θ (rad), placed by forward kinematics. No size limit.
    Path,
}

impl Encoding {
    pub fn name(self) -> &'static str {
        match self {
            Encoding::Full => "full",
            Encoding::Path => "path",
        }
    }
}

impl std::str::FromStr for Encoding {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "full" => Ok(Encoding::Full),
            "path" => Ok(Encoding::Path),
            other => Err(format!("unknown encoding {other:?} (full or path)")),
        }
    }
}

/// A push's path graph and where its nodes are in the tree.
#[derive(Debug, Clone, PartialEq)]
pub struct PathGraph {
    /// Tree node of each graph node: the root, the path, the contact's children.
    pub nodes: Vec<usize>,
    /// The root and the path: graph nodes 0..path_len.
    pub path_len: usize,
    pub input: GraphInput,
}

/// The path graph of a push at `contact` by `push` (m).
pub fn encode_forward_path(
    tree: &Tree,
    contact: usize,
    push: &Vector3<f64>,
) -> Result<PathGraph, EncodeError> {
    let n = tree.len();
    if contact == 0 || contact >= n {
        return Err(EncodeError::ContactNode { node: contact, n });
    }
    if !push.iter().all(|v| v.is_finite()) {
        return Err(EncodeError::NonFinite { what: "push" });
    }
    let mut nodes = tree.path_to_root(contact);
    nodes.reverse();
    let path_len = nodes.len();
    nodes.extend_from_slice(tree.children(contact));
    let m = nodes.len();
    let mut local = vec![usize::MAX; n];
    for (k, &j) in nodes.iter().enumerate() {
        local[j] = k;
    }
    let parents: Vec<Option<usize>> = nodes
        .iter()
        .map(|&j| tree.parent(j).map(|p| local[p]))
        .collect();
    let positions: Vec<Point3<f64>> = nodes.iter().map(|&j| tree.position(j)).collect();
    // κ over the path's branches (graph nodes 1..path_len); 0 elsewhere.
    let logs: Vec<f64> = nodes[1..path_len]
        .iter()
        .map(|&j| tree.branch(j).expect("non-root").stiffness.ln())
        .collect();
    let mean = logs.iter().sum::<f64>() / logs.len().max(1) as f64;
    let mut kappa = vec![0.0; m];
    for (k, l) in logs.iter().enumerate() {
        kappa[k + 1] = l - mean;
    }
    let edges = edge_attributes_with(&positions, &parents, &kappa);
    let mut node_features = vec![0.0f32; m];
    node_features[path_len - 1] = 1.0;
    Ok(PathGraph {
        nodes,
        path_len,
        input: GraphInput {
            task: Task::Forward,
            n: m,
            nodes: node_features,
            edges,
            global: vec![push.x as f32, push.y as f32, push.z as f32],
        },
    })
}

impl PathGraph {
    /// The targets a path model learns: θ of each graph node's joint, from
    /// the simulator's per-node joint rotations (zero off the path).
    pub fn rotation_targets(&self, joint_rotations: &[Vector3<f64>]) -> Vec<f32> {
        self.nodes
            .iter()
            .enumerate()
            .flat_map(|(k, &j)| {
                let t = if k > 0 && k < self.path_len {
                    joint_rotations[j]
                } else {
                    Vector3::zeros()
                };
                [t.x as f32, t.y as f32, t.z as f32]
            })
            .collect()
    }

    /// Final positions of every tree node from a model's per-graph-node
    /// rotations (`rows`: 3 numbers per graph node; only the path's are used).
    pub fn positions(&self, tree: &Tree, rows: &[f32]) -> Vec<Point3<f64>> {
        let thetas: Vec<(usize, Vector3<f64>)> = (1..self.path_len)
            .map(|k| {
                let r = &rows[3 * k..3 * k + 3];
                (
                    self.nodes[k],
                    Vector3::new(r[0] as f64, r[1] as f64, r[2] as f64),
                )
            })
            .collect();
        positions_from_rotations(tree, &thetas)
    }
}

/// Every node's position when the joints `(node, θ)` turn (the joint at
/// each node's parent; all others at rest).
pub fn positions_from_rotations(tree: &Tree, thetas: &[(usize, Vector3<f64>)]) -> Vec<Point3<f64>> {
    let mut all = vec![Vector3::zeros(); tree.len()];
    for (j, t) in thetas {
        all[*j] = *t;
    }
    deformed_positions(tree, &all)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{Push, SimConfig, simulate};
    use crate::tree::{OrchardParams, generate_orchard};

    #[test]
    fn simulator_rotations_through_the_path_graph_give_the_simulated_tree() {
        let tree = generate_orchard(300, 5, &OrchardParams::default()).unwrap();
        let contact = (1..tree.len())
            .filter(|&j| !tree.is_leaf(j))
            .max_by_key(|&j| tree.depth(j))
            .unwrap();
        let dir = tree.branch_direction(contact).unwrap();
        let push = dir.cross(&Vector3::z()).normalize() * 0.08;
        let outcome = simulate(
            &tree,
            &Push {
                node: contact,
                vector: push,
            },
            &SimConfig::default(),
        )
        .unwrap();
        let graph = encode_forward_path(&tree, contact, &push).unwrap();
        assert_eq!(graph.path_len, tree.depth(contact) + 1);
        assert_eq!(graph.input.n, graph.path_len + tree.children(contact).len());
        let rows = graph.rotation_targets(&outcome.joint_rotations);
        let placed = graph.positions(&tree, &rows);
        let worst = placed
            .iter()
            .zip(&outcome.final_positions)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        // f32 rotations: micrometres over metres of lever.
        assert!(worst < 1e-5, "{worst}");
        // κ is relative to the path: scaling every stiffness changes nothing.
        let kappa: f32 = (0..graph.input.n)
            .filter_map(|i| (i + 1 < graph.path_len).then(|| graph.input.edge(i, i + 1)[5]))
            .sum();
        assert!(kappa.abs() < 1e-4, "path κ sums to {kappa}");
    }
}
