//! Sets of generated trees: N-node trees with distinct topologies, each
//! reproducible from its recorded seed. Used by `treemanip trees generate`
//! and by the dataset collector, so both pick the very same trees.

use std::collections::HashSet;

use serde::{Deserialize, Serialize};

use super::crop::generate_crop;
use super::model::Tree;
use super::orchard::{OrchardParams, generate_orchard};
use super::sca::{ScaError, ScaParams, generate, tree_seed};

/// Which generator grows a set's trees.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TreeShape {
    /// Space Colonization, the paper's trees ([`super::sca`]).
    #[default]
    Sca,
    /// A central leader with scaffolds and laterals at the paper's node
    /// spacing ([`super::orchard`]): the shape of real-sized trees.
    Orchard,
    /// Both, alternating by candidate (even: SCA, odd: orchard).
    Mixed,
    /// N nodes cut from a 100-500-node orchard tree around one deep path
    /// ([`super::crop`]): small trees with the path depths of large ones.
    Crop,
    /// SCA, orchard and crop in turn by candidate (candidate mod 3).
    All,
}

impl TreeShape {
    /// Grows candidate `candidate`'s tree of `n` nodes from `seed`.
    pub fn generate(
        self,
        n: usize,
        seed: u64,
        candidate: u64,
        params: &ScaParams,
    ) -> Result<Tree, ScaError> {
        let shape = match self {
            TreeShape::Mixed => [TreeShape::Sca, TreeShape::Orchard][candidate as usize % 2],
            TreeShape::All => {
                [TreeShape::Sca, TreeShape::Orchard, TreeShape::Crop][candidate as usize % 3]
            }
            one => one,
        };
        let orchard = OrchardParams {
            tip_radius: params.tip_radius,
            wood: params.wood,
            ..OrchardParams::default()
        };
        match shape {
            TreeShape::Orchard => generate_orchard(n, seed, &orchard),
            TreeShape::Crop => generate_crop(n, seed, &orchard),
            _ => generate(n, seed, params),
        }
    }
}

impl std::str::FromStr for TreeShape {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "sca" => Ok(TreeShape::Sca),
            "orchard" => Ok(TreeShape::Orchard),
            "mixed" => Ok(TreeShape::Mixed),
            "crop" => Ok(TreeShape::Crop),
            "all" => Ok(TreeShape::All),
            other => Err(format!(
                "unknown tree shape {other:?} (sca, orchard, mixed, crop or all)"
            )),
        }
    }
}

/// Most candidate seeds tried per kept tree before giving up on distinct
/// topologies (the smallest size, N = 10, needs about 5 on average).
pub const CANDIDATES_PER_TREE: u64 = 100;

/// Where one tree of a set came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct TreeOrigin {
    pub n: usize,
    /// Position among the kept trees of this size.
    pub index: usize,
    /// The seed passed to the generator: `tree_seed(base_seed, n, candidate)`.
    pub seed: u64,
    /// How many candidates of this size were tried before this one.
    pub candidate: u64,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CollectionError {
    #[error(
        "only {found} distinct topologies of {n} nodes in {tried} seeds; ask for fewer trees or allow repeated topologies"
    )]
    TooFewTopologies { n: usize, found: usize, tried: u64 },
    #[error(transparent)]
    Generator(#[from] ScaError),
}

/// `count` trees of `n` nodes from `base_seed`. With `distinct`, a candidate
/// whose topology repeats an earlier one is skipped. Calls `on_tree` as each
/// tree is kept (for progress bars).
pub fn tree_set(
    n: usize,
    count: usize,
    base_seed: u64,
    params: &ScaParams,
    shape: TreeShape,
    distinct: bool,
    mut on_tree: impl FnMut(&TreeOrigin, &Tree),
) -> Result<Vec<(TreeOrigin, Tree)>, CollectionError> {
    let mut seen = HashSet::new();
    let mut kept = Vec::with_capacity(count);
    let budget = count as u64 * CANDIDATES_PER_TREE;
    for candidate in 0..budget {
        if kept.len() == count {
            break;
        }
        let seed = tree_seed(base_seed, n, candidate);
        let tree = shape.generate(n, seed, candidate, params)?;
        if distinct && !seen.insert(tree.topology_key()) {
            continue;
        }
        let origin = TreeOrigin {
            n,
            index: kept.len(),
            seed,
            candidate,
        };
        on_tree(&origin, &tree);
        kept.push((origin, tree));
    }
    if kept.len() < count {
        return Err(CollectionError::TooFewTopologies {
            n,
            found: kept.len(),
            tried: budget,
        });
    }
    Ok(kept)
}
