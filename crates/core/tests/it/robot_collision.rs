//! Collision checking: hand-placed contacts, 1 mm clearances, the ground,
//! the gripper's allowance, self-collision pairs.

use nalgebra::{Point3, Vector3};
use treemanip_core::robot::collision::{Allowed, CollisionModel, Hit, TreeObstacles};
use treemanip_core::robot::motion::rrt::Config;
use treemanip_core::robot::ur5::DISABLED_PAIRS;
use treemanip_core::robot::{Arm, ur5};

fn model() -> CollisionModel {
    CollisionModel::new(Arm::default())
}

/// A configuration reaching forward over the ground, arm clear of itself.
const REACH: Config = Config::new([0.0, -1.2, 1.4, -1.7, -std::f64::consts::FRAC_PI_2, 0.0]);

#[test]
fn zero_and_home_are_free_and_disabled_pairs_are_needed_for_that() {
    let m = model();
    let empty = TreeObstacles::empty();
    for q in [Config::zeros(6), ur5::HOME, REACH] {
        assert_eq!(m.check(&q, &empty, &Allowed::default()), None, "{q:?}");
    }
    // Without the disabled pairs, the capsules overlap in these valid
    // configurations, and only in those pairs.
    let strict = CollisionModel::with_disabled_pairs(Arm::default(), &[]);
    let mut seen = Vec::new();
    for q in [Config::zeros(6), ur5::HOME] {
        if let Some(Hit::SelfCollision { link, other }) =
            strict.check(&q, &empty, &Allowed::default())
        {
            assert!(
                DISABLED_PAIRS
                    .iter()
                    .any(|(a, b)| (*a == link && *b == other) || (*a == other && *b == link)),
                "{link} – {other}"
            );
            seen.push((link, other));
        }
    }
    assert!(!seen.is_empty());
}

/// Places a thin "branch" parallel to the forearm's tube capsule at a given
/// surface gap and returns what the checker says.
fn branch_beside_forearm(gap: f64) -> Option<Hit> {
    let m = model();
    let capsules = m.capsules_at(&REACH);
    let (_, a, b, r) = capsules
        .iter()
        .filter(|c| c.0 == "forearm_link")
        .max_by(|x, y| (x.2 - x.1).norm().total_cmp(&(y.2 - y.1).norm()))
        .copied()
        .unwrap();
    // Straight up from the tube (the tube is roughly horizontal in REACH).
    let axis = (b - a).normalize();
    let side = axis.cross(&Vector3::z()).cross(&axis).normalize();
    let branch_radius = 0.01;
    let shift = side * (r + branch_radius + gap);
    let mid = a + (b - a) * 0.5;
    let obstacles = TreeObstacles::from_capsules(&[(
        7,
        mid - axis * 0.05 + shift,
        mid + axis * 0.05 + shift,
        branch_radius,
    )]);
    m.check(&REACH, &obstacles, &Allowed::default())
}

#[test]
fn touching_and_one_millimetre_apart() {
    assert_eq!(branch_beside_forearm(0.001), None, "1 mm clearance is free");
    assert_eq!(
        branch_beside_forearm(0.0005),
        None,
        "0.5 mm clearance is free"
    );
    let hit = branch_beside_forearm(-0.0001);
    assert_eq!(
        hit,
        Some(Hit::Branch {
            link: "forearm_link".into(),
            node: 7
        }),
        "0.1 mm overlap collides"
    );
}

#[test]
fn the_ground_is_an_obstacle() {
    let m = model();
    let empty = TreeObstacles::empty();
    // Shoulder lift pointing the upper arm down into the ground.
    let down = [0.0, 1.2, 0.0, 0.0, 0.0, 0.0];
    assert!(matches!(
        m.check(&down, &empty, &Allowed::default()),
        Some(Hit::Ground { .. })
    ));
    // Mounted higher, the same configuration clears the ground.
    let high = CollisionModel::new(
        Arm::default().with_base(nalgebra::Isometry3::translation(-0.5, 0.0, 1.5)),
    );
    assert_eq!(high.check(&down, &empty, &Allowed::default()), None);
}

#[test]
fn the_gripper_may_touch_only_the_allowed_branch() {
    let m = model();
    let tool = m.robot.tool_pose(&REACH);
    // A branch through the slot, along the tool x axis, 3 cm in front of
    // the palm: between the fingers, touching neither.
    let x = tool.rotation * Vector3::x();
    let centre = tool * Point3::new(0.0, 0.0, 0.03);
    let in_slot = TreeObstacles::from_capsules(&[(4, centre - x * 0.1, centre + x * 0.1, 0.008)]);
    assert_eq!(m.check(&REACH, &in_slot, &Allowed::default()), None);
    // A thicker branch touches the fingers...
    let thick = TreeObstacles::from_capsules(&[(4, centre - x * 0.1, centre + x * 0.1, 0.012)]);
    let hit = m.check(&REACH, &thick, &Allowed::default());
    assert!(
        matches!(&hit, Some(Hit::Branch { link, node: 4 }) if link.starts_with("gripper_finger")),
        "{hit:?}"
    );
    // ... which is allowed for the contacted branch, and for it only.
    let allowed = Allowed {
        gripper_branches: vec![4],
    };
    assert_eq!(m.check(&REACH, &thick, &allowed), None);
    let other = Allowed {
        gripper_branches: vec![5],
    };
    assert!(m.check(&REACH, &thick, &other).is_some());
}

#[test]
fn a_generated_tree_in_front_of_the_arm() {
    use treemanip_core::tree::{ScaParams, generate};
    let m = model();
    let tree = generate(30, 1, &ScaParams::default()).unwrap();
    let obstacles = TreeObstacles::new(&tree);
    // Folded at home, the arm is clear of a tree half a metre away.
    assert_eq!(m.check(&ur5::HOME, &obstacles, &Allowed::default()), None);
    // Swinging the arm straight through the tree's trunk collides.
    let mut through = [0.0; 6];
    through[1] = -0.3;
    let hit = m.check(&through, &obstacles, &Allowed::default());
    assert!(
        matches!(hit, Some(Hit::Branch { .. })),
        "the arm through the tree must hit a branch: {hit:?}"
    );
}

/// An obstacle of each shape ([`Shape`]) blocks the arm where it overlaps
/// a link and not 1 mm further away: a sphere around the wrist, a box and
/// a capsule just touching its bounding distance.
#[test]
fn every_obstacle_shape_blocks_where_it_overlaps() {
    use treemanip_core::geometry::shape::Shape;
    let m = model();
    let tool = m.robot.tool_pose(&REACH).translation.vector;
    let x = Vector3::x();
    // How far the arm reaches along +x at this height: the first sphere
    // centre out along x from the tool that no longer touches.
    let touches = |shape: Shape| {
        let obstacles = TreeObstacles::empty().with_obstacles(std::slice::from_ref(&shape));
        matches!(
            m.check(&REACH, &obstacles, &Allowed::default()),
            Some(Hit::Obstacle { index: 0, .. })
        )
    };
    let sphere_at = |d: f64| Shape::Sphere {
        centre: Point3::from(tool + x * d),
        radius: 0.05,
    };
    assert!(touches(sphere_at(0.0)), "a sphere around the tool");
    let mut lo = 0.0;
    let mut hi = 1.0;
    assert!(!touches(sphere_at(hi)));
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if touches(sphere_at(mid)) {
            lo = mid
        } else {
            hi = mid
        }
    }
    // A box and a capsule that hold the last touching sphere touch too;
    // ones inside the first free sphere (1 mm further out) stay free.
    let (inside, outside) = (tool + x * (lo - 0.001), tool + x * (hi + 0.001));
    assert!(touches(sphere_at(lo - 0.001)) && !touches(sphere_at(hi + 0.001)));
    let cube =
        |c: Vector3<f64>, half: f64| Shape::turned_box(Point3::from(c), Vector3::repeat(half), 0.3);
    let rod = |c: Vector3<f64>, half: f64, radius: f64| Shape::Capsule {
        a: Point3::from(c - x * half),
        b: Point3::from(c + x * half),
        radius,
    };
    assert!(
        touches(cube(inside, 0.05)),
        "a cube around the touching sphere"
    );
    assert!(touches(rod(inside, 0.1, 0.05)), "a capsule around it");
    assert!(
        !touches(cube(outside, 0.05 / 3f64.sqrt() - 1e-9)),
        "a cube inside the free sphere"
    );
    assert!(!touches(rod(outside, 0.02, 0.03)), "a capsule inside it");
}
