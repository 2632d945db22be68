//! What training minimises and what validation measures.
//!
//! Losses are in normalised output units (Δp or T divided by their
//! training-split standard deviation); validation reports the paper's
//! metrics in metres.

use burn::tensor::activation::log_softmax;
use burn::tensor::{Device, Tensor};
use rayon::prelude::*;

use super::data::{Examples, Targets};
use super::device::tensor;
use super::modules::{Outputs, values};
use super::{EdgeLayout, Net, device_input};
use crate::graph::{Batch, Task};
use crate::nn::model::ModelWeights;

/// What [`loss`] divides its sum by: the real node coordinates (forward
/// model) or the examples (policy). Shards of a batch weight their losses
/// by their share of it.
pub(super) fn loss_denominator(task: Task, batch: &Batch) -> f64 {
    match task {
        Task::Forward => batch.mask.iter().map(|&m| m as f64).sum::<f64>() * 3.0,
        Task::Policy => batch.batch as f64,
    }
}

/// The loss of one batch (normalised units), a mean over
/// [`loss_denominator`].
pub(super) fn loss(
    task: Task,
    out: Outputs,
    batch: &Batch,
    targets: &Targets,
    scale: &([f64; 3], [f64; 3]),
    device: &Device,
) -> Tensor<1> {
    let (b, n) = (batch.batch, batch.n);
    let norm = |values: &[f32]| -> Vec<f32> {
        values
            .iter()
            .enumerate()
            .map(|(k, v)| ((*v as f64 - scale.0[k % 3]) / scale.1[k % 3]) as f32)
            .collect()
    };
    match task {
        Task::Forward => {
            let target = tensor(norm(&targets.displacement), [b, n, 3], device);
            let weight = tensor(targets.weight.clone(), [b, n, 1], device);
            ((out.vectors - target).square() * weight)
                .sum()
                .div_scalar(loss_denominator(task, batch) as f32)
        }
        Task::Policy => {
            let mut onehot = vec![0.0f32; b * n];
            for (k, &c) in targets.contact.iter().enumerate() {
                onehot[k * n + c] = 1.0;
            }
            let onehot = tensor(onehot, [b, n], device);
            let mask = tensor(batch.mask.clone(), [b, n], device);
            let logits = out.logits.expect("policy has logits");
            let masked = logits + (mask - 1.0).mul_scalar(1e9);
            let ce = -(log_softmax(masked, 1) * onehot.clone())
                .sum()
                .div_scalar(loss_denominator(task, batch) as f32);
            let at_contact: Tensor<2> = (out.vectors * onehot.unsqueeze_dim::<3>(2))
                .sum_dim(1)
                .reshape([b, 3]);
            let target = tensor(norm(&targets.push), [b, 3], device);
            let mse = (at_contact - target).square().mean();
            ce + mse
        }
    }
}

/// Validation loss, error and accuracy over the held-out trees.
pub(super) fn validate<M: Net>(
    model: &M,
    weights: &ModelWeights,
    examples: &Examples,
    batch_size: usize,
) -> (f64, f64, Option<f64>) {
    let device = Device::flex();
    let model = model.valid();
    let task = weights.task();
    let scale = weights.output_scale();
    // Batches run in parallel (element-wise ops are single-threaded in
    // burn-flex) and are summed in order, so the result is deterministic.
    let partials: Vec<(f64, f64, usize, usize)> = examples
        .validation_batches(batch_size)
        .par_iter()
        .map(|ids| {
            let (batch, targets) = examples.batch(task, ids);
            let out = model.run(&device_input(
                weights,
                &batch,
                EdgeLayout::of(weights),
                &device,
            ));
            let vectors = values(out.vectors.clone());
            let logits = out.logits.clone().map(values);
            let loss =
                loss(task, out, &batch, &targets, &scale, &device).into_scalar::<f32>() as f64;
            let logits = logits.as_deref();
            let (mut error_sum, mut correct) = (0.0, 0usize);
            // One graph of the batch per example id, in order.
            for (g, &id) in ids.iter().enumerate() {
                let (error, hit) = match examples.encoding.path_output() {
                    // A path model's error is the whole tree's, as served:
                    // its graph's rows placed on every node.
                    Some(output) if task == Task::Forward => {
                        let n = batch.n;
                        let rows: Vec<f32> = (g * n * 3..(g + 1) * n * 3)
                            .map(|i| denormalised(&vectors, &scale, i) as f32)
                            .collect();
                        (examples.tree_error(output, id, &rows), false)
                    }
                    _ => graph_score(task, &batch, &targets, &vectors, logits, &scale, g),
                };
                error_sum += error;
                correct += usize::from(hit);
            }
            (loss, error_sum, correct, batch.batch)
        })
        .collect();
    let batches = partials.len();
    let (mut loss_sum, mut error_sum, mut correct, mut count) = (0.0, 0.0, 0usize, 0usize);
    for (l, e, c, k) in partials {
        loss_sum += l;
        error_sum += e;
        correct += c;
        count += k;
    }
    let accuracy = (task == Task::Policy).then(|| correct as f64 / count.max(1) as f64);
    (
        loss_sum / batches.max(1) as f64,
        error_sum / count.max(1) as f64,
        accuracy,
    )
}

/// Output value `i` of a batch's flat 3-per-node output in metres (or
/// radians): the model's normalised value times its coordinate's standard
/// deviation plus its mean (`scale`: means, deviations).
fn denormalised(vectors: &[f32], scale: &([f64; 3], [f64; 3]), i: usize) -> f64 {
    let c = i % 3;
    vectors[i] as f64 * scale.1[c] + scale.0[c]
}

/// Graph `g`'s validation error (m) and, for the policy, whether its
/// arg-max affordance is the contacted node: the forward model's largest
/// node error, the policy's action error at the contacted node.
fn graph_score(
    task: Task,
    batch: &Batch,
    targets: &Targets,
    vectors: &[f32],
    logits: Option<&[f32]>,
    scale: &([f64; 3], [f64; 3]),
    g: usize,
) -> (f64, bool) {
    let n = batch.n;
    let denorm = |k: usize, c: usize| denormalised(vectors, scale, k * 3 + c);
    match task {
        Task::Forward => {
            let mut worst = 0.0f64;
            for j in 0..n {
                if batch.mask[g * n + j] == 0.0 {
                    continue;
                }
                let e: f64 = (0..3)
                    .map(|c| {
                        let d =
                            denorm(g * n + j, c) - targets.displacement[(g * n + j) * 3 + c] as f64;
                        d * d
                    })
                    .sum();
                worst = worst.max(e.sqrt());
            }
            (worst, false)
        }
        Task::Policy => {
            let c = targets.contact[g];
            let e: f64 = (0..3)
                .map(|k| {
                    let d = denorm(g * n + c, k) - targets.push[g * 3 + k] as f64;
                    d * d
                })
                .sum();
            let row = &logits.expect("policy logits")[g * n..(g + 1) * n];
            let best = (0..n)
                .filter(|&j| batch.mask[g * n + j] > 0.0)
                .max_by(|&a, &b| row[a].total_cmp(&row[b]))
                .unwrap_or(0);
            (e.sqrt(), best == c)
        }
    }
}
