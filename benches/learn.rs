//! Training throughput (burn, Flex backend) and inference latency of the
//! committed `models/*.onnx` through ort, one graph per call, on both
//! compiled-in engines: tract and the default, ONNX Runtime embedded in
//! the binary. A process runs on one backend only, so the bench runs
//! itself once per backend and prints one table with the ratio.
//!
//!     cargo bench --bench learn                  # training and inference
//!     cargo bench --bench learn -- inference     # inference only
//!     cargo bench --bench learn -- branches      # branch-only edge layouts only
//!
//! Prints numbers; asserts nothing.

use std::path::Path;
use std::time::{Duration, Instant};

use nalgebra::{Point3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use treemanip::graph::stats::StatsBuilder;
use treemanip::graph::{GraphInput, Task, batch, encode_forward, encode_policy};
use treemanip::infer::{OnnxModel, init_backend};
use treemanip::nn::gnn::{Connectivity, GnnConfig, GnnWeights};
use treemanip::nn::model::{Arch, ModelWeights};
use treemanip::nn::pointnet::{PointNetConfig, PointNetWeights, position_stats};
use treemanip::nn::train::data::Targets;
use treemanip::nn::train::{EdgeLayout, time_steps};
use treemanip::tree::{ScaParams, Tree, generate};

/// The training binary's allocator and its setting
/// ([`treemanip::nn::train::keep_freed_pages`]), so the step measured here
/// is the step `treemanip train` runs.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[allow(dead_code)] // the learn bench uses the peak only
#[path = "common/peak.rs"]
mod peak;
use peak::gemm_peak;

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

/// Targets of the right shapes for a batch of 128 graphs of `n` nodes
/// (the step's cost does not depend on their values).
fn made_up_targets(n: usize) -> Targets {
    Targets {
        displacement: (0..128 * n * 3).map(|k| (k % 7) as f32 * 0.01).collect(),
        contact: (0..128).map(|k| 1 + k % (n - 1)).collect(),
        push: (0..128 * 3).map(|k| (k % 5) as f32 * 0.02).collect(),
        weight: vec![1.0; 128 * n],
    }
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
            let targets = made_up_targets(n);
            let cores = rayon::current_num_threads();
            let steps = if arch == Arch::Gnn { 4 } else { 20 };
            // The recipe's step (one shard per core), then the whole batch
            // on the calling thread (matrix products still on every core):
            // the step before data-parallel training.
            for shards in [cores, 1] {
                let layout = EdgeLayout::of(&weights);
                let _ = time_steps(&weights, &b, &targets, 1, (shards, layout)); // warm-up
                let (prep, secs) = time_steps(&weights, &b, &targets, steps, (shards, layout));
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
                    "  {:<8} {:<9} N={n:<3} {shards} shard{} {:>7.1} samples/s  ({:.0} ms/step, shard prep {:.1} ms){compute}",
                    task.name(),
                    arch.name(),
                    if shards == 1 { " " } else { "s" },
                    samples_per_second,
                    1e3 * secs / steps as f64,
                    1e3 * prep
                );
            }
        }
    }
    branches();
}

/// The branch-only ablation models (forward GNN, N = 15): the same step
/// with edges as the list of parent–child pairs that `train` uses for
/// them, and on the masked N × N pairs.
fn branches() {
    println!("branch connectivity (forward GNN, N=15, batch 128, one shard per core)");
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let n = 15;
    let tree = generate(n, 5, &ScaParams::default()).unwrap();
    let gs = graphs(Task::Forward, &tree, 128, &mut rng);
    let b = batch(&gs).unwrap();
    let targets = made_up_targets(n);
    let cores = rayon::current_num_threads();
    for layers in [5usize, 20] {
        let ModelWeights::Gnn(paper) = paper_model(Task::Forward, Arch::Gnn, &gs) else {
            unreachable!("a GNN was asked for")
        };
        let config = GnnConfig {
            layers,
            connectivity: Connectivity::Branches,
            ..paper.config.clone()
        };
        let weights = ModelWeights::Gnn(GnnWeights::random(config, paper.stats.clone(), 1));
        let mut rates = Vec::new();
        for layout in [EdgeLayout::List, EdgeLayout::Dense] {
            let steps = 3;
            let _ = time_steps(&weights, &b, &targets, 1, (cores, layout)); // warm-up
            let (_, secs) = time_steps(&weights, &b, &targets, steps, (cores, layout));
            let samples_per_second = (128 * steps) as f64 / secs;
            rates.push(samples_per_second);
            println!(
                "  {layers:>2} layers  {:<5} {:>7.1} samples/s  ({:.0} ms/step)",
                format!("{layout:?}").to_lowercase(),
                samples_per_second,
                1e3 * secs / steps as f64
            );
        }
        println!(
            "  {layers:>2} layers  list / dense = {:.2}×",
            rates[0] / rates[1]
        );
    }
}

const MODELS: [&str; 4] = [
    "forward_gnn",
    "policy_gnn",
    "forward_pointnet",
    "policy_pointnet",
];
const SIZES: [usize; 3] = [10, 15, 30];

/// Child process: p50 latency (ms) of every model and size on the backend
/// this process was started for, one `model n p50 p95` line each.
fn inference_child(library: Option<std::path::PathBuf>) {
    let backend = init_backend(library.as_deref()).unwrap();
    eprintln!("child backend: {backend:?}");
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for stem in MODELS {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("models")
            .join(format!("{stem}.onnx"));
        let Ok(mut model) = OnnxModel::load(&path) else {
            continue;
        };
        for n in SIZES {
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
                "{stem} {n} {} {}",
                times[times.len() / 2],
                times[times.len() * 95 / 100]
            );
        }
    }
}

fn inference() {
    let exe = std::env::current_exe().unwrap();
    // `tract`: the compiled-in engine; `default`: what a process picks with
    // no library given (the embedded ONNX Runtime when built with it).
    // `dylib`: native ONNX Runtime loaded from a library on disk.
    let run = |tract: bool,
               dylib: Option<&str>|
     -> std::collections::BTreeMap<(String, usize), (f64, f64)> {
        let mut cmd = std::process::Command::new(&exe);
        cmd.arg("inference-child").env_remove("ORT_DYLIB_PATH");
        if tract {
            cmd.env("TREEMANIP_BACKEND", "tract");
        } else {
            cmd.env_remove("TREEMANIP_BACKEND");
        }
        if let Some(path) = dylib {
            cmd.env("ORT_DYLIB_PATH", path);
        }
        let out = cmd.output().expect("the bench runs itself");
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter_map(|l| {
                let f: Vec<&str> = l.split_whitespace().collect();
                Some((
                    (f.first()?.to_string(), f.get(1)?.parse().ok()?),
                    (f.get(2)?.parse().ok()?, f.get(3)?.parse().ok()?),
                ))
            })
            .collect()
    };
    let tract = run(true, None);
    let native = run(false, None);
    let library = std::process::Command::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scripts/fetch-onnxruntime"
    ))
    .output()
    .ok()
    .filter(|o| o.status.success())
    .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned());
    let dylib = library
        .as_deref()
        .map(|l| run(false, Some(l)))
        .unwrap_or_default();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let default = if treemanip::infer::EMBEDDED {
        "embedded ONNX Runtime"
    } else {
        "tract (built without the embedded ONNX Runtime)"
    };
    println!(
        "inference latency, batch 1, each backend in its own process ({threads} cores): tract vs the default, {default}"
    );
    println!(
        "  {:<17} {:>4} {:>10} {:>10} {:>12} {:>12} {:>16} {:>14} {:>16}",
        "model",
        "N",
        "tract p50",
        "tract p95",
        "default p50",
        "default p95",
        "ORT_DYLIB_PATH p50",
        "tract/native",
        "default/native"
    );
    for ((stem, n), (t50, t95)) in &tract {
        let get = |m: &std::collections::BTreeMap<(String, usize), (f64, f64)>| {
            m.get(&(stem.clone(), *n))
                .copied()
                .unwrap_or((f64::NAN, f64::NAN))
        };
        let ((o50, o95), (d50, _)) = (get(&native), get(&dylib));
        println!(
            "  {stem:<17} {n:>4} {t50:>7.2} ms {t95:>7.2} ms {o50:>9.2} ms {o95:>9.2} ms {d50:>15.2} ms {:>13.2}x {:>15.2}x",
            t50 / d50,
            o50 / d50
        );
    }
}

fn main() {
    let which = std::env::args().nth(1).unwrap_or_default();
    if which == "inference-child" {
        inference_child(std::env::var_os("ORT_DYLIB_PATH").map(std::path::PathBuf::from));
        return;
    }
    if which == "branches" {
        treemanip::nn::train::keep_freed_pages();
        branches();
        return;
    }
    if which != "inference" {
        treemanip::nn::train::keep_freed_pages();
        training();
    }
    if which != "training" {
        inference();
    }
}
