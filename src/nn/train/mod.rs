//! Training with burn (Flex CPU backend): Adam, batches of one tree size,
//! validation on held-out trees after every epoch, the best model kept,
//! and checkpoints that a later run resumes exactly (weights, optimiser
//! state, epoch and batch position; the shuffling is a function of the
//! seed and the epoch, so it needs no stored RNG state).
//!
//! Losses are taken in normalised output units (Δp or T divided by their
//! training-split standard deviation):
//! - forward model: mean squared error over the real nodes;
//! - contact policy: cross-entropy of the affordance softmax (over the
//!   tree's real nodes) against the contacted node, plus the mean squared
//!   error of the action predicted *at the contacted node*. The original
//!   code regressed the action at the arg-max node with weights 0.99/0.01;
//!   regressing at the true node gives every example a well-defined target
//!   from the first step, and the two terms are of the same order in
//!   normalised units, so they are simply added.
//!
//! A checkpoint directory holds `state.json` (configuration, progress,
//! history, the initial weights with their statistics), `model.bpk` and
//! `optimizer.bpk` (burn's burnpack records) and `best.json` (the weights
//! with the best validation score, which `treemanip export` reads).

pub mod data;
pub mod modules;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams};
use burn::tensor::activation::log_softmax;
use burn::tensor::{Device, Tensor, TensorData};
use serde::{Deserialize, Serialize};

use self::data::{Examples, Targets};
use self::modules::{DeviceInput, Outputs, TrainGnn, TrainPointNet, values};
use super::gnn::{Connectivity, EdgeAttributes, GnnConfig, GnnWeights};
use super::input::gnn_input;
use super::model::{Arch, ModelWeights};
use super::pointnet::{PointNetConfig, PointNetWeights, point_input};
use crate::graph::{Batch, Task};

/// Everything that defines a training run (stored in the checkpoint and in
/// the exported model's metadata).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    pub task: Task,
    pub arch: Arch,
    /// Directory with `train_N{n}.npz` files (`treemanip dataset collect`).
    pub data: PathBuf,
    /// Tree sizes to train on (the paper: 11, 13, 15, 17, 19).
    pub sizes: Vec<usize>,
    /// At most this many episodes per size (all when absent).
    pub limit_per_size: Option<usize>,
    pub epochs: usize,
    pub batch_size: usize,
    pub learning_rate: f64,
    /// Halve the rate after this many epochs without a better validation
    /// score, down to `min_learning_rate`.
    pub patience: usize,
    pub min_learning_rate: f64,
    /// Clip each step's gradient to this global L2 norm (absent: no clipping).
    #[serde(default)]
    pub grad_clip: Option<f64>,
    pub seed: u64,
    /// GNN only.
    pub layers: usize,
    pub hidden: usize,
    pub edge_attributes: EdgeAttributes,
    pub connectivity: Connectivity,
    /// The command line that started the run.
    pub command: String,
}

impl TrainConfig {
    /// The paper's setup for a task and architecture.
    pub fn paper(task: Task, arch: Arch, data: PathBuf) -> Self {
        let gnn = GnnConfig::paper(task);
        Self {
            task,
            arch,
            data,
            sizes: vec![11, 13, 15, 17, 19],
            limit_per_size: None,
            epochs: 100,
            batch_size: 64,
            learning_rate: 1e-3,
            patience: 2,
            min_learning_rate: 1e-4,
            grad_clip: Some(1.0),
            seed: 0,
            layers: gnn.layers,
            hidden: gnn.hidden,
            edge_attributes: gnn.edge_attributes,
            connectivity: gnn.connectivity,
            command: String::new(),
        }
    }
}

/// Validation after one epoch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpochRecord {
    pub epoch: usize,
    pub learning_rate: f64,
    pub train_loss: f64,
    pub validation_loss: f64,
    /// Forward: mean over episodes of the maximum node error (m), the
    /// paper's e_N. Policy: mean error of the action at the contacted node (m).
    pub validation_error: f64,
    /// Policy: how often the arg-max affordance is the contacted node.
    pub validation_accuracy: Option<f64>,
    pub seconds: f64,
    pub samples_per_second: f64,
}

/// Progress of a run; `state.json` in the checkpoint directory.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TrainState {
    pub config: TrainConfig,
    /// The initial weights (carry configuration and statistics).
    pub initial: ModelWeights,
    /// Next epoch and batch to run.
    pub epoch: usize,
    pub batch: usize,
    pub learning_rate: f64,
    pub epochs_without_improvement: usize,
    /// (epoch, validation score) of `best.json`; lower is better.
    pub best: Option<(usize, f64)>,
    pub history: Vec<EpochRecord>,
    pub samples: u64,
    pub seconds: f64,
    /// Running mean of the training loss within the current epoch.
    pub epoch_loss_sum: f64,
    pub epoch_loss_count: u64,
}

impl TrainState {
    pub fn finished(&self) -> bool {
        self.epoch >= self.config.epochs
    }
}

/// What the caller hears about (for progress bars and logs).
pub enum TrainEvent<'a> {
    EpochStart {
        epoch: usize,
        batches: usize,
        done: usize,
    },
    Step {
        loss: f64,
    },
    EpochEnd(&'a EpochRecord),
}

/// Why `train` returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    Finished,
    TimeBudget,
}

pub const STATE_FILE: &str = "state.json";
pub const BEST_FILE: &str = "best.json";
const MODEL_FILE: &str = "model.bpk";
const OPTIMIZER_FILE: &str = "optimizer.bpk";

/// A network burn can train.
trait Net: Module + Sized {
    fn build(weights: &ModelWeights, device: &Device) -> Self;
    fn run(&self, input: &DeviceInput) -> Outputs;
    fn weights(&self, initial: &ModelWeights) -> ModelWeights;
}

impl Net for TrainGnn {
    fn build(weights: &ModelWeights, device: &Device) -> Self {
        match weights {
            ModelWeights::Gnn(w) => TrainGnn::new(w, device),
            ModelWeights::PointNet(_) => unreachable!("GNN weights expected"),
        }
    }
    fn run(&self, input: &DeviceInput) -> Outputs {
        self.forward(input)
    }
    fn weights(&self, initial: &ModelWeights) -> ModelWeights {
        match initial {
            ModelWeights::Gnn(w) => ModelWeights::Gnn(self.to_weights(w)),
            ModelWeights::PointNet(_) => unreachable!("GNN weights expected"),
        }
    }
}

impl Net for TrainPointNet {
    fn build(weights: &ModelWeights, device: &Device) -> Self {
        match weights {
            ModelWeights::PointNet(w) => TrainPointNet::new(w, device),
            ModelWeights::Gnn(_) => unreachable!("PointNet weights expected"),
        }
    }
    fn run(&self, input: &DeviceInput) -> Outputs {
        self.forward(input)
    }
    fn weights(&self, initial: &ModelWeights) -> ModelWeights {
        match initial {
            ModelWeights::PointNet(w) => ModelWeights::PointNet(self.to_weights(w)),
            ModelWeights::Gnn(_) => unreachable!("PointNet weights expected"),
        }
    }
}

fn tensor<const D: usize>(values: Vec<f32>, shape: [usize; D], device: &Device) -> Tensor<D> {
    Tensor::from_data(TensorData::new(values, shape), device)
}

/// The model-side inputs of a batch, on `device`.
pub fn device_input(weights: &ModelWeights, batch: &Batch, device: &Device) -> DeviceInput {
    let (b, n) = (batch.batch, batch.n);
    let node_mask = tensor(batch.mask.clone(), [b, n], device);
    match weights {
        ModelWeights::Gnn(w) => {
            let task = w.config.task;
            let input = gnn_input(
                batch,
                &w.stats,
                w.config.edge_attributes,
                w.config.connectivity,
            );
            DeviceInput {
                nodes: tensor(input.nodes, [b, n, task.node_dim()], device),
                edges: Some(tensor(
                    input.edges,
                    [b, n, n, crate::graph::EDGE_DIM],
                    device,
                )),
                global: (task.global_dim() > 0)
                    .then(|| tensor(input.global, [b, task.global_dim()], device)),
                edge_mask: Some(tensor(input.edge_mask, [b, n, n, 1], device)),
                node_mask,
            }
        }
        ModelWeights::PointNet(w) => DeviceInput {
            nodes: tensor(point_input(w, batch), [b, n, w.config.point_dim()], device),
            edges: None,
            global: None,
            edge_mask: None,
            node_mask,
        },
    }
}

/// The loss of one batch (normalised units).
fn loss(
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
            let mask = tensor(batch.mask.clone(), [b, n, 1], device);
            let count = batch.mask.iter().sum::<f32>() * 3.0;
            ((out.vectors - target).square() * mask)
                .sum()
                .div_scalar(count)
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
                .div_scalar(b as f32);
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
fn validate<M: Net>(
    model: &M,
    weights: &ModelWeights,
    examples: &Examples,
    batch_size: usize,
) -> (f64, f64, Option<f64>) {
    let device = Device::flex();
    let model = model.valid();
    let task = weights.task();
    let scale = weights.output_scale();
    let (mut loss_sum, mut error_sum, mut correct, mut count, mut batches) =
        (0.0, 0.0, 0usize, 0usize, 0usize);
    for ids in examples.validation_batches(batch_size) {
        let (batch, targets) = examples.batch(task, &ids);
        let out = model.run(&device_input(weights, &batch, &device));
        let vectors = values(out.vectors.clone());
        let logits = out.logits.clone().map(values);
        loss_sum += loss(task, out, &batch, &targets, &scale, &device).into_scalar::<f32>() as f64;
        batches += 1;
        let n = batch.n;
        let denorm = |k: usize, c: usize| vectors[k * 3 + c] as f64 * scale.1[c] + scale.0[c];
        for g in 0..batch.batch {
            count += 1;
            match task {
                Task::Forward => {
                    let mut worst = 0.0f64;
                    for j in 0..n {
                        if batch.mask[g * n + j] == 0.0 {
                            continue;
                        }
                        let e: f64 = (0..3)
                            .map(|c| {
                                let d = denorm(g * n + j, c)
                                    - targets.displacement[(g * n + j) * 3 + c] as f64;
                                d * d
                            })
                            .sum();
                        worst = worst.max(e.sqrt());
                    }
                    error_sum += worst;
                }
                Task::Policy => {
                    let c = targets.contact[g];
                    let e: f64 = (0..3)
                        .map(|k| {
                            let d = denorm(g * n + c, k) - targets.push[g * 3 + k] as f64;
                            d * d
                        })
                        .sum();
                    error_sum += e.sqrt();
                    let row = &logits.as_ref().expect("policy logits")[g * n..(g + 1) * n];
                    let best = (0..n)
                        .filter(|&j| batch.mask[g * n + j] > 0.0)
                        .max_by(|&a, &b| row[a].total_cmp(&row[b]))
                        .unwrap_or(0);
                    correct += usize::from(best == c);
                }
            }
        }
    }
    let accuracy = (task == Task::Policy).then(|| correct as f64 / count.max(1) as f64);
    (
        loss_sum / batches.max(1) as f64,
        error_sum / count.max(1) as f64,
        accuracy,
    )
}

fn initial_weights(config: &TrainConfig, examples: &Examples) -> ModelWeights {
    let (stats, output, position) = examples.statistics(config.task);
    let seed = crate::seed::derive_seed(config.seed, &[0x1417]);
    let mut weights = match config.arch {
        Arch::Gnn => ModelWeights::Gnn(GnnWeights::random(
            GnnConfig {
                task: config.task,
                hidden: config.hidden,
                layers: config.layers,
                edge_attributes: config.edge_attributes,
                connectivity: config.connectivity,
            },
            stats,
            seed,
        )),
        Arch::PointNet => ModelWeights::PointNet(PointNetWeights::random(
            PointNetConfig::paper(config.task),
            stats,
            position,
            seed,
        )),
    };
    weights.set_output_scale(output.0, output.1);
    weights
}

fn write_json(path: &Path, value: &impl Serialize) -> anyhow::Result<()> {
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, serde_json::to_vec(value)?)
        .with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Reads the best weights of a checkpoint directory.
pub fn read_best(dir: &Path) -> anyhow::Result<ModelWeights> {
    let path = dir.join(BEST_FILE);
    let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
    serde_json::from_slice(&bytes).with_context(|| format!("parsing {}", path.display()))
}

pub fn read_state(dir: &Path) -> anyhow::Result<TrainState> {
    let path = dir.join(STATE_FILE);
    let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
    serde_json::from_slice(&bytes).with_context(|| format!("parsing {}", path.display()))
}

/// Trains (or, with `resume`, continues training) into checkpoint `dir`
/// until the configured epochs are done or `deadline` passes.
pub fn train(
    config: TrainConfig,
    dir: &Path,
    resume: bool,
    deadline: Option<Instant>,
    on_event: &mut dyn FnMut(TrainEvent),
) -> anyhow::Result<(TrainState, StopReason)> {
    let existing = dir.join(STATE_FILE).exists();
    if existing && !resume {
        bail!(
            "{} already holds a checkpoint: pass --resume to continue it, or choose another directory",
            dir.display()
        );
    }
    if resume && !existing {
        bail!("no checkpoint to resume in {}", dir.display());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let state = if resume {
        let mut state = read_state(dir)?;
        // Only the budget-like settings may change on resume.
        state.config.epochs = config.epochs;
        state
    } else {
        let examples = Examples::load(&config.data, &config.sizes, config.limit_per_size)?;
        let initial = initial_weights(&config, &examples);
        TrainState {
            learning_rate: config.learning_rate,
            config,
            initial,
            epoch: 0,
            batch: 0,
            epochs_without_improvement: 0,
            best: None,
            history: Vec::new(),
            samples: 0,
            seconds: 0.0,
            epoch_loss_sum: 0.0,
            epoch_loss_count: 0,
        }
    };
    match state.config.arch {
        Arch::Gnn => run::<TrainGnn>(state, dir, resume, deadline, on_event),
        Arch::PointNet => run::<TrainPointNet>(state, dir, resume, deadline, on_event),
    }
}

fn run<M: Net>(
    mut state: TrainState,
    dir: &Path,
    resume: bool,
    deadline: Option<Instant>,
    on_event: &mut dyn FnMut(TrainEvent),
) -> anyhow::Result<(TrainState, StopReason)> {
    let config = state.config.clone();
    let examples = Examples::load(&config.data, &config.sizes, config.limit_per_size)?;
    let device = Device::flex().autodiff();
    let mut model = M::build(&state.initial, &device);
    let mut optimizer = AdamConfig::new()
        .with_epsilon(1e-8)
        .with_grad_clipping(
            config
                .grad_clip
                .map(|c| burn::grad_clipping::GradientClippingConfig::Norm(c as f32)),
        )
        .init();
    if resume {
        model = model.load_file(dir.join(MODEL_FILE));
        optimizer = optimizer
            .load(dir.join(OPTIMIZER_FILE))
            .map_err(|e| anyhow::anyhow!("loading the optimiser state: {e}"))?;
    }
    let weights = state.initial.clone();
    let task = config.task;
    let scale = weights.output_scale();
    let save = |state: &TrainState, model: &M, optimizer: &burn::optim::ModuleOptimizer| {
        model
            .clone()
            .save_file(dir.join(MODEL_FILE))
            .map_err(|e| anyhow::anyhow!("saving the model: {e}"))?;
        optimizer
            .save(dir.join(OPTIMIZER_FILE))
            .map_err(|e| anyhow::anyhow!("saving the optimiser state: {e}"))?;
        write_json(&dir.join(STATE_FILE), state)
    };
    while state.epoch < config.epochs {
        let batches = examples.epoch_batches(config.seed, state.epoch, config.batch_size);
        on_event(TrainEvent::EpochStart {
            epoch: state.epoch,
            batches: batches.len(),
            done: state.batch,
        });
        let started = Instant::now();
        let samples_before = state.samples;
        while state.batch < batches.len() {
            if deadline.is_some_and(|d| Instant::now() >= d) {
                state.seconds += started.elapsed().as_secs_f64();
                save(&state, &model, &optimizer)?;
                return Ok((state, StopReason::TimeBudget));
            }
            let ids = &batches[state.batch];
            let (batch, targets) = examples.batch(task, ids);
            let out = model.run(&device_input(&weights, &batch, &device));
            let l = loss(task, out, &batch, &targets, &scale, &device);
            let value = l.clone().into_scalar::<f32>() as f64;
            let grads = GradientsParams::from_grads(l.backward(), &model);
            model = optimizer.step(state.learning_rate, model, grads);
            state.batch += 1;
            state.samples += ids.len() as u64;
            state.epoch_loss_sum += value;
            state.epoch_loss_count += 1;
            on_event(TrainEvent::Step { loss: value });
        }
        let seconds = started.elapsed().as_secs_f64();
        state.seconds += seconds;
        let (validation_loss, validation_error, validation_accuracy) =
            validate(&model, &weights, &examples, config.batch_size);
        let record = EpochRecord {
            epoch: state.epoch,
            learning_rate: state.learning_rate,
            train_loss: state.epoch_loss_sum / state.epoch_loss_count.max(1) as f64,
            validation_loss,
            validation_error,
            validation_accuracy,
            seconds,
            samples_per_second: (state.samples - samples_before) as f64 / seconds.max(1e-9),
        };
        let score = match task {
            Task::Forward => validation_error,
            Task::Policy => validation_loss,
        };
        if state.best.is_none_or(|(_, best)| score < best) {
            state.best = Some((state.epoch, score));
            state.epochs_without_improvement = 0;
            write_json(&dir.join(BEST_FILE), &model.weights(&weights))?;
        } else {
            state.epochs_without_improvement += 1;
            if state.epochs_without_improvement >= config.patience {
                state.learning_rate = (state.learning_rate * 0.5).max(config.min_learning_rate);
                state.epochs_without_improvement = 0;
            }
        }
        on_event(TrainEvent::EpochEnd(&record));
        state.history.push(record);
        state.epoch += 1;
        state.batch = 0;
        state.epoch_loss_sum = 0.0;
        state.epoch_loss_count = 0;
        save(&state, &model, &optimizer)?;
    }
    Ok((state, StopReason::Finished))
}

/// The weights a checkpoint's model holds right now (not necessarily the
/// best), for tests and inspection.
pub fn current_weights(dir: &Path) -> anyhow::Result<ModelWeights> {
    let state = read_state(dir)?;
    let device = Device::flex();
    Ok(match state.config.arch {
        Arch::Gnn => {
            let m = TrainGnn::build(&state.initial, &device).load_file(dir.join(MODEL_FILE));
            Net::weights(&m, &state.initial)
        }
        Arch::PointNet => {
            let m = TrainPointNet::build(&state.initial, &device).load_file(dir.join(MODEL_FILE));
            Net::weights(&m, &state.initial)
        }
    })
}

/// Runs the burn model (no autodiff) on a batch and returns de-normalised
/// outputs in the same form as the reference pass: for parity tests.
pub fn burn_forward(weights: &ModelWeights, batch: &Batch) -> super::gnn::GnnOutput {
    let device = Device::flex();
    let out = match weights {
        ModelWeights::Gnn(_) => {
            TrainGnn::build(weights, &device).run(&device_input(weights, batch, &device))
        }
        ModelWeights::PointNet(_) => {
            TrainPointNet::build(weights, &device).run(&device_input(weights, batch, &device))
        }
    };
    let (mean, std) = weights.output_scale();
    let vectors = values(out.vectors)
        .iter()
        .enumerate()
        .map(|(k, v)| (*v as f64 * std[k % 3] + mean[k % 3]) as f32)
        .collect();
    let affordance = out
        .logits
        .map(|l| super::gnn::masked_softmax(&values(l), &batch.mask, batch.batch, batch.n));
    super::gnn::GnnOutput {
        vectors,
        affordance,
    }
}

/// Runs `steps` optimisation steps on one fixed batch and returns the
/// seconds they took, excluding batch preparation: for the training
/// throughput benchmark.
pub fn time_steps(
    weights: &ModelWeights,
    batch: &Batch,
    targets: &Targets,
    steps: usize,
) -> (f64, f64) {
    fn go<M: Net>(
        weights: &ModelWeights,
        batch: &Batch,
        targets: &Targets,
        steps: usize,
    ) -> (f64, f64) {
        let device = Device::flex().autodiff();
        let mut model = M::build(weights, &device);
        let mut optimizer = AdamConfig::new().init();
        let scale = weights.output_scale();
        let prep = Instant::now();
        let input = device_input(weights, batch, &device);
        let prep = prep.elapsed().as_secs_f64();
        let started = Instant::now();
        for _ in 0..steps {
            let out = model.run(&input);
            let l = loss(weights.task(), out, batch, targets, &scale, &device);
            let grads = GradientsParams::from_grads(l.backward(), &model);
            model = optimizer.step(1e-3, model, grads);
        }
        (prep, started.elapsed().as_secs_f64())
    }
    match weights.arch() {
        Arch::Gnn => go::<TrainGnn>(weights, batch, targets, steps),
        Arch::PointNet => go::<TrainPointNet>(weights, batch, targets, steps),
    }
}
