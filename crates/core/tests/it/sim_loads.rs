//! Branch loads from the simulator (`sim::loads`) against closed forms and
//! the moment balance at every joint.

use nalgebra::{Point3, Rotation3, Vector3};
use treemanip_core::sim::loads::branch_loads;
use treemanip_core::sim::{ContactModel, GRIP_OFFSET, Hold, Push, SimConfig, simulate};
use treemanip_core::tree::{Tree, Wood};

use crate::common::random_tree_and_pushes;

/// One vertical branch of length ℓ and radius r from the root.
fn cantilever(length: f64, radius: f64) -> Tree {
    Tree::new(
        vec![Point3::origin(), Point3::new(0.0, 0.0, length)],
        vec![None, Some(0)],
        vec![None, Some(Wood::default().branch(radius, length))],
    )
    .unwrap()
}

/// A pinned tip carried along its circle by φ: the spring turns by φ, the
/// bending moment is K_s φ, and it equals the contact force's lever
/// moment F⊥·ℓ; the stress is 4M/(πr³) and the implied modulus is the
/// wood's.
#[test]
fn a_pinned_cantilever_carries_f_times_l() {
    let (length, radius, phi) = (0.4, 0.006, 0.3_f64);
    let tree = cantilever(length, radius);
    let tip = Point3::new(length * phi.sin(), 0.0, length * phi.cos());
    let push = Push {
        node: 1,
        vector: tip - tree.position(1),
    };
    let config = SimConfig {
        contact: ContactModel::Pinned,
        ..SimConfig::default()
    };
    let out = simulate(&tree, &push, &config).unwrap();
    let loads = branch_loads(&tree, &out.joint_rotations);
    let k = tree.branch(1).unwrap().stiffness;
    let moment = loads.bending_moment[1].unwrap();
    assert!(
        (moment - k * phi).abs() < 1e-6 * k * phi,
        "{moment} vs {}",
        k * phi
    );
    let force = Vector3::from(out.report.contact_force);
    let arm = tip - Point3::origin();
    let perpendicular = force - arm.normalize() * force.dot(&arm.normalize());
    assert!(
        (perpendicular.norm() * length - moment).abs() < 1e-6 * moment,
        "F⊥·ℓ = {} vs M = {moment}",
        perpendicular.norm() * length
    );
    assert!(loads.twisting_moment[1].unwrap() < 1e-9 * moment);
    let stress = loads.bending_stress[1].unwrap();
    let expected = 4.0 * moment / (std::f64::consts::PI * radius.powi(3));
    assert!((stress - expected).abs() < 1e-9 * expected);
    let e = loads.implied_modulus[1].unwrap();
    assert!((e - Wood::default().young_modulus).abs() < 1e-6 * e);
    let peak = loads.peak_stress.unwrap();
    assert_eq!(peak.node, 1);
    assert_eq!(loads.bending_moment[0], None);
}

/// On random trees, for both contact models, every joint on the path
/// carries exactly the contact force's moment about it, K_s θ (in the world
/// frame) = (g − P_joint) × F, with g the point the gripper holds; joints
/// off the path carry nothing; and the bending and twisting moments split
/// that moment across and along the branch.
#[test]
fn every_joint_balances_the_contact_force() {
    let mut checked = 0;
    for (seed, contact) in [
        (1u64, ContactModel::Slot),
        (2, ContactModel::Pinned),
        (3, ContactModel::Slot),
        (4, ContactModel::Pinned),
    ] {
        let (tree, pushes) = random_tree_and_pushes(900 + seed, 12, 6);
        let config = SimConfig {
            contact,
            ..SimConfig::default()
        };
        for push in pushes {
            let Ok(out) = simulate(&tree, &push, &config) else {
                continue;
            };
            let loads = branch_loads(&tree, &out.joint_rotations);
            let n = tree.len();
            let mut orientation = vec![Rotation3::identity(); n];
            for j in 1..n {
                let i = tree.parents()[j].unwrap();
                orientation[j] = orientation[i] * Rotation3::new(out.joint_rotations[j]);
            }
            let force = Vector3::from(out.report.contact_force);
            let j = push.node;
            let grip = match out.report.hold {
                Hold::OnAxis => {
                    tree.position(j) - tree.branch_direction(j).unwrap() * GRIP_OFFSET + push.vector
                }
                Hold::AtNode => out.final_positions[j],
                Hold::AtBase => out.final_positions[tree.parent(j).unwrap()],
            };
            let mut on_path = vec![false; n];
            let mut k = j;
            while let Some(parent) = tree.parents()[k] {
                on_path[k] = true;
                let stiffness = tree.branch(k).unwrap().stiffness;
                let spring = orientation[parent] * (out.joint_rotations[k] * stiffness);
                let lever = (grip - out.final_positions[parent]).cross(&force);
                assert!(
                    (spring - lever).norm() <= 1e-6 * spring.norm().max(1e-9),
                    "joint {k}: K θ = {spring:?}, (g − P) × F = {lever:?}"
                );
                let (bending, twist) = (
                    loads.bending_moment[k].unwrap(),
                    loads.twisting_moment[k].unwrap(),
                );
                assert!((bending.hypot(twist) - spring.norm()).abs() <= 1e-9 * spring.norm());
                checked += 1;
                k = parent;
            }
            for (moment, _) in loads
                .bending_moment
                .iter()
                .zip(&on_path)
                .skip(1)
                .filter(|(_, on)| !**on)
            {
                assert_eq!(*moment, Some(0.0), "off the path");
            }
            let peak = loads.peak_stress.unwrap();
            assert!(on_path[peak.node]);
            assert!(
                loads
                    .bending_stress
                    .iter()
                    .flatten()
                    .all(|s| *s <= peak.stress)
            );
        }
    }
    assert!(checked >= 40, "{checked} joints checked");
}

/// A guarded push on a slot-held cantilever stops where the closed form
/// puts the force at the guard: the branch turns by φ = atan(t/g) for a
/// gripper t along (g = ℓ − grip offset), held at √(g² + t²) from the
/// joint, so |F| = K φ / √(g² + t²).
#[test]
fn a_guarded_push_stops_where_the_closed_form_force_reaches_the_guard() {
    use treemanip_core::sim::guarded::{GUARD_TOLERANCE, guarded_push};
    let (length, radius) = (0.4, 0.006);
    let tree = cantilever(length, radius);
    let k = tree.branch(1).unwrap().stiffness;
    let g = length - GRIP_OFFSET;
    let force_at = |t: f64| k * (t / g).atan() / (g * g + t * t).sqrt();
    let push = Push {
        node: 1,
        vector: Vector3::x() * 0.08,
    };
    let config = SimConfig::default();
    for stop_t in [0.013, 0.05] {
        let stop_at = force_at(stop_t);
        let guarded = guarded_push(&tree, &push, &config, stop_at).unwrap();
        assert!(guarded.stopped);
        let t = guarded.fraction * 0.08;
        assert!(
            t <= stop_t + 1e-9 && stop_t - t <= GUARD_TOLERANCE,
            "stopped {t} m along, the closed form says {stop_t}"
        );
        let force = Vector3::from(guarded.outcome.report.contact_force).norm();
        assert!(
            force <= stop_at && force > 0.99 * stop_at,
            "{force} N, guard {stop_at}"
        );
        // The tree stands where the closed form puts it at that point.
        let phi = (t / g).atan();
        let tip = Point3::new(length * phi.sin(), 0.0, length * phi.cos());
        assert!((guarded.outcome.final_positions[1] - tip).norm() < 1e-9);
    }
    // Past its deadline a guarded push simulates nothing more.
    let past = SimConfig {
        solver: treemanip_core::sim::solver::SolverOptions {
            deadline: Some(std::time::Instant::now() - std::time::Duration::from_millis(1)),
            ..Default::default()
        },
        ..SimConfig::default()
    };
    assert_eq!(
        guarded_push(&tree, &push, &past, 1.0).unwrap_err(),
        treemanip_core::sim::SimError::OutOfTime { iterations: 0 }
    );
    // A guard above the whole push's force never trips: the push as the
    // simulator gives it.
    let whole = simulate(&tree, &push, &config).unwrap();
    let guarded = guarded_push(&tree, &push, &config, force_at(0.08) * 1.01).unwrap();
    assert!(!guarded.stopped && guarded.fraction == 1.0);
    assert!((guarded.outcome.final_positions[1] - whole.final_positions[1]).norm() < 1e-9);
}

/// On random trees the guarded push never ends above its guard, carries
/// out the whole push when the push stays below it, and stops short when
/// it does not.
#[test]
fn a_guarded_push_never_ends_above_its_guard() {
    use treemanip_core::sim::guarded::guarded_push;
    let config = SimConfig::default();
    let (mut stopped, mut whole) = (0, 0);
    let cases = (0..4).flat_map(|seed| {
        let (tree, pushes) = random_tree_and_pushes(seed, 20, 6);
        pushes.into_iter().map(move |p| (tree.clone(), p))
    });
    for (tree, push) in cases {
        let Ok(out) = simulate(&tree, &push, &config) else {
            continue;
        };
        let full = Vector3::from(out.report.contact_force).norm();
        for stop_at in [0.5 * full, 2.0 * full] {
            let Ok(g) = guarded_push(&tree, &push, &config, stop_at) else {
                continue;
            };
            let f = Vector3::from(g.outcome.report.contact_force).norm();
            assert!(f <= stop_at, "{f} N over the guard {stop_at}");
            if g.stopped {
                stopped += 1;
                assert!(g.fraction < 1.0);
            } else {
                whole += 1;
                assert!(
                    (g.outcome.final_positions[push.node] - out.final_positions[push.node]).norm()
                        < 1e-6
                );
            }
        }
    }
    assert!(
        stopped >= 8 && whole >= 8,
        "stopped {stopped}, whole {whole}"
    );
}
