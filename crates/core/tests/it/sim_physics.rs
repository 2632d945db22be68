//! The push simulator against closed forms, optimality conditions, an
//! independent minimiser, and symmetry.

use nalgebra::{DVector, Point3, Rotation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use treemanip_core::sim::contact::Contact;
use treemanip_core::sim::path_joints::PathChain;
use treemanip_core::sim::{
    ContactModel, GRIP_OFFSET, Hold, Push, SimConfig, SimError, elastic_energy, simulate,
};
use treemanip_core::tree::{Branch, Tree};

fn branch(length: f64, stiffness: f64) -> Branch {
    Branch {
        radius: 0.01,
        length,
        stiffness,
        damping: stiffness / 10.0,
    }
}

/// A vertical chain: root at the origin, branches of the given lengths and
/// stiffnesses stacked along +z.
fn vertical_chain(parts: &[(f64, f64)]) -> Tree {
    let mut positions = vec![Point3::origin()];
    let mut parents = vec![None];
    let mut branches = vec![None];
    for (k, &(l, s)) in parts.iter().enumerate() {
        positions.push(positions[k] + Vector3::z() * l);
        parents.push(Some(k));
        branches.push(Some(branch(l, s)));
    }
    Tree::new(positions, parents, branches).unwrap()
}

pub(crate) fn slot() -> SimConfig {
    SimConfig::default()
}

fn pinned() -> SimConfig {
    SimConfig {
        contact: ContactModel::Pinned,
        ..SimConfig::default()
    }
}

use crate::common::random_tree_and_pushes;

#[test]
fn single_branch_turns_by_the_angle_geometry_dictates() {
    let (l, k) = (0.2, 40.0);
    let tree = vertical_chain(&[(l, k)]);
    let t = 0.04;
    let out = simulate(
        &tree,
        &Push {
            node: 1,
            vector: Vector3::x() * t,
        },
        &slot(),
    )
    .unwrap();
    let grip = l - GRIP_OFFSET;
    let angle = (t / grip).atan();
    let expected = Point3::new(l * angle.sin(), 0.0, l * angle.cos());
    assert!(
        (out.final_positions[1] - expected).norm() < 1e-12,
        "{}",
        out.final_positions[1]
    );
    assert!((out.joint_rotations[1] - Vector3::y() * angle).norm() < 1e-12);
    let report = &out.report;
    assert_eq!(report.hold, Hold::OnAxis);
    assert!(report.constraint_residual < 1e-12);
    assert!(report.kkt_residual < 1e-8);
    let slide = (grip * grip + t * t).sqrt();
    assert!((report.slide.unwrap() - slide).abs() < 1e-12);
    assert!((report.energy - 0.5 * k * angle * angle).abs() < 1e-12);
    // Moment balance: the slot pushes perpendicular to the deformed branch
    // with |F| · slide = K θ.
    let force = Vector3::from(report.contact_force);
    let axis = (out.final_positions[1] - Point3::origin()).normalize();
    assert!(force.dot(&axis).abs() < 1e-9);
    assert!((force.norm() * slide - k * angle).abs() < 1e-9, "{force}");
    assert!(force.x > 0.0, "the gripper pushes along +x");
}

#[test]
fn single_branch_pinned_cannot_stretch() {
    let tree = vertical_chain(&[(0.2, 40.0)]);
    let err = simulate(
        &tree,
        &Push {
            node: 1,
            vector: Vector3::x() * 0.05,
        },
        &pinned(),
    )
    .unwrap_err();
    assert!(matches!(err, SimError::OutOfReach { node: 1, .. }), "{err}");
    // On the sphere of reach it works: carry the tip along a circle.
    let angle: f64 = 0.3;
    let target = Vector3::new(0.2 * angle.sin(), 0.0, 0.2 * angle.cos());
    let out = simulate(
        &tree,
        &Push {
            node: 1,
            vector: target - Vector3::z() * 0.2,
        },
        &pinned(),
    )
    .unwrap();
    assert!((out.joint_rotations[1] - Vector3::y() * angle).norm() < 1e-10);
}

/// Two collinear branches, the tip carried to a reachable point in the x–z
/// plane: the two-link inverse kinematics has two solutions (elbow either
/// way); the steady state is the one with less spring energy.
#[test]
fn two_branch_chain_matches_the_analytic_minimum_pinned() {
    let (l1, k1, l2, k2) = (0.3, 120.0, 0.2, 25.0);
    let tree = vertical_chain(&[(l1, k1), (l2, k2)]);
    for push in [
        Vector3::new(0.08, 0.0, -0.03),
        Vector3::new(-0.12, 0.0, -0.06),
        Vector3::new(0.03, 0.0, -0.01),
    ] {
        let target = Point3::new(0.0, 0.0, l1 + l2) + push;
        // Angles from vertical in the x–z plane: a1 at the root, a2 relative.
        let (x, z) = (target.x, target.z);
        let d2 = x * x + z * z;
        let cos_a2 = (d2 - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for a2 in [cos_a2.acos(), -cos_a2.acos()] {
            // Tip = l1 (sin a1, cos a1) + l2 (sin(a1 + a2), cos(a1 + a2)).
            let a1 = x.atan2(z) - (l2 * a2.sin()).atan2(l1 + l2 * a2.cos());
            let energy = 0.5 * k1 * a1 * a1 + 0.5 * k2 * a2 * a2;
            if energy < best.0 {
                best = (energy, a1, a2);
            }
        }
        let (energy, a1, a2) = best;
        let out = simulate(
            &tree,
            &Push {
                node: 2,
                vector: push,
            },
            &pinned(),
        )
        .unwrap();
        assert!(
            (out.report.energy - energy).abs() < 1e-10 * energy.max(1.0),
            "{} vs {energy}",
            out.report.energy
        );
        assert!(
            (out.joint_rotations[1] - Vector3::y() * a1).norm() < 1e-8,
            "{:?} vs {a1}",
            out.joint_rotations[1]
        );
        assert!((out.joint_rotations[2] - Vector3::y() * a2).norm() < 1e-8);
        let node1 = Point3::new(l1 * a1.sin(), 0.0, l1 * a1.cos());
        assert!((out.final_positions[1] - node1).norm() < 1e-9);
        assert!((out.final_positions[2] - target).norm() < 1e-12);
    }
}

/// The same chain with the slot: the gripper point must lie on the second
/// branch's axis. In the plane that leaves one free angle: for each a1 the
/// axis must point at the gripper, which fixes a2. Minimise over a1 by a
/// dense scan and golden-section refinement.
#[test]
fn two_branch_chain_matches_the_analytic_minimum_slot() {
    let (l1, k1, l2, k2) = (0.3, 120.0, 0.2, 25.0);
    let tree = vertical_chain(&[(l1, k1), (l2, k2)]);
    let push = Vector3::new(0.06, 0.0, 0.0);
    let grip = Point3::new(0.0, 0.0, l1 + l2 - GRIP_OFFSET) + push;
    let energy_at = |a1: f64| {
        let node1 = Point3::new(l1 * a1.sin(), 0.0, l1 * a1.cos());
        let d = grip - node1;
        let a2 = d.x.atan2(d.z) - a1;
        0.5 * k1 * a1 * a1 + 0.5 * k2 * a2 * a2
    };
    let mut best = (f64::INFINITY, 0.0);
    for i in 0..=20000 {
        let a1 = -0.5 + i as f64 * 1e-4 * 0.5;
        if energy_at(a1) < best.0 {
            best = (energy_at(a1), a1);
        }
    }
    let (mut lo, mut hi) = (best.1 - 1e-4, best.1 + 1e-4);
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..200 {
        let (m1, m2) = (hi - phi * (hi - lo), lo + phi * (hi - lo));
        if energy_at(m1) < energy_at(m2) {
            hi = m2
        } else {
            lo = m1
        }
    }
    let a1 = (lo + hi) / 2.0;
    let out = simulate(
        &tree,
        &Push {
            node: 2,
            vector: push,
        },
        &slot(),
    )
    .unwrap();
    assert_eq!(out.report.hold, Hold::OnAxis);
    assert!(
        (out.report.energy - energy_at(a1)).abs() < 1e-10,
        "{} vs {}",
        out.report.energy,
        energy_at(a1)
    );
    assert!(
        (out.joint_rotations[1] - Vector3::y() * a1).norm() < 1e-7,
        "{:?} vs {a1}",
        out.joint_rotations[1]
    );
}

#[test]
fn subtree_beyond_the_contact_is_rigid_and_off_path_joints_rest() {
    let mut checked = 0;
    for seed in 0..30 {
        let (tree, pushes) = random_tree_and_pushes(seed, 20, 5);
        for push in pushes {
            let Ok(out) = simulate(&tree, &push, &slot()) else {
                continue;
            };
            checked += 1;
            let path = tree.path_to_root(push.node);
            for j in 1..tree.len() {
                if !path.contains(&j) {
                    assert_eq!(
                        out.joint_rotations[j],
                        Vector3::zeros(),
                        "joint {j} off the path moved"
                    );
                }
                // Every branch keeps its length.
                let p = tree.parent(j).unwrap();
                let l = (out.final_positions[j] - out.final_positions[p]).norm();
                assert!((l - tree.branch(j).unwrap().length).abs() < 1e-12);
            }
            // The subtree beyond the contact moves as one rigid body.
            let subtree = tree.subtree(push.node);
            for &a in &subtree {
                for &b in &subtree {
                    let before = (tree.position(a) - tree.position(b)).norm();
                    let after = (out.final_positions[a] - out.final_positions[b]).norm();
                    assert!((before - after).abs() < 1e-12);
                }
            }
            // Nodes hanging off the root side of the path stay put.
            for x in 0..tree.len() {
                if tree
                    .path_to_root(x)
                    .iter()
                    .all(|a| !path[..path.len() - 1].contains(a) || *a == 0)
                {
                    assert!((out.final_positions[x] - tree.position(x)).norm() < 1e-15);
                }
            }
        }
    }
    assert!(checked > 60, "only {checked} pushes solved");
}

/// Projects joint angles back onto c(θ) = 0 by Gauss-Newton steps.
fn project(chain: &PathChain, contact: &Contact, mut theta: Vec<f64>) -> Option<Vec<f64>> {
    for _ in 0..100 {
        let (c, jac) = contact.evaluate(chain, &chain.pose(&theta));
        if c.amax() < 1e-13 {
            return Some(theta);
        }
        let step: DVector<f64> = jac.clone().pseudo_inverse(1e-12).ok()? * c;
        for (t, s) in theta.iter_mut().zip(step.iter()) {
            *t -= s;
        }
    }
    None
}

#[test]
fn solutions_are_kkt_points_and_beat_every_feasible_perturbation() {
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let mut solved = 0;
    for seed in 0..12 {
        let (tree, pushes) = random_tree_and_pushes(100 + seed, 15, 4);
        for push in pushes {
            let Ok(out) = simulate(&tree, &push, &slot()) else {
                continue;
            };
            if out.report.hold != Hold::OnAxis {
                continue;
            }
            solved += 1;
            assert!(out.report.kkt_residual < 1e-8, "{:?}", out.report);
            assert!(out.report.constraint_residual < 1e-10);
            let chain = PathChain::new(&tree, push.node);
            let contact = Contact::new(&tree, push.node, &push.vector, ContactModel::Slot);
            let theta: Vec<f64> = chain
                .nodes
                .iter()
                .flat_map(|&a| out.joint_rotations[a].iter().copied().collect::<Vec<_>>())
                .collect();
            let best = out.report.energy;
            let mut tried = 0;
            for _ in 0..40 {
                let scale = [1e-3, 1e-2, 5e-2][tried % 3];
                let perturbed: Vec<f64> = theta
                    .iter()
                    .map(|t| t + scale * rng.random_range(-1.0..1.0))
                    .collect();
                let Some(feasible) = project(&chain, &contact, perturbed) else {
                    continue;
                };
                tried += 1;
                let mut rotations = vec![Vector3::zeros(); tree.len()];
                for (k, &a) in chain.nodes.iter().enumerate() {
                    rotations[a] =
                        Vector3::new(feasible[3 * k], feasible[3 * k + 1], feasible[3 * k + 2]);
                }
                let energy = elastic_energy(&tree, &rotations);
                assert!(
                    energy >= best - 1e-9 * best.max(1e-3),
                    "perturbation has {energy} < {best}"
                );
            }
            assert!(tried >= 20);
        }
    }
    assert!(solved >= 15, "only {solved} on-axis solutions");
}

#[test]
fn rotating_tree_and_push_about_the_vertical_rotates_the_answer() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for seed in 0..10 {
        let (tree, pushes) = random_tree_and_pushes(300 + seed, 18, 3);
        let angle = rng.random_range(0.0..std::f64::consts::TAU);
        let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), angle);
        let turned = Tree::new(
            tree.positions().iter().map(|p| turn * p).collect(),
            tree.parents().to_vec(),
            tree.branches().to_vec(),
        )
        .unwrap();
        for push in pushes {
            for config in [slot(), pinned()] {
                let Ok(a) = simulate(&tree, &push, &config) else {
                    continue;
                };
                let b = simulate(
                    &turned,
                    &Push {
                        node: push.node,
                        vector: turn * push.vector,
                    },
                    &config,
                )
                .unwrap();
                for (p, q) in a.final_positions.iter().zip(&b.final_positions) {
                    assert!((turn * p - q).norm() < 1e-9, "{} vs {}", turn * p, q);
                }
                assert!(
                    (a.report.energy - b.report.energy).abs() < 1e-9 * a.report.energy.max(1e-3)
                );
            }
        }
    }
}

#[test]
fn large_pushes_on_short_branches_converge() {
    // A zig-zag chain of six ~7 cm branches of falling stiffness (so it has
    // slack to follow), its tip carried 15 cm: joints turn by 14–32°.
    let mut positions = vec![Point3::origin()];
    let mut parents = vec![None];
    let mut branches = vec![None];
    for k in 1..=6 {
        let p = Point3::new(
            if k % 2 == 1 { 0.035 } else { -0.035 },
            0.0,
            0.06 * k as f64,
        );
        let l = (p - positions[k - 1]).norm();
        positions.push(p);
        parents.push(Some(k - 1));
        branches.push(Some(branch(l, 35.0 - 5.0 * k as f64)));
    }
    let tree = Tree::new(positions, parents, branches).unwrap();
    let mut solved = 0;
    for dir in [
        Vector3::x(),
        Vector3::new(1.0, 1.0, -0.5),
        Vector3::new(0.0, -1.0, -0.6),
        Vector3::new(-1.0, 0.2, -1.0),
    ] {
        let out = simulate(
            &tree,
            &Push {
                node: 6,
                vector: dir.normalize() * 0.15,
            },
            &pinned(),
        )
        .unwrap();
        assert!(out.report.kkt_residual < 1e-8);
        assert!(out.report.constraint_residual < 1e-12);
        assert!(
            out.report.max_joint_angle > 0.2,
            "{}",
            out.report.max_joint_angle
        );
        solved += 1;
    }
    assert_eq!(solved, 4);
}

#[test]
fn invalid_pushes_are_typed_errors() {
    let tree = vertical_chain(&[(0.2, 40.0), (0.2, 20.0)]);
    let push = |node, v: Vector3<f64>| simulate(&tree, &Push { node, vector: v }, &slot());
    assert_eq!(
        push(0, Vector3::x() * 0.05).unwrap_err(),
        SimError::RootContact
    );
    assert_eq!(
        push(3, Vector3::x() * 0.05).unwrap_err(),
        SimError::NodeOutOfRange { node: 3, n: 3 }
    );
    assert_eq!(
        push(1, Vector3::new(f64::NAN, 0.0, 0.0)).unwrap_err(),
        SimError::NonFinitePush
    );
    assert!(matches!(
        push(1, Vector3::x() * 2.0).unwrap_err(),
        SimError::PushTooLong { .. }
    ));
    // A leaf pushed far sideways slips out of the slot past its tip.
    let single = vertical_chain(&[(0.2, 40.0)]);
    let err = simulate(
        &single,
        &Push {
            node: 1,
            vector: Vector3::x() * 0.12,
        },
        &slot(),
    )
    .unwrap_err();
    assert!(matches!(err, SimError::LostBranch { .. }), "{err}");
    // At a fork the slot catches instead. A stiff trunk and two softer
    // branches; node 2 (with child 3) is pushed so far that the slot slides
    // past it, and the tree can still carry node 2 to the gripper point.
    let tree = vertical_chain(&[(0.2, 400.0), (0.2, 20.0), (0.2, 10.0)]);
    let shove = Vector3::new(0.14, 0.0, -0.02);
    let out = simulate(
        &tree,
        &Push {
            node: 2,
            vector: shove,
        },
        &slot(),
    )
    .unwrap();
    assert_eq!(out.report.hold, Hold::AtNode);
    let grip = Point3::new(0.0, 0.0, 0.4 - GRIP_OFFSET) + shove;
    assert!((out.final_positions[2] - grip).norm() < 1e-12);
    assert!(out.report.kkt_residual < 1e-8);
    // Without a child the same push loses the branch.
    let short = vertical_chain(&[(0.2, 400.0), (0.2, 20.0)]);
    let err = simulate(
        &short,
        &Push {
            node: 2,
            vector: shove,
        },
        &slot(),
    )
    .unwrap_err();
    assert!(matches!(err, SimError::LostBranch { .. }), "{err}");
    // Pushed back along the branch past its base, the slot catches on the
    // fork there: the gripper carries node 2 to its point, and the pushed
    // branch (node 3) moves rigidly with it.
    let back = Vector3::new(0.02, 0.0, -0.22);
    let out = simulate(
        &tree,
        &Push {
            node: 3,
            vector: back,
        },
        &slot(),
    )
    .unwrap();
    assert_eq!(out.report.hold, Hold::AtBase);
    let grip = Point3::new(0.0, 0.0, 0.6 - GRIP_OFFSET) + back;
    assert!((out.final_positions[2] - grip).norm() < 1e-9);
    assert_eq!(out.joint_rotations[3], Vector3::zeros());
    assert!(out.report.kkt_residual < 1e-8);
    // At the trunk's foot nothing carries the fork: the branch is lost.
    let err = simulate(
        &single,
        &Push {
            node: 1,
            vector: back,
        },
        &slot(),
    )
    .unwrap_err();
    assert!(
        matches!(err, SimError::LostBranch { slide, .. } if slide < 0.0),
        "{err}"
    );
}
