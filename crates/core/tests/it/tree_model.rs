//! The tree model: every validation error, and the derived views.

use nalgebra::Point3;
use treemanip_core::tree::{Branch, MAX_NODES, Tree, TreeError, Wood};

/// A hand-built tree:
/// ```text
///        3   4
///         \ /
///          2   5
///          |  /
///          1 /
///          |/        (5 hangs from 1)
///          0
/// ```
/// Positions, parents and branches, the three arrays [`Tree::new`] takes.
type Parts = (Vec<Point3<f64>>, Vec<Option<usize>>, Vec<Option<Branch>>);

fn sample() -> Parts {
    let positions = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(0.0, 0.0, 0.4),
        Point3::new(0.0, 0.0, 0.7),
        Point3::new(-0.2, 0.0, 0.9),
        Point3::new(0.2, 0.0, 0.9),
        Point3::new(0.3, 0.1, 0.6),
    ];
    let parents = vec![None, Some(0), Some(1), Some(2), Some(2), Some(1)];
    let wood = Wood::default();
    let branches = (0..positions.len())
        .map(|j| parents[j].map(|p: usize| wood.branch(0.01, (positions[j] - positions[p]).norm())))
        .collect();
    (positions, parents, branches)
}

fn build(
    f: impl FnOnce(&mut Vec<Point3<f64>>, &mut Vec<Option<usize>>, &mut Vec<Option<Branch>>),
) -> Result<Tree, TreeError> {
    let (mut p, mut par, mut b) = sample();
    f(&mut p, &mut par, &mut b);
    Tree::new(p, par, b)
}

#[test]
fn sample_is_valid_and_views_are_right() {
    let tree = build(|_, _, _| {}).unwrap();
    assert_eq!(tree.len(), 6);
    assert_eq!(tree.children(0), &[1]);
    assert_eq!(tree.children(1), &[2, 5]);
    assert_eq!(tree.children(2), &[3, 4]);
    assert!(tree.is_leaf(3) && tree.is_leaf(4) && tree.is_leaf(5) && !tree.is_leaf(2));
    assert_eq!(
        (0..6).map(|j| tree.depth(j)).collect::<Vec<_>>(),
        [0, 1, 2, 3, 3, 2]
    );
    assert_eq!(tree.path_to_root(4), [4, 2, 1, 0]);
    assert_eq!(tree.path_to_root(0), [0]);
    assert_eq!(tree.subtree(1), [1, 2, 3, 4, 5]);
    assert_eq!(tree.subtree(2), [2, 3, 4]);
    assert_eq!(tree.subtree(5), [5]);
    assert!((tree.height() - 0.9).abs() < 1e-12);
    assert!(tree.branch(0).is_none());
    let d = tree.branch_direction(3).unwrap();
    assert!((d - nalgebra::Vector3::new(-0.2, 0.0, 0.2).normalize()).norm() < 1e-12);
}

#[test]
fn orientation_is_plus_one_exactly_from_ancestor_to_descendant() {
    let tree = build(|_, _, _| {}).unwrap();
    for i in 0..6 {
        for j in 0..6 {
            let expected = if i == j {
                0.0
            } else if tree.path_to_root(j)[1..].contains(&i) {
                1.0
            } else {
                -1.0
            };
            assert_eq!(tree.orientation(i, j), expected, "v[{i}][{j}]");
        }
    }
    assert_eq!(tree.orientation(0, 4), 1.0);
    assert_eq!(tree.orientation(4, 0), -1.0);
    assert_eq!(tree.orientation(3, 4), -1.0, "siblings point neither way");
    assert_eq!(tree.orientation(4, 3), -1.0);
    assert_eq!(tree.orientation(5, 3), -1.0, "cousins");
}

#[test]
fn topology_key_ignores_child_order_but_not_shape() {
    let a = build(|_, _, _| {}).unwrap();
    // Swap the labels of nodes 3 and 5: 5 becomes a child of 2, 3 of 1.
    let b = build(|p, par, br| {
        p.swap(3, 5);
        par.swap(3, 5);
        br.swap(3, 5);
    })
    .unwrap();
    assert_eq!(a.topology_key(), b.topology_key());
    // Move leaf 5 under node 3: a different shape.
    let c = build(|p, par, b| {
        par[5] = Some(3);
        p[5] = Point3::new(-0.3, 0.0, 1.1);
        b[5] = Some(Wood::default().branch(0.01, (p[5] - p[3]).norm()));
    })
    .unwrap();
    assert_ne!(a.topology_key(), c.topology_key());
}

#[test]
fn too_few_and_too_many_nodes() {
    let err = Tree::new(vec![Point3::origin()], vec![None], vec![None]).unwrap_err();
    assert_eq!(
        err,
        TreeError::NodeCount {
            got: 1,
            min: 2,
            max: MAX_NODES
        }
    );
    let n = MAX_NODES + 1;
    let positions = (0..n).map(|k| Point3::new(0.0, 0.0, k as f64)).collect();
    let parents = (0..n).map(|k| k.checked_sub(1)).collect();
    let branches = (0..n)
        .map(|k| (k > 0).then(|| Wood::default().branch(0.01, 1.0)))
        .collect();
    let err = Tree::new(positions, parents, branches).unwrap_err();
    assert!(matches!(err, TreeError::NodeCount { got, .. } if got == n));
    assert!(err.to_string().contains("between 2 and 512"), "{err}");
}

#[test]
fn mismatched_array_lengths() {
    let err = build(|_, par, _| {
        par.pop();
    })
    .unwrap_err();
    assert_eq!(
        err,
        TreeError::LengthMismatch {
            field: "parents",
            expected: 6,
            got: 5
        }
    );
    let err = build(|_, _, b| b.push(None)).unwrap_err();
    assert_eq!(
        err,
        TreeError::LengthMismatch {
            field: "branches",
            expected: 6,
            got: 7
        }
    );
}

#[test]
fn no_root() {
    let err = build(|_, par, _| par[0] = Some(1)).unwrap_err();
    assert_eq!(err, TreeError::NoRoot);
}

#[test]
fn several_roots() {
    let err = build(|_, par, _| {
        par[3] = None;
        par[5] = None;
    })
    .unwrap_err();
    assert_eq!(
        err,
        TreeError::MultipleRoots {
            nodes: vec![0, 3, 5]
        }
    );
    assert!(err.to_string().contains("[0, 3, 5]"));
}

#[test]
fn root_must_be_node_zero() {
    let err = build(|_, par, _| {
        par[0] = Some(1);
        par[1] = None;
    })
    .unwrap_err();
    assert_eq!(err, TreeError::RootNotFirst { node: 1 });
}

#[test]
fn parent_out_of_range() {
    let err = build(|_, par, _| par[4] = Some(6)).unwrap_err();
    assert_eq!(
        err,
        TreeError::ParentOutOfRange {
            node: 4,
            parent: 6,
            n: 6
        }
    );
    assert!(err.to_string().contains("node 4"));
}

#[test]
fn cycles_are_reported_with_their_nodes() {
    let err = build(|_, par, _| {
        par[1] = Some(2); // 1 -> 2 -> 1
    })
    .unwrap_err();
    assert_eq!(err, TreeError::Cycle { nodes: vec![1, 2] });
    let err = build(|_, par, _| par[3] = Some(3)).unwrap_err();
    assert_eq!(err, TreeError::Cycle { nodes: vec![3] });
}

#[test]
fn a_node_hanging_from_a_cycle_is_disconnected() {
    // 3 <-> 4 form a cycle; 5 hangs from 4 and never reaches the root.
    let err = build(|_, par, _| {
        par[5] = Some(4);
        par[4] = Some(3);
        par[3] = Some(4);
    })
    .unwrap_err();
    assert_eq!(err, TreeError::Cycle { nodes: vec![3, 4] });
    // Reported for the lowest-numbered affected node: make that the hanger.
    let err = build(|_, par, _| {
        par[2] = Some(4);
        par[4] = Some(5);
        par[5] = Some(4);
    })
    .unwrap_err();
    assert_eq!(err, TreeError::Disconnected { node: 2 });
}

#[test]
fn non_finite_numbers_name_field_and_node() {
    let err = build(|p, _, _| p[2].y = f64::NAN).unwrap_err();
    assert_eq!(
        err,
        TreeError::NonFinite {
            field: "positions",
            node: 2
        }
    );
    let err = build(|p, _, _| p[0].z = f64::INFINITY).unwrap_err();
    assert_eq!(
        err,
        TreeError::NonFinite {
            field: "positions",
            node: 0
        }
    );
    for (field, set) in [
        (
            "radius",
            (|b: &mut Branch| b.radius = f64::NAN) as fn(&mut Branch),
        ),
        ("length", |b: &mut Branch| b.length = f64::INFINITY),
        ("stiffness", |b: &mut Branch| {
            b.stiffness = f64::NEG_INFINITY
        }),
        ("damping", |b: &mut Branch| b.damping = f64::NAN),
    ] {
        let err = build(|_, _, b| set(b[4].as_mut().unwrap())).unwrap_err();
        assert_eq!(err, TreeError::NonFinite { field, node: 4 });
    }
}

#[test]
fn non_positive_parameters() {
    for (field, set) in [
        (
            "radius",
            (|b: &mut Branch| b.radius = 0.0) as fn(&mut Branch),
        ),
        ("radius", |b: &mut Branch| b.radius = -0.01),
        ("length", |b: &mut Branch| b.length = 0.0),
        ("stiffness", |b: &mut Branch| b.stiffness = -5.0),
    ] {
        let err = build(|_, _, b| set(b[3].as_mut().unwrap())).unwrap_err();
        assert!(
            matches!(err, TreeError::NonPositive { field: f, node: 3, .. } if f == field),
            "{field}: {err:?}"
        );
    }
    let err = build(|_, _, b| b[3].as_mut().unwrap().damping = -1.0).unwrap_err();
    assert_eq!(
        err,
        TreeError::NegativeDamping {
            node: 3,
            value: -1.0
        }
    );
    // Zero damping is allowed: a purely elastic joint.
    build(|_, _, b| b[3].as_mut().unwrap().damping = 0.0).unwrap();
}

#[test]
fn missing_branch_parameters() {
    let err = build(|_, _, b| b[5] = None).unwrap_err();
    assert_eq!(err, TreeError::MissingBranch { node: 5 });
    // The root's entry is ignored.
    let tree = build(|_, _, b| b[0] = Some(Wood::default().branch(1.0, 1.0))).unwrap();
    assert!(tree.branch(0).is_none());
}

#[test]
fn branch_length_must_match_node_positions() {
    let err = build(|_, _, b| b[2].as_mut().unwrap().length = 0.35).unwrap_err();
    match err {
        TreeError::BranchLength {
            node,
            stored,
            measured,
        } => {
            assert_eq!(node, 2);
            assert_eq!(stored, 0.35);
            assert!((measured - 0.3).abs() < 1e-12);
        }
        other => panic!("{other:?}"),
    }
    // Coincident nodes: zero measured length, positive stored length.
    let err = build(|p, _, _| p[5] = p[1]).unwrap_err();
    assert!(
        matches!(err, TreeError::BranchLength { node: 5, .. }),
        "{err:?}"
    );
    // Within tolerance is fine.
    build(|_, _, b| b[2].as_mut().unwrap().length = 0.3 * (1.0 + 5e-7)).unwrap();
}

#[test]
fn stiffness_follows_the_cantilever_formula() {
    let wood = Wood::default();
    let (r, l) = (0.012, 0.25);
    let k = wood.stiffness(r, l);
    let expected = wood.young_modulus * std::f64::consts::PI * r.powi(4) / (2.0 * l);
    assert!((k - expected).abs() <= 1e-12 * expected);
    // Doubling the radius makes the joint 16× stiffer; doubling the length halves it.
    assert!((wood.stiffness(2.0 * r, l) / k - 16.0).abs() < 1e-9);
    assert!((wood.stiffness(r, 2.0 * l) / k - 0.5).abs() < 1e-12);
    let b = wood.branch(r, l);
    assert!((b.damping - b.stiffness / 10.0).abs() <= 1e-12 * b.stiffness);
}
