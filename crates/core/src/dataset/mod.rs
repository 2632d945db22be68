//! Push-interaction datasets: generated trees, random pushes, simulated
//! steady states, stored as one `.npz` per split and tree size
//! (`train_N15.npz`), readable with numpy alone. Schema: `docs/dataset.md`.

pub mod collect;
pub mod npz;
pub mod shard;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::sim::{Hold, Push};
use crate::tree::Tree;
use crate::tree::collection::TreeOrigin;

pub use collect::{CollectConfig, SizeStats, collect_size};
pub use npz::{read_size_file, write_size_file};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    Train,
    Test,
}

impl Split {
    pub fn name(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Test => "test",
        }
    }

    /// Number mixed into seeds, so the splits draw different trees and pushes.
    pub fn seed_part(self) -> u64 {
        match self {
            Split::Train => 1,
            Split::Test => 2,
        }
    }

    /// `train_N15.npz`.
    pub fn file_name(self, n: usize) -> String {
        format!("{}_N{n}.npz", self.name())
    }
}

impl std::str::FromStr for Split {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        [Split::Train, Split::Test]
            .into_iter()
            .find(|split| split.name() == s)
            .ok_or_else(|| format!("unknown split {s:?} (train or test)"))
    }
}

/// One push episode on one of the file's trees.
#[derive(Debug, Clone, PartialEq)]
pub struct Episode {
    /// Index into [`SizeData::trees`].
    pub tree: usize,
    pub push: Push,
    /// Steady-state node positions p′ (m).
    pub final_positions: Vec<Point3<f64>>,
    /// What the gripper held at the end.
    pub hold: Hold,
}

/// Everything in one `.npz`: the trees of one size and their episodes.
#[derive(Debug, Clone, PartialEq)]
pub struct SizeData {
    pub split: Split,
    pub n: usize,
    pub trees: Vec<(TreeOrigin, Tree)>,
    pub episodes: Vec<Episode>,
}

impl SizeData {
    /// The tree an episode was pushed on.
    pub fn tree_of(&self, episode: &Episode) -> &Tree {
        &self.trees[episode.tree].1
    }
}
