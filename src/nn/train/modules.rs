//! The trainable burn counterparts of [`GnnWeights`] and
//! [`PointNetWeights`], built from and written back to the plain weights.
//!
//! Node embeddings are [B, N, H]; edge embeddings are dense, [B, N, N, H]
//! (entry i, j is the edge i → j), or, for branch-only models, a list
//! [E, H] of the pairs that carry messages ([`Edges`]). As in the exported
//! graph, the first layer of every edge MLP is split by input, W_g g +
//! W_i n_i + W_j n_j + W_e e_ij, so the node terms are computed once per
//! node and broadcast (dense) or gathered (list) onto the edges (1.5–1.7×
//! faster training than concatenating).

use burn::module::{Module, Param};
use burn::nn::Linear as BurnLinear;
use burn::tensor::activation::relu;
use burn::tensor::{Device, IndexingUpdateOp, Int, Tensor, TensorData};

use crate::nn::gnn::{Block, GnnWeights, Linear, Mlp};
use crate::nn::pointnet::PointNetWeights;

/// Our row-major out × in weights as a burn layer ([in, out] weight).
fn to_burn(layer: &Linear, device: &Device) -> BurnLinear {
    let (i, o) = (layer.inputs, layer.outputs);
    let mut transposed = vec![0.0f32; i * o];
    for r in 0..o {
        for c in 0..i {
            transposed[c * o + r] = layer.weight[r * i + c];
        }
    }
    BurnLinear {
        weight: Param::from_data(TensorData::new(transposed, [i, o]), device),
        bias: Some(Param::from_data(
            TensorData::new(layer.bias.clone(), [o]),
            device,
        )),
    }
}

/// A tensor's values, row-major.
pub fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .as_slice::<f32>()
        .expect("f32 tensor")
        .to_vec()
}

fn from_burn(layer: &BurnLinear) -> Linear {
    let [i, o] = layer.weight.dims();
    let w = values(layer.weight.val());
    let mut weight = vec![0.0f32; i * o];
    for r in 0..o {
        for c in 0..i {
            weight[r * i + c] = w[c * o + r];
        }
    }
    let bias = layer
        .bias
        .as_ref()
        .map(|b| values(b.val()))
        .unwrap_or_else(|| vec![0.0; o]);
    Linear {
        inputs: i,
        outputs: o,
        weight,
        bias,
    }
}

/// Linear → ReLU → Linear → ReLU → Linear.
#[derive(Module, Debug)]
pub struct TrainMlp {
    first: BurnLinear,
    second: BurnLinear,
    third: BurnLinear,
}

impl TrainMlp {
    pub(crate) fn new(mlp: &Mlp, device: &Device) -> Self {
        Self {
            first: to_burn(&mlp.layers[0], device),
            second: to_burn(&mlp.layers[1], device),
            third: to_burn(&mlp.layers[2], device),
        }
    }

    pub(crate) fn weights(&self) -> Mlp {
        Mlp {
            layers: [
                from_burn(&self.first),
                from_burn(&self.second),
                from_burn(&self.third),
            ],
        }
    }

    pub(crate) fn forward<const D: usize>(&self, x: Tensor<D>) -> Tensor<D> {
        self.tail(apply(&self.first, x))
    }

    /// Layers 2 and 3 after the caller's layer-1 pre-activation.
    fn tail<const D: usize>(&self, pre: Tensor<D>) -> Tensor<D> {
        let a = relu(pre);
        let b = relu(apply(&self.second, a));
        apply(&self.third, b)
    }

    /// x · W₁ restricted to the input columns `from..to`, no bias.
    fn first_part<const D: usize>(&self, x: Tensor<D>, from: usize, to: usize) -> Tensor<D> {
        part(&self.first, x, from, to)
    }

    fn first_bias<const D: usize>(&self, pre: Tensor<D>) -> Tensor<D> {
        add_bias(&self.first, pre)
    }
}

fn part<const D: usize>(layer: &BurnLinear, x: Tensor<D>, from: usize, to: usize) -> Tensor<D> {
    let w = layer.weight.val();
    let [_, o] = w.dims();
    rows_matmul(x, w.slice([from..to, 0..o]))
}

/// x [..., d_in] · w [d_in, d_out], with every leading axis folded into
/// the rows of one 2-D matrix product (several times faster on Flex than
/// a broadcast batched product).
fn rows_matmul<const D: usize>(x: Tensor<D>, w: Tensor<2>) -> Tensor<D> {
    let dims = x.dims();
    let [d_in, d_out] = w.dims();
    let rows = dims[..D - 1].iter().product::<usize>();
    let mut out = dims;
    out[D - 1] = d_out;
    x.reshape([rows, d_in]).matmul(w).reshape(out)
}

/// A burn linear layer applied with [`rows_matmul`].
fn apply<const D: usize>(layer: &BurnLinear, x: Tensor<D>) -> Tensor<D> {
    add_bias(layer, rows_matmul(x, layer.weight.val()))
}

fn add_bias<const D: usize>(layer: &BurnLinear, pre: Tensor<D>) -> Tensor<D> {
    match &layer.bias {
        Some(b) => {
            let [o] = b.dims();
            let mut shape = [1usize; D];
            shape[D - 1] = o;
            pre + b.val().reshape(shape)
        }
        None => pre,
    }
}

#[derive(Module, Debug)]
pub struct TrainBlock {
    edge: TrainMlp,
    node: TrainMlp,
}

/// Network outputs in normalised units: vectors [B, N, 3], logits [B, N].
pub struct Outputs {
    pub vectors: Tensor<3>,
    pub logits: Option<Tensor<2>>,
}

/// Model-side inputs on the device (see [`crate::nn::input`]).
pub struct DeviceInput {
    /// [B, N, d]: GNN node attributes, or PointNet point features.
    pub nodes: Tensor<3>,
    /// GNN only.
    pub edges: Option<Edges>,
    /// [B, 3] (GNN forward model only).
    pub global: Option<Tensor<2>>,
    /// [B, N].
    pub node_mask: Tensor<2>,
}

/// A GNN's edges on the device (see [`super::EdgeLayout`]).
#[allow(clippy::large_enum_variant)] // one per batch, built once: boxing buys nothing
pub enum Edges {
    /// Every pair: attributes [B, N, N, 5] and a mask [B, N, N, 1] that is
    /// 1 where i → j carries a message.
    Dense {
        attributes: Tensor<4>,
        mask: Tensor<4>,
    },
    /// Only the E pairs that carry messages, over the whole batch:
    /// attributes [E, 5], sender and receiver as flat node indices
    /// (g · N + i) and the graph g of each pair.
    List {
        attributes: Tensor<2>,
        sender: Tensor<1, Int>,
        receiver: Tensor<1, Int>,
        graph: Tensor<1, Int>,
    },
}

#[derive(Module, Debug)]
pub struct TrainGnn {
    node_encoder: TrainMlp,
    edge_encoder: TrainMlp,
    global_encoder: Option<TrainMlp>,
    blocks: Vec<TrainBlock>,
    vector_head: TrainMlp,
    affordance_head: Option<TrainMlp>,
}

impl TrainGnn {
    pub fn new(w: &GnnWeights, device: &Device) -> Self {
        Self {
            node_encoder: TrainMlp::new(&w.node_encoder, device),
            edge_encoder: TrainMlp::new(&w.edge_encoder, device),
            global_encoder: w.global_encoder.as_ref().map(|m| TrainMlp::new(m, device)),
            blocks: w
                .blocks
                .iter()
                .map(|b| TrainBlock {
                    edge: TrainMlp::new(&b.edge, device),
                    node: TrainMlp::new(&b.node, device),
                })
                .collect(),
            vector_head: TrainMlp::new(&w.vector_head, device),
            affordance_head: w.affordance_head.as_ref().map(|m| TrainMlp::new(m, device)),
        }
    }

    /// The trained parameters written into `template` (which supplies the
    /// configuration and statistics).
    pub fn to_weights(&self, template: &GnnWeights) -> GnnWeights {
        GnnWeights {
            node_encoder: self.node_encoder.weights(),
            edge_encoder: self.edge_encoder.weights(),
            global_encoder: self.global_encoder.as_ref().map(TrainMlp::weights),
            blocks: self
                .blocks
                .iter()
                .map(|b| Block {
                    edge: b.edge.weights(),
                    node: b.node.weights(),
                })
                .collect(),
            vector_head: self.vector_head.weights(),
            affordance_head: self.affordance_head.as_ref().map(TrainMlp::weights),
            ..template.clone()
        }
    }

    pub fn forward(&self, input: &DeviceInput) -> Outputs {
        let [b, n, _] = input.nodes.dims();
        let hn = self.node_encoder.forward(input.nodes.clone());
        let hg = match (&self.global_encoder, &input.global) {
            (Some(enc), Some(g)) => Some(enc.forward(g.clone())),
            _ => None,
        };
        let hn = match input.edges.as_ref().expect("GNN input has edges") {
            Edges::Dense { attributes, mask } => self.pass_dense(hn, hg.as_ref(), attributes, mask),
            Edges::List {
                attributes,
                sender,
                receiver,
                graph,
            } => self.pass_list(hn, hg.as_ref(), attributes, [sender, receiver, graph]),
        };
        Outputs {
            vectors: self.vector_head.forward(hn.clone()),
            logits: self
                .affordance_head
                .as_ref()
                .map(|head| head.forward(hn).reshape([b, n])),
        }
    }

    /// The graph2graph blocks on dense edges: node embeddings after them.
    fn pass_dense(
        &self,
        mut hn: Tensor<3>,
        hg: Option<&Tensor<2>>,
        attributes: &Tensor<4>,
        mask: &Tensor<4>,
    ) -> Tensor<3> {
        let [b, n, h] = hn.dims();
        let g0 = if hg.is_some() { h } else { 0 };
        let mut he = self.edge_encoder.forward(attributes.clone());
        for block in &self.blocks {
            let sender = block
                .edge
                .first_part(hn.clone(), g0, g0 + h)
                .unsqueeze_dim::<4>(2);
            let receiver = block
                .edge
                .first_part(hn.clone(), g0 + h, g0 + 2 * h)
                .unsqueeze_dim::<4>(1);
            let mut pre = block.edge.first_part(he.clone(), g0 + 2 * h, g0 + 3 * h);
            pre = pre + sender + receiver;
            if let Some(hg) = hg {
                pre = pre
                    + block
                        .edge
                        .first_part(hg.clone(), 0, h)
                        .reshape([b, 1, 1, h]);
            }
            let new_e = block.edge.tail(block.edge.first_bias(pre));
            let aggregated: Tensor<3> =
                (new_e.clone() * mask.clone()).sum_dim(1).reshape([b, n, h]);
            hn = hn.clone() + block.update_nodes(hn, aggregated, hg, g0);
            he = he + new_e;
        }
        hn
    }

    /// The graph2graph blocks on a list of edges `[sender, receiver,
    /// graph]`: node embeddings after them.
    fn pass_list(
        &self,
        mut hn: Tensor<3>,
        hg: Option<&Tensor<2>>,
        attributes: &Tensor<2>,
        [sender, receiver, graph]: [&Tensor<1, Int>; 3],
    ) -> Tensor<3> {
        let [b, n, h] = hn.dims();
        let g0 = if hg.is_some() { h } else { 0 };
        let mut he = self.edge_encoder.forward(attributes.clone());
        let device = hn.device();
        for block in &self.blocks {
            let flat = hn.clone().reshape([b * n, h]);
            let from = block.edge.first_part(flat.clone(), g0, g0 + h);
            let to = block.edge.first_part(flat, g0 + h, g0 + 2 * h);
            let mut pre = block.edge.first_part(he.clone(), g0 + 2 * h, g0 + 3 * h)
                + from.select(0, sender.clone())
                + to.select(0, receiver.clone());
            if let Some(hg) = hg {
                pre = pre
                    + block
                        .edge
                        .first_part(hg.clone(), 0, h)
                        .select(0, graph.clone());
            }
            let new_e = block.edge.tail(block.edge.first_bias(pre));
            let aggregated = Tensor::<2>::zeros([b * n, h], &device)
                .select_assign(0, receiver.clone(), new_e.clone(), IndexingUpdateOp::Add)
                .reshape([b, n, h]);
            hn = hn.clone() + block.update_nodes(hn, aggregated, hg, g0);
            he = he + new_e;
        }
        hn
    }
}

impl TrainBlock {
    /// The node MLP on [g, n_i, Σ_j e_ji]: the residual update of the nodes.
    fn update_nodes(
        &self,
        hn: Tensor<3>,
        aggregated: Tensor<3>,
        hg: Option<&Tensor<2>>,
        g0: usize,
    ) -> Tensor<3> {
        let [b, _, h] = hn.dims();
        let mut pre = self.node.first_part(hn, g0, g0 + h)
            + self.node.first_part(aggregated, g0 + h, g0 + 2 * h);
        if let Some(hg) = hg {
            pre = pre + self.node.first_part(hg.clone(), 0, h).reshape([b, 1, h]);
        }
        self.node.tail(self.node.first_bias(pre))
    }
}

#[derive(Module, Debug)]
pub struct TrainPointNet {
    local: Vec<BurnLinear>,
    feature: Vec<BurnLinear>,
    trunk: Vec<BurnLinear>,
    vector_head: BurnLinear,
    affordance_head: Option<BurnLinear>,
}

impl TrainPointNet {
    pub fn new(w: &PointNetWeights, device: &Device) -> Self {
        let layers = |ls: &[Linear]| ls.iter().map(|l| to_burn(l, device)).collect();
        Self {
            local: layers(&w.local),
            feature: layers(&w.feature),
            trunk: layers(&w.trunk),
            vector_head: to_burn(&w.vector_head, device),
            affordance_head: w.affordance_head.as_ref().map(|l| to_burn(l, device)),
        }
    }

    pub fn to_weights(&self, template: &PointNetWeights) -> PointNetWeights {
        let pair = |ls: &[BurnLinear]| [from_burn(&ls[0]), from_burn(&ls[1])];
        PointNetWeights {
            local: pair(&self.local),
            feature: pair(&self.feature),
            trunk: pair(&self.trunk),
            vector_head: from_burn(&self.vector_head),
            affordance_head: self.affordance_head.as_ref().map(from_burn),
            ..template.clone()
        }
    }

    /// `input.nodes` holds the normalised point features.
    pub fn forward(&self, input: &DeviceInput) -> Outputs {
        let [b, n, _] = input.nodes.dims();
        let local = relu(apply(&self.local[0], input.nodes.clone()));
        let local = relu(apply(&self.local[1], local));
        let f = relu(apply(&self.feature[0], local.clone()));
        let f = relu(apply(&self.feature[1], f));
        // ≥ 0 after the ReLU: zeroing padded points keeps the max over real ones.
        let f = f * input.node_mask.clone().unsqueeze_dim::<3>(2);
        let global = f.max_dim(1); // [B, 1, G]
        let l = local.dims()[2];
        let g = global.dims()[2];
        let pre = part(&self.trunk[0], local, 0, l) + part(&self.trunk[0], global, l, l + g);
        let t = relu(add_bias(&self.trunk[0], pre));
        let t = relu(apply(&self.trunk[1], t));
        Outputs {
            vectors: apply(&self.vector_head, t.clone()),
            logits: self
                .affordance_head
                .as_ref()
                .map(|head| apply(head, t).reshape([b, n])),
        }
    }
}
