//! Training throughput (burn, Flex backend) and inference latency (ONNX
//! through ort: tract, or native ONNX Runtime when `ORT_DYLIB_PATH` is set).
//!
//!     cargo bench --bench learn                      # tract
//!     ORT_DYLIB_PATH=$(scripts/fetch-onnxruntime) cargo bench --bench learn
//!     cargo bench --bench learn --features x86-v4    # AVX-512 training kernels
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

fn training() {
    println!("training throughput (batch 64, one tree size per batch, Adam step included)");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for (task, arch) in [
        (Task::Forward, Arch::Gnn),
        (Task::Policy, Arch::Gnn),
        (Task::Forward, Arch::PointNet),
    ] {
        for n in [15usize, 30] {
            let tree = generate(n, 5, &ScaParams::default()).unwrap();
            let gs = graphs(task, &tree, 64, &mut rng);
            let weights = paper_model(task, arch, &gs);
            let b = batch(&gs).unwrap();
            let targets = Targets {
                displacement: (0..64 * n * 3).map(|k| (k % 7) as f32 * 0.01).collect(),
                contact: (0..64).map(|k| 1 + k % (n - 1)).collect(),
                push: (0..64 * 3).map(|k| (k % 5) as f32 * 0.02).collect(),
            };
            let _ = time_steps(&weights, &b, &targets, 1); // warm-up
            let steps = if arch == Arch::Gnn { 4 } else { 20 };
            let (prep, secs) = time_steps(&weights, &b, &targets, steps);
            println!(
                "  {:<8} {:<9} N={n:<3} {:>7.1} samples/s  ({:.0} ms/step, input prep {:.1} ms)",
                task.name(),
                arch.name(),
                (64 * steps) as f64 / secs,
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
