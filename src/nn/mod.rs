//! The learned models: the paper's GNN as plain weights with a reference
//! forward pass, and its export to ONNX. (Training arrives with issue 4.)

pub mod gnn;
pub mod onnx;
