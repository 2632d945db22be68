//! Collecting episodes: for each split and size, a set of distinct trees and
//! pushes drawn as in the paper, simulated in parallel. Every episode has
//! its own random stream (derived from the base seed, split, size and
//! episode index), so the files do not depend on thread scheduling.
//!
//! A push the simulator rejects (the gripper loses the branch, the node
//! cannot be carried that far, no convergence) is discarded and counted,
//! and the episode draws another push on the same tree, as the original
//! data collection discarded such episodes.

use std::collections::BTreeMap;
use std::time::Instant;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Episode, SizeData, Split};
use crate::seed::derive_seed;
use crate::sim::sampling::PushDistribution;
use crate::sim::{ContactModel, Hold, SimConfig, simulate};
use crate::tree::collection::{CollectionError, TreeShape, tree_set};

fn is_sca(shape: &TreeShape) -> bool {
    *shape == TreeShape::Sca
}
use crate::tree::{ScaParams, StiffnessVariation};

/// Seed part of the trees' stiffness streams (no episode index reaches it).
const STIFFNESS_STREAM: u64 = u64::MAX - 1;

/// How a dataset is made; recorded next to it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CollectConfig {
    pub seed: u64,
    /// Trees per split and size (the paper: 100 unique topologies).
    pub trees_per_size: usize,
    /// Skip generated trees whose topology repeats an earlier one.
    pub distinct_topologies: bool,
    pub tree_params: ScaParams,
    /// Which generator grows the trees (SCA unless recorded otherwise).
    #[serde(default, skip_serializing_if = "is_sca")]
    pub shape: TreeShape,
    pub pushes: PushDistribution,
    pub contact: ContactModel,
    /// Pushes drawn for one episode before giving up on it.
    pub max_attempts: usize,
    /// Stiffness varied away from the radius formula, per tree
    /// ([`StiffnessVariation`]); none by default (the paper's data). The
    /// files then hold each tree's varied stiffness, which `tree_seed`
    /// alone does not give back.
    #[serde(default, skip_serializing_if = "StiffnessVariation::is_none")]
    pub stiffness: StiffnessVariation,
}

impl Default for CollectConfig {
    fn default() -> Self {
        Self {
            seed: 7,
            trees_per_size: 100,
            distinct_topologies: true,
            tree_params: ScaParams::default(),
            shape: TreeShape::Sca,
            pushes: PushDistribution::default(),
            contact: ContactModel::Slot,
            max_attempts: 1000,
            stiffness: StiffnessVariation::NONE,
        }
    }
}

/// The discard reason of a push whose slot slid back to the base fork
/// ([`Hold::AtBase`]).
pub const CAUGHT_AT_BASE: &str = "caught_at_base";

/// What collecting one file took and found.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SizeStats {
    pub split: Split,
    pub n: usize,
    pub kept: usize,
    /// Discarded pushes by reason (`lost_branch`, `out_of_reach`,
    /// [`CAUGHT_AT_BASE`], …).
    pub discarded: BTreeMap<String, usize>,
    /// Pushes where the slot slid to a fork and held the node there.
    pub caught_at_fork: usize,
    /// No-Action baseline: mean over episodes of the largest node
    /// displacement max_j |p′_j − p_j| (m) — the paper's e_N when the tree is
    /// left still.
    pub no_action_error: f64,
    /// Largest node displacement in any episode (m).
    pub max_displacement: f64,
    pub mean_iterations: f64,
    pub max_kkt_residual: f64,
    /// Wall-clock time (s); not in `summary.json`, which depends only on
    /// the configuration (so equal runs, and merged shards, write equal
    /// files), but printed.
    #[serde(skip)]
    pub seconds: f64,
}

impl SizeStats {
    pub fn discarded_total(&self) -> usize {
        self.discarded.values().sum()
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CollectError {
    #[error(transparent)]
    Trees(#[from] CollectionError),
    #[error(
        "episode {episode} of {split}_N{n}: {attempts} pushes in a row were discarded (last: {last})"
    )]
    TooManyDiscards {
        split: &'static str,
        n: usize,
        episode: usize,
        attempts: usize,
        last: String,
    },
}

struct EpisodeResult {
    episode: Episode,
    discarded: Vec<&'static str>,
    iterations: usize,
    kkt: f64,
    displacement: f64,
}

/// Collects `episodes` episodes on `config.trees_per_size` trees of `n`
/// nodes. `progress` is called once per finished episode.
pub fn collect_size(
    split: Split,
    n: usize,
    episodes: usize,
    config: &CollectConfig,
    progress: &(dyn Fn() + Sync),
) -> Result<(SizeData, SizeStats), CollectError> {
    let start = Instant::now();
    let tree_base = derive_seed(config.seed, &[split.seed_part()]);
    let trees = tree_set(
        n,
        config.trees_per_size,
        tree_base,
        &config.tree_params,
        config.shape,
        config.distinct_topologies,
        |_, _| {},
    )?;
    // Each tree's stiffness variation from its own stream (split, size,
    // tree index), independent of the episodes' streams.
    let trees: Vec<_> = trees
        .into_iter()
        .enumerate()
        .map(|(index, (origin, tree))| {
            let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(
                config.seed,
                &[split.seed_part(), n as u64, index as u64, STIFFNESS_STREAM],
            ));
            (origin, config.stiffness.apply(&tree, &mut rng))
        })
        .collect();
    let sim = SimConfig {
        contact: config.contact,
        ..SimConfig::default()
    };
    let results: Vec<Result<EpisodeResult, CollectError>> = (0..episodes)
        .into_par_iter()
        .map(|e| {
            let mut rng = ChaCha8Rng::seed_from_u64(derive_seed(
                config.seed,
                &[split.seed_part(), n as u64, e as u64],
            ));
            // Episodes cycle through the trees so each gets the same share.
            let tree_index = e % trees.len();
            let tree = &trees[tree_index].1;
            let mut discarded = Vec::new();
            loop {
                let push = config.pushes.sample(tree, &mut rng);
                // The slot slid back to the base fork: the push moved
                // that node, not the one drawn. Left out like a lost
                // branch (as it was before the simulator caught it), so
                // the data say what a push at its node does.
                let outcome = simulate(tree, &push, &sim)
                    .map_err(|err| (err.kind(), Some(err)))
                    .and_then(|outcome| {
                        if outcome.report.hold == Hold::AtBase {
                            Err((CAUGHT_AT_BASE, None))
                        } else {
                            Ok(outcome)
                        }
                    });
                match outcome {
                    Ok(outcome) => {
                        progress();
                        let displacement = outcome
                            .final_positions
                            .iter()
                            .zip(tree.positions())
                            .map(|(a, b)| (a - b).norm())
                            .fold(0.0, f64::max);
                        return Ok(EpisodeResult {
                            episode: Episode {
                                tree: tree_index,
                                push,
                                final_positions: outcome.final_positions,
                                hold: outcome.report.hold,
                            },
                            discarded,
                            iterations: outcome.report.iterations,
                            kkt: outcome.report.kkt_residual,
                            displacement,
                        });
                    }
                    Err((kind, err)) => {
                        discarded.push(kind);
                        if discarded.len() >= config.max_attempts {
                            return Err(CollectError::TooManyDiscards {
                                split: split.name(),
                                n,
                                episode: e,
                                attempts: discarded.len(),
                                last: err.map_or_else(
                                    || "the slot slid back to the branch's base fork".to_owned(),
                                    |e| e.to_string(),
                                ),
                            });
                        }
                    }
                }
            }
        })
        .collect();

    let mut stats = SizeStats {
        split,
        n,
        kept: 0,
        discarded: BTreeMap::new(),
        caught_at_fork: 0,
        no_action_error: 0.0,
        max_displacement: 0.0,
        mean_iterations: 0.0,
        max_kkt_residual: 0.0,
        seconds: 0.0,
    };
    let mut kept = Vec::with_capacity(episodes);
    for result in results {
        let r = result?;
        for kind in r.discarded {
            *stats.discarded.entry(kind.to_owned()).or_default() += 1;
        }
        if r.episode.hold == crate::sim::Hold::AtNode && config.contact == ContactModel::Slot {
            stats.caught_at_fork += 1;
        }
        stats.no_action_error += r.displacement;
        stats.max_displacement = stats.max_displacement.max(r.displacement);
        stats.mean_iterations += r.iterations as f64;
        stats.max_kkt_residual = stats.max_kkt_residual.max(r.kkt);
        kept.push(r.episode);
    }
    stats.kept = kept.len();
    if stats.kept > 0 {
        stats.no_action_error /= stats.kept as f64;
        stats.mean_iterations /= stats.kept as f64;
    }
    stats.seconds = start.elapsed().as_secs_f64();
    Ok((
        SizeData {
            split,
            n,
            trees,
            episodes: kept,
        },
        stats,
    ))
}
