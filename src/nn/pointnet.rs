//! The PointNet baseline (Qi et al. 2017, segmentation variant) as plain
//! weights with a reference forward pass.
//!
//! Each node is a point; it sees no edges. Per point: a shared MLP to 64
//! (the local feature), then to 1024; a max over the tree's real points
//! gives the global feature; [local, global] (1088) goes through
//! 1088 → 512 → 128 and the same heads as the GNN.
//!
//! Point input: the node's position relative to the root, [p_j − p_0], then
//! the task's node attribute and global attribute (forward: [c_j, T];
//! policy: [p′_j − p_j]). The paper's baseline lists only the latter; we add
//! the position because a point cloud without coordinates cannot tell one
//! node from another, and a baseline that weak would say nothing. Every
//! input is derived from the same [`Batch`] the GNN reads (p_j − p_0 is the
//! Δp of edge 0 → j), so both models share one encoder and one ONNX input
//! signature.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::gnn::{Linear, masked_softmax};
use super::input::normalise;
use crate::graph::contract::ModelOutput;
use crate::graph::{Batch, EDGE_DIM, FeatureStats, GraphInput, Task, stats::Running};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointNetConfig {
    pub task: Task,
    /// Local feature width (64).
    pub local: usize,
    /// Global feature width (1024).
    pub global: usize,
}

impl PointNetConfig {
    pub fn paper(task: Task) -> Self {
        Self {
            task,
            local: 64,
            global: 1024,
        }
    }

    /// Values per point: position, node attribute, global attribute.
    pub fn point_dim(&self) -> usize {
        3 + self.task.node_dim() + self.task.global_dim()
    }
}

/// Trunk widths after the concatenation, as in FACTS.md.
pub const TRUNK: [usize; 2] = [512, 128];

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointNetWeights {
    pub config: PointNetConfig,
    /// Node and global attribute statistics (edges unused).
    pub stats: FeatureStats,
    /// Statistics of p_j − p_0 over real nodes.
    pub position_mean: [f64; 3],
    pub position_std: [f64; 3],
    pub output_mean: [f64; 3],
    pub output_std: [f64; 3],
    /// point → local → local.
    pub local: [Linear; 2],
    /// local → 128 → global.
    pub feature: [Linear; 2],
    /// [local, global] → 512 → 128.
    pub trunk: [Linear; 2],
    pub vector_head: Linear,
    pub affordance_head: Option<Linear>,
}

/// Statistics of the node positions relative to the root, over real nodes.
pub fn position_stats<'a>(
    graphs: impl IntoIterator<Item = &'a GraphInput>,
) -> ([f64; 3], [f64; 3]) {
    let mut running = Running::new(3);
    for g in graphs {
        for j in 0..g.n {
            running.push(&g.edge(0, j)[..3]);
        }
    }
    let (m, s) = running.finish();
    ([m[0], m[1], m[2]], [s[0], s[1], s[2]])
}

impl PointNetWeights {
    pub fn random(
        config: PointNetConfig,
        stats: FeatureStats,
        position: ([f64; 3], [f64; 3]),
        seed: u64,
    ) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (l, gl) = (config.local, config.global);
        let local = [
            Linear::random(config.point_dim(), l, &mut rng),
            Linear::random(l, l, &mut rng),
        ];
        let feature = [
            Linear::random(l, 128, &mut rng),
            Linear::random(128, gl, &mut rng),
        ];
        let trunk = [
            Linear::random(l + gl, TRUNK[0], &mut rng),
            Linear::random(TRUNK[0], TRUNK[1], &mut rng),
        ];
        let vector_head = Linear::random(TRUNK[1], 3, &mut rng);
        let affordance_head =
            (config.task == Task::Policy).then(|| Linear::random(TRUNK[1], 1, &mut rng));
        Self {
            config,
            stats,
            position_mean: position.0,
            position_std: position.1,
            output_mean: [0.0; 3],
            output_std: [1.0; 3],
            local,
            feature,
            trunk,
            vector_head,
            affordance_head,
        }
    }
}

/// Normalised point inputs, B × N × point_dim (padded points included).
pub fn point_input(weights: &PointNetWeights, batch: &Batch) -> Vec<f32> {
    let task = weights.config.task;
    assert_eq!(batch.task, task, "batch and model tasks differ");
    let (b, n) = (batch.batch, batch.n);
    let (nd, gd, pd) = (
        task.node_dim(),
        task.global_dim(),
        weights.config.point_dim(),
    );
    let s = &weights.stats;
    let nodes = normalise(&batch.nodes, &s.node_mean, &s.node_std);
    let global = normalise(&batch.global, &s.global_mean, &s.global_std);
    let mut out = vec![0.0f32; b * n * pd];
    for g in 0..b {
        for j in 0..n {
            let row = &mut out[(g * n + j) * pd..(g * n + j + 1) * pd];
            let e = ((g * n) * n + j) * EDGE_DIM; // edge 0 → j
            for (c, slot) in row[..3].iter_mut().enumerate() {
                *slot = ((batch.edges[e + c] as f64 - weights.position_mean[c])
                    / weights.position_std[c]) as f32;
            }
            row[3..3 + nd].copy_from_slice(&nodes[(g * n + j) * nd..(g * n + j + 1) * nd]);
            row[3 + nd..].copy_from_slice(&global[g * gd..(g + 1) * gd]);
        }
    }
    out
}

fn dense_relu(layer: &Linear, x: &[f32]) -> Vec<f32> {
    let mut y = vec![0.0; layer.outputs];
    layer.apply(x, &mut y);
    y.iter_mut().for_each(|v| *v = v.max(0.0));
    y
}

/// The reference forward pass, point by point.
pub fn forward(weights: &PointNetWeights, batch: &Batch) -> ModelOutput {
    let (b, n, pd) = (batch.batch, batch.n, weights.config.point_dim());
    let points = point_input(weights, batch);
    let mut vectors = vec![0.0f32; b * n * 3];
    let mut logits = vec![0.0f32; b * n];
    for g in 0..b {
        let locals: Vec<Vec<f32>> = (0..n)
            .map(|j| {
                let x = &points[(g * n + j) * pd..(g * n + j + 1) * pd];
                dense_relu(&weights.local[1], &dense_relu(&weights.local[0], x))
            })
            .collect();
        let mut global = vec![0.0f32; weights.config.global];
        for (j, local) in locals.iter().enumerate() {
            if batch.mask[g * n + j] == 0.0 {
                continue;
            }
            let f = dense_relu(&weights.feature[1], &dense_relu(&weights.feature[0], local));
            global.iter_mut().zip(&f).for_each(|(m, v)| *m = m.max(*v));
        }
        for (j, local) in locals.iter().enumerate() {
            let x: Vec<f32> = local.iter().chain(&global).copied().collect();
            let t = dense_relu(&weights.trunk[1], &dense_relu(&weights.trunk[0], &x));
            let mut y = [0.0f32; 3];
            weights.vector_head.apply(&t, &mut y);
            for c in 0..3 {
                vectors[(g * n + j) * 3 + c] =
                    (y[c] as f64 * weights.output_std[c] + weights.output_mean[c]) as f32;
            }
            if let Some(head) = &weights.affordance_head {
                head.apply(&t, &mut logits[g * n + j..g * n + j + 1]);
            }
        }
    }
    ModelOutput {
        vectors,
        affordance: weights
            .affordance_head
            .as_ref()
            .map(|_| masked_softmax(&logits, &batch.mask, b, n)),
    }
}
