//! What the networks actually see: a [`Batch`] normalised with the model's
//! statistics, with dropped edge attributes zeroed and the masks that say
//! which nodes and node pairs are real. Written once and used by the
//! reference forward passes and by training; the ONNX graphs compute the
//! same thing from raw inputs (the parity tests hold them together).

use serde::{Deserialize, Serialize};

use crate::graph::{BRANCH_COLUMN, Batch, EDGE_DIM, FeatureStats};

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
                let branch = batch.edges[k * EDGE_DIM + BRANCH_COLUMN] > 0.5;
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

/// The edge-attribute groups of e_ij = [Δp, v, b, κ]: `delta_p` is Δp,
/// `orientation` the topology (v and the branch flag b), `stiffness` κ
/// (the paper's K_s, in layout 2 as a log ratio). A dropped group is
/// zeroed after normalisation, which is the same as the encoder never
/// seeing it; the input layout stays the same for every model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct EdgeAttributes {
    pub delta_p: bool,
    pub orientation: bool,
    pub stiffness: bool,
}

impl Default for EdgeAttributes {
    fn default() -> Self {
        Self {
            delta_p: true,
            orientation: true,
            stiffness: true,
        }
    }
}

impl EdgeAttributes {
    /// Multiplier per edge column (1 kept, 0 dropped).
    pub fn column_mask(&self) -> [f32; EDGE_DIM] {
        let f = |b: bool| if b { 1.0 } else { 0.0 };
        let d = f(self.delta_p);
        let v = f(self.orientation);
        [d, d, d, v, v, f(self.stiffness)]
    }

    /// "dp+v+ks", "v+ks", "none", ...
    pub fn label(&self) -> String {
        let parts = self.names(false);
        if parts.is_empty() {
            "none".to_owned()
        } else {
            parts.join("+")
        }
    }

    /// The attributes used, in edge-vector order: as `--edge-attributes`
    /// spells them (`dp`, `v`, `ks`) or, with `display`, as the paper does
    /// (`Δp`, `v`, `K_s`).
    pub fn names(&self, display: bool) -> Vec<&'static str> {
        [
            (self.delta_p, "dp", "Δp"),
            (self.orientation, "v", "v"),
            (self.stiffness, "ks", "K_s"),
        ]
        .iter()
        .filter(|(on, _, _)| *on)
        .map(|&(_, code, shown)| if display { shown } else { code })
        .collect()
    }
}

impl std::str::FromStr for EdgeAttributes {
    type Err = String;

    /// Parses `label()` output: "dp+v+ks", "dp+ks", "none", ...
    fn from_str(s: &str) -> Result<Self, String> {
        let mut out = Self {
            delta_p: false,
            orientation: false,
            stiffness: false,
        };
        if s == "none" {
            return Ok(out);
        }
        for part in s.split('+') {
            match part.trim() {
                "dp" => out.delta_p = true,
                "v" => out.orientation = true,
                "ks" => out.stiffness = true,
                other => {
                    return Err(format!(
                        "unknown edge attribute {other:?} (expected dp, v, ks joined by +, or none)"
                    ));
                }
            }
        }
        Ok(out)
    }
}

/// Message passing over every ordered node pair (the paper) or only over
/// the tree's branches, in both directions (the ablation's "partial").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Connectivity {
    #[default]
    Full,
    Branches,
}
