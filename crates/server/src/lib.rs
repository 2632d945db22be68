//! treemanip's HTTP service (axum): the domain API (`/v1`), the Open
//! Inference Protocol (`/v2`), the viewer, metrics and graceful shutdown.
//! Handlers only translate between JSON and the library
//! (`treemanip-core`, `treemanip-infer`).

pub mod api;
pub mod fuzz;
