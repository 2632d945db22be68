//! What the networks actually see: a [`Batch`] normalised with the model's
//! statistics, with dropped edge attributes zeroed and the masks that say
//! which nodes and node pairs are real. Written once and used by the
//! reference forward passes and by training; the ONNX graphs compute the
//! same thing from raw inputs (the parity tests hold them together).

use crate::graph::{Batch, EDGE_DIM, FeatureStats};

use super::gnn::{Connectivity, EdgeAttributes};

/// Normalised dense inputs of one batch (f32, row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct GnnInput {
    pub batch: usize,
    pub n: usize,
    /// B × N × node_dim.
    pub nodes: Vec<f32>,
    /// B × N × N × EDGE_DIM, dropped columns zero.
    pub edges: Vec<f32>,
    /// B × global_dim.
    pub global: Vec<f32>,
    /// B × N × N: 1 where i → j carries a message (real i ≠ j, and a branch
    /// under [`Connectivity::Branches`]).
    pub edge_mask: Vec<f32>,
    /// B × N: 1 for real nodes.
    pub node_mask: Vec<f32>,
}

/// (x − mean) / std, the statistics cycling with the feature index.
pub fn normalise(values: &[f32], mean: &[f64], std: &[f64]) -> Vec<f32> {
    if mean.is_empty() {
        return values.to_vec();
    }
    values
        .iter()
        .enumerate()
        .map(|(k, v)| ((*v as f64 - mean[k % mean.len()]) / std[k % std.len()]) as f32)
        .collect()
}

pub fn gnn_input(
    batch: &Batch,
    stats: &FeatureStats,
    attributes: EdgeAttributes,
    connectivity: Connectivity,
) -> GnnInput {
    let (b, n) = (batch.batch, batch.n);
    let columns = attributes.column_mask();
    let mut edges = normalise(&batch.edges, &stats.edge_mean, &stats.edge_std);
    for (k, v) in edges.iter_mut().enumerate() {
        *v *= columns[k % EDGE_DIM];
    }
    let mut edge_mask = vec![0.0f32; b * n * n];
    for g in 0..b {
        for i in 0..n {
            for j in 0..n {
                let k = (g * n + i) * n + j;
                let real = i != j && batch.mask[g * n + i] > 0.0 && batch.mask[g * n + j] > 0.0;
                let branch = batch.edges[k * EDGE_DIM + 4] > 0.0;
                let linked = match connectivity {
                    Connectivity::Full => true,
                    Connectivity::Branches => branch,
                };
                if real && linked {
                    edge_mask[k] = 1.0;
                }
            }
        }
    }
    GnnInput {
        batch: b,
        n,
        nodes: normalise(&batch.nodes, &stats.node_mean, &stats.node_std),
        edges,
        global: normalise(&batch.global, &stats.global_mean, &stats.global_std),
        edge_mask,
        node_mask: batch.mask.clone(),
    }
}
