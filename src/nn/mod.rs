//! The learned models. Each architecture exists twice: as plain weights
//! with a deliberately simple reference forward pass (`gnn`, `pointnet`),
//! which is what gets exported to ONNX (`onnx`), and as a burn module that
//! is trained (`train`). Training starts from and ends in the plain
//! weights, so the two are compared number for number in the tests.

pub mod gnn;
pub mod input;
pub mod model;
pub mod onnx;
pub mod pointnet;
pub mod train;
