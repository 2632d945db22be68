//! Training with burn (Flex CPU backend): Adam, batches of one tree size,
//! validation on held-out trees after every epoch, the best model kept,
//! and checkpoints that a later run resumes exactly (weights, optimiser
//! state, epoch and batch position; the shuffling and the augmentation
//! angles are functions of the seed, epoch and batch, so no RNG state is
//! stored). See [`checkpoint`] for the files.
//!
//! The recipe ([`TrainConfig::paper`]): Adam from 1e-3 with a cosine decay
//! to 1e-5 over the planned epochs, batch 128, gradient norm clipped at 1,
//! and each example turned by a fresh random angle about the vertical axis
//! every epoch. That rotation is an exact symmetry of the simulator
//! (gravity off, isotropic joints), so it is free data; measured on this
//! project's split it is what takes the forward GNN from 3.4 cm to about
//! 1.4 cm in ~117 epochs. The older plateau schedule (halve after
//! `patience` epochs without improvement) remains selectable.
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

pub mod checkpoint;
pub mod data;
mod device;
pub mod finetune;
pub mod foliage;
mod loss;
mod memory;
pub mod modules;
pub mod step;

pub use self::device::{EdgeLayout, device_input};
pub use self::memory::keep_freed_pages;

use crate::graph::path::Encoding;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::bail;
use burn::module::Module;
use burn::optim::AdamConfig;
use burn::tensor::Device;
use serde::{Deserialize, Serialize};

use self::checkpoint::{
    BEST_FILE, MODEL_FILE, OPTIMIZER_FILE, cpu_model, load_module, save_module, write_json,
};
pub use self::checkpoint::{
    Normalisation, STATE_FILE, TrainState, current_weights, read_best, read_state,
};
pub use self::data::TurnWeight;
use self::data::{Examples, Targets};
use self::loss::validate;
use self::modules::{DeviceInput, Outputs, TrainGnn, TrainPointNet, values};
use super::gnn::{Connectivity, EdgeAttributes, GnnConfig};
use super::model::{Arch, ModelWeights};
use crate::graph::{Batch, Task};

/// How the learning rate moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Schedule {
    /// Halve after `patience` epochs without a better validation score,
    /// down to `min_learning_rate`.
    Plateau,
    /// From `learning_rate` to `min_learning_rate` along half a cosine over
    /// the planned `epochs`, updated every step.
    Cosine,
}

impl Schedule {
    /// The rate for a step `progress` ∈ [0, 1] of the way through the plan
    /// (cosine), or the plateau schedule's current rate.
    pub fn rate(self, config: &TrainConfig, plateau_rate: f64, progress: f64) -> f64 {
        match self {
            Schedule::Plateau => plateau_rate,
            Schedule::Cosine => {
                let t = progress.clamp(0.0, 1.0);
                let (hi, lo) = (config.learning_rate, config.min_learning_rate);
                lo + 0.5 * (hi - lo) * (1.0 + (std::f64::consts::PI * t).cos())
            }
        }
    }
}

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
    /// Planned epochs (the cosine schedule spans them).
    pub epochs: usize,
    pub batch_size: usize,
    pub learning_rate: f64,
    pub schedule: Schedule,
    /// Plateau schedule: halve the rate after this many epochs without a
    /// better validation score.
    pub patience: usize,
    /// Floor of the plateau schedule; end point of the cosine one.
    pub min_learning_rate: f64,
    /// Turn every example by a random angle about the vertical axis
    /// through its root, drawn afresh each epoch.
    pub augment_rotation: bool,
    /// Clip each step's gradient to this global L2 norm (absent: no clipping).
    #[serde(default)]
    pub grad_clip: Option<f64>,
    pub seed: u64,
    /// GNN only.
    pub layers: usize,
    pub hidden: usize,
    pub edge_attributes: EdgeAttributes,
    pub connectivity: Connectivity,
    /// GNN: the whole tree (the paper) or the push's path.
    #[serde(default)]
    pub encoding: Encoding,
    /// The graph encoding the run feeds (`crate::graph::FEATURE_LAYOUT_VERSION`
    /// when it started); checkpoints from before the field existed are layout 1.
    #[serde(default = "layout_one")]
    pub feature_layout: u32,
    /// A checkpoint directory whose best weights start this run
    /// (fine-tuning), carried over to this run's layout; absent: random.
    #[serde(default)]
    pub init_from: Option<PathBuf>,
    /// A path rotation model: what each branch's squared turn error is
    /// weighed by ([`TurnWeight`]; uniform for runs from before the field
    /// existed).
    #[serde(default)]
    pub turn_weight: TurnWeight,
    /// The command line that started the run.
    pub command: String,
}

fn layout_one() -> u32 {
    1
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
            epochs: 120,
            batch_size: 128,
            learning_rate: 1e-3,
            schedule: Schedule::Cosine,
            patience: 2,
            min_learning_rate: 1e-5,
            augment_rotation: true,
            grad_clip: Some(1.0),
            seed: 0,
            layers: gnn.layers,
            hidden: gnn.hidden,
            edge_attributes: gnn.edge_attributes,
            connectivity: gnn.connectivity,
            encoding: gnn.encoding,
            feature_layout: crate::graph::FEATURE_LAYOUT_VERSION,
            init_from: None,
            turn_weight: TurnWeight::Uniform,
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

/// A network burn can train.
pub(crate) trait Net: Module + Sized + Sync {
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

/// What may change when a run is resumed.
#[derive(Debug, Clone, Default)]
pub struct ResumeOptions {
    /// A new plan of epochs (the cosine schedule stretches from where the
    /// run stands); absent keeps the stored plan.
    pub epochs: Option<usize>,
    /// The dataset directory, if it moved (the data must be the same).
    pub data: Option<PathBuf>,
    /// The command line, appended to the run's history.
    pub command: String,
}

/// Starts a new run in checkpoint `dir` (which must not hold one) and
/// trains until the planned epochs are done or `deadline` passes.
pub fn train(
    config: TrainConfig,
    dir: &Path,
    deadline: Option<Instant>,
    on_event: &mut dyn FnMut(TrainEvent),
) -> anyhow::Result<(TrainState, StopReason)> {
    if dir.join(STATE_FILE).exists() {
        bail!(
            "{} already holds a checkpoint: pass --resume to continue it, or choose another directory",
            dir.display()
        );
    }
    std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("creating {}: {e}", dir.display()))?;
    let examples = examples_of(&config)?;
    let state = TrainState {
        normalisation: Normalisation::of(&examples, &config)?,
        learning_rate: config.learning_rate,
        commands: vec![config.command.clone()],
        config,
        epoch: 0,
        batch: 0,
        epochs_without_improvement: 0,
        best: None,
        history: Vec::new(),
        samples: 0,
        seconds: 0.0,
        epoch_loss_sum: 0.0,
        epoch_loss_count: 0,
        cpus: Vec::new(),
    };
    run_arch(state, examples, dir, false, deadline, on_event)
}

/// The examples a run's configuration names.
fn examples_of(config: &TrainConfig) -> anyhow::Result<Examples> {
    let mut examples = Examples::load(
        &config.data,
        &config.sizes,
        config.limit_per_size,
        config.encoding,
    )?;
    if config.turn_weight != TurnWeight::Uniform {
        anyhow::ensure!(
            config.encoding == Encoding::PathRotation,
            "weighing turns is for the path_rotation encoding"
        );
        examples.weigh_turns(config.turn_weight);
    }
    Ok(examples)
}

/// [`run`] for the run's architecture.
fn run_arch(
    state: TrainState,
    examples: Examples,
    dir: &Path,
    resumed: bool,
    deadline: Option<Instant>,
    on_event: &mut dyn FnMut(TrainEvent),
) -> anyhow::Result<(TrainState, StopReason)> {
    match state.config.arch {
        Arch::Gnn => run::<TrainGnn>(state, examples, dir, resumed, deadline, on_event),
        Arch::PointNet => run::<TrainPointNet>(state, examples, dir, resumed, deadline, on_event),
    }
}

/// Continues the run in checkpoint `dir` exactly where it stopped.
pub fn resume(
    dir: &Path,
    options: ResumeOptions,
    deadline: Option<Instant>,
    on_event: &mut dyn FnMut(TrainEvent),
) -> anyhow::Result<(TrainState, StopReason)> {
    if !dir.join(STATE_FILE).exists() {
        bail!("no checkpoint to resume in {}", dir.display());
    }
    let mut state = read_state(dir)?;
    if let Some(epochs) = options.epochs {
        state.config.epochs = epochs;
    }
    if let Some(data) = options.data {
        state.config.data = data;
    }
    state.commands.push(options.command);
    let config = &state.config;
    let examples = examples_of(config)?;
    anyhow::ensure!(
        Normalisation::of(&examples, config)? == state.normalisation,
        "the data in {} is not the data this run started on (its statistics differ); regenerate it with the run's dataset command",
        config.data.display()
    );
    run_arch(state, examples, dir, true, deadline, on_event)
}

fn run<M: Net>(
    mut state: TrainState,
    examples: Examples,
    dir: &Path,
    resume: bool,
    deadline: Option<Instant>,
    on_event: &mut dyn FnMut(TrainEvent),
) -> anyhow::Result<(TrainState, StopReason)> {
    let config = state.config.clone();
    let cpu = cpu_model();
    if !state.cpus.contains(&cpu) {
        state.cpus.push(cpu);
    }
    let device = Device::flex().autodiff();
    anyhow::ensure!(
        state.config.arch == Arch::PointNet
            || state.config.feature_layout == crate::graph::FEATURE_LAYOUT_VERSION,
        "{} was trained on feature layout {}; this build encodes layout {}: start a new run from it with --init-from {}",
        dir.display(),
        state.config.feature_layout,
        crate::graph::FEATURE_LAYOUT_VERSION,
        dir.display()
    );
    let weights = state.initial_weights()?;
    let mut model = M::build(&weights, &device);
    let mut optimizer = AdamConfig::new()
        .with_epsilon(1e-8)
        .with_grad_clipping(
            config
                .grad_clip
                .map(|c| burn::grad_clipping::GradientClippingConfig::Norm(c as f32)),
        )
        .init();
    if resume {
        model = load_module(model, &dir.join(MODEL_FILE))?;
        optimizer = optimizer
            .load(dir.join(OPTIMIZER_FILE))
            .map_err(|e| anyhow::anyhow!("loading the optimiser state: {e}"))?;
    }
    let task = config.task;
    let save = |state: &TrainState, model: &M, optimizer: &burn::optim::ModuleOptimizer| {
        save_module(model, &dir.join(MODEL_FILE))?;
        let tmp = dir.join("optimizer.bpk.tmp");
        optimizer
            .save(&tmp)
            .map_err(|e| anyhow::anyhow!("saving the optimiser state: {e}"))?;
        std::fs::rename(&tmp, dir.join(OPTIMIZER_FILE))?;
        write_json(&dir.join(STATE_FILE), state)
    };
    let layout = EdgeLayout::of(&weights);
    while state.epoch < state.config.epochs {
        let batches = examples.epoch_batches(config.seed, state.epoch, config.batch_size);
        on_event(TrainEvent::EpochStart {
            epoch: state.epoch,
            batches: batches.len(),
            done: state.batch,
        });
        let started = Instant::now();
        let samples_before = state.samples;
        let mut rate = state.learning_rate;
        while state.batch < batches.len() {
            if deadline.is_some_and(|d| Instant::now() >= d) {
                state.seconds += started.elapsed().as_secs_f64();
                save(&state, &model, &optimizer)?;
                return Ok((state, StopReason::TimeBudget));
            }
            let ids = &batches[state.batch];
            let angles = if config.augment_rotation {
                Examples::rotation_angles(config.seed, state.epoch, state.batch, ids.len())
            } else {
                Vec::new()
            };
            let (batch, targets) = examples.batch_rotated(task, ids, &angles);
            let shards = step::shards(&batch, &targets, rayon::current_num_threads());
            let progress = (state.epoch as f64 + state.batch as f64 / batches.len() as f64)
                / state.config.epochs as f64;
            rate = config
                .schedule
                .rate(&state.config, state.learning_rate, progress);
            let (value, grads) = step::gradients(&model, &weights, &shards, layout, &device);
            model = optimizer.step(rate, model, grads);
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
            learning_rate: rate,
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
            save_module(&model, &dir.join(BEST_FILE))?;
        } else {
            state.epochs_without_improvement += 1;
            // Only the plateau schedule reads this rate; under the cosine
            // it would drift down and show a rate that is not in use.
            if config.schedule == Schedule::Plateau
                && state.epochs_without_improvement >= config.patience
            {
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

/// Runs the burn model (no autodiff) on a batch and returns de-normalised
/// outputs in the same form as the reference pass: for parity tests.
pub fn burn_forward(weights: &ModelWeights, batch: &Batch) -> crate::graph::contract::ModelOutput {
    let device = Device::flex();
    let input = device_input(weights, batch, EdgeLayout::of(weights), &device);
    let out = match weights {
        ModelWeights::Gnn(_) => TrainGnn::build(weights, &device).run(&input),
        ModelWeights::PointNet(_) => TrainPointNet::build(weights, &device).run(&input),
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
    crate::graph::contract::ModelOutput {
        vectors,
        affordance,
    }
}

/// Runs `steps` optimisation steps on one fixed batch cut into `shards`
/// shards (`train` uses one per core), edges laid out as `layout`, and
/// returns the seconds spent cutting the batch and the seconds the steps
/// took: for the training throughput benchmark.
pub fn time_steps(
    weights: &ModelWeights,
    batch: &Batch,
    targets: &Targets,
    steps: usize,
    (shards, layout): (usize, EdgeLayout),
) -> (f64, f64) {
    fn go<M: Net>(
        weights: &ModelWeights,
        batch: &Batch,
        targets: &Targets,
        steps: usize,
        (count, layout): (usize, EdgeLayout),
    ) -> (f64, f64) {
        let device = Device::flex().autodiff();
        let mut model = M::build(weights, &device);
        let mut optimizer = AdamConfig::new().init();
        let prep = Instant::now();
        let shards = step::shards(batch, targets, count);
        let prep = prep.elapsed().as_secs_f64();
        let started = Instant::now();
        for _ in 0..steps {
            let (_, grads) = step::gradients(&model, weights, &shards, layout, &device);
            model = optimizer.step(1e-3, model, grads);
        }
        (prep, started.elapsed().as_secs_f64())
    }
    match weights.arch() {
        Arch::Gnn => go::<TrainGnn>(weights, batch, targets, steps, (shards, layout)),
        Arch::PointNet => go::<TrainPointNet>(weights, batch, targets, steps, (shards, layout)),
    }
}
