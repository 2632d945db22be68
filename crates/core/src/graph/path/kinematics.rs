//! Forward kinematics on a path graph and on the whole tree: where nodes go
//! when the path joints turn. Shared by the encoder (the linearised push's
//! prior at the graph's nodes) and the decoders (a model's answer placed on
//! the whole tree).

use nalgebra::{Point3, Rotation3, Vector3};

use crate::sim::deformed_positions;
use crate::tree::Tree;

/// Where the graph's nodes go when path node k's joint turns by
/// `rotations[k]` (k < `path_len`; the root's is ignored): the path by
/// forward kinematics along it, each side node rigidly with the branch
/// ending at its path node. O(path), where placing the whole tree
/// ([`positions_from_rotations`]) is O(N).
pub(super) fn graph_positions(
    tree: &Tree,
    nodes: &[usize],
    path_len: usize,
    hangs_from: &[usize],
    rotations: &[Vector3<f64>],
) -> Vec<Point3<f64>> {
    let mut orientation = vec![Rotation3::identity(); path_len];
    let mut placed = Vec::with_capacity(nodes.len());
    placed.push(tree.position(nodes[0]));
    for k in 1..path_len {
        orientation[k] = orientation[k - 1] * Rotation3::new(rotations[k]);
        let rest = tree.position(nodes[k]) - tree.position(nodes[k - 1]);
        placed.push(placed[k - 1] + orientation[k] * rest);
    }
    for (s, &k) in hangs_from.iter().enumerate() {
        let rest = tree.position(nodes[path_len + s]) - tree.position(nodes[k]);
        placed.push(placed[k] + orientation[k] * rest);
    }
    placed
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

/// The whole tree under the linearised push of `push` (m) at `contact`
/// (slot contact): what a path model's all-zero answer should place.
#[cfg(test)]
pub(super) fn linearised_tree(
    tree: &Tree,
    contact: usize,
    push: &Vector3<f64>,
) -> Vec<Point3<f64>> {
    use crate::sim::linear::linear_rotations;
    use crate::sim::{ContactModel, Push};
    let push = Push {
        node: contact,
        vector: *push,
    };
    positions_from_rotations(tree, &linear_rotations(tree, &push, ContactModel::Slot))
}
