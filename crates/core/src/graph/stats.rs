//! Per-feature normalisation statistics, computed once from the training
//! split and stored with a model (in its metadata and, as constants, inside
//! its ONNX graph), so that clients send raw SI values.
//!
//! Means and standard deviations are taken over real entries only: nodes of
//! the graphs (no padding) and edges i → j with i ≠ j. A feature whose
//! spread is below `MIN_STD` (say, constant in the data) is left unscaled.

use serde::{Deserialize, Serialize};

use super::{EDGE_DIM, GraphInput, Task};

/// Standard deviations below this are treated as 1 (no scaling).
pub const MIN_STD: f64 = 1e-8;

/// Mean and standard deviation of each feature of each attribute kind.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FeatureStats {
    pub task: Task,
    pub node_mean: Vec<f64>,
    pub node_std: Vec<f64>,
    pub edge_mean: Vec<f64>,
    pub edge_std: Vec<f64>,
    pub global_mean: Vec<f64>,
    pub global_std: Vec<f64>,
    /// Graphs the statistics were computed from.
    pub graphs: usize,
}

/// Welford's running mean and variance, per feature.
#[derive(Debug, Clone)]
pub struct Running {
    count: f64,
    mean: Vec<f64>,
    m2: Vec<f64>,
}

impl Running {
    pub fn new(dim: usize) -> Self {
        Self {
            count: 0.0,
            mean: vec![0.0; dim],
            m2: vec![0.0; dim],
        }
    }

    pub fn push(&mut self, values: &[f32]) {
        self.count += 1.0;
        for (k, &v) in values.iter().enumerate() {
            let v = v as f64;
            let delta = v - self.mean[k];
            self.mean[k] += delta / self.count;
            self.m2[k] += delta * (v - self.mean[k]);
        }
    }

    /// (mean, std), with spreads below [`MIN_STD`] replaced by 1.
    pub fn finish(&self) -> (Vec<f64>, Vec<f64>) {
        let std = self
            .m2
            .iter()
            .map(|m2| {
                let s = if self.count > 1.0 {
                    (m2 / self.count).sqrt()
                } else {
                    0.0
                };
                if s < MIN_STD { 1.0 } else { s }
            })
            .collect();
        (self.mean.clone(), std)
    }
}

/// Accumulates statistics graph by graph.
#[derive(Debug, Clone)]
pub struct StatsBuilder {
    task: Task,
    nodes: Running,
    edges: Running,
    global: Running,
    graphs: usize,
}

impl StatsBuilder {
    pub fn new(task: Task) -> Self {
        Self {
            task,
            nodes: Running::new(task.node_dim()),
            edges: Running::new(EDGE_DIM),
            global: Running::new(task.global_dim()),
            graphs: 0,
        }
    }

    /// Adds one graph; graphs of another task are ignored with a panic in
    /// debug builds (a programming error).
    pub fn add(&mut self, graph: &GraphInput) {
        debug_assert_eq!(graph.task, self.task);
        for j in 0..graph.n {
            self.nodes.push(graph.node(j));
            for i in 0..graph.n {
                if i != j {
                    self.edges.push(graph.edge(i, j));
                }
            }
        }
        if !graph.global.is_empty() {
            self.global.push(&graph.global);
        }
        self.graphs += 1;
    }

    pub fn finish(&self) -> FeatureStats {
        let (node_mean, node_std) = self.nodes.finish();
        let (edge_mean, edge_std) = self.edges.finish();
        let (global_mean, global_std) = self.global.finish();
        FeatureStats {
            task: self.task,
            node_mean,
            node_std,
            edge_mean,
            edge_std,
            global_mean,
            global_std,
            graphs: self.graphs,
        }
    }
}
