//! The cheap reachability test a search asks of every candidate push:
//! [`reachable`] stops at the first usable pre-contact configuration and
//! must answer as the full [`reach`] does, outcome included; the lazy IK
//! solutions are the sorted ones, as a set.

use std::path::PathBuf;

use nalgebra::Isometry3;
use treemanip_core::robot::Arm;
use treemanip_core::robot::collision::{CollisionModel, TreeObstacles};
use treemanip_core::robot::model::description::RobotDescription;
use treemanip_core::robot::motion::push_motion::{pre_contact_poses, reach, reachable};

/// The shipped Panda (numerical IK, 7 joints) standing in front of the
/// trees the paper's generator grows.
fn panda() -> CollisionModel {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let path = dir.join("panda.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let description = RobotDescription::from_toml_str(&text, &path).unwrap();
    let arm = Arm::from_description(&description).unwrap();
    CollisionModel::new(arm.with_base(Isometry3::translation(0.0, -0.55, 0.35)))
}

#[test]
fn reachable_answers_as_the_full_reach() {
    let model = panda();
    let home = model.robot.home();
    let mut outcomes = std::collections::BTreeMap::new();
    for seed in 0..6 {
        let (tree, pushes) = crate::common::random_tree_and_pushes(seed, 20, 12);
        let obstacles = TreeObstacles::new(&tree);
        for push in &pushes {
            let full = reach(&model, &tree, &obstacles, push, &home);
            let first = reachable(&model, &tree, &obstacles, push, &home);
            assert_eq!(full.as_ref().map(|_| ()).map_err(|o| *o), first, "{push:?}");
            *outcomes.entry(format!("{first:?}")).or_insert(0) += 1;
        }
    }
    // The sample holds reachable pushes and more than one kind of failure,
    // so the agreement above is not of one answer.
    assert!(outcomes.contains_key("Ok(())"), "{outcomes:?}");
    assert!(outcomes.len() >= 3, "{outcomes:?}");
}

#[test]
fn lazy_ik_solutions_are_the_sorted_solutions() {
    let model = panda();
    let arm = &model.robot;
    let home = arm.home();
    let mut solved = 0;
    for seed in 0..4 {
        let (tree, pushes) = crate::common::random_tree_and_pushes(seed, 15, 8);
        for push in &pushes {
            let Some(poses) = pre_contact_poses(&tree, push) else {
                continue;
            };
            for pose in &poses {
                let sorted = arm.inverse_kinematics(pose, &home);
                let lazy: Vec<_> = arm.ik_solutions(pose, &home).collect();
                assert_eq!(sorted.len(), lazy.len());
                for q in &lazy {
                    assert!(sorted.contains(q));
                    // Each solution puts the tool where asked.
                    let at = arm.tool_pose(q);
                    assert!((at.translation.vector - pose.translation.vector).norm() < 1e-5);
                    assert!(at.rotation.angle_to(&pose.rotation) < 1e-4);
                }
                // Nearest the reference first.
                assert!(
                    sorted
                        .windows(2)
                        .all(|w| w[0].max_abs_diff(&home) <= w[1].max_abs_diff(&home))
                );
                solved += usize::from(!lazy.is_empty());
            }
        }
    }
    assert!(solved > 10, "only {solved} poses solved");
}

/// A short arm with a narrow wrist pushes upward from below: the bare
/// Unitree Z1 (reach 0.97 m, wrist pitch ±87°, yaw ±77°) in a base region
/// in front of the trees reaches upward pushes (tilted more than 24°) from
/// the stances turned with the push (`base::stance_offsets`): 36 of the
/// 73 below; from the level stances alone it reached 6.
#[test]
fn a_short_arm_stands_below_an_upward_push() {
    use nalgebra::Vector3;
    use treemanip_core::planner::base::BaseRegion;
    use treemanip_core::planner::{Planner, Stance};
    use treemanip_core::robot::catalog::{RobotSpec, load};
    let Some(erd) = crate::common::robot_data() else {
        return;
    };
    let spec: RobotSpec = format!(
        "z1={}/z1_description/urdf/z1.urdf,tip=link06",
        erd.display()
    )
    .parse()
    .unwrap();
    let arm = load(&spec, &[erd.clone(), erd.join("../..")]).unwrap();
    let planner = Planner::new(CollisionModel::new(arm));
    let stance = Stance::Region(BaseRegion {
        min: Vector3::new(-1.0, -0.5, 0.1),
        max: Vector3::new(0.0, 0.5, 1.0),
        yaw: None,
    });
    let (mut upward, mut reached) = (0, 0);
    for seed in 0..6 {
        let (tree, pushes) = crate::common::random_tree_and_pushes(seed, 20, 40);
        let test = planner.reach_test(&tree, &[], &stance, None);
        for push in pushes.iter().filter(|p| p.vector.z > 0.4 * p.vector.norm()) {
            upward += 1;
            reached += usize::from(test(push));
        }
    }
    assert!(upward >= 30, "{upward} upward pushes");
    assert!(
        reached * 10 >= upward * 3,
        "{reached} of {upward} upward pushes reached"
    );
}
