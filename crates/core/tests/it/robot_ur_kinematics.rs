//! The closed-form fast path for any chain with UR kinematics: its DH
//! lengths fitted to the URDF, checked on the built-in UR5, the shipped
//! UR5 and UR10 (ROS-Industrial URDFs), and refused for the 7-joint arms.

use std::path::Path;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use treemanip_core::robot::kinematics::ur_kinematics::UrKinematics;
use treemanip_core::robot::model::description::RobotDescription;
use treemanip_core::robot::model::urdf_chain::Chain;
use treemanip_core::robot::model::urdf_chain::random_configuration;
use treemanip_core::robot::ur5;

fn shipped(name: &str) -> Chain {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .join("robots")
        .join(format!("{name}.toml"));
    let text = std::fs::read_to_string(&path).unwrap();
    RobotDescription::from_toml_str(&text, &path)
        .unwrap()
        .chain()
        .unwrap()
}

/// Random reachable poses of `chain` solved in closed form: every pose has
/// a solution, and every solution puts the tip there (1e-9).
fn round_trip(name: &str, chain: &Chain, ur: &UrKinematics) {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for _ in 0..300 {
        let q = random_configuration(chain, &mut rng);
        let goal = chain.tip_pose(&q);
        let reference: [f64; 6] = std::array::from_fn(|i| q[i] + 0.3);
        let solutions = ur.solve(&goal, &reference);
        assert!(!solutions.is_empty(), "{name}: no solution for {q:?}");
        for s in &solutions {
            let tip = chain.tip_pose(s);
            assert!(
                (tip.translation.vector - goal.translation.vector).norm() < 1e-9
                    && tip.rotation.angle_to(&goal.rotation) < 1e-9,
                "{name}: a solution misses"
            );
            for (v, (lo, hi)) in s.iter().zip(chain.limits()) {
                assert!(*v >= lo && *v <= hi);
            }
        }
    }
}

#[test]
fn ur_arms_are_recognised_and_solved_in_closed_form() {
    let builtin = Chain::from_urdf_str(ur5::URDF, Some("base_link"), Some("tool")).unwrap();
    let ur = UrKinematics::detect(&builtin).expect("the built-in UR5 has UR kinematics");
    // The UR5's published lengths come back (up to sign: a UR can be
    // matched with some joints turned the other way).
    for (got, want) in [
        (ur.dh.a[1], -0.425),
        (ur.dh.a[2], -0.39225),
        (ur.dh.d[3], 0.10915),
        (ur.dh.d[4], 0.09465),
    ] {
        assert!((got.abs() - f64::abs(want)).abs() < 1e-7, "{got} vs {want}");
    }
    round_trip("built-in UR5", &builtin, &ur);
    for (name, a2, a3, d4, d5) in [
        ("ur5", -0.425, -0.39225, 0.10915, 0.09465),
        ("ur10", -0.612, -0.5723, 0.163941, 0.1157),
    ] {
        let chain = shipped(name);
        let ur = UrKinematics::detect(&chain).unwrap_or_else(|| panic!("{name}: not UR"));
        for (got, want) in [
            (ur.dh.a[1], a2),
            (ur.dh.a[2], a3),
            (ur.dh.d[3], d4),
            (ur.dh.d[4], d5),
        ] {
            assert!(
                (got.abs() - f64::abs(want)).abs() < 1e-6,
                "{name}: {got} vs {want}"
            );
        }
        round_trip(name, &chain, &ur);
    }
    for name in ["panda", "iiwa"] {
        assert!(UrKinematics::detect(&shipped(name)).is_none(), "{name}");
    }
}
