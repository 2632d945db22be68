//! Writing a [`GnnWeights`] model as an ONNX graph (opset 17), with the
//! prost ONNX types tract ships (`tract_onnx::pb`).
//!
//! Inputs (f32, symbolic batch B and node count N): `nodes` [B, N, d_n],
//! `edges` [B, N, N, 5] (entry i, j is the edge i → j), `global` [B, 3]
//! (forward model only), `mask` [B, N]. Outputs: `displacement` [B, N, 3]
//! (forward) or `action` [B, N, 3] and `affordance` [B, N] (policy). Inputs
//! are raw SI values: normalisation and de-normalisation are in the graph.
//!
//! The first layer of f_e on concat(g, n_i, n_j, e_ij) is split by input,
//! W_g g + W_i n_i + W_j n_j + W_e e_ij, so the node terms are computed once
//! per node and broadcast over the N × N edges.

use crate::graph::contract;
use prost::Message;
use tract_onnx::pb::{
    self, AttributeProto, GraphProto, ModelProto, NodeProto, OperatorSetIdProto,
    StringStringEntryProto, TensorProto, TypeProto, ValueInfoProto,
};

use super::gnn::{Connectivity, GnnWeights, Linear, Mlp};
use super::pointnet::PointNetWeights;
use crate::graph::{BRANCH_COLUMN, EDGE_DIM, Task};

pub const OPSET: i64 = 17;

/// Builds a graph node by node, naming intermediate values uniquely.
#[derive(Default)]
struct Builder {
    nodes: Vec<NodeProto>,
    initializers: Vec<TensorProto>,
    counter: usize,
}

impl Builder {
    fn fresh(&mut self, hint: &str) -> String {
        self.counter += 1;
        format!("{hint}_{}", self.counter)
    }

    fn constant_f32(&mut self, hint: &str, dims: &[i64], data: Vec<f32>) -> String {
        let name = self.fresh(hint);
        self.initializers.push(TensorProto {
            name: name.clone(),
            dims: dims.to_vec(),
            data_type: pb::tensor_proto::DataType::Float as i32,
            float_data: data,
            ..Default::default()
        });
        name
    }

    fn constant_i64(&mut self, hint: &str, data: Vec<i64>) -> String {
        let name = self.fresh(hint);
        self.initializers.push(TensorProto {
            name: name.clone(),
            dims: vec![data.len() as i64],
            data_type: pb::tensor_proto::DataType::Int64 as i32,
            int64_data: data,
            ..Default::default()
        });
        name
    }

    fn op(&mut self, op_type: &str, inputs: &[&str], attributes: Vec<AttributeProto>) -> String {
        let output = self.fresh(&op_type.to_ascii_lowercase());
        self.op_named(op_type, inputs, attributes, &output);
        output
    }

    fn op_named(
        &mut self,
        op_type: &str,
        inputs: &[&str],
        attributes: Vec<AttributeProto>,
        output: &str,
    ) {
        self.nodes.push(NodeProto {
            input: inputs.iter().map(|s| s.to_string()).collect(),
            output: vec![output.to_owned()],
            name: format!("{op_type}_{}", self.nodes.len()),
            op_type: op_type.to_owned(),
            attribute: attributes,
            ..Default::default()
        });
    }

    fn unsqueeze(&mut self, x: &str, axes: &[i64]) -> String {
        let axes = self.constant_i64("axes", axes.to_vec());
        self.op("Unsqueeze", &[x, &axes], vec![])
    }

    /// x · Wᵀ (no bias) for the input columns `from..to` of `linear`.
    fn matmul_columns(&mut self, x: &str, linear: &Linear, from: usize, to: usize) -> String {
        let cols = to - from;
        let mut wt = vec![0.0f32; cols * linear.outputs];
        for o in 0..linear.outputs {
            for c in 0..cols {
                wt[c * linear.outputs + o] = linear.weight[o * linear.inputs + from + c];
            }
        }
        let w = self.constant_f32("w", &[cols as i64, linear.outputs as i64], wt);
        self.op("MatMul", &[x, &w], vec![])
    }

    fn bias(&mut self, x: &str, linear: &Linear) -> String {
        let b = self.constant_f32("b", &[linear.outputs as i64], linear.bias.clone());
        self.op("Add", &[x, &b], vec![])
    }

    fn linear(&mut self, x: &str, linear: &Linear) -> String {
        let y = self.matmul_columns(x, linear, 0, linear.inputs);
        self.bias(&y, linear)
    }

    /// Layers 2 and 3 of an MLP, after the caller computed layer 1's
    /// pre-activation.
    fn mlp_tail(&mut self, pre: &str, mlp: &Mlp) -> String {
        let a = self.op("Relu", &[pre], vec![]);
        let b = self.linear(&a, &mlp.layers[1]);
        let b = self.op("Relu", &[&b], vec![]);
        self.linear(&b, &mlp.layers[2])
    }

    fn mlp(&mut self, x: &str, mlp: &Mlp) -> String {
        let pre = self.linear(x, &mlp.layers[0]);
        self.mlp_tail(&pre, mlp)
    }

    fn normalise(&mut self, x: &str, mean: &[f64], std: &[f64]) -> String {
        let m = self.constant_f32(
            "mean",
            &[mean.len() as i64],
            mean.iter().map(|v| *v as f32).collect(),
        );
        let s = self.constant_f32(
            "std",
            &[std.len() as i64],
            std.iter().map(|v| *v as f32).collect(),
        );
        let centred = self.op("Sub", &[x, &m], vec![]);
        self.op("Div", &[&centred, &s], vec![])
    }
}

fn int_attribute(name: &str, value: i64) -> AttributeProto {
    AttributeProto {
        name: name.to_owned(),
        r#type: pb::attribute_proto::AttributeType::Int as i32,
        i: value,
        ..Default::default()
    }
}

fn ints_attribute(name: &str, values: &[i64]) -> AttributeProto {
    AttributeProto {
        name: name.to_owned(),
        r#type: pb::attribute_proto::AttributeType::Ints as i32,
        ints: values.to_vec(),
        ..Default::default()
    }
}

fn tensor_value(name: &str, dims: &[&str]) -> ValueInfoProto {
    use pb::tensor_shape_proto::{Dimension, dimension::Value};
    let dim = dims
        .iter()
        .map(|d| Dimension {
            value: Some(match d.parse::<i64>() {
                Ok(v) => Value::DimValue(v),
                Err(_) => Value::DimParam(d.to_string()),
            }),
            ..Default::default()
        })
        .collect();
    ValueInfoProto {
        name: name.to_owned(),
        r#type: Some(TypeProto {
            value: Some(pb::type_proto::Value::TensorType(pb::type_proto::Tensor {
                elem_type: pb::tensor_proto::DataType::Float as i32,
                shape: Some(pb::TensorShapeProto { dim }),
            })),
            ..Default::default()
        }),
        ..Default::default()
    }
}

/// The model as ONNX bytes, with `metadata` stored in `metadata_props`.
pub fn export(weights: &GnnWeights, metadata: &[(String, String)]) -> Vec<u8> {
    let task = weights.config.task;
    let s = &weights.stats;
    let h = weights.config.hidden;
    let mut g = Builder::default();
    let inputs = graph_inputs(task);

    // Edge mask m[b, i, j] = mask_i · mask_j · (i ≠ j), as [B, N, N, 1].
    let mask_i = g.unsqueeze(contract::MASK, &[2]);
    let mask_j = g.unsqueeze(contract::MASK, &[1]);
    let pair = g.op("Mul", &[&mask_i, &mask_j], vec![]);
    let zero = g.constant_i64("index", vec![0]);
    let first = g.op("Gather", &[&pair, &zero], vec![int_attribute("axis", 0)]); // [1, N, N]
    let square = g.op("Squeeze", &[&first, &zero], vec![]); // [N, N]
    let eye = g.op("EyeLike", &[&square], vec![]);
    let one = g.constant_f32("one", &[], vec![1.0]);
    let off_diagonal = g.op("Sub", &[&one, &eye], vec![]);
    let edge_mask = g.op("Mul", &[&pair, &off_diagonal], vec![]);
    let mut edge_mask = g.unsqueeze(&edge_mask, &[3]);
    if weights.config.connectivity == Connectivity::Branches {
        // Branch pairs are exactly those with b = 1.
        let from = g.constant_i64("starts", vec![BRANCH_COLUMN as i64]);
        let to = g.constant_i64("ends", vec![BRANCH_COLUMN as i64 + 1]);
        let axis = g.constant_i64("axes", vec![3]);
        let flag = g.op("Slice", &[contract::EDGES, &from, &to, &axis], vec![]);
        let half = g.constant_f32("half", &[], vec![0.5]);
        let branch = g.op("Greater", &[&flag, &half], vec![]);
        let branch = g.op(
            "Cast",
            &[&branch],
            vec![int_attribute(
                "to",
                pb::tensor_proto::DataType::Float as i64,
            )],
        );
        edge_mask = g.op("Mul", &[&edge_mask, &branch], vec![]);
    }

    let nodes = g.normalise(contract::NODES, &s.node_mean, &s.node_std);
    let mut edges = g.normalise(contract::EDGES, &s.edge_mean, &s.edge_std);
    let columns = weights.config.edge_attributes.column_mask();
    if columns.contains(&0.0) {
        let keep = g.constant_f32("columns", &[EDGE_DIM as i64], columns.to_vec());
        edges = g.op("Mul", &[&edges, &keep], vec![]);
    }
    let mut hn = g.mlp(&nodes, &weights.node_encoder);
    let mut he = g.mlp(&edges, &weights.edge_encoder);
    let hg = weights.global_encoder.as_ref().map(|enc| {
        let global = g.normalise(contract::GLOBAL, &s.global_mean, &s.global_std);
        g.mlp(&global, enc)
    });
    let hg_width = if hg.is_some() { h } else { 0 };
    for block in &weights.blocks {
        let first = &block.edge.layers[0];
        // W_i n_i over senders (axis 1), W_j n_j over receivers (axis 2).
        let sender = g.matmul_columns(&hn, first, hg_width, hg_width + h);
        let sender = g.unsqueeze(&sender, &[2]);
        let receiver = g.matmul_columns(&hn, first, hg_width + h, hg_width + 2 * h);
        let receiver = g.unsqueeze(&receiver, &[1]);
        let edge_term = g.matmul_columns(&he, first, hg_width + 2 * h, hg_width + 3 * h);
        let mut pre = g.op("Add", &[&edge_term, &sender], vec![]);
        pre = g.op("Add", &[&pre, &receiver], vec![]);
        if let Some(hg) = &hg {
            let global_term = g.matmul_columns(hg, first, 0, h);
            let global_term = g.unsqueeze(&global_term, &[1, 2]);
            pre = g.op("Add", &[&pre, &global_term], vec![]);
        }
        pre = g.bias(&pre, first);
        let new_e = g.mlp_tail(&pre, &block.edge);
        let masked = g.op("Mul", &[&new_e, &edge_mask], vec![]);
        let axis1 = g.constant_i64("axes", vec![1]);
        let aggregated = g.op(
            "ReduceSum",
            &[&masked, &axis1],
            vec![int_attribute("keepdims", 0)],
        );

        let node_first = &block.node.layers[0];
        let mut npre = g.matmul_columns(&hn, node_first, hg_width, hg_width + h);
        let agg_term = g.matmul_columns(&aggregated, node_first, hg_width + h, hg_width + 2 * h);
        npre = g.op("Add", &[&npre, &agg_term], vec![]);
        if let Some(hg) = &hg {
            let global_term = g.matmul_columns(hg, node_first, 0, h);
            let global_term = g.unsqueeze(&global_term, &[1]);
            npre = g.op("Add", &[&npre, &global_term], vec![]);
        }
        npre = g.bias(&npre, node_first);
        let new_n = g.mlp_tail(&npre, &block.node);
        hn = g.op("Add", &[&hn, &new_n], vec![]);
        he = g.op("Add", &[&he, &new_e], vec![]);
    }

    let raw = g.mlp(&hn, &weights.vector_head);
    let logits = weights
        .affordance_head
        .as_ref()
        .map(|head| g.mlp(&hn, head));
    let heads = Heads {
        raw: &raw,
        logits: logits.as_deref(),
        mean: &weights.output_mean,
        std: &weights.output_std,
    };
    g.finish(task, "gnn", heads, inputs, metadata)
}

/// What an architecture's last layers hand to [`Builder::finish`]: the
/// vector head's raw output, the affordance logits (policies), and the
/// training split's output mean and standard deviation.
struct Heads<'a> {
    raw: &'a str,
    logits: Option<&'a str>,
    mean: &'a [f64; 3],
    std: &'a [f64; 3],
}

/// The graph's inputs for a task: the same for every architecture.
fn graph_inputs(task: Task) -> Vec<ValueInfoProto> {
    let nd = task.node_dim().to_string();
    let edge_dim = EDGE_DIM.to_string();
    let mut inputs = vec![
        tensor_value(contract::NODES, &["B", "N", &nd]),
        tensor_value(contract::EDGES, &["B", "N", "N", &edge_dim]),
    ];
    if task.global_dim() > 0 {
        inputs.push(tensor_value(contract::GLOBAL, &["B", "3"]));
    }
    inputs.push(tensor_value(contract::MASK, &["B", "N"]));
    inputs
}

impl Builder {
    /// De-normalises the vector head into `displacement` (forward) or
    /// `action` (policy) and turns the logits [B, N, 1] into `affordance`,
    /// a softmax over each graph's real nodes.
    fn outputs(
        &mut self,
        task: Task,
        raw: &str,
        logits: Option<&str>,
        mean: &[f64; 3],
        std: &[f64; 3],
    ) -> Vec<ValueInfoProto> {
        let g = self;
        let std = g.constant_f32("out_std", &[3], std.iter().map(|v| *v as f32).collect());
        let mean = g.constant_f32("out_mean", &[3], mean.iter().map(|v| *v as f32).collect());
        let scaled = g.op("Mul", &[raw, &std], vec![]);
        let vector_name = if task == Task::Forward {
            contract::DISPLACEMENT
        } else {
            contract::ACTION
        };
        g.op_named("Add", &[&scaled, &mean], vec![], vector_name);
        let mut outputs = vec![tensor_value(vector_name, &["B", "N", "3"])];
        if let Some(logits) = logits {
            let two = g.constant_i64("axes", vec![2]);
            let logits = g.op("Squeeze", &[logits, &two], vec![]);
            // Padded nodes get a logit of −1e9, hence zero affordance.
            let one = g.constant_f32("one", &[], vec![1.0]);
            let off = g.op("Sub", &[contract::MASK, &one], vec![]);
            let big = g.constant_f32("big", &[], vec![1e9]);
            let penalty = g.op("Mul", &[&off, &big], vec![]);
            let masked = g.op("Add", &[&logits, &penalty], vec![]);
            g.op_named(
                "Softmax",
                &[&masked],
                vec![int_attribute("axis", 1)],
                contract::AFFORDANCE,
            );
            outputs.push(tensor_value(contract::AFFORDANCE, &["B", "N"]));
        }
        outputs
    }

    /// The heads de-normalised into the task's outputs, and the model
    /// named `treemanip_{arch}_{task}`.
    fn finish(
        mut self,
        task: Task,
        arch: &str,
        heads: Heads<'_>,
        inputs: Vec<ValueInfoProto>,
        metadata: &[(String, String)],
    ) -> Vec<u8> {
        let outputs = self.outputs(task, heads.raw, heads.logits, heads.mean, heads.std);
        let name = format!("treemanip_{arch}_{task:?}").to_lowercase();
        self.into_model(&name, inputs, outputs, metadata)
    }

    fn into_model(
        self,
        name: &str,
        inputs: Vec<ValueInfoProto>,
        outputs: Vec<ValueInfoProto>,
        metadata: &[(String, String)],
    ) -> Vec<u8> {
        let model = ModelProto {
            ir_version: 8,
            opset_import: vec![OperatorSetIdProto {
                domain: String::new(),
                version: OPSET,
            }],
            producer_name: "treemanip".to_owned(),
            producer_version: env!("CARGO_PKG_VERSION").to_owned(),
            graph: Some(GraphProto {
                node: self.nodes,
                name: name.to_owned(),
                initializer: self.initializers,
                input: inputs,
                output: outputs,
                ..Default::default()
            }),
            metadata_props: metadata
                .iter()
                .map(|(k, v)| StringStringEntryProto {
                    key: k.clone(),
                    value: v.clone(),
                })
                .collect(),
            ..Default::default()
        };
        model.encode_to_vec()
    }
}

/// The PointNet baseline as ONNX bytes; same inputs and outputs as the GNN.
/// The first layers are split by input part, so the per-graph terms (push
/// T, global feature) are computed once and broadcast over the points.
pub fn export_pointnet(weights: &PointNetWeights, metadata: &[(String, String)]) -> Vec<u8> {
    let task = weights.config.task;
    let s = &weights.stats;
    let (nd, gd) = (task.node_dim(), task.global_dim());
    let mut g = Builder::default();
    let inputs = graph_inputs(task);

    // p_j − p_0 is the Δp of edge 0 → j: edges[:, 0, :, 0:3].
    let starts = g.constant_i64("starts", vec![0, 0]);
    let ends = g.constant_i64("ends", vec![1, 3]);
    let axes = g.constant_i64("axes", vec![1, 3]);
    let row = g.op("Slice", &[contract::EDGES, &starts, &ends, &axes], vec![]);
    let one = g.constant_i64("axes", vec![1]);
    let position = g.op("Squeeze", &[&row, &one], vec![]);
    let position = g.normalise(&position, &weights.position_mean, &weights.position_std);
    let nodes = g.normalise(contract::NODES, &s.node_mean, &s.node_std);

    let first = &weights.local[0];
    let mut pre = g.matmul_columns(&position, first, 0, 3);
    let node_term = g.matmul_columns(&nodes, first, 3, 3 + nd);
    pre = g.op("Add", &[&pre, &node_term], vec![]);
    if gd > 0 {
        let global = g.normalise(contract::GLOBAL, &s.global_mean, &s.global_std);
        let global_term = g.matmul_columns(&global, first, 3 + nd, 3 + nd + gd);
        let global_term = g.unsqueeze(&global_term, &[1]);
        pre = g.op("Add", &[&pre, &global_term], vec![]);
    }
    pre = g.bias(&pre, first);
    let a = g.op("Relu", &[&pre], vec![]);
    let local = g.linear(&a, &weights.local[1]);
    let local = g.op("Relu", &[&local], vec![]);

    let f = g.linear(&local, &weights.feature[0]);
    let f = g.op("Relu", &[&f], vec![]);
    let f = g.linear(&f, &weights.feature[1]);
    let f = g.op("Relu", &[&f], vec![]);
    // Features are ≥ 0 after the ReLU, so zeroing padded points leaves the
    // max over real points unchanged.
    let point_mask = g.unsqueeze(contract::MASK, &[2]);
    let f = g.op("Mul", &[&f, &point_mask], vec![]);
    // Opset 17's ReduceMax takes its axes as an attribute.
    let global_feature = g.op(
        "ReduceMax",
        &[&f],
        vec![int_attribute("keepdims", 1), ints_attribute("axes", &[1])],
    );

    let (l, gl) = (weights.config.local, weights.config.global);
    let trunk0 = &weights.trunk[0];
    let local_term = g.matmul_columns(&local, trunk0, 0, l);
    let global_term = g.matmul_columns(&global_feature, trunk0, l, l + gl);
    let pre = g.op("Add", &[&local_term, &global_term], vec![]);
    let pre = g.bias(&pre, trunk0);
    let t = g.op("Relu", &[&pre], vec![]);
    let t = g.linear(&t, &weights.trunk[1]);
    let t = g.op("Relu", &[&t], vec![]);

    let raw = g.linear(&t, &weights.vector_head);
    let logits = weights
        .affordance_head
        .as_ref()
        .map(|head| g.linear(&t, head));
    let heads = Heads {
        raw: &raw,
        logits: logits.as_deref(),
        mean: &weights.output_mean,
        std: &weights.output_std,
    };
    g.finish(task, "pointnet", heads, inputs, metadata)
}

/// The same model with `metadata` set: keys already present are replaced,
/// new keys appended. For adding what a later version records (such as the
/// model's domain) without retraining or re-exporting the weights.
pub fn with_metadata(bytes: &[u8], metadata: &[(String, String)]) -> Result<Vec<u8>, String> {
    let mut model = ModelProto::decode(bytes).map_err(|e| format!("not an ONNX model: {e}"))?;
    for (key, value) in metadata {
        match model.metadata_props.iter_mut().find(|p| &p.key == key) {
            Some(entry) => entry.value = value.clone(),
            None => model.metadata_props.push(StringStringEntryProto {
                key: key.clone(),
                value: value.clone(),
            }),
        }
    }
    Ok(model.encode_to_vec())
}
