//! The paper's GNN as plain weights, and a straightforward reference
//! forward pass over dense batches.
//!
//! Architecture (Sanchez-Gonzalez et al. graph2graph, as in the paper):
//! encoders turn normalised node, edge (and, for the forward model, global)
//! attributes into H-dimensional embeddings; each of the L layers computes
//! e*_ij = f_e(g, n_i, n_j, e_ij), aggregates ê_j = Σ_i e*_ij over the real
//! senders i ≠ j, computes n*_j = f_n(g, n_j, ê_j), and adds both as
//! residuals; heads read the node embeddings. Every MLP has three linear
//! layers with ReLU between them.
//!
//! The reference pass evaluates f_e on the concatenated inputs edge by edge,
//! deliberately unlike the exported ONNX graph (which splits the first layer
//! of f_e by input), so the two check each other.

use crate::graph::path::Encoding;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::input::gnn_input;
pub use super::input::{Connectivity, EdgeAttributes};
use crate::graph::contract::ModelOutput;
use crate::graph::{Batch, EDGE_DIM, FeatureStats, Task};
pub use crate::model::mlp::{Linear, Mlp};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GnnConfig {
    pub task: Task,
    /// Embedding width H (the paper: 128).
    pub hidden: usize,
    /// graph2graph layers L (the paper: 5).
    pub layers: usize,
    /// Which edge attributes the model sees (ablation; the paper: all).
    #[serde(default)]
    pub edge_attributes: EdgeAttributes,
    /// Which node pairs exchange messages (ablation; the paper: full).
    #[serde(default)]
    pub connectivity: Connectivity,
    /// What graph the model reads and what it answers: the paper's whole
    /// tree (Δp per node) or the push's path (θ per path joint).
    #[serde(default)]
    pub encoding: Encoding,
}

impl GnnConfig {
    /// The paper's model: H = 128, L = 5, all edge attributes, fully connected.
    pub fn paper(task: Task) -> Self {
        Self {
            task,
            hidden: 128,
            layers: 5,
            edge_attributes: EdgeAttributes::default(),
            connectivity: Connectivity::default(),
            encoding: Encoding::Full,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Block {
    /// f_e on [g, n_i, n_j, e_ij].
    pub edge: Mlp,
    /// f_n on [g, n_j, ê_j].
    pub node: Mlp,
}

/// Everything needed to run (or export) one model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GnnWeights {
    pub config: GnnConfig,
    /// Input normalisation.
    pub stats: FeatureStats,
    /// Output de-normalisation of the 3-vector head (Δp or T): y·std + mean.
    pub output_mean: [f64; 3],
    pub output_std: [f64; 3],
    pub node_encoder: Mlp,
    pub edge_encoder: Mlp,
    /// Forward model only.
    pub global_encoder: Option<Mlp>,
    pub blocks: Vec<Block>,
    /// Δp (forward) or the per-node push T (policy).
    pub vector_head: Mlp,
    /// Policy only: one affordance logit per node.
    pub affordance_head: Option<Mlp>,
}

impl GnnWeights {
    /// Randomly initialised weights (for tests and as a training start).
    pub fn random(config: GnnConfig, stats: FeatureStats, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let h = config.hidden;
        let task = config.task;
        let hg = if task.global_dim() > 0 { h } else { 0 };
        let node_encoder = Mlp::random(task.node_dim(), h, h, &mut rng);
        let edge_encoder = Mlp::random(EDGE_DIM, h, h, &mut rng);
        let global_encoder =
            (task.global_dim() > 0).then(|| Mlp::random(task.global_dim(), h, h, &mut rng));
        // Residual branches start small (their last layer scaled by 0.1),
        // so the stack begins close to the identity and the initial outputs
        // stay O(1) however many layers there are.
        let small = |mut mlp: Mlp| {
            mlp.layers[2].weight.iter_mut().for_each(|w| *w *= 0.1);
            mlp.layers[2].bias.iter_mut().for_each(|b| *b = 0.0);
            mlp
        };
        let blocks = (0..config.layers)
            .map(|_| Block {
                edge: small(Mlp::random(hg + 3 * h, h, h, &mut rng)),
                node: small(Mlp::random(hg + 2 * h, h, h, &mut rng)),
            })
            .collect();
        let vector_head = Mlp::random(h, h, 3, &mut rng);
        let affordance_head = (task == Task::Policy).then(|| Mlp::random(h, h, 1, &mut rng));
        Self {
            config,
            stats,
            output_mean: [0.0; 3],
            output_std: [1.0; 3],
            node_encoder,
            edge_encoder,
            global_encoder,
            blocks,
            vector_head,
            affordance_head,
        }
    }
}

impl GnnWeights {
    /// FLOPs of one forward pass on one graph of `n` nodes, counted from the
    /// layer shapes as the matrix products the training module and the
    /// exported graph run: the first layer of every block MLP is split by
    /// input (W_g g + W_i n_i + W_j n_j + W_e e_ij), so only the edge term
    /// runs on all N² pairs, the node terms on N rows and the global term
    /// once; layers 2 and 3 of the edge MLPs run on the N² pairs. A training
    /// step (forward and backward) costs about three times this.
    pub fn flops_per_graph(&self, n: usize) -> f64 {
        let (n, e) = (n as f64, (n * n) as f64);
        let global = self
            .global_encoder
            .as_ref()
            .map_or(0, |m| m.layers[2].outputs) as f64;
        let mut flops =
            n * self.node_encoder.flops_per_row() + e * self.edge_encoder.flops_per_row();
        flops += self.global_encoder.as_ref().map_or(0.0, Mlp::flops_per_row);
        for block in &self.blocks {
            // Edge MLP: [g, n_i, n_j, e_ij] in; node MLP: [g, n_i, Σ e] in.
            let [first, second, third] = &block.edge.layers;
            let out = 2.0 * first.outputs as f64;
            let width = (first.inputs as f64 - global) / 3.0;
            flops += out * (global + 2.0 * n * width + e * width);
            flops += e * (second.flops_per_row() + third.flops_per_row());
            let [first, second, third] = &block.node.layers;
            let out = 2.0 * first.outputs as f64;
            flops += out * (global + n * (first.inputs as f64 - global));
            flops += n * (second.flops_per_row() + third.flops_per_row());
        }
        flops += n * self.vector_head.flops_per_row();
        flops
            + n * self
                .affordance_head
                .as_ref()
                .map_or(0.0, Mlp::flops_per_row)
    }
}

/// The reference forward pass.
pub fn forward(weights: &GnnWeights, batch: &Batch) -> ModelOutput {
    let task = weights.config.task;
    assert_eq!(batch.task, task, "batch and model tasks differ");
    let (b, n, h) = (batch.batch, batch.n, weights.config.hidden);
    let (nd, gd) = (task.node_dim(), task.global_dim());
    let input = gnn_input(
        batch,
        &weights.stats,
        weights.config.edge_attributes,
        weights.config.connectivity,
    );
    let (nodes, edges, global) = (&input.nodes, &input.edges, &input.global);
    let mut hn = vec![0.0f32; b * n * h];
    let mut he = vec![0.0f32; b * n * n * h];
    let mut hg = vec![0.0f32; b * h];
    for g in 0..b {
        for j in 0..n {
            let x = &nodes[(g * n + j) * nd..(g * n + j + 1) * nd];
            hn[(g * n + j) * h..(g * n + j + 1) * h]
                .copy_from_slice(&weights.node_encoder.apply(x));
            for i in 0..n {
                let k = (g * n + i) * n + j;
                let x = &edges[k * EDGE_DIM..(k + 1) * EDGE_DIM];
                he[k * h..(k + 1) * h].copy_from_slice(&weights.edge_encoder.apply(x));
            }
        }
        if let Some(enc) = &weights.global_encoder {
            hg[g * h..(g + 1) * h].copy_from_slice(&enc.apply(&global[g * gd..(g + 1) * gd]));
        }
    }
    let use_global = weights.global_encoder.is_some();
    for block in &weights.blocks {
        let mut new_e = vec![0.0f32; b * n * n * h];
        let mut agg = vec![0.0f32; b * n * h];
        for g in 0..b {
            for i in 0..n {
                for j in 0..n {
                    let k = (g * n + i) * n + j;
                    let mut x = Vec::with_capacity(4 * h);
                    if use_global {
                        x.extend_from_slice(&hg[g * h..(g + 1) * h]);
                    }
                    x.extend_from_slice(&hn[(g * n + i) * h..(g * n + i + 1) * h]);
                    x.extend_from_slice(&hn[(g * n + j) * h..(g * n + j + 1) * h]);
                    x.extend_from_slice(&he[k * h..(k + 1) * h]);
                    let e = block.edge.apply(&x);
                    if input.edge_mask[k] > 0.0 {
                        for c in 0..h {
                            agg[(g * n + j) * h + c] += e[c];
                        }
                    }
                    new_e[k * h..(k + 1) * h].copy_from_slice(&e);
                }
            }
        }
        let mut new_n = vec![0.0f32; b * n * h];
        for g in 0..b {
            for j in 0..n {
                let mut x = Vec::with_capacity(3 * h);
                if use_global {
                    x.extend_from_slice(&hg[g * h..(g + 1) * h]);
                }
                x.extend_from_slice(&hn[(g * n + j) * h..(g * n + j + 1) * h]);
                x.extend_from_slice(&agg[(g * n + j) * h..(g * n + j + 1) * h]);
                new_n[(g * n + j) * h..(g * n + j + 1) * h].copy_from_slice(&block.node.apply(&x));
            }
        }
        hn.iter_mut().zip(&new_n).for_each(|(a, d)| *a += d);
        he.iter_mut().zip(&new_e).for_each(|(a, d)| *a += d);
    }
    let mut vectors = vec![0.0f32; b * n * 3];
    let mut logits = vec![0.0f32; b * n];
    for g in 0..b {
        for j in 0..n {
            let x = &hn[(g * n + j) * h..(g * n + j + 1) * h];
            let y = weights.vector_head.apply(x);
            for c in 0..3 {
                vectors[(g * n + j) * 3 + c] =
                    (y[c] as f64 * weights.output_std[c] + weights.output_mean[c]) as f32;
            }
            if let Some(head) = &weights.affordance_head {
                logits[g * n + j] = head.apply(x)[0];
            }
        }
    }
    let affordance = weights
        .affordance_head
        .as_ref()
        .map(|_| masked_softmax(&logits, &batch.mask, b, n));
    ModelOutput {
        vectors,
        affordance,
    }
}

/// Softmax of B × N logits over each graph's real nodes; padded nodes get 0.
pub fn masked_softmax(logits: &[f32], mask: &[f32], b: usize, n: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; b * n];
    for g in 0..b {
        let real: Vec<usize> = (0..n).filter(|&j| mask[g * n + j] > 0.0).collect();
        let max = real
            .iter()
            .map(|&j| logits[g * n + j])
            .fold(f32::NEG_INFINITY, f32::max);
        let sum: f32 = real.iter().map(|&j| (logits[g * n + j] - max).exp()).sum();
        for &j in &real {
            out[g * n + j] = (logits[g * n + j] - max).exp() / sum;
        }
    }
    out
}
