//! The path encoding: a forward model that reads only the joints a push
//! can move and the branches that show how they turn.
//!
//! In the quasi-static model ([`crate::sim`]) a push at node c rotates only
//! the joints on the path from the root to c; every other subtree turns
//! rigidly with its parent branch, and the stiffness of branches off the
//! path plays no part. So the answer for any tree, however large, is fixed
//! by the path: its rest geometry, its stiffness *ratios* and the push. The
//! path encoding feeds the paper's graph network a small graph:
//!
//! - nodes: the root, the path a_1 … a_m (a_m = c), then every child of a
//!   path node that is not itself on the path (the first node of each side
//!   branch, whose motion shows the path branch's twist, and c's children,
//!   the fork that stops a gripper sliding off);
//! - edges: every ordered pair, with the paper's attributes [Δp, v, b, κ]
//!   ([`super::edge_attributes_with`]), where κ is ln K_s relative to the
//!   mean over the *path's* branches (only path ratios matter; the side
//!   branches carry κ = 0);
//! - node n_j = \[c_j\], global g = \[T\], and the output Δp_j per graph node,
//!   exactly as for the paper's forward model.
//!
//! What the model answers per graph node, and how it becomes the whole
//! tree's motion ([`decode`]), depends on the encoding:
//!
//! - [`Encoding::PathRotation`] (the served `forward_path` model): each path
//!   branch's rotation beyond the linearised push's, in the world frame;
//!   forward kinematics places the path and carries every subtree off it
//!   rigidly. An error in one branch's turn moves its subtree by the turn
//!   times the subtree's reach, and nothing else.
//! - [`Encoding::Path`] (the first path model, kept loadable): each graph
//!   node's Δp beyond the linearised push's; each path branch's orientation
//!   is the rotation that best maps its own rest direction and its side
//!   branches' onto the predicted ones (Wahba's problem, by SVD). A branch
//!   10 cm long turns by the *difference* of two predicted positions over
//!   10 cm, and a 500-node tree hangs a metre of subtree from it: the same
//!   Δp error costs three times the e_N it costs a 20-node tree.
//!
//! Either way rigid subtrees stay rigid by construction, and the cost is
//! O(m² + N) instead of O(N²).

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::{EncodeError, GraphInput, Task, edge_attributes_with};
use crate::sim::linear::linear_rotations;
use crate::sim::{ContactModel, Push};
use crate::tree::Tree;
use kinematics::graph_positions;

pub mod decode;
pub mod hold;
pub mod kinematics;

/// What graph a model reads and what its 3-vector output means.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Encoding {
    /// The paper's: every node of the tree, fully connected; the output is
    /// each node's displacement Δp (m). Costs O(N²); limited to
    /// [`crate::tree::FULL_GRAPH_MAX_NODES`].
    #[default]
    Full,
    /// The root-to-contact path and its side branches (this module); the
    /// output is each graph node's Δp beyond the linearised push, placed on
    /// the whole tree as path joint rotations. Any tree size; the graph
    /// itself has at most [`PATH_GRAPH_MAX_NODES`] nodes, side branches only
    /// up to [`PATH_GRAPH_TRAINED_NODES`]. The first path model's; kept so
    /// that its files still load and answer as they did.
    Path,
    /// The same graph; the output is each path branch's rotation (rad,
    /// world frame, a rotation vector) beyond the linearised push's, zero
    /// for the root and the side nodes ([`PathGraph::rotation_targets`]).
    PathRotation,
}

impl Encoding {
    /// Every encoding, in the order the API lists them.
    pub const ALL: [Encoding; 3] = [Encoding::Full, Encoding::PathRotation, Encoding::Path];

    pub fn name(self) -> &'static str {
        match self {
            Encoding::Full => "full",
            Encoding::Path => "path",
            Encoding::PathRotation => "path_rotation",
        }
    }

    /// What a path model's three numbers per graph node mean; `None` for
    /// the paper's encoding, which reads the whole tree.
    pub fn path_output(self) -> Option<PathOutput> {
        match self {
            Encoding::Full => None,
            Encoding::Path => Some(PathOutput::Displacement),
            Encoding::PathRotation => Some(PathOutput::Rotation),
        }
    }

    /// Whether the model reads a push's path graph (any tree size) rather
    /// than the whole tree.
    pub fn is_path(self) -> bool {
        self.path_output().is_some()
    }
}

/// What a path model answers per graph node (3 numbers each), beyond the
/// linearised push; [`decode`] places either on the whole tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PathOutput {
    /// Δp (m) of every graph node ([`Encoding::Path`]).
    Displacement,
    /// Each path branch's turn (rad, world frame) ([`Encoding::PathRotation`]).
    Rotation,
}

impl std::str::FromStr for Encoding {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Encoding::ALL
            .into_iter()
            .find(|e| e.name() == s)
            .ok_or_else(|| format!("unknown encoding {s:?} (full, path_rotation or path)"))
    }
}

/// A push's path graph and where its nodes are in the tree.
#[derive(Debug, Clone, PartialEq)]
pub struct PathGraph {
    /// Tree node of each graph node: the root, the path, then the side
    /// branches' first nodes.
    pub nodes: Vec<usize>,
    /// The root and the path: graph nodes 0..path_len (the contact last).
    pub path_len: usize,
    /// The push (m).
    pub push: Vector3<f64>,
    /// For each side node (graph index ≥ path_len), the graph index of the
    /// path node it hangs from.
    pub hangs_from: Vec<usize>,
    /// The linearised push's Δp of each graph node (m, 3 per node,
    /// [`crate::sim::linear`]): the model learns what the push does beyond it.
    pub prior: Vec<f32>,
    /// The linearised push's rotation of each graph node's joint (rad, the
    /// convention of [`crate::sim::deformed_positions`]; zero for the root
    /// and the side nodes): where a rotation model's answer starts.
    pub prior_rotations: Vec<Vector3<f64>>,
    pub input: GraphInput,
}

/// Most nodes of one path graph: the fully connected models' limit
/// ([`crate::tree::FULL_GRAPH_MAX_NODES`]), so one push costs what the
/// paper's GNN costs at most. A path deeper than this is refused
/// ([`EncodeError::PathTooDeep`]).
pub const PATH_GRAPH_MAX_NODES: usize = crate::tree::FULL_GRAPH_MAX_NODES;

/// Side branches join a path graph while it has fewer nodes than this (the
/// path itself is always whole): those nearest the contact first (the
/// joints that turn most); the others' branches are placed by the least
/// turn, as for a side node in line with its path branch. The models learn
/// from trees of at most 60 nodes, whose path graphs have 13 nodes at the
/// median and 30 at the 99th percentile (`--shape all`, 7,320 pushes),
/// while a 500-node orchard tree's would have 32 at the median and up to 58
/// with every side branch. Graphs kept within the bulk of what training saw
/// err less and cost the square of their size. Held-out orchard trees
/// (`eval sizes`, 96 pushes per size, the same weights), e_N (cm) at
/// N = 100 / 200 / 500 for this limit, the served turn-answering model
/// (`encoding: path_rotation`) and, in brackets, the first Δp model's:
///
/// | limit | seed 1001 | seed 2002 |
/// | --- | --- | --- |
/// | 16 | 2.97 / 3.68 / 4.42 (5.39 / 6.79 / 6.73) | 3.41 / 3.42 / 5.09 (6.24 / 6.09 / 8.10) |
/// | 20 | (5.29 / 6.49 / 7.06) | (6.13 / 5.95 / 8.66) |
/// | **24** | 2.99 / 3.55 / 4.39 (5.28 / 6.50 / 7.08) | 3.36 / 3.34 / 5.01 (6.18 / 5.92 / 8.37) |
/// | 32 | 2.99 / 3.58 / 4.46 (5.31 / 6.67 / 7.29) | 3.36 / 3.36 / 5.08 (6.18 / 6.11 / 8.55) |
/// | 64 | 2.99 / 3.58 / 4.94 (– / – / 7.59) | 3.36 / 3.36 / 5.17 (– / 6.11 / 8.70) |
///
/// 24 is at or below 32 everywhere for both models and, for the 64 deepest
/// pushes of a 500-node tree, 24-31 nodes a graph instead of 32: 75 against
/// 100 ms of inference on 2 cores (AMD EPYC).
pub const PATH_GRAPH_TRAINED_NODES: usize = 24;

/// Most joints from the root to a contact that one path graph holds (its
/// nodes less the contact's own).
pub const PATH_MAX_JOINTS: usize = PATH_GRAPH_MAX_NODES - 1;

/// Whether one path graph holds a push at `node`: the one test behind the
/// encoder's refusal, the domain check's `path_joints` and the planner's
/// skipping of pushes a path model cannot read.
pub fn path_fits(tree: &Tree, node: usize) -> bool {
    tree.depth(node) <= PATH_MAX_JOINTS
}

/// Smallest angle (rad) between a side node's direction from its path node
/// and the path branch: closer to collinear, the pair says little about
/// the branch's twist.
const SIDE_ANGLE: f64 = 0.35;

/// Nodes of a side subtree looked at for one off the path branch's line.
const SIDE_LOOK: usize = 32;

/// The node standing for the side subtree rooted at child `c` of path node
/// `a` (whose parent is `before`): `c` itself, or where `c`'s branch runs
/// on nearly in line with the path branch, the nearest node of its subtree
/// (breadth first, at most [`SIDE_LOOK`] looked at) that lies off that line. The whole side
/// subtree turns rigidly with the path branch, so any of its nodes shows
/// the turn; one off the line also shows the twist.
fn side_representative(tree: &Tree, before: usize, a: usize, c: usize) -> usize {
    let axis = tree.position(a) - tree.position(before);
    // Breadth first, nearest nodes first, a bounded look.
    let mut queue = std::collections::VecDeque::from([c]);
    let mut seen = 0;
    while let Some(d) = queue.pop_front() {
        if (tree.position(d) - tree.position(a)).angle(&axis) > SIDE_ANGLE {
            return d;
        }
        seen += 1;
        if seen >= SIDE_LOOK {
            break;
        }
        queue.extend(tree.children(d));
    }
    c
}

/// The path graph of a push at `contact` by `push` (m).
pub fn encode_forward_path(
    tree: &Tree,
    contact: usize,
    push: &Vector3<f64>,
) -> Result<PathGraph, EncodeError> {
    super::check_push(tree, contact, push)?;
    let n = tree.len();
    if !path_fits(tree, contact) {
        return Err(EncodeError::PathTooDeep {
            node: contact,
            joints: tree.depth(contact),
            max: PATH_MAX_JOINTS,
        });
    }
    let mut nodes = tree.path_to_root(contact);
    nodes.reverse();
    let path_len = nodes.len();
    let mut hangs_from = Vec::new();
    // Side branches from the contact towards the root, while they fit.
    for k in (1..path_len).rev() {
        let next = nodes.get(k + 1).copied();
        for &c in tree.children(nodes[k]) {
            if Some(c) != next && nodes.len() < PATH_GRAPH_TRAINED_NODES.max(path_len) {
                nodes.push(side_representative(tree, nodes[k - 1], nodes[k], c));
                hangs_from.push(k);
            }
        }
    }
    let m = nodes.len();
    let mut local = vec![usize::MAX; n];
    for (k, &j) in nodes[..path_len].iter().enumerate() {
        local[j] = k;
    }
    // A side node hangs from its path node directly (it stands for the
    // rigid side subtree, whose first branch it may lie beyond).
    let parents: Vec<Option<usize>> = (0..m)
        .map(|g| match g {
            0 => None,
            g if g < path_len => Some(g - 1),
            g => Some(hangs_from[g - path_len]),
        })
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
    let linear = linear_rotations(
        tree,
        &Push {
            node: contact,
            vector: *push,
        },
        ContactModel::Slot,
    );
    let prior_rotations: Vec<Vector3<f64>> = (0..m)
        .map(|k| match k {
            k if k > 0 && k < path_len => linear
                .iter()
                .find(|(j, _)| *j == nodes[k])
                .map_or_else(Vector3::zeros, |(_, t)| *t),
            _ => Vector3::zeros(),
        })
        .collect();
    let prior = graph_positions(tree, &nodes, path_len, &hangs_from, &prior_rotations)
        .iter()
        .zip(&nodes)
        .flat_map(|(placed, &j)| {
            let d = placed - tree.position(j);
            [d.x as f32, d.y as f32, d.z as f32]
        })
        .collect();
    Ok(PathGraph {
        nodes,
        path_len,
        push: *push,
        hangs_from,
        prior,
        prior_rotations,
        input: GraphInput {
            task: Task::Forward,
            n: m,
            nodes: node_features,
            edges,
            global: vec![push.x as f32, push.y as f32, push.z as f32],
        },
    })
}

/// An 8 cm push at `contact`, level and across its branch, and what the
/// simulator makes of it (`None` where it refuses): the exact answer the
/// path tests compare against.
#[cfg(test)]
pub(crate) fn simulated_side_push(
    tree: &Tree,
    contact: usize,
) -> Option<(Vector3<f64>, crate::sim::PushOutcome)> {
    use crate::sim::{Push, SimConfig, simulate};
    let axis = tree.branch_direction(contact)?;
    let push = axis.cross(&Vector3::z()).normalize() * 0.08;
    let push_at = Push {
        node: contact,
        vector: push,
    };
    let outcome = simulate(tree, &push_at, &SimConfig::default()).ok()?;
    Some((push, outcome))
}

#[cfg(test)]
mod tests {
    use super::kinematics::linearised_tree;
    use super::*;
    use crate::tree::{OrchardParams, generate_orchard};

    /// A comb: a 20-joint spine with two twigs at every spine node. Its
    /// deepest push's graph holds the root, the path and as many side nodes
    /// as the trained size allows, those nearest the contact first; a
    /// 40-joint spine's, its path alone; a spine of 70 joints is
    /// refused by name.
    #[test]
    fn path_graphs_hold_at_most_their_limit() {
        use crate::tree::{Branch, Tree};
        let comb = |spine: usize| {
            let mut positions = vec![Point3::origin()];
            let mut parents = vec![None];
            for k in 1..=spine {
                positions.push(Point3::new(0.0, 0.0, 0.1 * k as f64));
                parents.push(Some(if k == 1 { 0 } else { 3 * (k - 1) - 2 }));
                for side in [-1.0, 1.0] {
                    positions.push(Point3::new(0.08 * side, 0.0, 0.1 * k as f64 + 0.05));
                    parents.push(Some(3 * k - 2));
                }
            }
            let branches = (0..positions.len())
                .map(|j| {
                    parents[j].map(|p: usize| {
                        let length = (positions[j] - positions[p]).norm();
                        Branch {
                            radius: 0.01,
                            length,
                            stiffness: 50.0,
                            damping: 1.0,
                        }
                    })
                })
                .collect();
            Tree::new(positions, parents, branches).unwrap()
        };
        let tree = comb(20);
        let tip = 3 * 20 - 2;
        assert_eq!(tree.depth(tip), 20);
        let graph = encode_forward_path(&tree, tip, &(Vector3::x() * 0.05)).unwrap();
        assert_eq!(graph.input.n, PATH_GRAPH_TRAINED_NODES);
        assert_eq!(graph.path_len, 21);
        // 3 side nodes: both twigs of the spine node nearest the contact
        // and one of the next.
        assert_eq!(graph.hangs_from.len(), PATH_GRAPH_TRAINED_NODES - 21);
        assert_eq!(graph.hangs_from.iter().min(), Some(&19));
        let placed = graph.positions(
            PathOutput::Displacement,
            &tree,
            &vec![0.0; 3 * graph.input.n],
        );
        assert_eq!(placed.len(), tree.len());
        // A path longer than the side branches' limit stays whole, alone.
        let long = comb(40);
        let graph = encode_forward_path(&long, 3 * 40 - 2, &(Vector3::x() * 0.05)).unwrap();
        assert_eq!((graph.input.n, graph.path_len), (41, 41));
        assert_eq!(
            graph
                .positions(PathOutput::Rotation, &long, &vec![0.0; 3 * 41])
                .len(),
            long.len()
        );
        let deep = comb(70);
        assert_eq!(
            encode_forward_path(&deep, 3 * 70 - 2, &Vector3::x()),
            Err(EncodeError::PathTooDeep {
                node: 3 * 70 - 2,
                joints: 70,
                max: PATH_GRAPH_MAX_NODES - 1
            })
        );
    }

    /// The prior placed on the graph's nodes alone is the whole tree's
    /// forward kinematics at those nodes.
    #[test]
    fn the_graphs_prior_is_the_whole_trees_at_its_nodes() {
        let tree = generate_orchard(200, 9, &OrchardParams::default()).unwrap();
        for contact in (5..tree.len()).step_by(17) {
            let push = Vector3::new(0.06, -0.03, 0.02);
            let graph = encode_forward_path(&tree, contact, &push).unwrap();
            let all = linearised_tree(&tree, contact, &push);
            for (k, &j) in graph.nodes.iter().enumerate() {
                let d = all[j] - tree.position(j);
                for a in 0..3 {
                    assert!(
                        (graph.prior[3 * k + a] as f64 - d[a]).abs() < 1e-6,
                        "node {j}"
                    );
                }
            }
            assert!(
                graph.prior.iter().any(|v| v.abs() > 1e-3),
                "the push moves the graph"
            );
        }
    }
}
