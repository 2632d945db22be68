//! Any arm from its URDF (`robot::model::urdf_chain`, `robot::kinematics::numeric_ik`): the chain's
//! forward kinematics against our UR5 model and against Pinocchio on a
//! Franka Panda no one here wrote (example-robot-data), the numerical IK on
//! random reachable poses of both, and broken URDFs named.

use std::path::PathBuf;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use treemanip_core::robot::kinematics::numeric_ik::{IkOptions, solve};
use treemanip_core::robot::model::urdf_chain::random_configuration;
use treemanip_core::robot::model::urdf_chain::{Chain, ChainError, JointKind};
use treemanip_core::robot::{Arm, ur5};

/// The Panda URDF that the `example-robot-data` package ships, or `None`
/// (the test then says why it skipped, unless Python is required).
pub fn panda_urdf() -> Option<PathBuf> {
    let path = crate::common::robot_data()?.join("panda_description/urdf/panda.urdf");
    assert!(
        path.is_file(),
        "example-robot-data ships {}",
        path.display()
    );
    Some(path)
}

fn ur5_chain() -> Chain {
    Chain::from_urdf_str(ur5::URDF, Some("base_link"), Some("tool")).unwrap()
}

/// Our UR5 read as a generic chain moves its tool exactly as the UR5 model
/// does (at 200 random configurations).
#[test]
fn the_ur5_as_a_chain_matches_the_ur5_model() {
    let chain = ur5_chain();
    assert_eq!(chain.dof(), 6);
    let names: Vec<&str> = chain.variables().map(|j| j.name.as_str()).collect();
    assert_eq!(names, ur5::JOINT_NAMES);
    let arm = Arm::default().with_base(nalgebra::Isometry3::identity());
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for _ in 0..200 {
        let q = random_configuration(&chain, &mut rng);
        let ours = chain.tip_pose(&q);
        let theirs = arm.tool_pose(&<[f64; 6]>::try_from(q.as_slice()).unwrap());
        assert!((ours.translation.vector - theirs.translation.vector).norm() < 1e-12);
        assert!(ours.rotation.angle_to(&theirs.rotation) < 1e-12);
    }
}

/// The Jacobian is the derivative of the tip pose (central differences).
#[test]
fn the_jacobian_is_the_derivative_of_the_pose() {
    let chain = ur5_chain();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for _ in 0..20 {
        let q = random_configuration(&chain, &mut rng);
        let (pose, jac) = chain.jacobian(&q);
        for v in 0..chain.dof() {
            let h = 1e-6;
            let (mut a, mut b) = (q.clone(), q.clone());
            a[v] += h;
            b[v] -= h;
            let (pa, pb) = (chain.tip_pose(&a), chain.tip_pose(&b));
            let linear = (pa.translation.vector - pb.translation.vector) / (2.0 * h);
            let angular = (pa.rotation * pb.rotation.inverse()).scaled_axis() / (2.0 * h);
            for k in 0..3 {
                assert!(
                    (jac[(k, v)] - linear[k]).abs() < 1e-6,
                    "linear {k} of joint {v}"
                );
                assert!(
                    (jac[(k + 3, v)] - angular[k]).abs() < 1e-6,
                    "angular {k} of joint {v}"
                );
            }
        }
        let _ = pose;
    }
}

/// The Panda (7 joints, fingers past the hand) read from the URDF
/// example-robot-data ships: its hand's pose agrees with Pinocchio's at
/// random configurations, and without a tip the chain asks for one (it
/// branches into the two fingers).
#[test]
fn the_panda_matches_pinocchio() {
    let Some(path) = panda_urdf() else { return };
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(matches!(
        Chain::from_urdf_str(&text, None, None),
        Err(ChainError::AmbiguousTip { .. })
    ));
    let chain = Chain::from_urdf_str(&text, Some("panda_link0"), Some("panda_hand")).unwrap();
    assert_eq!(chain.dof(), 7);
    assert!(chain.joints.iter().any(|j| j.kind == JointKind::Fixed));
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let configurations: Vec<Vec<f64>> = (0..50)
        .map(|_| random_configuration(&chain, &mut rng))
        .collect();
    let script = format!(
        r#"
import json, sys, numpy as np, pinocchio as pin
model = pin.buildModelFromUrdf({path:?})
data = model.createData()
frame = model.getFrameId("panda_hand")
out = []
for q in json.load(sys.stdin):
    full = pin.neutral(model)
    full[:7] = q
    pin.framesForwardKinematics(model, data, full)
    m = data.oMf[frame]
    out.append([list(m.translation), [list(r) for r in m.rotation]])
print(json.dumps(out))
"#,
        path = path.to_str().unwrap()
    );
    let out = crate::common::python_json(&script, &serde_json::to_value(&configurations).unwrap());
    let theirs: Vec<(Vec<f64>, Vec<Vec<f64>>)> = serde_json::from_slice(&out).unwrap();
    for (q, (t, r)) in configurations.iter().zip(theirs) {
        let ours = chain.tip_pose(q);
        let p = ours.translation.vector;
        assert!(
            (p - nalgebra::Vector3::new(t[0], t[1], t[2])).norm() < 1e-9,
            "{q:?}: {p:?} vs {t:?}"
        );
        let m = ours.rotation.to_rotation_matrix();
        for (i, row) in r.iter().enumerate() {
            for (k, v) in row.iter().enumerate() {
                assert!((m[(i, k)] - v).abs() < 1e-9);
            }
        }
    }
}

/// The numerical IK reaches random reachable poses (the pose of a random
/// configuration inside the limits) of the UR5 and the Panda, and its
/// answers are within the limits and put the tip there.
#[test]
fn numerical_ik_reaches_random_reachable_poses() {
    let mut chains = vec![("ur5", ur5_chain(), ur5::HOME.to_vec())];
    if let Some(path) = panda_urdf() {
        let text = std::fs::read_to_string(path).unwrap();
        let panda = Chain::from_urdf_str(&text, Some("panda_link0"), Some("panda_hand")).unwrap();
        let reference: Vec<f64> = panda
            .limits()
            .iter()
            .map(|(lo, hi)| (lo + hi) / 2.0)
            .collect();
        chains.push(("panda", panda, reference));
    }
    for (name, chain, reference) in chains {
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        let trials = 200;
        let mut solved = 0;
        for k in 0..trials {
            let goal = chain.tip_pose(&random_configuration(&chain, &mut rng));
            let options = IkOptions {
                seed: k,
                ..IkOptions::default()
            };
            let Some(q) = solve(&chain, &goal, &reference, &options) else {
                continue;
            };
            solved += 1;
            for (v, (lo, hi)) in q.iter().zip(chain.limits()) {
                assert!((lo..=hi).contains(v));
            }
            let reached = chain.tip_pose(&q);
            assert!((reached.translation.vector - goal.translation.vector).norm() < 1e-5);
            assert!(reached.rotation.angle_to(&goal.rotation) < 1e-4);
        }
        assert!(solved * 100 >= trials * 99, "{name}: {solved} of {trials}");
    }
}

/// Broken URDFs get an error naming what is wrong.
#[test]
fn broken_urdfs_are_named() {
    let arm = |joints: &str| {
        format!(
            r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/>{joints}</robot>"#
        )
    };
    let revolute = |name: &str, parent: &str, child: &str, limit: &str| {
        format!(
            r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/>{limit}</joint>"#
        )
    };
    let limit = r#"<limit lower="-1" upper="1" velocity="1" effort="1"/>"#;
    let good = arm(&(revolute("j1", "a", "b", limit) + &revolute("j2", "b", "c", limit)));
    let chain = Chain::from_urdf_str(&good, None, None).unwrap();
    assert_eq!(
        (
            chain.base_link.as_str(),
            chain.tip_link.as_str(),
            chain.dof()
        ),
        ("a", "c", 2)
    );
    let cases = [
        (
            arm(&(revolute("j1", "a", "b", "") + &revolute("j2", "b", "c", limit))),
            "j1",
        ),
        (
            arm(&(revolute("j1", "a", "b", limit) + &revolute("j2", "a", "b", limit))),
            "kinematic loop",
        ),
        (
            arm(&(revolute("j1", "a", "b", limit) + &revolute("j2", "b", "zz", limit))),
            "zz",
        ),
        (
            arm(&revolute("j1", "a", "b", limit).replace("revolute", "floating")),
            "not supported",
        ),
        ("<robot".to_owned(), "cannot be read"),
    ];
    for (urdf, expected) in cases {
        let e = Chain::from_urdf_str(&urdf, None, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains(expected), "{e} (expected `{expected}`)");
    }
    assert_eq!(
        Chain::from_urdf_str(&good, Some("a"), Some("nope")).unwrap_err(),
        ChainError::UnknownLink("nope".into())
    );
    assert!(matches!(
        Chain::from_urdf_str(&good, Some("c"), Some("a")),
        Err(ChainError::NoChain { .. })
    ));
}
