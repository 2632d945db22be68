//! The models' input/output contract, in one place: tensor names, element
//! type and shapes (B graphs of N nodes), as the exported ONNX graphs
//! declare them (`nn::onnx`) and as the server's Open Inference Protocol
//! endpoints describe and check them. Values are raw SI features from
//! [`crate::graph`]; normalisation happens inside the graph.

use super::{Batch, EDGE_DIM, Task};

pub const NODES: &str = "nodes";
pub const EDGES: &str = "edges";
pub const GLOBAL: &str = "global";
pub const MASK: &str = "mask";
pub const DISPLACEMENT: &str = "displacement";
pub const ACTION: &str = "action";
pub const AFFORDANCE: &str = "affordance";

/// One dimension of a tensor's shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dim {
    /// B, the graphs in the batch.
    Batch,
    /// N, the (padded) node count.
    Nodes,
    Fixed(usize),
}

impl Dim {
    /// The Open Inference Protocol's spelling: −1 for a variable dimension.
    pub fn oip(self) -> i64 {
        match self {
            Dim::Batch | Dim::Nodes => -1,
            Dim::Fixed(d) => d as i64,
        }
    }
}

/// A tensor of the contract: FP32 always.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TensorSpec {
    pub name: &'static str,
    pub dims: Vec<Dim>,
}

impl TensorSpec {
    fn new(name: &'static str, dims: &[Dim]) -> Self {
        Self {
            name,
            dims: dims.to_vec(),
        }
    }

    /// The concrete shape for B and N.
    pub fn shape(&self, b: usize, n: usize) -> Vec<usize> {
        self.dims
            .iter()
            .map(|d| match d {
                Dim::Batch => b,
                Dim::Nodes => n,
                Dim::Fixed(k) => *k,
            })
            .collect()
    }
}

/// The element type of every tensor, in the protocol's words.
pub const DATATYPE: &str = "FP32";

pub fn inputs(task: Task) -> Vec<TensorSpec> {
    use Dim::*;
    let mut out = vec![
        TensorSpec::new(NODES, &[Batch, Nodes, Fixed(task.node_dim())]),
        TensorSpec::new(EDGES, &[Batch, Nodes, Nodes, Fixed(EDGE_DIM)]),
    ];
    if task.global_dim() > 0 {
        out.push(TensorSpec::new(GLOBAL, &[Batch, Fixed(task.global_dim())]));
    }
    out.push(TensorSpec::new(MASK, &[Batch, Nodes]));
    out
}

pub fn outputs(task: Task) -> Vec<TensorSpec> {
    use Dim::*;
    match task {
        Task::Forward => vec![TensorSpec::new(DISPLACEMENT, &[Batch, Nodes, Fixed(3)])],
        Task::Policy => vec![
            TensorSpec::new(ACTION, &[Batch, Nodes, Fixed(3)]),
            TensorSpec::new(AFFORDANCE, &[Batch, Nodes]),
        ],
    }
}

/// Why a set of named tensors is not a model input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContractError {
    #[error("input `{0}` is missing")]
    Missing(&'static str),
    #[error("input `{0}` is not an input of this model")]
    Unknown(String),
    #[error("input `{name}` has shape {got:?}, expected {expected}")]
    Shape {
        name: &'static str,
        got: Vec<usize>,
        expected: String,
    },
    #[error("input `{name}` has {got} values, its shape {shape:?} needs {expected}")]
    Length {
        name: &'static str,
        got: usize,
        shape: Vec<usize>,
        expected: usize,
    },
    #[error("input `{0}` holds a value that is not finite")]
    NonFinite(&'static str),
    #[error("{what} is {got}; at most {max} is accepted")]
    TooLarge {
        what: &'static str,
        got: usize,
        max: usize,
    },
}

/// Named input tensors (row-major f32 values and their shape) → the batch
/// the model runs on, every shape checked against the contract; B and N
/// come from the tensors and are bounded by `max_batch` and `max_nodes`.
pub fn batch_from_tensors(
    task: Task,
    tensors: Vec<(String, Vec<usize>, Vec<f32>)>,
    max_batch: usize,
    max_nodes: usize,
) -> Result<Batch, ContractError> {
    let specs = inputs(task);
    for (name, _, _) in &tensors {
        if !specs.iter().any(|s| s.name == name) {
            return Err(ContractError::Unknown(name.clone()));
        }
    }
    let find = |name: &'static str| {
        tensors
            .iter()
            .find(|(n, _, _)| n == name)
            .ok_or(ContractError::Missing(name))
    };
    let (_, mask_shape, _) = find(MASK)?;
    let [b, n] = mask_shape[..] else {
        return Err(ContractError::Shape {
            name: MASK,
            got: mask_shape.clone(),
            expected: "[B, N]".to_owned(),
        });
    };
    if b > max_batch {
        return Err(ContractError::TooLarge {
            what: "the batch",
            got: b,
            max: max_batch,
        });
    }
    if n > max_nodes {
        return Err(ContractError::TooLarge {
            what: "the node count",
            got: n,
            max: max_nodes,
        });
    }
    let mut values = Vec::new();
    for spec in &specs {
        let (_, shape, data) = find(spec.name)?;
        let expected = spec.shape(b, n);
        if *shape != expected {
            return Err(ContractError::Shape {
                name: spec.name,
                got: shape.clone(),
                expected: format!("{expected:?}"),
            });
        }
        let count: usize = expected.iter().product();
        if data.len() != count {
            return Err(ContractError::Length {
                name: spec.name,
                got: data.len(),
                shape: expected,
                expected: count,
            });
        }
        if !data.iter().all(|v| v.is_finite()) {
            return Err(ContractError::NonFinite(spec.name));
        }
        values.push(data.clone());
    }
    let mut values = values.into_iter();
    let nodes = values.next().expect("nodes");
    let edges = values.next().expect("edges");
    let global = if task.global_dim() > 0 {
        values.next().expect("global")
    } else {
        Vec::new()
    };
    let mask = values.next().expect("mask");
    Ok(Batch {
        task,
        batch: b,
        n,
        nodes,
        edges,
        global,
        mask,
    })
}

/// What a model returns for a batch (B × N × …, padded nodes included).
#[derive(Debug, Clone, PartialEq)]
pub struct ModelOutput {
    /// B × N × 3: Δp (forward) or T_j (policy), SI units.
    pub vectors: Vec<f32>,
    /// Policy: B × N affordances, each graph's real nodes summing to 1.
    pub affordance: Option<Vec<f32>>,
}
