//! The graph encoding of the paper (Section III-C), written once and used
//! by training, export, evaluation and the server.
//!
//! A tree of N nodes becomes a **fully connected** directed graph: every
//! ordered pair (i, j), i ≠ j, is an edge i → j (sender i, receiver j) with
//! attributes
//!
//! ```text
//!     e_ij = [p_j − p_i (3, m), v_ij, b_ij, κ_ij]
//! ```
//!
//! where v_ij = +1 when i is an ancestor of j (root → leaf), −1 otherwise;
//! b_ij = 1 when i and j are parent and child (in either direction), 0
//! otherwise; and κ_ij = ln K_s,ij − mean over the tree's branches of
//! ln K_s (dimensionless) for the branch joining i and j, 0 for pairs that
//! are not a branch.
//!
//! Why κ and not K_s (layout 1 fed K_s in N·m/rad): a push is displacement
//! controlled, and its steady state minimises Σ ½ K_s |θ|² under the
//! contact constraint, so multiplying every K_s by one factor moves no
//! node. Only stiffness *ratios* change the outcome, and κ holds exactly
//! those: a global factor leaves every κ unchanged. The log scale makes
//! a branch twice as stiff as its neighbour the same step wherever it is
//! in the tree (K_s spans four decades between twigs and trunk). b carries
//! the adjacency that a zero K_s carried in layout 1. Node and global
//! attributes depend on the task:
//!
//! | task | node n_j | global g |
//! | --- | --- | --- |
//! | forward model | \[c_j\] (1 at the contacted node) | \[T\] (push, m) |
//! | contact policy | [p′_j − p_j] (target offset, m) | none |
//!
//! Features are raw SI values; normalisation (statistics from the training
//! split, [`FeatureStats`]) is applied inside the model, so clients send SI
//! units. Graphs of different sizes are batched densely, padded to the
//! largest N with a node mask; padded nodes and self-edges carry zeros and
//! are excluded from sums by the mask.
//!
//! The documentation beside the code: `docs/learning.md`.

pub mod contract;
pub mod path;
pub mod stats;

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

pub use stats::FeatureStats;

use crate::tree::Tree;

/// Version of the feature layout below; stored in model metadata so a
/// model and the encoder that feeds it can be checked against each other.
///
/// 1: edges [Δp, v, K_s]; 2: edges [Δp, v, b, κ] (scale-free stiffness).
pub const FEATURE_LAYOUT_VERSION: u32 = 2;

/// Edge attributes: Δp (3), v, b, κ.
pub const EDGE_DIM: usize = 6;

/// Column of b (1 for parent–child pairs) in an edge vector.
pub const BRANCH_COLUMN: usize = 4;

/// Column of κ (log stiffness relative to the tree's mean) in an edge vector.
pub const LOG_STIFFNESS_COLUMN: usize = 5;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Task {
    /// Predict node displacements from a push.
    Forward,
    /// Predict per-node pushes and affordances from target offsets.
    Policy,
}

impl Task {
    /// `forward` or `policy`, as in model file names and metadata.
    pub fn name(self) -> &'static str {
        match self {
            Task::Forward => "forward",
            Task::Policy => "policy",
        }
    }

    pub fn node_dim(self) -> usize {
        match self {
            Task::Forward => 1,
            Task::Policy => 3,
        }
    }

    pub fn global_dim(self) -> usize {
        match self {
            Task::Forward => 3,
            Task::Policy => 0,
        }
    }
}

/// One encoded graph (f32, row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct GraphInput {
    pub task: Task,
    pub n: usize,
    /// N × node_dim.
    pub nodes: Vec<f32>,
    /// N × N × EDGE_DIM; entry (i, j) is the edge i → j; (i, i) is zero.
    pub edges: Vec<f32>,
    /// global_dim values.
    pub global: Vec<f32>,
}

impl GraphInput {
    pub fn edge(&self, i: usize, j: usize) -> &[f32] {
        let k = (i * self.n + j) * EDGE_DIM;
        &self.edges[k..k + EDGE_DIM]
    }

    pub fn node(&self, j: usize) -> &[f32] {
        let d = self.task.node_dim();
        &self.nodes[j * d..(j + 1) * d]
    }

    /// The same graph for the tree (and push, or target) turned by `angle`
    /// (rad) about the vertical axis z through the root. Every vector
    /// feature turns with it (Δp; the push T; the target offsets p′ − p). Gravity is off and joints are isotropic, so
    /// this is an exact symmetry of the simulator: training augments with it.
    /// v, b and κ are invariant.
    pub fn rotate_about_vertical(&mut self, angle: f64) {
        let (sin, cos) = angle.sin_cos();
        let edges = self.edges.chunks_exact_mut(EDGE_DIM);
        let nodes = match self.task {
            Task::Forward => None,
            Task::Policy => Some(self.nodes.chunks_exact_mut(3)),
        };
        let global = match self.task {
            Task::Forward => Some(self.global.chunks_exact_mut(3)),
            Task::Policy => None,
        };
        for v in edges
            .chain(nodes.into_iter().flatten())
            .chain(global.into_iter().flatten())
        {
            rotate_xy(v, sin, cos);
        }
    }
}

/// Turns the first two components of `v` (x, y) by the angle with the
/// given sine and cosine; z stays.
pub fn rotate_xy(v: &mut [f32], sin: f64, cos: f64) {
    let (x, y) = (v[0] as f64, v[1] as f64);
    v[0] = (cos * x - sin * y) as f32;
    v[1] = (sin * x + cos * y) as f32;
}

/// κ_j = ln K_s,j − mean over branches of ln K_s, indexed by node (0 at the
/// root). Branches with a non-positive or non-finite K_s (which requests
/// and dataset files never carry: they are validated) count as κ = 0 and
/// stay out of the mean.
pub fn log_stiffness_ratios(tree: &Tree) -> Vec<f64> {
    let logs: Vec<Option<f64>> = (0..tree.len())
        .map(|j| {
            tree.branch(j)
                .map(|b| b.stiffness)
                .filter(|k| k.is_finite() && *k > 0.0)
                .map(f64::ln)
        })
        .collect();
    let valid: Vec<f64> = logs.iter().flatten().copied().collect();
    let mean = if valid.is_empty() {
        0.0
    } else {
        valid.iter().sum::<f64>() / valid.len() as f64
    };
    logs.iter().map(|l| l.map_or(0.0, |l| l - mean)).collect()
}

/// The edge attributes of a tree at rest: shared by both tasks.
pub fn edge_attributes(tree: &Tree) -> Vec<f32> {
    edge_attributes_with(
        tree.positions(),
        tree.parents(),
        &log_stiffness_ratios(tree),
    )
}

/// The edge attributes of any rooted graph (positions, parents, and κ of
/// the branch ending at each node): the one definition behind both
/// encodings ([`path`] feeds it a path's subgraph).
pub fn edge_attributes_with(
    positions: &[Point3<f64>],
    parents: &[Option<usize>],
    kappa: &[f64],
) -> Vec<f32> {
    let n = positions.len();
    let is_ancestor = |a: usize, mut j: usize| {
        while let Some(p) = parents[j] {
            if p == a {
                return true;
            }
            j = p;
        }
        false
    };
    let mut edges = vec![0.0f32; n * n * EDGE_DIM];
    for i in 0..n {
        for j in 0..n {
            if i == j {
                continue;
            }
            let d = positions[j] - positions[i];
            let k = (i * n + j) * EDGE_DIM;
            edges[k] = d.x as f32;
            edges[k + 1] = d.y as f32;
            edges[k + 2] = d.z as f32;
            edges[k + 3] = if is_ancestor(i, j) { 1.0 } else { -1.0 };
            let branch = if parents[j] == Some(i) {
                Some(j)
            } else if parents[i] == Some(j) {
                Some(i)
            } else {
                None
            };
            if let Some(b) = branch {
                edges[k + BRANCH_COLUMN] = 1.0;
                edges[k + LOG_STIFFNESS_COLUMN] = kappa[b] as f32;
            }
        }
    }
    edges
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EncodeError {
    #[error("contact node {node} is not a non-root node of this {n}-node tree")]
    ContactNode { node: usize, n: usize },
    #[error("{got} target positions for a tree of {n} nodes")]
    TargetCount { got: usize, n: usize },
    #[error("non-finite {what}")]
    NonFinite { what: &'static str },
    #[error(
        "node {node} is {joints} joints from the root; a path model reads paths of at most {max} joints"
    )]
    PathTooDeep {
        node: usize,
        joints: usize,
        max: usize,
    },
}

/// Forward model input: the tree, the contacted node and the push T (m).
pub fn encode_forward(
    tree: &Tree,
    contact: usize,
    push: &Vector3<f64>,
) -> Result<GraphInput, EncodeError> {
    check_push(tree, contact, push)?;
    let n = tree.len();
    let mut nodes = vec![0.0f32; n];
    nodes[contact] = 1.0;
    Ok(GraphInput {
        task: Task::Forward,
        n,
        nodes,
        edges: edge_attributes(tree),
        global: vec![push.x as f32, push.y as f32, push.z as f32],
    })
}

/// `to − from` per node, as the models read and write it (3 f32 per node):
/// a policy's target offsets p′ − p, a forward model's displacements.
pub fn offsets(to: &[Point3<f64>], from: &[Point3<f64>]) -> Vec<f32> {
    to.iter()
        .zip(from)
        .flat_map(|(a, b)| {
            let d = a - b;
            [d.x as f32, d.y as f32, d.z as f32]
        })
        .collect()
}

/// What every forward encoding needs of a push: a non-root node of the
/// tree and a finite vector.
pub(crate) fn check_push(
    tree: &Tree,
    contact: usize,
    push: &Vector3<f64>,
) -> Result<(), EncodeError> {
    let n = tree.len();
    if contact == 0 || contact >= n {
        return Err(EncodeError::ContactNode { node: contact, n });
    }
    if !push.iter().all(|v| v.is_finite()) {
        return Err(EncodeError::NonFinite { what: "push" });
    }
    Ok(())
}

/// Contact policy input: the tree and where its nodes should go (m).
pub fn encode_policy(tree: &Tree, targets: &[Point3<f64>]) -> Result<GraphInput, EncodeError> {
    let n = tree.len();
    if targets.len() != n {
        return Err(EncodeError::TargetCount {
            got: targets.len(),
            n,
        });
    }
    if targets.iter().any(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(EncodeError::NonFinite {
            what: "target position",
        });
    }
    let nodes = offsets(targets, tree.positions());
    Ok(GraphInput {
        task: Task::Policy,
        n,
        nodes,
        edges: edge_attributes(tree),
        global: Vec::new(),
    })
}

/// Graphs of one task padded to a common size.
#[derive(Debug, Clone, PartialEq)]
pub struct Batch {
    pub task: Task,
    pub batch: usize,
    /// Padded node count.
    pub n: usize,
    /// B × N × node_dim.
    pub nodes: Vec<f32>,
    /// B × N × N × EDGE_DIM.
    pub edges: Vec<f32>,
    /// B × global_dim.
    pub global: Vec<f32>,
    /// B × N: 1 for real nodes, 0 for padding.
    pub mask: Vec<f32>,
}

impl Batch {
    /// The graphs `range` of this batch, with the same padding.
    pub fn rows(&self, range: std::ops::Range<usize>) -> Batch {
        let (nd, gd, n) = (self.task.node_dim(), self.task.global_dim(), self.n);
        let cut = |v: &[f32], per: usize| v[range.start * per..range.end * per].to_vec();
        Batch {
            task: self.task,
            batch: range.len(),
            n,
            nodes: cut(&self.nodes, n * nd),
            edges: cut(&self.edges, n * n * EDGE_DIM),
            global: cut(&self.global, gd),
            mask: cut(&self.mask, n),
        }
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BatchError {
    #[error("an empty batch")]
    Empty,
    #[error("graphs of different tasks in one batch")]
    MixedTasks,
}

/// Pads `graphs` to the largest N and stacks them.
pub fn batch(graphs: &[GraphInput]) -> Result<Batch, BatchError> {
    let first = graphs.first().ok_or(BatchError::Empty)?;
    let task = first.task;
    if graphs.iter().any(|g| g.task != task) {
        return Err(BatchError::MixedTasks);
    }
    let (nd, gd) = (task.node_dim(), task.global_dim());
    let n = graphs.iter().map(|g| g.n).max().unwrap_or(0);
    let b = graphs.len();
    let mut out = Batch {
        task,
        batch: b,
        n,
        nodes: vec![0.0; b * n * nd],
        edges: vec![0.0; b * n * n * EDGE_DIM],
        global: vec![0.0; b * gd],
        mask: vec![0.0; b * n],
    };
    for (k, g) in graphs.iter().enumerate() {
        let m = g.n;
        out.nodes[k * n * nd..k * n * nd + m * nd].copy_from_slice(&g.nodes);
        for i in 0..m {
            let src = i * m * EDGE_DIM;
            let dst = ((k * n + i) * n) * EDGE_DIM;
            out.edges[dst..dst + m * EDGE_DIM].copy_from_slice(&g.edges[src..src + m * EDGE_DIM]);
        }
        out.global[k * gd..(k + 1) * gd].copy_from_slice(&g.global);
        out.mask[k * n..k * n + m].fill(1.0);
    }
    Ok(out)
}
