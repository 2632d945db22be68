//! Crops: a small tree cut from a large one around one deep root-to-tip
//! path.
//!
//! Why they exist: gravity is off and a push is quasi-static, so a push at
//! node j bends only the joints on j's root path and every other subtree
//! moves rigidly with its parent ([`crate::sim`]). Cutting away subtrees off
//! that path changes nothing on it. A crop of n nodes therefore shows a
//! model trained on small trees what a push deep inside a 500-node tree
//! does: the same path depth (15-35 joints), the same pipe-model radii and
//! stiffnesses along it, and side branches where the large tree has them.
//! The path encoding ([`crate::graph::path`]) learns from exactly that, and
//! without crops its training trees of at most 60 nodes have paths half as
//! deep as the largest trees it answers.
//!
//! A crop keeps the root path of one tip of an orchard tree
//! ([`super::orchard`]) of 100-500 nodes, then adds nodes next to what it
//! has kept, in random order, until it has n: partial side branches along
//! the whole path, as a scan of one scaffold would show them.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::model::{MAX_NODES, Tree};
use super::orchard::{OrchardParams, generate_orchard};
use super::sca::{ScaError, check_node_count};

/// Size range of the orchard trees crops are cut from.
pub const CROP_SOURCE_NODES: (usize, usize) = (100, MAX_NODES - 12);

/// The tree made of `keep`'s nodes of `tree`, which must contain the root
/// and, with every node, its parent. Nodes keep their order (the root stays
/// node 0), positions and branches.
pub fn induced_subtree(tree: &Tree, keep: &[usize]) -> Tree {
    let mut keep = keep.to_vec();
    keep.sort_unstable();
    keep.dedup();
    let mut index = vec![usize::MAX; tree.len()];
    for (new, &old) in keep.iter().enumerate() {
        index[old] = new;
    }
    assert_eq!(keep.first(), Some(&0), "a crop keeps the root");
    let parents = keep
        .iter()
        .map(|&j| {
            tree.parent(j).map(|p| {
                assert!(index[p] != usize::MAX, "node {j} kept without its parent");
                index[p]
            })
        })
        .collect();
    Tree::new(
        keep.iter().map(|&j| tree.position(j)).collect(),
        parents,
        keep.iter().map(|&j| tree.branch(j).copied()).collect(),
    )
    .expect("an induced subtree of a valid tree is valid")
}

/// `n` nodes of `tree` around the root path of one tip: a leaf drawn among
/// those at most `0.8 (n − 1)` joints deep (room for side branches), its
/// path, then neighbours of the kept nodes drawn at random until there are
/// `n`. Returns the tree unchanged when it has at most `n` nodes.
pub fn crop_around_path(tree: &Tree, n: usize, rng: &mut ChaCha8Rng) -> Tree {
    if tree.len() <= n {
        return tree.clone();
    }
    let max_depth = ((n - 1) as f64 * 0.8).floor().max(1.0) as usize;
    let leaves: Vec<usize> = (1..tree.len())
        .filter(|&j| tree.is_leaf(j) && tree.depth(j) <= max_depth)
        .collect();
    let tip = match leaves.len() {
        0 => {
            // Every leaf is deeper: the deepest node the cap allows.
            (1..tree.len())
                .filter(|&j| tree.depth(j) <= max_depth)
                .max_by_key(|&j| (tree.depth(j), j))
                .unwrap_or(1)
        }
        count => leaves[rng.random_range(0..count)],
    };
    let mut kept = vec![false; tree.len()];
    let mut keep = tree.path_to_root(tip);
    for &j in &keep {
        kept[j] = true;
    }
    let mut frontier: Vec<usize> = keep
        .iter()
        .flat_map(|&j| tree.children(j).iter().copied())
        .filter(|&c| !kept[c])
        .collect();
    while keep.len() < n && !frontier.is_empty() {
        let j = frontier.swap_remove(rng.random_range(0..frontier.len()));
        kept[j] = true;
        keep.push(j);
        frontier.extend(tree.children(j).iter().copied());
    }
    induced_subtree(tree, &keep)
}

/// A crop of `n` nodes ([`crop_around_path`]) of an orchard tree whose size
/// is drawn from [`CROP_SOURCE_NODES`], reproducible from `seed`.
pub fn generate_crop(n: usize, seed: u64, params: &OrchardParams) -> Result<Tree, ScaError> {
    check_node_count(n, MAX_NODES)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xC0_FFEE);
    let (lo, hi) = CROP_SOURCE_NODES;
    let source = rng.random_range(lo.max(n)..=hi.max(n));
    let tree = generate_orchard(source, seed, params)?;
    Ok(crop_around_path(&tree, n, &mut rng))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crops_have_n_nodes_and_deep_paths() {
        let p = OrchardParams::default();
        let mut deepest = 0;
        for seed in 0..12 {
            let tree = generate_crop(60, seed, &p).unwrap();
            assert_eq!(tree.len(), 60);
            assert_eq!(generate_crop(60, seed, &p).unwrap(), tree, "reproducible");
            deepest = deepest.max((0..60).map(|j| tree.depth(j)).max().unwrap());
            // Segments at the paper's spacing, as in the source tree.
            for (_, b) in tree.branches_iter() {
                assert!((0.03..0.16).contains(&b.length), "{}", b.length);
            }
        }
        // An orchard tree of 60 nodes has paths of about 9 joints; crops
        // reach the depths of 200-500-node trees.
        assert!(deepest >= 20, "deepest path {deepest}");
    }
}
