//! The graph encoding on hand-built trees: feature values, v_ij, K_s = 0
//! off-branch, masks and padding, normalisation statistics.

use nalgebra::{Point3, Vector3};
use treemanip_core::graph::stats::StatsBuilder;
use treemanip_core::graph::{
    BRANCH_COLUMN, EDGE_DIM, EncodeError, LOG_STIFFNESS_COLUMN, Task, batch, encode_forward,
    encode_policy,
};
use treemanip_core::tree::{Tree, Wood};

/// 0 → 1 → 2, and 1 → 3: a trunk with a fork at node 1.
fn fork() -> Tree {
    let positions = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(0.0, 0.0, 0.5),
        Point3::new(0.1, 0.0, 0.9),
        Point3::new(-0.3, 0.2, 0.7),
    ];
    let parents = vec![None, Some(0), Some(1), Some(1)];
    let radii = [0.0, 0.02, 0.01, 0.008];
    let wood = Wood::default();
    let branches = (0..4)
        .map(|j| {
            parents[j].map(|p: usize| wood.branch(radii[j], (positions[j] - positions[p]).norm()))
        })
        .collect();
    Tree::new(positions, parents, branches).unwrap()
}

#[test]
fn forward_encoding_has_the_papers_attributes() {
    let tree = fork();
    let push = Vector3::new(0.05, -0.02, 0.01);
    let g = encode_forward(&tree, 2, &push).unwrap();
    assert_eq!((g.task, g.n), (Task::Forward, 4));
    assert_eq!(
        g.nodes,
        vec![0.0, 0.0, 1.0, 0.0],
        "c_j is 1 at the contacted node only"
    );
    assert_eq!(g.global, vec![0.05f32, -0.02, 0.01]);
    for i in 0..4 {
        for j in 0..4 {
            let e = g.edge(i, j);
            if i == j {
                assert_eq!(e, &[0.0; EDGE_DIM], "self-edges are zero");
                continue;
            }
            let d = tree.position(j) - tree.position(i);
            assert_eq!(
                &e[..3],
                &[d.x as f32, d.y as f32, d.z as f32],
                "Δp of {i}→{j}"
            );
        }
    }
    // v_ij: +1 exactly from an ancestor to a descendant.
    let v = |i, j| g.edge(i, j)[3];
    assert_eq!(v(0, 1), 1.0);
    assert_eq!(v(0, 3), 1.0);
    assert_eq!(v(1, 2), 1.0);
    assert_eq!(v(2, 1), -1.0);
    assert_eq!(v(2, 3), -1.0, "siblings");
    assert_eq!(v(3, 0), -1.0);
    // b and κ: the branch flag and ln K_s − the tree's mean ln K_s, between
    // parent and child in both directions; 0 otherwise.
    let (b, kappa) = (
        |i, j| g.edge(i, j)[BRANCH_COLUMN],
        |i, j| g.edge(i, j)[LOG_STIFFNESS_COLUMN],
    );
    let ln_k = |c: usize| tree.branch(c).unwrap().stiffness.ln();
    let mean = (ln_k(1) + ln_k(2) + ln_k(3)) / 3.0;
    for (parent, child) in [(0, 1), (1, 2), (1, 3)] {
        let expected = (ln_k(child) - mean) as f32;
        for (i, j) in [(parent, child), (child, parent)] {
            assert_eq!(b(i, j), 1.0);
            assert!((kappa(i, j) - expected).abs() < 1e-6, "κ of {i}→{j}");
        }
    }
    for (i, j) in [(0, 2), (0, 3), (2, 3), (3, 2), (2, 0)] {
        assert_eq!(
            (b(i, j), kappa(i, j)),
            (0.0, 0.0),
            "{i}→{j} is not a branch"
        );
    }
    // A global factor on every K_s leaves the encoding exactly as it was.
    let k: Vec<f64> = tree
        .branches()
        .iter()
        .map(|b| b.map_or(0.0, |b| b.stiffness * 7.3))
        .collect();
    let scaled = encode_forward(
        &treemanip_core::identify::with_stiffness(&tree, &k),
        1,
        &push,
    )
    .unwrap();
    for (x, y) in scaled.edges.iter().zip(&g.edges) {
        assert!((x - y).abs() < 1e-6);
    }
}

#[test]
fn policy_encoding_carries_target_offsets() {
    let tree = fork();
    let mut targets = tree.positions().to_vec();
    targets[2] += Vector3::new(0.1, 0.0, -0.05);
    targets[3] += Vector3::new(0.0, 0.02, 0.0);
    let g = encode_policy(&tree, &targets).unwrap();
    assert_eq!(g.task, Task::Policy);
    assert!(g.global.is_empty());
    assert_eq!(g.node(0), &[0.0, 0.0, 0.0]);
    assert_eq!(g.node(2), &[0.1f32, 0.0, -0.05]);
    assert_eq!(g.node(3), &[0.0, 0.02f32, 0.0]);
    // Same edges as the forward model.
    assert_eq!(
        g.edges,
        encode_forward(&tree, 1, &Vector3::zeros()).unwrap().edges
    );
}

#[test]
fn bad_inputs_are_errors() {
    let tree = fork();
    assert_eq!(
        encode_forward(&tree, 0, &Vector3::x()).unwrap_err(),
        EncodeError::ContactNode { node: 0, n: 4 }
    );
    assert_eq!(
        encode_forward(&tree, 4, &Vector3::x()).unwrap_err(),
        EncodeError::ContactNode { node: 4, n: 4 }
    );
    assert!(matches!(
        encode_forward(&tree, 1, &Vector3::new(f64::NAN, 0.0, 0.0)),
        Err(EncodeError::NonFinite { .. })
    ));
    assert_eq!(
        encode_policy(&tree, &[Point3::origin(); 3]).unwrap_err(),
        EncodeError::TargetCount { got: 3, n: 4 }
    );
    let mut targets = tree.positions().to_vec();
    targets[1].y = f64::INFINITY;
    assert!(matches!(
        encode_policy(&tree, &targets),
        Err(EncodeError::NonFinite { .. })
    ));
}

#[test]
fn batches_pad_with_zeros_and_mask_real_nodes() {
    let big = fork();
    let small = Tree::new(
        big.positions()[..2].to_vec(),
        big.parents()[..2].to_vec(),
        big.branches()[..2].to_vec(),
    )
    .unwrap();
    let a = encode_forward(&small, 1, &Vector3::x()).unwrap();
    let b = encode_forward(&big, 3, &Vector3::y()).unwrap();
    let batch = batch(&[a.clone(), b.clone()]).unwrap();
    assert_eq!((batch.batch, batch.n), (2, 4));
    assert_eq!(batch.mask, vec![1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]);
    assert_eq!(&batch.nodes[..4], &[0.0, 1.0, 0.0, 0.0]);
    assert_eq!(&batch.nodes[4..], b.nodes.as_slice());
    assert_eq!(&batch.global, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let edge = |k: usize, i: usize, j: usize| {
        let s = ((k * 4 + i) * 4 + j) * EDGE_DIM;
        batch.edges[s..s + EDGE_DIM].to_vec()
    };
    assert_eq!(edge(0, 0, 1), a.edge(0, 1));
    assert_eq!(edge(0, 1, 0), a.edge(1, 0));
    for (i, j) in [(0, 2), (2, 0), (3, 3), (1, 3)] {
        assert_eq!(edge(0, i, j), vec![0.0; EDGE_DIM], "padding {i}→{j}");
    }
    for i in 0..4 {
        for j in 0..4 {
            assert_eq!(edge(1, i, j), b.edge(i, j));
        }
    }
    let policy = encode_policy(&big, big.positions()).unwrap();
    assert!(
        treemanip_core::graph::batch(&[b, policy]).is_err(),
        "mixed tasks"
    );
    assert!(treemanip_core::graph::batch(&[]).is_err(), "empty");
}

#[test]
fn statistics_cover_real_entries_only() {
    let tree = fork();
    let push = Vector3::new(0.1, 0.0, 0.0);
    let mut builder = StatsBuilder::new(Task::Forward);
    let graphs = [
        encode_forward(&tree, 1, &push).unwrap(),
        encode_forward(&tree, 3, &push).unwrap(),
    ];
    for g in &graphs {
        builder.add(g);
    }
    let stats = builder.finish();
    assert_eq!(stats.graphs, 2);
    // c_j: two 1s among 8 nodes.
    assert!((stats.node_mean[0] - 0.25).abs() < 1e-12);
    assert!((stats.node_std[0] - (0.25f64 * 0.75).sqrt()).abs() < 1e-12);
    // The same push twice: no spread, so no scaling.
    assert_eq!(stats.global_mean, vec![0.1f32 as f64, 0.0, 0.0]);
    assert_eq!(stats.global_std, vec![1.0, 1.0, 1.0]);
    // v over the 12 real edges of each graph: 5 ancestor pairs (+1), 7 others (−1).
    assert!((stats.edge_mean[3] - (5.0 - 7.0) / 12.0).abs() < 1e-12);
    // b: 6 of the 12 directed edges are branches. κ sums to zero over a
    // tree's branches, so its mean over edges is 0.
    assert!((stats.edge_mean[BRANCH_COLUMN] - 0.5).abs() < 1e-12);
    assert!(stats.edge_mean[LOG_STIFFNESS_COLUMN].abs() < 1e-6);
}
