//! URDF export → import is lossless, for generated trees and for arbitrary
//! valid trees (parents after children, far-off roots, extreme values).

use nalgebra::{Point3, Vector3};
use proptest::prelude::*;
use treemanip_core::tree::urdf::{UrdfError, from_urdf_str, to_urdf_string};
use treemanip_core::tree::{Branch, MAX_NODES, ScaParams, Tree, TreeError, Wood, generate};

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()) + 1e-15
}

fn assert_same(a: &Tree, b: &Tree) {
    assert_eq!(a.len(), b.len());
    assert_eq!(a.parents(), b.parents());
    for j in 0..a.len() {
        let (p, q) = (a.position(j), b.position(j));
        let scale = p.coords.norm().max(1.0);
        assert!((p - q).norm() <= 1e-9 * scale, "position {j}: {p} vs {q}");
        match (a.branch(j), b.branch(j)) {
            (None, None) => {}
            (Some(x), Some(y)) => {
                assert!(close(x.radius, y.radius), "radius {j}");
                assert!(close(x.length, y.length), "length {j}");
                assert!(close(x.stiffness, y.stiffness), "stiffness {j}");
                assert!(close(x.damping, y.damping), "damping {j}");
            }
            other => panic!("branch {j}: {other:?}"),
        }
    }
}

fn round_trip(tree: &Tree) -> Tree {
    let text = to_urdf_string(tree, "t", &Wood::default());
    from_urdf_str(&text).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// An arbitrary valid tree: random attachment, random labels (a parent may
/// have a larger index than its child), random geometry and parameters.
fn arbitrary_tree() -> impl Strategy<Value = Tree> {
    (2usize..=MAX_NODES)
        .prop_flat_map(|n| {
            (
                Just(n),
                proptest::collection::vec(any::<u64>(), n),
                proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0), n),
                proptest::collection::vec(
                    (1e-4f64..1.0, 1e-3f64..2.0, 1e-3f64..1e7, 0.0f64..1e6),
                    n,
                ),
                (-100.0f64..100.0, -100.0f64..100.0, -10.0f64..10.0),
                any::<u64>(),
            )
        })
        .prop_map(|(n, attach, dirs, params, root, shuffle)| {
            // Build in growth order (parent index < child index) ...
            let mut parents = vec![None];
            let mut positions = vec![Point3::new(root.0, root.1, root.2)];
            let mut branches = vec![None];
            for j in 1..n {
                let parent = (attach[j] % j as u64) as usize;
                let (r, len, k, d) = params[j];
                let mut dir = Vector3::new(dirs[j].0, dirs[j].1, dirs[j].2);
                if dir.norm() < 1e-3 {
                    dir = Vector3::z();
                }
                positions.push(positions[parent] + dir.normalize() * len);
                parents.push(Some(parent));
                branches.push(Some(Branch {
                    radius: r,
                    length: len,
                    stiffness: k,
                    damping: d,
                }));
            }
            // ... then relabel every node but the root.
            let mut order: Vec<usize> = (1..n).collect();
            let mut state = shuffle | 1;
            for i in (1..order.len()).rev() {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                order.swap(i, (state % (i as u64 + 1)) as usize);
            }
            let mut label = vec![0usize; n];
            for (new, &old) in order.iter().enumerate() {
                label[old] = new + 1;
            }
            let mut p2 = vec![Point3::origin(); n];
            let mut par2 = vec![None; n];
            let mut b2 = vec![None; n];
            for old in 0..n {
                let new = label[old];
                p2[new] = positions[old];
                par2[new] = parents[old].map(|p| label[p]);
                b2[new] = branches[old].map(|b: Branch| Branch {
                    length: (positions[old] - positions[parents[old].unwrap()]).norm(),
                    ..b
                });
            }
            Tree::new(p2, par2, b2).expect("constructed valid")
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn generated_trees_round_trip(n in 10usize..=30, seed in any::<u64>()) {
        let tree = generate(n, seed, &ScaParams::default()).unwrap();
        assert_same(&tree, &round_trip(&tree));
    }

    #[test]
    fn arbitrary_trees_round_trip(tree in arbitrary_tree()) {
        let back = round_trip(&tree);
        assert_same(&tree, &back);
        // And the second trip is exact: nothing drifts.
        let again = round_trip(&back);
        prop_assert_eq!(to_urdf_string(&back, "t", &Wood::default()), to_urdf_string(&again, "t", &Wood::default()));
    }
}

fn sample_urdf() -> String {
    let tree = generate(12, 5, &ScaParams::default()).unwrap();
    to_urdf_string(&tree, "sample", &Wood::default())
}

#[test]
fn urdf_carries_stiffness_and_damping_where_consumers_look() {
    let tree = generate(12, 5, &ScaParams::default()).unwrap();
    let text = sample_urdf();
    let b = tree.branch(7).unwrap();
    for axis in ["rx", "ry", "rz"] {
        let block = format!(
            "<gazebo reference=\"branch_7_{axis}\">\n    <springStiffness>{}</springStiffness>",
            b.stiffness
        );
        assert!(text.contains(&block), "missing {block}");
    }
    assert!(text.contains(&format!("damping=\"{}\"", b.damping)));
    assert!(text.contains(&format!(
        "<cylinder radius=\"{}\" length=\"{}\"/>",
        b.radius, b.length
    )));
    // urdf-rs sees three revolute joints per branch plus N fixed ones.
    let robot = urdf_rs::read_from_string(&text).unwrap();
    let revolute = robot
        .joints
        .iter()
        .filter(|j| j.joint_type == urdf_rs::JointType::Revolute)
        .count();
    assert_eq!(revolute, 3 * 11);
    assert_eq!(robot.joints.len(), 3 * 11 + 12);
}

#[test]
fn malformed_documents_are_parse_errors() {
    assert!(matches!(
        from_urdf_str("not xml at all <"),
        Err(UrdfError::Parse(_))
    ));
    let text = sample_urdf().replace("<springStiffness>", "<springStiffness>x");
    let err = from_urdf_str(&text).unwrap_err();
    assert!(
        matches!(&err, UrdfError::Parse(m) if m.contains("springStiffness")),
        "{err}"
    );
}

#[test]
fn missing_pieces_are_named() {
    let text = sample_urdf();
    let err = from_urdf_str(&text.replace("name=\"node_4_tip\"", "name=\"renamed\"")).unwrap_err();
    assert!(err.to_string().contains("node_4_tip"), "{err}");
    let err = from_urdf_str(&text.replace("reference=\"branch_3_rx\"", "reference=\"other\""))
        .unwrap_err();
    assert!(err.to_string().contains("branch_3_rx"), "{err}");
    let err = from_urdf_str(&text.replace("name=\"root_joint\"", "name=\"r\"")).unwrap_err();
    assert!(err.to_string().contains("root_joint"), "{err}");
}

#[test]
fn an_invalid_tree_inside_valid_urdf_is_a_tree_error() {
    // Make branch 5's stored length disagree with its node positions.
    let tree = generate(12, 5, &ScaParams::default()).unwrap();
    let b = tree.branch(5).unwrap();
    let text = sample_urdf().replace(
        &format!("length=\"{}\"", b.length),
        &format!("length=\"{}\"", b.length * 2.0),
    );
    let err = from_urdf_str(&text).unwrap_err();
    assert!(
        matches!(
            err,
            UrdfError::Tree(TreeError::BranchLength { node: 5, .. })
        ),
        "{err}"
    );
    // A joint that makes node 1 hang from node 3, below it: a cycle.
    let text = sample_urdf().replacen(
        "<parent link=\"node_0\"/>\n    <child link=\"branch_1_x\"/>",
        "<parent link=\"node_3\"/>\n    <child link=\"branch_1_x\"/>",
        1,
    );
    assert_eq!(tree.path_to_root(3).last(), Some(&0));
    assert!(
        tree.is_ancestor(1, 3),
        "the sample's trunk node 1 carries node 3"
    );
    let err = from_urdf_str(&text).unwrap_err();
    assert!(
        matches!(&err, UrdfError::Tree(TreeError::Cycle { nodes }) if nodes.contains(&1) && nodes.contains(&3)),
        "{err}"
    );
}
