//! The UR5 model: committed URDF, forward kinematics against an independent
//! DH computation, and collision capsules that enclose the real link meshes.

use std::f64::consts::PI;

use nalgebra::{Isometry3, Matrix4, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use treemanip_core::geometry::shape::Shape;
use treemanip_core::robot::Arm;
use treemanip_core::robot::model::tool;
use treemanip_core::robot::ur5::{self, DH_A, DH_ALPHA, DH_D, JOINT_LIMITS};

#[test]
fn committed_urdf_is_the_generated_one() {
    let generated = ur5::urdf_string();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/ur5_gripper.urdf");
    if std::env::var_os("TREEMANIP_BLESS").is_some() {
        std::fs::write(path, &generated).unwrap();
    }
    assert!(
        ur5::URDF == generated,
        "assets/ur5_gripper.urdf is stale: run `TREEMANIP_BLESS=1 cargo test -p treemanip-core --test it robot_model`"
    );
}

/// Standard DH: T = Π Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i), written out as 4×4
/// matrices, independent of the URDF chain.
fn dh_flange(q: &[f64; 6]) -> Matrix4<f64> {
    let mut t = Matrix4::identity();
    for i in 0..6 {
        let (ct, st) = (q[i].cos(), q[i].sin());
        let (ca, sa) = (DH_ALPHA[i].cos(), DH_ALPHA[i].sin());
        #[rustfmt::skip]
        let a = Matrix4::new(
            ct, -st * ca,  st * sa, DH_A[i] * ct,
            st,  ct * ca, -ct * sa, DH_A[i] * st,
            0.0,      sa,       ca, DH_D[i],
            0.0,     0.0,      0.0, 1.0,
        );
        t *= a;
    }
    t
}

fn random_q(rng: &mut ChaCha8Rng) -> [f64; 6] {
    std::array::from_fn(|i| rng.random_range(JOINT_LIMITS[i].0..JOINT_LIMITS[i].1))
}

/// World pose of the DH base frame 0 (`base_link_inertia`, fixed to the
/// mount).
fn dh_base(robot: &Arm) -> Isometry3<f64> {
    let frame0 = robot.link_index("base_link_inertia").unwrap();
    robot.link_poses(&[0.0; 6])[frame0]
}

#[test]
fn forward_kinematics_matches_an_independent_dh_computation() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let base = Isometry3::new(Vector3::new(-0.5, 0.2, 0.1), Vector3::new(0.0, 0.0, 0.3));
    let robot = Arm::default().with_base(base);
    let flange = robot.link_index("wrist_3_link").unwrap();
    for _ in 0..200 {
        let q = random_q(&mut rng);
        let fk = robot.link_poses(&q)[flange].to_homogeneous();
        let expected = dh_base(&robot).to_homogeneous() * dh_flange(&q);
        assert!(
            (fk - expected).abs().max() < 1e-9,
            "q = {q:?}\n{fk}\n{expected}"
        );
    }
    // The DH base frame is the mount turned by π about z.
    let frame0 = dh_base(&robot);
    assert!((frame0.translation.vector - base.translation.vector).norm() < 1e-15);
    assert!(
        (frame0.rotation.angle_to(
            &(base.rotation * nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), PI))
        ))
        .abs()
            < 1e-12
    );
}

#[test]
fn tool_frame_sits_on_the_palm_face() {
    let robot = Arm::default();
    let q = ur5::HOME;
    let poses = robot.link_poses(&q);
    let flange = poses[robot.link_index("wrist_3_link").unwrap()];
    let tool = robot.tool_pose(&q);
    let offset = flange.inverse() * tool;
    assert!((offset.translation.vector - Vector3::new(0.0, 0.0, tool::TOOL_OFFSET)).norm() < 1e-15);
    assert!(offset.rotation.angle() < 1e-15);
    // Slot: the two finger boxes leave 2 cm between them.
    let fingers: Vec<f64> = tool::GRIPPER_BOXES[2..]
        .iter()
        .map(|b| b.centre[1])
        .collect();
    let gap = (fingers[0] - fingers[1]).abs() - tool::FINGER_THICKNESS;
    assert!((gap - tool::SLOT_WIDTH).abs() < 1e-15);
}

#[test]
fn capsules_enclose_the_reference_meshes() {
    // The ROS-Industrial UR5 collision meshes in our link frames, measured
    // once by scripts/measure-ur5-meshes.py. A triangle with all three
    // corners inside one capsule lies inside it (capsules are convex), so
    // this shows the capsules cover every mesh surface, not just vertices.
    let meshes: serde_json::Value = serde_json::from_str(include_str!(
        "../../../../tests/data/ur5_mesh_triangles.json"
    ))
    .unwrap();
    let robot = Arm::default();
    let mut checked = 0;
    for (link, shapes) in robot.link_shapes() {
        let Some(mesh) = meshes["links"].get(link) else {
            continue;
        };
        let capsules: Vec<(Vector3<f64>, Vector3<f64>, f64)> = shapes
            .iter()
            .filter_map(|s| match s {
                Shape::Capsule { a, b, radius } => Some((a.coords, b.coords, *radius)),
                _ => None,
            })
            .collect();
        assert!(!capsules.is_empty(), "{link} has no capsule");
        let vertices: Vec<Vector3<f64>> = mesh["vertices"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| {
                Vector3::new(
                    v[0].as_f64().unwrap(),
                    v[1].as_f64().unwrap(),
                    v[2].as_f64().unwrap(),
                )
            })
            .collect();
        let inside = |p: &Vector3<f64>, (a, b, r): &(Vector3<f64>, Vector3<f64>, f64)| {
            let ab = b - a;
            let t = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
            (p - (a + ab * t)).norm() <= *r
        };
        for triangle in mesh["triangles"].as_array().unwrap() {
            let corners: Vec<&Vector3<f64>> = (0..3)
                .map(|k| &vertices[triangle[k].as_u64().unwrap() as usize])
                .collect();
            assert!(
                capsules
                    .iter()
                    .any(|c| corners.iter().all(|p| inside(p, c))),
                "{link}: triangle {corners:?} is not inside any one capsule"
            );
            checked += 1;
        }
    }
    assert!(checked > 5000, "only {checked} triangles checked");
    assert_eq!(
        meshes["links"].as_object().unwrap().len(),
        7,
        "every arm link has a mesh"
    );
}

#[test]
fn home_pose_holds_the_gripper_in_front_of_the_tree() {
    // With the paper's mount, home puts the tool between the robot and the
    // tree, above the ground, pointing roughly at the tree.
    let robot = Arm::default();
    let tool = robot.tool_pose(&ur5::HOME);
    let p = tool.translation.vector;
    println!(
        "home tool position {:?}, z axis {:?}",
        p.as_slice(),
        (tool.rotation * Vector3::z()).as_slice()
    );
    assert!(p.z > 0.1, "tool above ground: {p}");
}

mod inverse_kinematics {
    use super::*;
    use treemanip_core::robot::kinematics::ur_closed_form::{
        self, forward, nearest_within_limits, solve, wrap,
    };

    fn pose_error(a: &Matrix4<f64>, b: &Matrix4<f64>) -> f64 {
        (a - b).abs().max()
    }

    #[test]
    fn every_solution_reaches_the_pose_and_generic_poses_have_eight() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut counts = [0usize; 9];
        let total = 500;
        for _ in 0..total {
            let q: [f64; 6] = std::array::from_fn(|_| rng.random_range(-PI..PI));
            let target = forward(&q);
            let solutions = solve(&target, &[0.0; 6]);
            assert!(
                !solutions.is_empty(),
                "no solution for a reachable pose, q = {q:?}"
            );
            for s in &solutions {
                assert!(
                    pose_error(&forward(s), &target) < 1e-9,
                    "q = {q:?} solution {s:?}"
                );
            }
            // The configuration we started from is among them.
            assert!(
                solutions
                    .iter()
                    .any(|s| s.iter().zip(&q).all(|(a, b)| wrap(a - b).abs() < 1e-7)),
                "q = {q:?} not recovered from {solutions:?}"
            );
            counts[solutions.len()] += 1;
        }
        // Branches come in pairs (elbow up/down); away from the boundary of
        // the workspace all eight exist.
        println!("solution counts 0..=8: {counts:?}");
        assert!(
            counts
                .iter()
                .enumerate()
                .all(|(k, &c)| k % 2 == 0 || c == 0),
            "{counts:?}"
        );
        assert!(counts[8] > total * 7 / 10, "{counts:?}");
    }

    #[test]
    fn wrist_singularity_takes_theta6_from_the_reference() {
        // θ5 = 0 aligns joints 4 and 6: only θ4 + θ6 is determined.
        let q = [0.3, -1.0, 1.2, -0.4, 0.0, 0.5];
        let target = forward(&q);
        let reference = [0.0, 0.0, 0.0, 0.0, 0.0, 0.9];
        let solutions = solve(&target, &reference);
        assert!(!solutions.is_empty());
        for s in &solutions {
            assert!(pose_error(&forward(s), &target) < 1e-9, "{s:?}");
        }
        assert!(
            solutions
                .iter()
                .any(|s| (s[5] - 0.9).abs() < 1e-12 && s[4].abs() < 1e-9)
        );
    }

    #[test]
    fn shoulder_singularity_and_unreachable_poses() {
        // Wrist centre on the shoulder's offset circle: θ1 branches coincide.
        let q = [0.2, -1.3, 1.6, -0.8, 1.1, 0.4];
        let t = forward(&q);
        assert!(
            solve(&t, &[0.0; 6])
                .iter()
                .all(|s| pose_error(&forward(s), &t) < 1e-9)
        );
        // 2 m away is out of reach.
        let mut far = Matrix4::identity();
        far[(0, 3)] = 2.0;
        assert!(solve(&far, &[0.0; 6]).is_empty());
    }

    #[test]
    fn wraps_pick_the_nearest_equivalent_within_limits() {
        let q = [3.0, -3.0, 3.0, -0.1, 0.1, 2.0];
        let reference = [-3.0, 3.0, 0.0, 6.0, -6.0, 2.0];
        let near = nearest_within_limits(&q, &reference).unwrap();
        assert!((near[0] - (3.0 - 2.0 * PI)).abs() < 1e-12);
        assert!((near[1] - (-3.0 + 2.0 * PI)).abs() < 1e-12);
        assert!((near[2] - 3.0).abs() < 1e-12, "the elbow is limited to ±π");
        assert!((near[3] - (-0.1 + 2.0 * PI)).abs() < 1e-12);
        assert!((near[4] - (0.1 - 2.0 * PI)).abs() < 1e-12);
        // No equivalent inside the limits: 0.1 + 2π > 2π, so 0.1 stays.
        let kept = nearest_within_limits(
            &[0.0, 0.0, 0.0, 0.1, 0.0, 0.0],
            &[0.0, 0.0, 0.0, 6.2, 0.0, 0.0],
        )
        .unwrap();
        assert_eq!(kept[3], 0.1);
        assert_eq!(near[5], 2.0);
        let _ = ur_closed_form::dh_transform(0, 0.0);
    }

    #[test]
    fn tool_pose_inverse_kinematics_in_the_world() {
        let robot = Arm::default();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..100 {
            let q = random_q(&mut rng);
            let tool = robot.tool_pose(&q);
            let solutions = robot.inverse_kinematics(&tool, &q.into());
            assert!(!solutions.is_empty());
            // The nearest solution is q itself.
            let first = solutions[0];
            assert!(
                first.iter().zip(&q).all(|(a, b)| (a - b).abs() < 1e-7),
                "{first:?} vs {q:?}"
            );
            for s in &solutions {
                let reached = robot.tool_pose(s);
                assert!((reached.translation.vector - tool.translation.vector).norm() < 1e-9);
                assert!(reached.rotation.angle_to(&tool.rotation) < 1e-9);
                for (i, v) in s.iter().enumerate() {
                    assert!((JOINT_LIMITS[i].0..=JOINT_LIMITS[i].1).contains(v));
                }
            }
        }
    }
}
