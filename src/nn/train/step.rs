//! One optimisation step's loss and gradients, data-parallel over the
//! cores.
//!
//! burn-flex runs matrix products on every core but element-wise ops
//! (bias, ReLU, broadcasts, masks and their backward passes) on the calling
//! thread. perf on a policy training showed the process at 1.35 of its
//! 2 cores, the rayon workers idle while the main thread did element-wise
//! work. Cutting the batch into one shard per core and running each shard's
//! forward and backward pass on its own core keeps both busy all the time.
//!
//! Each shard runs on its own fork of the model (same parameter ids, its
//! own autodiff graph: shards sharing one graph would serialise their
//! backward passes on its lock), and its loss is weighted by its share of
//! the batch's loss denominator, so the summed gradients are the gradients
//! of the whole batch's loss, not an approximation of them.

use burn::optim::{GradientsAccumulator, GradientsParams, SgdConfig};
use burn::tensor::Device;
use rayon::prelude::*;

use super::data::Targets;
use super::loss::{loss, loss_denominator};
use super::modules::{TrainGnn, TrainPointNet};
use super::{EdgeLayout, Net, device_input};
use crate::graph::Batch;
use crate::nn::model::{Arch, ModelWeights};

/// A batch cut into `count` shards of consecutive examples (sizes differ by
/// at most one; never more shards than examples).
pub fn shards(batch: &Batch, targets: &Targets, count: usize) -> Vec<(Batch, Targets)> {
    let count = count.clamp(1, batch.batch.max(1));
    let (per, extra) = (batch.batch / count, batch.batch % count);
    let mut start = 0;
    (0..count)
        .map(|k| {
            let end = start + per + usize::from(k < extra);
            let range = start..end;
            start = end;
            (batch.rows(range.clone()), targets.rows(range, batch.n))
        })
        .collect()
}

/// The whole batch's loss (normalised units) and its gradients, one shard
/// per rayon task.
pub(super) fn gradients<M: Net>(
    model: &M,
    weights: &ModelWeights,
    shards: &[(Batch, Targets)],
    layout: EdgeLayout,
    device: &Device,
) -> (f64, GradientsParams) {
    let task = weights.task();
    let scale = weights.output_scale();
    let total: f64 = shards
        .iter()
        .map(|(batch, _)| loss_denominator(task, batch))
        .sum();
    let forks: Vec<M> = shards.iter().map(|_| model.clone().fork(device)).collect();
    let results: Vec<(f64, GradientsParams)> = forks
        .into_par_iter()
        .zip(shards.par_iter())
        .map(|(fork, (batch, targets))| {
            let out = fork.run(&device_input(weights, batch, layout, device));
            let share = loss_denominator(task, batch) / total;
            let l = loss(task, out, batch, targets, &scale, device).mul_scalar(share as f32);
            let value = l.clone().into_scalar::<f32>() as f64;
            (value, GradientsParams::from_grads(l.backward(), &fork))
        })
        .collect();
    let mut accumulator = GradientsAccumulator::new();
    let mut value = 0.0;
    for (v, grads) in results {
        value += v;
        accumulator.accumulate(model, grads);
    }
    (value, accumulator.grads())
}

/// One plain gradient-descent step (w − rate · ∇loss) on `batch` cut into
/// `count` shards, edges laid out as `layout`: the loss before the step and
/// the weights after it. For tests: neither sharding nor the layout may
/// change the step.
pub fn descend(
    weights: &ModelWeights,
    batch: &Batch,
    targets: &Targets,
    (count, layout): (usize, EdgeLayout),
    rate: f64,
) -> (f64, ModelWeights) {
    let shards = shards(batch, targets, count);
    match weights.arch() {
        Arch::Gnn => descend_with::<TrainGnn>(weights, &shards, layout, rate),
        Arch::PointNet => descend_with::<TrainPointNet>(weights, &shards, layout, rate),
    }
}

/// [`descend`] for one architecture.
fn descend_with<M: Net>(
    weights: &ModelWeights,
    shards: &[(Batch, Targets)],
    layout: EdgeLayout,
    rate: f64,
) -> (f64, ModelWeights) {
    let device = Device::flex().autodiff();
    let model = M::build(weights, &device);
    let (value, grads) = gradients(&model, weights, shards, layout, &device);
    let model = SgdConfig::new().init().step(rate, model, grads);
    (value, model.weights(weights))
}
