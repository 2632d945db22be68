//! Dynamic batching across callers (`infer::batcher`): batched answers
//! equal unbatched ones, sizes are never mixed in one batch, queued jobs
//! are merged, and cancelled or expired jobs never run.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use nalgebra::Vector3;
use treemanip_core::graph::{Batch, batch, encode_forward};
use treemanip_core::tree::{ScaParams, generate};
use treemanip_infer::batcher::{BatchLimits, JobControl};
use treemanip_infer::models::ServedModel;
use treemanip_infer::{InferError, OnnxModel};

const MODEL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models/forward_gnn.onnx");

fn job(n: usize, k: usize) -> Batch {
    let tree = generate(n, 3 + k as u64, &ScaParams::default()).unwrap();
    let push = Vector3::new(0.05, -0.01 * k as f64, 0.02);
    batch(&[encode_forward(&tree, 1 + k % (n - 1), &push).unwrap()]).unwrap()
}

fn served(max_batch: usize, max_delay: Duration) -> ServedModel {
    ServedModel::load_with(
        Path::new(MODEL),
        1,
        BatchLimits {
            max_batch,
            max_delay,
            ..BatchLimits::default()
        },
    )
    .unwrap()
}

#[test]
fn batched_answers_equal_unbatched_ones_across_mixed_tree_sizes() {
    let model = served(64, Duration::from_millis(20));
    let jobs: Vec<Batch> = (0..12)
        .map(|k| job(if k % 3 == 0 { 15 } else { 10 }, k))
        .collect();
    // All queued at once, answered together.
    let pending: Vec<_> = jobs
        .iter()
        .map(|b| model.batcher().submit(b.clone(), JobControl::default()))
        .collect();
    let batched: Vec<_> = pending.into_iter().map(|p| p.wait().unwrap()).collect();
    let (batches, graphs) = model.batcher().batches_run();
    assert_eq!(graphs, 12);
    assert!(batches >= 2, "two tree sizes never share a batch");
    assert!(batches < 12, "queued jobs were merged ({batches} batches)");
    let bytes = std::fs::read(MODEL).unwrap();
    let meta = treemanip_infer::read_metadata(&bytes).unwrap();
    let mut alone = OnnxModel::from_bytes(&bytes, meta).unwrap();
    for (b, got) in jobs.iter().zip(&batched) {
        let want = alone.run(b).unwrap();
        assert_eq!(want.vectors.len(), got.vectors.len());
        for (w, g) in want.vectors.iter().zip(&got.vectors) {
            assert!((w - g).abs() <= 1e-5 * (1.0 + w.abs()), "{w} vs {g}");
        }
    }
}

#[test]
fn large_trees_get_smaller_batches() {
    use treemanip_infer::batcher::{MAX_PAIRS, graphs_per_batch};
    assert_eq!(graphs_per_batch(15, 64, MAX_PAIRS), 64);
    assert_eq!(graphs_per_batch(30, 64, MAX_PAIRS), 16);
    assert_eq!(graphs_per_batch(64, 64, MAX_PAIRS), 3);
    assert_eq!(graphs_per_batch(200, 64, MAX_PAIRS), 1);
    // Eight queued jobs of 30 nodes with room for 4 · 30² pairs: 4 per batch.
    let model = ServedModel::load_with(
        Path::new(MODEL),
        1,
        BatchLimits {
            max_batch: 64,
            max_pairs: 4 * 900,
            max_delay: Duration::from_secs(5),
        },
    )
    .unwrap();
    let pending: Vec<_> = (0..8)
        .map(|k| model.batcher().submit(job(30, k), JobControl::default()))
        .collect();
    for p in pending {
        p.wait().unwrap();
    }
    assert_eq!(model.batcher().batches_run(), (2, 8));
}

#[test]
fn jobs_queued_together_run_as_one_batch() {
    let model = served(8, Duration::from_secs(5));
    let started = Instant::now();
    let pending: Vec<_> = (0..8)
        .map(|k| model.batcher().submit(job(10, k), JobControl::default()))
        .collect();
    for p in pending {
        p.wait().unwrap();
    }
    assert_eq!(model.batcher().batches_run(), (1, 8));
    // Full before the delay ran out: it did not wait the 5 s.
    assert!(started.elapsed() < Duration::from_secs(4));
}

#[test]
fn cancelled_and_expired_jobs_are_answered_without_running() {
    let model = served(64, Duration::ZERO);
    let cancelled = JobControl {
        cancelled: Some(Arc::new(AtomicBool::new(true))),
        ..JobControl::default()
    };
    let expired = JobControl {
        deadline: Some(Instant::now()),
        ..JobControl::default()
    };
    assert!(matches!(
        model.batcher().run(job(10, 0), cancelled),
        Err(InferError::Cancelled)
    ));
    assert!(matches!(
        model.batcher().run(job(10, 1), expired),
        Err(InferError::DeadlineExceeded)
    ));
    assert_eq!(model.batcher().batches_run(), (0, 0), "nothing ran");
    model
        .batcher()
        .run(job(10, 2), JobControl::default())
        .unwrap();
    assert_eq!(model.batcher().batches_run(), (1, 1));
}
