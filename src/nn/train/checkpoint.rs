//! A training run's checkpoint directory: everything a later run (possibly
//! on another machine, in another session) needs to continue exactly.
//!
//! | file | what | form |
//! | --- | --- | --- |
//! | `state.json` | configuration, normalisation statistics, progress, learning-rate state, history, the commands that ran | small JSON (a few kB) |
//! | `model.bpk` | current weights | burnpack (f32) |
//! | `optimizer.bpk` | Adam's first and second moments and step counts | burnpack (f32) |
//! | `best.bpk` | weights with the best validation score (what `treemanip export` reads) | burnpack (f32) |
//!
//! The initial weights are not stored: they are a function of the
//! configuration, the statistics and the seed ([`initial_weights`]), and
//! the data order and augmentation angles are functions of (seed, epoch,
//! batch), so no RNG state needs saving either. Everything is binary f32
//! but `state.json`, so a GNN checkpoint is about 4 × its weights (model,
//! best, two Adam moments) and can live in git.

use std::path::Path;

use anyhow::Context;
use burn::module::Module;
use burn::tensor::Device;
use serde::{Deserialize, Serialize};

use super::data::{Examples, MeanStd};
use super::modules::{TrainGnn, TrainPointNet};
use super::{EpochRecord, Net, TrainConfig};
use crate::graph::FeatureStats;
use crate::nn::gnn::{GnnConfig, GnnWeights};
use crate::nn::model::{Arch, ModelWeights};
use crate::nn::pointnet::{PointNetConfig, PointNetWeights};

pub const STATE_FILE: &str = "state.json";
pub const MODEL_FILE: &str = "model.bpk";
pub const OPTIMIZER_FILE: &str = "optimizer.bpk";
pub const BEST_FILE: &str = "best.bpk";

/// Normalisation statistics of the training examples (never the
/// validation or test trees).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Normalisation {
    pub features: FeatureStats,
    /// Of the output (Δp or T).
    pub output: MeanStd,
    /// Of p_j − p_0 (the PointNet's per-point position).
    pub position: MeanStd,
}

impl Normalisation {
    /// The statistics a run on `examples` uses: its own, or with
    /// `init_from`, the source run's wherever the features are shared
    /// ([`super::finetune::normalisation`]).
    pub fn of(examples: &Examples, config: &TrainConfig) -> anyhow::Result<Self> {
        let (features, output, position) = examples.statistics(config.task);
        let fresh = Self {
            features,
            output,
            position,
        };
        Ok(match &config.init_from {
            Some(dir) => {
                super::finetune::normalisation(&super::finetune::source_state(dir)?, fresh)
            }
            None => fresh,
        })
    }
}

/// Progress of a run; `state.json` in the checkpoint directory.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TrainState {
    pub config: TrainConfig,
    pub normalisation: Normalisation,
    /// Next epoch and batch to run.
    pub epoch: usize,
    pub batch: usize,
    /// Plateau schedule: the current rate and epochs since an improvement.
    pub learning_rate: f64,
    pub epochs_without_improvement: usize,
    /// (epoch, validation score) of `best.bpk`; lower is better.
    pub best: Option<(usize, f64)>,
    pub history: Vec<EpochRecord>,
    pub samples: u64,
    pub seconds: f64,
    /// Running mean of the training loss within the current epoch.
    pub epoch_loss_sum: f64,
    pub epoch_loss_count: u64,
    /// Every command that started or resumed this run, in order.
    pub commands: Vec<String>,
    /// CPU model of each machine that trained it (deduplicated).
    #[serde(default)]
    pub cpus: Vec<String>,
}

impl TrainState {
    pub fn finished(&self) -> bool {
        self.epoch >= self.config.epochs
    }

    /// The weights the run started from, with the configuration and
    /// statistics every later set of weights shares.
    pub fn initial_weights(&self) -> anyhow::Result<ModelWeights> {
        initial_weights(&self.config, &self.normalisation)
    }
}

/// The run's initial weights: deterministic in (config, statistics, seed),
/// or with `init_from`, the source run's best weights carried over to this
/// run's layout ([`super::finetune`]).
pub fn initial_weights(config: &TrainConfig, norm: &Normalisation) -> anyhow::Result<ModelWeights> {
    if let Some(dir) = &config.init_from {
        return super::finetune::initial_weights(dir, config, norm);
    }
    let mut weights = random_weights(config, norm);
    // A checkpoint of an older layout is read with its own edge width
    // (to be exported refused, or carried over by `--init-from`).
    if let ModelWeights::Gnn(w) = &mut weights {
        let dim = super::finetune::edge_dim(config.feature_layout)?;
        let layer = &mut w.edge_encoder.layers[0];
        if layer.inputs != dim {
            layer.weight = vec![0.0; layer.outputs * dim];
            layer.inputs = dim;
        }
    }
    Ok(weights)
}

fn random_weights(config: &TrainConfig, norm: &Normalisation) -> ModelWeights {
    let seed = crate::seed::derive_seed(config.seed, &[0x1417]);
    let mut weights = match config.arch {
        Arch::Gnn => ModelWeights::Gnn(GnnWeights::random(
            GnnConfig {
                task: config.task,
                hidden: config.hidden,
                layers: config.layers,
                edge_attributes: config.edge_attributes,
                connectivity: config.connectivity,
                encoding: config.encoding,
            },
            norm.features.clone(),
            seed,
        )),
        Arch::PointNet => ModelWeights::PointNet(PointNetWeights::random(
            PointNetConfig::paper(config.task),
            norm.features.clone(),
            norm.position,
            seed,
        )),
    };
    weights.set_output_scale(norm.output.0, norm.output.1);
    weights
}

pub fn write_json(path: &Path, value: &impl Serialize) -> anyhow::Result<()> {
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, serde_json::to_vec_pretty(value)?)
        .with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Writes a module's weights to `path` atomically (a crash mid-write leaves
/// the previous file).
pub(super) fn save_module<M: Module>(module: &M, path: &Path) -> anyhow::Result<()> {
    let tmp = path.with_extension("bpk.tmp");
    module
        .clone()
        .save_file(&tmp)
        .map_err(|e| anyhow::anyhow!("writing {}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("writing {}", path.display()))
}

pub(super) fn load_module<M: Module>(module: M, path: &Path) -> anyhow::Result<M> {
    module
        .try_load_file(path)
        .map_err(|e| anyhow::anyhow!("reading {}: {e}", path.display()))
}

pub fn read_state(dir: &Path) -> anyhow::Result<TrainState> {
    let path = dir.join(STATE_FILE);
    let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
    serde_json::from_slice(&bytes).with_context(|| format!("parsing {}", path.display()))
}

fn weights_in(dir: &Path, state: &TrainState, file: &str) -> anyhow::Result<ModelWeights> {
    let initial = state.initial_weights()?;
    let device = Device::flex();
    let path = dir.join(file);
    Ok(match state.config.arch {
        Arch::Gnn => {
            let m = load_module(TrainGnn::build(&initial, &device), &path)?;
            Net::weights(&m, &initial)
        }
        Arch::PointNet => {
            let m = load_module(TrainPointNet::build(&initial, &device), &path)?;
            Net::weights(&m, &initial)
        }
    })
}

/// The best weights of a checkpoint directory.
pub fn read_best(dir: &Path) -> anyhow::Result<ModelWeights> {
    weights_in(dir, &read_state(dir)?, BEST_FILE)
}

/// The best weights of a checkpoint directory whose state is already read.
pub fn read_best_of(dir: &Path, state: &TrainState) -> anyhow::Result<ModelWeights> {
    weights_in(dir, state, BEST_FILE)
}

/// The weights a checkpoint's model holds right now (not necessarily the
/// best), for tests and inspection.
pub fn current_weights(dir: &Path) -> anyhow::Result<ModelWeights> {
    weights_in(dir, &read_state(dir)?, MODEL_FILE)
}

/// This machine's CPU model, as /proc/cpuinfo names it.
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_owned())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_owned())
}
