//! A batch as the burn networks take it, on a device: normalised by the
//! model's statistics ([`crate::nn::input`]) and, for the GNN, with the
//! edges either dense or as a list of the pairs that carry messages.

use burn::tensor::{Device, Int, Tensor, TensorData};

use super::modules::{DeviceInput, Edges};
use crate::graph::{Batch, EDGE_DIM};
use crate::nn::gnn::Connectivity;
use crate::nn::input::{GnnInput, gnn_input};
use crate::nn::model::ModelWeights;
use crate::nn::pointnet::point_input;

/// How a GNN's edges are laid out for training.
///
/// Both compute the same function (a test holds them together); they
/// differ in cost. Dense runs every edge MLP on all N × N pairs and masks
/// the messages that do not count, which suits full connectivity (every
/// pair counts) and keeps the matrix products large. Under branch
/// connectivity only the 2 (N − 1) parent–child pairs carry messages, so
/// a list of them is 5–8× cheaper per layer at the trained sizes; that is
/// what makes the 10-, 15- and 20-layer branch ablations affordable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeLayout {
    Dense,
    List,
}

impl EdgeLayout {
    /// The cheaper layout for `connectivity`.
    pub fn preferred(connectivity: Connectivity) -> Self {
        match connectivity {
            Connectivity::Full => EdgeLayout::Dense,
            Connectivity::Branches => EdgeLayout::List,
        }
    }

    /// The cheaper layout for `weights` (dense for models without edges).
    pub fn of(weights: &ModelWeights) -> Self {
        match weights {
            ModelWeights::Gnn(w) => Self::preferred(w.config.connectivity),
            ModelWeights::PointNet(_) => EdgeLayout::Dense,
        }
    }
}

pub(super) fn tensor<const D: usize>(
    values: Vec<f32>,
    shape: [usize; D],
    device: &Device,
) -> Tensor<D> {
    Tensor::from_data(TensorData::new(values, shape), device)
}

fn indices(values: Vec<i64>, device: &Device) -> Tensor<1, Int> {
    let len = values.len();
    Tensor::from_data(TensorData::new(values, [len]), device)
}

/// The model-side inputs of a batch, on `device`, with the edges laid out
/// as `layout` says (a batch without any message-carrying pair stays
/// dense).
pub fn device_input(
    weights: &ModelWeights,
    batch: &Batch,
    layout: EdgeLayout,
    device: &Device,
) -> DeviceInput {
    let (b, n) = (batch.batch, batch.n);
    let node_mask = tensor(batch.mask.clone(), [b, n], device);
    match weights {
        ModelWeights::Gnn(w) => {
            let task = w.config.task;
            let mut input = gnn_input(
                batch,
                &w.stats,
                w.config.edge_attributes,
                w.config.connectivity,
            );
            let list = match layout {
                EdgeLayout::List => edge_list(&input, device),
                EdgeLayout::Dense => None,
            };
            let edges = list.unwrap_or_else(|| Edges::Dense {
                attributes: tensor(
                    std::mem::take(&mut input.edges),
                    [b, n, n, EDGE_DIM],
                    device,
                ),
                mask: tensor(std::mem::take(&mut input.edge_mask), [b, n, n, 1], device),
            });
            DeviceInput {
                nodes: tensor(input.nodes, [b, n, task.node_dim()], device),
                edges: Some(edges),
                global: (task.global_dim() > 0)
                    .then(|| tensor(input.global, [b, task.global_dim()], device)),
                node_mask,
            }
        }
        ModelWeights::PointNet(w) => DeviceInput {
            nodes: tensor(point_input(w, batch), [b, n, w.config.point_dim()], device),
            edges: None,
            global: None,
            node_mask,
        },
    }
}

/// The message-carrying pairs i → j of every graph, in batch order, with
/// node indices flattened over the batch (g · N + i); `None` when there
/// are none.
fn edge_list(input: &GnnInput, device: &Device) -> Option<Edges> {
    let n = input.n;
    let (mut attributes, mut sender, mut receiver, mut graph) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (k, _) in input
        .edge_mask
        .iter()
        .enumerate()
        .filter(|(_, m)| **m > 0.0)
    {
        let (g, i, j) = (k / (n * n), (k / n) % n, k % n);
        attributes.extend_from_slice(&input.edges[k * EDGE_DIM..(k + 1) * EDGE_DIM]);
        sender.push((g * n + i) as i64);
        receiver.push((g * n + j) as i64);
        graph.push(g as i64);
    }
    let pairs = sender.len();
    (pairs > 0).then(|| Edges::List {
        attributes: tensor(attributes, [pairs, EDGE_DIM], device),
        sender: indices(sender, device),
        receiver: indices(receiver, device),
        graph: indices(graph, device),
    })
}
