//! Shared by the benches: the machine's f32 GEMM peak and the FLOPs of the
//! paper's GNN, so that throughput can be read as a fraction of the peak.

use std::time::Instant;

use nalgebra::Vector3;
use treemanip::graph::stats::StatsBuilder;
use treemanip::graph::{Task, encode_forward};
use treemanip::nn::gnn::{GnnConfig, GnnWeights};
use treemanip::tree::{ScaParams, generate};

/// The f32 GEMM peak of burn's Flex backend on this machine: a 1024³
/// matmul on all cores, best of several runs (GFLOP/s).
pub fn gemm_peak() -> f64 {
    use burn::tensor::{Device, Distribution, Tensor};
    let device = Device::flex();
    let a = Tensor::<2>::random([1024, 1024], Distribution::Default, &device);
    let b = Tensor::<2>::random([1024, 1024], Distribution::Default, &device);
    let mut best = f64::INFINITY;
    for _ in 0..8 {
        let t = Instant::now();
        let c = a.clone().matmul(b.clone());
        std::hint::black_box(c.into_data());
        best = best.min(t.elapsed().as_secs_f64());
    }
    2.0 * 1024f64.powi(3) / best / 1e9
}

/// FLOPs of one forward pass of the paper's forward GNN on `n` nodes,
/// counted from its layer shapes.
pub fn forward_gnn_flops(n: usize) -> f64 {
    let tree = generate(n.max(3), 1, &ScaParams::default()).unwrap();
    let mut stats = StatsBuilder::new(Task::Forward);
    stats.add(&encode_forward(&tree, 1, &Vector3::new(0.05, 0.0, 0.0)).unwrap());
    GnnWeights::random(GnnConfig::paper(Task::Forward), stats.finish(), 1).flops_per_graph(n)
}
