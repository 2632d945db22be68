//! Training throughput (burn, Flex backend) and inference latency (ONNX
//! through ort: tract, or native ONNX Runtime when `ORT_DYLIB_PATH` is set).
//!
//!     cargo bench --bench learn                      # tract
//!     ORT_DYLIB_PATH=$(scripts/fetch-onnxruntime) cargo bench --bench learn
//!
//! Inference runs the committed `models/*.onnx` single-threaded, one graph
//! per call. Prints numbers; asserts nothing.

use std::path::Path;
use std::time::{Duration, Instant};

use nalgebra::{Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use treemanip::graph::stats::StatsBuilder;
use treemanip::graph::{GraphInput, Task, batch, encode_forward, encode_policy};
use treemanip::infer::{OnnxModel, init_backend};
use treemanip::nn::gnn::{GnnConfig, GnnWeights};
use treemanip::nn::model::{Arch, ModelWeights};
use treemanip::nn::pointnet::{PointNetConfig, PointNetWeights, position_stats};
use treemanip::nn::train::data::Targets;
use treemanip::nn::train::time_steps;
use treemanip::tree::{ScaParams, Tree, generate};

fn graphs(task: Task, tree: &Tree, count: usize, rng: &mut ChaCha8Rng) -> Vec<GraphInput> {
    (0..count)
        .map(|_| {
            let push = Vector3::new(
                rng.random_range(-0.1..0.1),
                rng.random_range(-0.1..0.1),
                rng.random_range(-0.1..0.1),
            );
            match task {
                Task::Forward => {
                    encode_forward(tree, rng.random_range(1..tree.len()), &push).unwrap()
                }
                Task::Policy => {
                    let targets: Vec<Point3<f64>> =
                        tree.positions().iter().map(|p| p + push * 0.3).collect();
                    encode_policy(tree, &targets).unwrap()
                }
            }
        })
        .collect()
}

fn paper_model(task: Task, arch: Arch, gs: &[GraphInput]) -> ModelWeights {
    let mut stats = StatsBuilder::new(task);
    gs.iter().for_each(|g| stats.add(g));
    match arch {
        Arch::Gnn => ModelWeights::Gnn(GnnWeights::random(
            GnnConfig::paper(task),
            stats.finish(),
            1,
        )),
        Arch::PointNet => ModelWeights::PointNet(PointNetWeights::random(
            PointNetConfig::paper(task),
            stats.finish(),
            position_stats(gs),
            1,
        )),
    }
}

/// The f32 GEMM peak of burn's Flex backend on this machine: a 1024³
/// matmul on all cores, best of several runs (GFLOP/s).
fn gemm_peak() -> f64 {
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

fn training() {
    let peak = gemm_peak();
    println!(
        "f32 GEMM peak (burn Flex, 1024³, {} threads, best of 8): {peak:.1} GFLOP/s",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!(
        "training throughput (batch 128 as the recipe, one tree size per batch, Adam step included)"
    );
    println!("  GNN step FLOPs = 3 × forward, forward counted from the layer shapes");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for (task, arch) in [
        (Task::Forward, Arch::Gnn),
        (Task::Policy, Arch::Gnn),
        (Task::Forward, Arch::PointNet),
    ] {
        for n in [15usize, 30] {
            let tree = generate(n, 5, &ScaParams::default()).unwrap();
            let gs = graphs(task, &tree, 128, &mut rng);
            let weights = paper_model(task, arch, &gs);
            let b = batch(&gs).unwrap();
            let targets = Targets {
                displacement: (0..128 * n * 3).map(|k| (k % 7) as f32 * 0.01).collect(),
                contact: (0..128).map(|k| 1 + k % (n - 1)).collect(),
                push: (0..128 * 3).map(|k| (k % 5) as f32 * 0.02).collect(),
            };
            let _ = time_steps(&weights, &b, &targets, 1); // warm-up
            let steps = if arch == Arch::Gnn { 4 } else { 20 };
            let (prep, secs) = time_steps(&weights, &b, &targets, steps);
            let samples_per_second = (128 * steps) as f64 / secs;
            let compute = match &weights {
                ModelWeights::Gnn(w) => {
                    let gflops = samples_per_second * 3.0 * w.flops_per_graph(n) / 1e9;
                    format!(
                        "  {gflops:.1} GFLOP/s = {:.0} % of peak",
                        100.0 * gflops / peak
                    )
                }
                ModelWeights::PointNet(_) => String::new(),
            };
            println!(
                "  {:<8} {:<9} N={n:<3} {:>7.1} samples/s  ({:.0} ms/step, input prep {:.1} ms){compute}",
                task.name(),
                arch.name(),
                samples_per_second,
                1e3 * secs / steps as f64,
                1e3 * prep
            );
        }
    }
}

fn inference() {
    let library = std::env::var_os("ORT_DYLIB_PATH").map(std::path::PathBuf::from);
    let backend = init_backend(library.as_deref()).unwrap();
    println!("inference latency, backend {backend:?} (one graph per call)");
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for stem in [
        "forward_gnn",
        "policy_gnn",
        "forward_pointnet",
        "policy_pointnet",
    ] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("models")
            .join(format!("{stem}.onnx"));
        let Ok(mut model) = OnnxModel::load(&path) else {
            println!("  {stem}: not found, skipped");
            continue;
        };
        for n in [10usize, 15, 30] {
            let tree = generate(n, 6, &ScaParams::default()).unwrap();
            let b = batch(&graphs(model.task(), &tree, 1, &mut rng)).unwrap();
            model.run(&b).unwrap();
            let mut times = Vec::new();
            let start = Instant::now();
            while start.elapsed() < Duration::from_millis(1500) || times.len() < 10 {
                let t = Instant::now();
                std::hint::black_box(model.run(&b).unwrap());
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            times.sort_by(f64::total_cmp);
            println!(
                "  {stem:<17} N={n:<3} p50 {:>6.2} ms  p95 {:>6.2} ms  ({} runs)",
                times[times.len() / 2],
                times[times.len() * 95 / 100],
                times.len()
            );
        }
    }
}

fn main() {
    let which = std::env::args().nth(1).unwrap_or_default();
    if which != "inference" {
        training();
    }
    if which != "training" {
        inference();
    }
}
