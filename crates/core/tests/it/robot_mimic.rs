//! A mimic joint on the planning chain (a parallelogram: the third joint
//! turns back by what the second turns, so the forearm keeps the upper
//! arm's orientation): the arm loads from a bare URDF with one variable
//! per free joint, its kinematics keep the parallelogram, the numerical IK
//! solves it, the lever arms bound how fast any point of it moves, and
//! edges the conservative check passes are free at every dense sample.

use nalgebra::{Point3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use treemanip_core::robot::Arm;
use treemanip_core::robot::arm::PAPER_BASE;
use treemanip_core::robot::catalog::{self, RobotSpec};
use treemanip_core::robot::collision::{Allowed, CollisionModel, TreeObstacles};
use treemanip_core::robot::motion::rrt::{Config, MotionValidator};
use treemanip_core::robot::motion::scene::PlanningScene;

const URDF: &str = r#"<robot name="parallelogram">
  <link name="base"><collision><origin xyz="0 0 0.05"/><geometry><cylinder radius="0.06" length="0.1"/></geometry></collision></link>
  <link name="l1"><collision><origin xyz="0 0 0.15"/><geometry><capsule radius="0.04" length="0.3"/></geometry></collision></link>
  <link name="l2"><collision><origin xyz="0 0 0.15"/><geometry><capsule radius="0.035" length="0.3"/></geometry></collision></link>
  <link name="l3"><collision><origin xyz="0 0 0.12"/><geometry><capsule radius="0.03" length="0.25"/></geometry></collision></link>
  <link name="l4"><collision><origin xyz="0 0 0.05"/><geometry><box size="0.05 0.05 0.1"/></geometry></collision></link>
  <link name="l5"><collision><origin xyz="0 0 0.03"/><geometry><sphere radius="0.03"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-2.5" upper="2.5" velocity="2" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" velocity="2" effort="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0 0 0.3"/><axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" velocity="2" effort="1"/><mimic joint="j2" multiplier="-1"/></joint>
  <joint name="j4" type="revolute"><parent link="l3"/><child link="l4"/><origin xyz="0 0 0.25"/><axis xyz="0 0 1"/><limit lower="-2.5" upper="2.5" velocity="2" effort="1"/></joint>
  <joint name="j5" type="revolute"><parent link="l4"/><child link="l5"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="2" effort="1"/></joint>
</robot>"#;

fn arm() -> Arm {
    arm_from(URDF, "parallelogram")
}

fn arm_from(urdf: &str, tag: &str) -> Arm {
    let dir = crate::common::temp_dir(&format!("mimic-{tag}"));
    let path = dir.join("parallelogram.urdf");
    std::fs::write(&path, urdf).unwrap();
    let spec: RobotSpec = format!("parallelogram={}", path.display()).parse().unwrap();
    // Built as `catalog::load` builds an arm, without its refusal of
    // arms under six joints (a push needs them; these kinematic checks
    // do not).
    let description =
        catalog::load_description(&spec, &[]).expect("a chain with a mimic joint loads");
    let arm = Arm::from_description(&description).unwrap();
    let home = catalog::free_home(&arm).expect("a free home");
    arm.with_home(home).unwrap()
}

fn random_config(rng: &mut ChaCha8Rng, arm: &Arm) -> Config {
    let limits = arm.limits();
    Config::from_slice(
        &limits
            .iter()
            .map(|(lo, hi)| rng.random_range(*lo..=*hi))
            .collect::<Vec<_>>(),
    )
}

#[test]
fn a_mimic_joint_on_the_chain_plans_soundly() {
    let arm = arm();
    assert_eq!(arm.dof(), 4, "j3 follows j2: four variables");
    assert_eq!(
        arm.joint_names().collect::<Vec<_>>(),
        ["j1", "j2", "j4", "j5"]
    );
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    // The parallelogram: l3 keeps l1's orientation whatever j2 is.
    let index = |name: &str| arm.link_index(name).unwrap();
    for _ in 0..20 {
        let q = random_config(&mut rng, &arm);
        let poses = arm.link_poses(&q);
        let (r1, r3): (UnitQuaternion<f64>, UnitQuaternion<f64>) =
            (poses[index("l1")].rotation, poses[index("l3")].rotation);
        assert!(r1.angle_to(&r3) < 1e-12, "l3 turned with j2 at {q:?}");
        // The forearm's base is where the upper arm ends.
        let elbow = poses[index("l2")] * Point3::new(0.0, 0.0, 0.3);
        assert!((poses[index("l3")] * Point3::origin() - elbow).norm() < 1e-12);
    }
    // Numerical IK on poses the arm reaches (4 joints: only such poses).
    let mut solved = 0;
    for _ in 0..50 {
        let q = random_config(&mut rng, &arm);
        let pose = arm.tool_pose(&q);
        if let Some(found) = arm.inverse_kinematics(&pose, &arm.home()).first() {
            let back = arm.tool_pose(found);
            assert!((back.translation.vector - pose.translation.vector).norm() < 1e-6);
            solved += 1;
        }
    }
    assert!(solved >= 45, "IK solved {solved}/50");
    // The lever arms bound every point's motion, the mimic joint's turn
    // included: j2 moves the forearm's tip by both of its joints (which
    // add up when the mimic turns the same way).
    let same_way = arm_from(
        &URDF.replace("multiplier=\"-1\"", "multiplier=\"1\""),
        "same",
    );
    assert_lever_arms_bound_motion(&same_way, &mut rng);
    assert_lever_arms_bound_motion(&arm, &mut rng);
    let model = CollisionModel::new(arm.clone().with_base(PAPER_BASE));
    // Edges the scene passes among poles are free at 400 samples along
    // them. A half ring of poles 0.22 m around the base (the elbow swings
    // out to 0.3 m).
    let centre = PAPER_BASE.translation.vector;
    let poles: Vec<_> = (0..12)
        .map(|k| {
            let angle = std::f64::consts::PI * k as f64 / 11.0;
            let foot = Point3::new(
                centre.x + 0.22 * angle.cos(),
                centre.y + 0.22 * angle.sin(),
                0.0,
            );
            (k, foot, foot + Vector3::z() * 0.9, 0.02)
        })
        .collect();
    let obstacles = TreeObstacles::from_capsules(&poles);
    let scene = PlanningScene::new(&model, &obstacles, Allowed::default());
    let (mut passed, mut refused) = (0, 0);
    for _ in 0..300 {
        let a = random_config(&mut rng, &arm);
        let b = random_config(&mut rng, &arm);
        if !(scene.config_valid(&a) && scene.config_valid(&b)) {
            continue;
        }
        if !scene.edge_valid(&a, &b) {
            refused += 1;
            continue;
        }
        passed += 1;
        for k in 0..=400 {
            let q = a.lerp(&b, k as f64 / 400.0);
            assert!(
                model.check(&q, &obstacles, &Allowed::default()).is_none(),
                "a passed edge collides at {q:?}"
            );
        }
    }
    eprintln!("edges: {passed} passed, {refused} refused");
    assert!(
        passed > 10 && refused > 10,
        "{passed} passed, {refused} refused"
    );
}

/// Every capsule end moves no farther than lever_i |Δq_i| over small
/// random steps of one joint i.
fn assert_lever_arms_bound_motion(arm: &Arm, rng: &mut ChaCha8Rng) {
    let model = CollisionModel::new(arm.clone().with_base(PAPER_BASE));
    let lever = *model.lever_arms();
    for _ in 0..200 {
        let a = random_config(rng, arm);
        // One joint at a time: each lever arm on its own must hold.
        let mut b = a;
        b[rng.random_range(0..arm.dof())] += rng.random_range(-1e-3..1e-3);
        let bound: f64 = (0..arm.dof()).map(|i| lever[i] * (b[i] - a[i]).abs()).sum();
        for (ca, cb) in model.capsules_at(&a).iter().zip(model.capsules_at(&b)) {
            for (p, q) in [(ca.1, cb.1), (ca.2, cb.2)] {
                assert!(
                    (q - p).norm() <= bound + 1e-12,
                    "{}: {} > {bound}",
                    ca.0,
                    (q - p).norm()
                );
            }
        }
    }
}
