//! The exported ONNX graph, run through ort on tract, matches the reference
//! forward pass; the backend falls back to tract without a native library.

use std::path::Path;

use nalgebra::Vector3;
use prost::Message;
use treemanip::graph::contract::ModelOutput;
use treemanip::graph::stats::StatsBuilder;
use treemanip::graph::{GraphInput, Task, batch, encode_forward, encode_policy};
use treemanip::infer::{Backend, OnnxModel, init_backend};
use treemanip::nn::gnn::{GnnConfig, GnnWeights, forward};
use treemanip::nn::onnx::export;
use treemanip::tree::{ScaParams, Tree, generate};

/// Every test in this binary asks for a library that is not there.
fn tract() {
    let backend = init_backend(Some(Path::new("/nonexistent/libonnxruntime.so.1.31.1"))).unwrap();
    assert_eq!(backend, Backend::Tract);
}

fn trees() -> Vec<Tree> {
    [(5usize, 1u64), (10, 2), (17, 3)]
        .iter()
        .map(|&(n, s)| generate(n, s, &ScaParams::default()).unwrap())
        .collect()
}

fn graphs(task: Task) -> Vec<GraphInput> {
    trees()
        .iter()
        .enumerate()
        .map(|(k, tree)| match task {
            Task::Forward => {
                encode_forward(tree, 1 + k, &Vector3::new(0.05, -0.02 * k as f64, 0.03)).unwrap()
            }
            Task::Policy => {
                let targets: Vec<_> = tree
                    .positions()
                    .iter()
                    .enumerate()
                    .map(|(j, p)| p + Vector3::new(0.01 * j as f64, -0.02, 0.005 * k as f64))
                    .collect();
                encode_policy(tree, &targets).unwrap()
            }
        })
        .collect()
}

fn model(task: Task) -> GnnWeights {
    let mut stats = StatsBuilder::new(task);
    for g in graphs(task) {
        stats.add(&g);
    }
    let mut weights = GnnWeights::random(
        GnnConfig {
            hidden: 16,
            layers: 3,
            ..GnnConfig::paper(task)
        },
        stats.finish(),
        42,
    );
    weights.output_mean = [0.01, -0.02, 0.03];
    weights.output_std = [0.05, 0.1, 0.2];
    weights
}

fn assert_close(reference: &ModelOutput, onnx: &ModelOutput, mask: &[f32]) {
    let scale = reference
        .vectors
        .iter()
        .fold(1e-3f32, |m, v| m.max(v.abs()));
    for (k, m) in mask.iter().enumerate() {
        if *m == 0.0 {
            continue;
        }
        for c in 0..3 {
            let (a, b) = (reference.vectors[k * 3 + c], onnx.vectors[k * 3 + c]);
            assert!(
                (a - b).abs() <= 1e-4 * scale,
                "node {k} component {c}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn forward_model_onnx_matches_the_reference() {
    tract();
    let weights = model(Task::Forward);
    let bytes = export(&weights, &[("feature_layout_version".into(), "1".into())]);
    let mut onnx = OnnxModel::from_bytes(&bytes, Vec::new()).unwrap();
    // Several sizes in one padded batch, and each graph alone.
    let all = graphs(Task::Forward);
    let padded = batch(&all).unwrap();
    assert_close(
        &forward(&weights, &padded),
        &onnx.run(&padded).unwrap(),
        &padded.mask,
    );
    for g in &all {
        let single = batch(std::slice::from_ref(g)).unwrap();
        assert_close(
            &forward(&weights, &single),
            &onnx.run(&single).unwrap(),
            &single.mask,
        );
    }
    // Padding does not change a graph's answer.
    let alone = forward(&weights, &batch(&all[..1]).unwrap());
    let with_others = forward(&weights, &padded);
    for k in 0..all[0].n * 3 {
        assert!((alone.vectors[k] - with_others.vectors[k]).abs() < 1e-5);
    }
}

#[test]
fn policy_onnx_matches_the_reference_and_affordances_sum_to_one() {
    tract();
    let weights = model(Task::Policy);
    let bytes = export(&weights, &[]);
    let mut onnx = OnnxModel::from_bytes(&bytes, Vec::new()).unwrap();
    let padded = batch(&graphs(Task::Policy)).unwrap();
    let reference = forward(&weights, &padded);
    let got = onnx.run(&padded).unwrap();
    assert_close(&reference, &got, &padded.mask);
    let (ra, ga) = (reference.affordance.unwrap(), got.affordance.unwrap());
    for g in 0..padded.batch {
        let row = &ga[g * padded.n..(g + 1) * padded.n];
        let mask = &padded.mask[g * padded.n..(g + 1) * padded.n];
        let sum: f32 = row.iter().sum();
        assert!((sum - 1.0).abs() < 1e-5, "graph {g}: {sum}");
        for (j, (a, m)) in row.iter().zip(mask).enumerate() {
            if *m == 0.0 {
                assert!(*a < 1e-6, "padded node {j} has affordance {a}");
            } else {
                assert!((a - ra[g * padded.n + j]).abs() < 1e-5);
            }
        }
    }
}

#[test]
fn the_exported_file_describes_itself() {
    tract();
    let weights = model(Task::Forward);
    let bytes = export(
        &weights,
        &[
            ("seed".into(), "42".into()),
            ("architecture".into(), "gnn".into()),
        ],
    );
    let proto = tract_onnx::pb::ModelProto::decode(bytes.as_slice()).unwrap();
    assert_eq!(proto.opset_import[0].version, 17);
    let keys: Vec<_> = proto
        .metadata_props
        .iter()
        .map(|p| (p.key.as_str(), p.value.as_str()))
        .collect();
    assert_eq!(keys, vec![("seed", "42"), ("architecture", "gnn")]);
    let graph = proto.graph.unwrap();
    let inputs: Vec<_> = graph.input.iter().map(|i| i.name.as_str()).collect();
    assert_eq!(inputs, vec!["nodes", "edges", "global", "mask"]);
    // A broken model is a load error, not a panic.
    assert!(OnnxModel::from_bytes(b"not onnx", Vec::new()).is_err());
}

/// Without a library given, the default backend is the ONNX Runtime
/// embedded in the binary, and it computes what the reference pass does.
#[test]
fn the_embedded_onnx_runtime_is_the_default_and_matches_the_reference() {
    if !treemanip::infer::EMBEDDED {
        println!(
            "skipped: built without the embedded ONNX Runtime (TREEMANIP_EMBED_ORT=0 or no network)"
        );
        return;
    }
    let backend = init_backend(None).unwrap();
    assert!(
        matches!(backend, Backend::OnnxRuntime { embedded: true, .. }),
        "{backend:?}"
    );
    for task in [Task::Forward, Task::Policy] {
        let weights = model(task);
        let bytes = export(&weights, &[]);
        let mut onnx = OnnxModel::from_bytes(&bytes, Vec::new()).unwrap();
        let padded = batch(&graphs(task)).unwrap();
        assert_close(
            &forward(&weights, &padded),
            &onnx.run(&padded).unwrap(),
            &padded.mask,
        );
    }
}
