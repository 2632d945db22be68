//! Crops of large trees (`tree::crop`): valid training data because a
//! push on the kept path moves the kept nodes exactly as it moves them in
//! the whole tree (gravity off, quasi-static: only the path's joints bend).

use nalgebra::Vector3;
use treemanip_core::sim::{Push, SimConfig, simulate};
use treemanip_core::tree::crop::induced_subtree;
use treemanip_core::tree::{OrchardParams, generate_orchard};

#[test]
fn a_push_on_the_path_moves_a_crop_as_it_moves_the_whole_tree() {
    let whole = generate_orchard(150, 3, &OrchardParams::default()).unwrap();
    // The deepest tip's path and a part of the first scaffold, with every
    // kept node's parents, so that the map back to the whole tree is known.
    let tip = (1..whole.len()).max_by_key(|&j| whole.depth(j)).unwrap();
    let mut keep = whole.path_to_root(tip);
    for j in whole.subtree(whole.children(0)[0]).into_iter().take(10) {
        keep.extend(whole.path_to_root(j));
    }
    keep.sort_unstable();
    keep.dedup();
    let crop = induced_subtree(&whole, &keep);
    assert!(crop.len() < whole.len() / 2, "{}", crop.len());
    let config = SimConfig::default();
    for &depth_from_tip in &[0, 3, 6] {
        let node = whole.path_to_root(tip)[depth_from_tip];
        let direction = whole.branch_direction(node).unwrap();
        let vector = direction.cross(&Vector3::z()).normalize() * 0.08;
        let a = simulate(&whole, &Push { node, vector }, &config).unwrap();
        let node_in_crop = keep.binary_search(&node).unwrap();
        let b = simulate(
            &crop,
            &Push {
                node: node_in_crop,
                vector,
            },
            &config,
        )
        .unwrap();
        let mut moved = 0.0f64;
        for (new, &old) in keep.iter().enumerate() {
            let d = (a.final_positions[old] - b.final_positions[new]).norm();
            assert!(d < 1e-4, "push at {node}, node {old}: {d} m");
            moved = moved.max((a.final_positions[old] - whole.position(old)).norm());
        }
        assert!(moved > 0.03, "the push moved the tree ({moved} m)");
    }
}
