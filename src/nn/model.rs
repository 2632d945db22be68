//! One type for "a trained model, whatever its architecture": what
//! checkpoints store, what export writes and what evaluation compares.

use serde::{Deserialize, Serialize};

use super::gnn::{self, GnnWeights};
use super::onnx;
use super::pointnet::{self, PointNetWeights};
use crate::graph::contract::ModelOutput;
use crate::graph::path::Encoding;
use crate::graph::{Batch, Task};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Arch {
    Gnn,
    PointNet,
}

impl Arch {
    pub fn name(self) -> &'static str {
        match self {
            Arch::Gnn => "gnn",
            Arch::PointNet => "pointnet",
        }
    }
}

impl std::str::FromStr for Arch {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "gnn" => Ok(Arch::Gnn),
            "pointnet" => Ok(Arch::PointNet),
            other => Err(format!("unknown architecture {other:?} (gnn or pointnet)")),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "arch", rename_all = "lowercase")]
#[allow(clippy::large_enum_variant)] // a handful exist at a time; boxing buys nothing
pub enum ModelWeights {
    Gnn(GnnWeights),
    PointNet(PointNetWeights),
}

impl ModelWeights {
    pub fn task(&self) -> Task {
        match self {
            ModelWeights::Gnn(w) => w.config.task,
            ModelWeights::PointNet(w) => w.config.task,
        }
    }

    pub fn arch(&self) -> Arch {
        match self {
            ModelWeights::Gnn(_) => Arch::Gnn,
            ModelWeights::PointNet(_) => Arch::PointNet,
        }
    }

    /// What graph the model reads.
    pub fn encoding(&self) -> Encoding {
        match self {
            ModelWeights::Gnn(w) => w.config.encoding,
            ModelWeights::PointNet(_) => Encoding::Full,
        }
    }

    /// `forward_gnn`, `policy_pointnet`, `forward_path` (a GNN on the
    /// push's path), ...: the file stem in `models/`.
    pub fn stem(&self) -> String {
        match self.encoding() {
            Encoding::Full => format!("{}_{}", self.task().name(), self.arch().name()),
            Encoding::Path | Encoding::PathRotation => format!("{}_path", self.task().name()),
        }
    }

    /// The reference forward pass.
    pub fn forward(&self, batch: &Batch) -> ModelOutput {
        match self {
            ModelWeights::Gnn(w) => gnn::forward(w, batch),
            ModelWeights::PointNet(w) => pointnet::forward(w, batch),
        }
    }

    pub fn to_onnx(&self, metadata: &[(String, String)]) -> Vec<u8> {
        match self {
            ModelWeights::Gnn(w) => onnx::export(w, metadata),
            ModelWeights::PointNet(w) => onnx::export_pointnet(w, metadata),
        }
    }

    pub fn output_scale(&self) -> ([f64; 3], [f64; 3]) {
        match self {
            ModelWeights::Gnn(w) => (w.output_mean, w.output_std),
            ModelWeights::PointNet(w) => (w.output_mean, w.output_std),
        }
    }

    pub fn set_output_scale(&mut self, mean: [f64; 3], std: [f64; 3]) {
        match self {
            ModelWeights::Gnn(w) => (w.output_mean, w.output_std) = (mean, std),
            ModelWeights::PointNet(w) => (w.output_mean, w.output_std) = (mean, std),
        }
    }

    /// A one-line description for logs and metadata.
    pub fn describe(&self) -> String {
        match self {
            ModelWeights::Gnn(w) => format!(
                "gnn{}: {} graph2graph layers, hidden {}, edge attributes {}, {:?} connectivity",
                match w.config.encoding {
                    Encoding::Full => "",
                    Encoding::Path => " on the push's path and its side branches (Δp out)",
                    Encoding::PathRotation => {
                        " on the push's path and its side branches (branch turns out)"
                    }
                },
                w.config.layers,
                w.config.hidden,
                w.config.edge_attributes.label(),
                w.config.connectivity
            )
            .to_lowercase(),
            ModelWeights::PointNet(w) => format!(
                "pointnet: local {}, global {}, trunk {:?}",
                w.config.local,
                w.config.global,
                pointnet::TRUNK
            ),
        }
    }
}
