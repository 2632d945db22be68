//! Starting a run from another run's best weights (`--init-from`), across
//! a change of the graph encoding.
//!
//! Layout 1 fed the edge encoder [Δp, v, K_s]; layout 2 feeds
//! [Δp, v, b, κ] (`crate::graph`). Every weight but the edge encoder's
//! first layer means the same in both, so a layout-1 model is carried
//! over as it is, with that layer widened:
//! - the columns of Δp and v, and every normalisation statistic the two
//!   layouts share (nodes, global, output, Δp, v), are the source's, so the
//!   network starts computing what it computed before;
//! - the K_s column's weight moves to b, scaled so that a branch and a
//!   non-branch pair see the same pre-activation as a branch of the
//!   training split's mean K_s did (w·(K_s − μ)/σ → a·w·(b − μ_b)/σ_b + c·w);
//! - κ's column starts at zero: the network learns what the ratios add.
//!
//! Measured on the shipped forward GNN: the widened model's error on
//! nominal trees before any fine-tuning is in `training/README.md`.

use std::path::Path;

use anyhow::{Context, bail};

use super::checkpoint::{Normalisation, TrainState, read_best_of, read_state};
use crate::graph::{BRANCH_COLUMN, EDGE_DIM, FEATURE_LAYOUT_VERSION, LOG_STIFFNESS_COLUMN};
use crate::nn::gnn::GnnWeights;
use crate::nn::model::ModelWeights;

/// Edge columns of a feature layout.
pub fn edge_dim(layout: u32) -> anyhow::Result<usize> {
    match layout {
        1 => Ok(5),
        FEATURE_LAYOUT_VERSION => Ok(EDGE_DIM),
        other => bail!(
            "feature layout {other} is unknown to this build (it encodes layout {FEATURE_LAYOUT_VERSION})"
        ),
    }
}

/// Layout 1's K_s column.
const LAYOUT_1_STIFFNESS: usize = 4;

/// The source run of `--init-from`, checked to be something this build can
/// carry over.
pub fn source_state(dir: &Path) -> anyhow::Result<TrainState> {
    let state = read_state(dir).with_context(|| {
        format!(
            "reading the run to start from ({}): it must be a checkpoint directory",
            dir.display()
        )
    })?;
    anyhow::ensure!(
        state.best.is_some(),
        "{} has no best weights yet (no finished epoch)",
        dir.display()
    );
    edge_dim(state.config.feature_layout)?;
    Ok(state)
}

/// The statistics of a run that starts from `source`: the source's
/// wherever the layouts share a feature, `fresh` (this run's data) for
/// the columns that are new.
pub fn normalisation(source: &TrainState, fresh: Normalisation) -> Normalisation {
    let old = &source.normalisation;
    let mut out = fresh;
    out.features.node_mean = old.features.node_mean.clone();
    out.features.node_std = old.features.node_std.clone();
    out.features.global_mean = old.features.global_mean.clone();
    out.features.global_std = old.features.global_std.clone();
    for c in 0..BRANCH_COLUMN {
        out.features.edge_mean[c] = old.features.edge_mean[c];
        out.features.edge_std[c] = old.features.edge_std[c];
    }
    if source.config.feature_layout == FEATURE_LAYOUT_VERSION {
        out.features.edge_mean = old.features.edge_mean.clone();
        out.features.edge_std = old.features.edge_std.clone();
    }
    out.output = old.output;
    out.position = old.position;
    out
}

/// The source's best weights, adapted to this run's layout, statistics and
/// edge attributes (an ablation may drop a group the source used).
pub fn initial_weights(
    dir: &Path,
    config: &super::TrainConfig,
    norm: &Normalisation,
) -> anyhow::Result<ModelWeights> {
    let source = source_state(dir)?;
    let weights = read_best_of(dir, &source)?;
    let ModelWeights::Gnn(mut w) = weights else {
        bail!(
            "{} holds a PointNet; --init-from carries GNN weights over",
            dir.display()
        );
    };
    if source.config.feature_layout == 1 {
        widen_edge_encoder(&mut w, &source.normalisation, norm);
    }
    w.stats = norm.features.clone();
    w.config.edge_attributes = config.edge_attributes;
    Ok(ModelWeights::Gnn(w))
}

/// Layout 1 → 2 on the edge encoder's first layer (see the module docs).
fn widen_edge_encoder(w: &mut GnnWeights, old: &Normalisation, new: &Normalisation) {
    let (mu_k, sd_k) = (
        old.features.edge_mean[LAYOUT_1_STIFFNESS],
        old.features.edge_std[LAYOUT_1_STIFFNESS],
    );
    let (mu_b, sd_b) = (
        new.features.edge_mean[BRANCH_COLUMN],
        new.features.edge_std[BRANCH_COLUMN],
    );
    // The mean K_s over all pairs is (share of branch pairs) × (mean over
    // branches), and the share of branch pairs is b's mean.
    let branch_k = if mu_b > 0.0 { mu_k / mu_b } else { 0.0 };
    let old_branch = (branch_k - mu_k) / sd_k;
    let old_other = -mu_k / sd_k;
    let new_branch = (1.0 - mu_b) / sd_b;
    let new_other = -mu_b / sd_b;
    let a = (old_branch - old_other) / (new_branch - new_other);
    let c = old_other - a * new_other;
    let layer = &mut w.edge_encoder.layers[0];
    let old_inputs = layer.inputs;
    let mut weight = Vec::with_capacity(layer.outputs * EDGE_DIM);
    for o in 0..layer.outputs {
        let row = &layer.weight[o * old_inputs..(o + 1) * old_inputs];
        let mut new_row = [0.0f32; EDGE_DIM];
        new_row[..BRANCH_COLUMN].copy_from_slice(&row[..BRANCH_COLUMN]);
        new_row[BRANCH_COLUMN] = (a * row[LAYOUT_1_STIFFNESS] as f64) as f32;
        new_row[LOG_STIFFNESS_COLUMN] = 0.0;
        layer.bias[o] += (c * row[LAYOUT_1_STIFFNESS] as f64) as f32;
        weight.extend_from_slice(&new_row);
    }
    layer.weight = weight;
    layer.inputs = EDGE_DIM;
}
