//! The tree every other module works on: rigid branches between nodes,
//! spherical spring-damper joints at each branch's parent node, a fixed root.
//!
//! A [`Tree`] can only be built through [`Tree::new`] (or helpers that call
//! it), so every `Tree` in the program is known to be a valid rooted tree with
//! finite, positive, self-consistent parameters. Later stages (simulation,
//! graph encoding, the HTTP API) rely on that and do not re-check.
//!
//! Units are SI throughout: positions and lengths in metres, radii in
//! metres, stiffness K_s in N·m/rad, damping K_d in N·m·s/rad.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

/// Largest tree accepted anywhere in treemanip: a whole young orchard tree
/// at the paper's node spacing (several hundred joints).
///
/// The simulator, the planner and identification work on the root-to-contact
/// path and a bounding-volume hierarchy of the branches, so their cost grows
/// with the path's depth and about linearly in N. The models that read the
/// *fully connected* graph (the paper's GNN and PointNet, whose edge tensors
/// grow as N²) declare a smaller limit of their own in their card
/// ([`FULL_GRAPH_MAX_NODES`]); the path models have none.
pub const MAX_NODES: usize = 512;

/// Largest tree a model on the fully connected graph is run on: at N = 64
/// that is 4,032 directed edges, about 5× the paper's largest tree (N = 30,
/// 870 edges), one forward pass in tens of milliseconds and a few MB of
/// activations. At 512 nodes it would be 262,000 edges and gigabytes.
pub const FULL_GRAPH_MAX_NODES: usize = 64;

/// Smallest tree: the fixed root and one branch.
pub const MIN_NODES: usize = 2;

/// A stored branch length may differ from the distance between its end nodes
/// by at most this fraction of that distance (plus [`LENGTH_ABS_TOLERANCE`]).
/// Loose enough for values that went through a text format with ~7
/// significant digits, tight enough to catch a length that belongs to
/// another branch.
pub const LENGTH_REL_TOLERANCE: f64 = 1e-6;

/// Absolute slack on the branch-length check, in metres.
pub const LENGTH_ABS_TOLERANCE: f64 = 1e-9;

/// The physical parameters of the branch that ends at a node (the link from
/// the node's parent to the node). The joint that carries them sits at the
/// parent node.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Branch {
    /// Cross-section radius r (m).
    pub radius: f64,
    /// Length ℓ (m); equals the distance between the branch's end nodes.
    pub length: f64,
    /// Joint stiffness K_s (N·m/rad), the same about all three axes.
    pub stiffness: f64,
    /// Joint damping K_d (N·m·s/rad), the same about all three axes.
    pub damping: f64,
}

/// Why a set of arrays is not a valid tree. Every variant names the node (and
/// the field) at fault so a user can fix the input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TreeError {
    #[error("a tree needs between {min} and {max} nodes, got {got}")]
    NodeCount { got: usize, min: usize, max: usize },
    #[error("`{field}` has {got} entries but `positions` has {expected}")]
    LengthMismatch {
        field: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("no root: exactly one node must have no parent (node 0)")]
    NoRoot,
    #[error("several roots: nodes {nodes:?} have no parent; only node 0 may be the root")]
    MultipleRoots { nodes: Vec<usize> },
    #[error("node {node} has no parent, but the root must be node 0")]
    RootNotFirst { node: usize },
    #[error("node {node} has parent {parent}, which is out of range (the tree has {n} nodes)")]
    ParentOutOfRange {
        node: usize,
        parent: usize,
        n: usize,
    },
    #[error("nodes {nodes:?} form a cycle through their parents")]
    Cycle { nodes: Vec<usize> },
    #[error("node {node} is not connected to the root (its parent chain ends in a cycle)")]
    Disconnected { node: usize },
    #[error("`{field}` of node {node} is not a finite number")]
    NonFinite { field: &'static str, node: usize },
    #[error("`{field}` of node {node} must be positive, got {value}")]
    NonPositive {
        field: &'static str,
        node: usize,
        value: f64,
    },
    #[error("`damping` of node {node} must be zero or positive, got {value}")]
    NegativeDamping { node: usize, value: f64 },
    #[error("node {node} has no branch parameters (every non-root node needs one)")]
    MissingBranch { node: usize },
    #[error("branch of node {node} has length {stored} m but its end nodes are {measured} m apart")]
    BranchLength {
        node: usize,
        stored: f64,
        measured: f64,
    },
}

/// A validated tree. Node 0 is the fixed root; every other node has exactly
/// one parent and a [`Branch`].
#[derive(Debug, Clone, PartialEq)]
pub struct Tree {
    positions: Vec<Point3<f64>>,
    parents: Vec<Option<usize>>,
    branches: Vec<Option<Branch>>,
    children: Vec<Vec<usize>>,
    depth: Vec<usize>,
}

impl Tree {
    /// Validates and builds a tree. `branches[j]` belongs to the branch that
    /// ends at node j; the root's entry is ignored (use `None`).
    pub fn new(
        positions: Vec<Point3<f64>>,
        parents: Vec<Option<usize>>,
        branches: Vec<Option<Branch>>,
    ) -> Result<Self, TreeError> {
        let n = positions.len();
        if !(MIN_NODES..=MAX_NODES).contains(&n) {
            return Err(TreeError::NodeCount {
                got: n,
                min: MIN_NODES,
                max: MAX_NODES,
            });
        }
        for (field, got) in [("parents", parents.len()), ("branches", branches.len())] {
            if got != n {
                return Err(TreeError::LengthMismatch {
                    field,
                    expected: n,
                    got,
                });
            }
        }
        // Structure first: a broken parent chain explains bad numbers
        // derived from it (for example positions summed along it).
        let depth = validate_topology(&parents)?;
        for (node, p) in positions.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(TreeError::NonFinite {
                    field: "positions",
                    node,
                });
            }
        }
        let mut branches = branches;
        branches[0] = None;
        for node in 1..n {
            let branch = branches[node].ok_or(TreeError::MissingBranch { node })?;
            let parent = parents[node].expect("validated: non-root nodes have parents");
            validate_branch(node, &branch, (positions[node] - positions[parent]).norm())?;
        }
        let mut children = vec![Vec::new(); n];
        for (node, parent) in parents.iter().enumerate() {
            if let Some(p) = parent {
                children[*p].push(node);
            }
        }
        Ok(Self {
            positions,
            parents,
            branches,
            children,
            depth,
        })
    }

    /// Number of nodes N, root included.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Always false: a valid tree has at least [`MIN_NODES`] nodes.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    pub fn positions(&self) -> &[Point3<f64>] {
        &self.positions
    }

    pub fn position(&self, node: usize) -> Point3<f64> {
        self.positions[node]
    }

    pub fn parents(&self) -> &[Option<usize>] {
        &self.parents
    }

    pub fn parent(&self, node: usize) -> Option<usize> {
        self.parents[node]
    }

    /// The branch ending at `node`; `None` for the root.
    pub fn branch(&self, node: usize) -> Option<&Branch> {
        self.branches[node].as_ref()
    }

    pub fn branches(&self) -> &[Option<Branch>] {
        &self.branches
    }

    /// Non-root nodes with their branches, in index order.
    pub fn branches_iter(&self) -> impl Iterator<Item = (usize, &Branch)> {
        self.branches
            .iter()
            .enumerate()
            .filter_map(|(j, b)| b.as_ref().map(|b| (j, b)))
    }

    /// Unit vector along the branch ending at `node`, parent → node.
    pub fn branch_direction(&self, node: usize) -> Option<Vector3<f64>> {
        let parent = self.parents[node]?;
        Some((self.positions[node] - self.positions[parent]).normalize())
    }

    pub fn children(&self, node: usize) -> &[usize] {
        &self.children[node]
    }

    /// Number of branches between `node` and the root (0 for the root).
    pub fn depth(&self, node: usize) -> usize {
        self.depth[node]
    }

    pub fn is_leaf(&self, node: usize) -> bool {
        self.children[node].is_empty()
    }

    /// `node`, its parent, …, the root.
    pub fn path_to_root(&self, node: usize) -> Vec<usize> {
        let mut path = vec![node];
        let mut current = node;
        while let Some(p) = self.parents[current] {
            path.push(p);
            current = p;
        }
        path
    }

    /// `node` and all its descendants, in depth-first pre-order.
    pub fn subtree(&self, node: usize) -> Vec<usize> {
        let mut out = Vec::new();
        let mut stack = vec![node];
        while let Some(j) = stack.pop() {
            out.push(j);
            stack.extend(self.children[j].iter().rev());
        }
        out
    }

    /// True when `ancestor` lies on the path from `node` to the root
    /// (a node is not its own ancestor).
    pub fn is_ancestor(&self, ancestor: usize, node: usize) -> bool {
        let mut current = node;
        while let Some(p) = self.parents[current] {
            if p == ancestor {
                return true;
            }
            current = p;
        }
        false
    }

    /// The paper's v_ij for the directed edge i → j of the fully connected
    /// graph: +1 when the edge points from root towards leaf (i is an ancestor
    /// of j), −1 otherwise, as in the original implementation. Self-edges are
    /// not part of the graph and get 0.
    pub fn orientation(&self, i: usize, j: usize) -> f64 {
        if i == j {
            0.0
        } else if self.is_ancestor(i, j) {
            1.0
        } else {
            -1.0
        }
    }

    /// Height of the tree: highest node above the root (m).
    pub fn height(&self) -> f64 {
        let z0 = self.positions[0].z;
        self.positions
            .iter()
            .map(|p| p.z - z0)
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Smallest distance between any two distinct nodes (m).
    pub fn min_node_spacing(&self) -> f64 {
        let mut best = f64::INFINITY;
        for i in 0..self.len() {
            for j in (i + 1)..self.len() {
                best = best.min((self.positions[i] - self.positions[j]).norm());
            }
        }
        best
    }

    /// A string that is equal for two trees exactly when their rooted,
    /// unordered topologies are isomorphic (AHU encoding). Used to keep the
    /// generated topologies of one size unique.
    pub fn topology_key(&self) -> String {
        fn encode(tree: &Tree, node: usize) -> String {
            let mut parts: Vec<String> = tree.children[node]
                .iter()
                .map(|&c| encode(tree, c))
                .collect();
            parts.sort();
            format!("({})", parts.concat())
        }
        encode(self, 0)
    }
}

/// Checks the parent array and returns each node's depth.
fn validate_topology(parents: &[Option<usize>]) -> Result<Vec<usize>, TreeError> {
    let n = parents.len();
    let roots: Vec<usize> = (0..n).filter(|&j| parents[j].is_none()).collect();
    match roots.as_slice() {
        [] => return Err(TreeError::NoRoot),
        [0] => {}
        [node] => return Err(TreeError::RootNotFirst { node: *node }),
        _ => return Err(TreeError::MultipleRoots { nodes: roots }),
    }
    for (node, parent) in parents.iter().enumerate() {
        if let Some(p) = *parent
            && p >= n
        {
            return Err(TreeError::ParentOutOfRange { node, parent: p, n });
        }
    }
    // Walk each node's parent chain; depth[] memoises finished nodes.
    const UNKNOWN: usize = usize::MAX;
    let mut depth = vec![UNKNOWN; n];
    depth[0] = 0;
    for start in 1..n {
        let mut chain = Vec::new();
        let mut current = start;
        while depth[current] == UNKNOWN {
            if let Some(pos) = chain.iter().position(|&c| c == current) {
                let mut cycle: Vec<usize> = chain[pos..].to_vec();
                if cycle.contains(&start) {
                    cycle.sort_unstable();
                    return Err(TreeError::Cycle { nodes: cycle });
                }
                return Err(TreeError::Disconnected { node: start });
            }
            chain.push(current);
            current = parents[current].expect("only node 0 has no parent");
        }
        let mut d = depth[current];
        for &node in chain.iter().rev() {
            d += 1;
            depth[node] = d;
        }
    }
    Ok(depth)
}

fn validate_branch(node: usize, b: &Branch, measured: f64) -> Result<(), TreeError> {
    for (field, value) in [
        ("radius", b.radius),
        ("length", b.length),
        ("stiffness", b.stiffness),
        ("damping", b.damping),
    ] {
        if !value.is_finite() {
            return Err(TreeError::NonFinite { field, node });
        }
    }
    for (field, value) in [
        ("radius", b.radius),
        ("length", b.length),
        ("stiffness", b.stiffness),
    ] {
        if value <= 0.0 {
            return Err(TreeError::NonPositive { field, node, value });
        }
    }
    if b.damping < 0.0 {
        return Err(TreeError::NegativeDamping {
            node,
            value: b.damping,
        });
    }
    if (b.length - measured).abs() > LENGTH_REL_TOLERANCE * measured + LENGTH_ABS_TOLERANCE {
        return Err(TreeError::BranchLength {
            node,
            stored: b.length,
            measured,
        });
    }
    Ok(())
}
