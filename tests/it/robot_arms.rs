//! Every shipped arm, and a URDF with mesh collision geometry that the
//! project did not write (pybullet's Franka Panda), loads and plans: its
//! home is free, and the pushes it plans on random trees are controller
//! trajectories within its own limits, collision-free, with the push
//! straight at constant tool orientation by an independent forward
//! kinematics (Pinocchio), convertible one to one into ROS 2 messages.

use std::time::Duration;

use nalgebra::{Isometry3, Matrix4, Rotation3, UnitQuaternion, Vector3};
use treemanip::planner::{Plan, Planner, Query, Stance, Strategy};
use treemanip::robot::arm::PAPER_BASE;
use treemanip::robot::arm::tool_line::APPROACH_OFFSET;
use treemanip::robot::catalog::{self, RobotSpec};
use treemanip::robot::collision::{Allowed, CollisionModel, TreeObstacles};
use treemanip::robot::model::description::RobotDescription;
use treemanip::robot::motion::ros::JointTrajectory;

use treemanip::robot::{Arm, BaseStance, PROBE_PUSHES, UR5_REACH};

/// The shipped descriptions (`robots/*.toml`).
pub const SHIPPED: [&str; 4] = ["ur5", "ur10", "panda", "iiwa"];

/// A shipped description by name.
pub fn shipped(name: &str) -> Arm {
    let spec = RobotSpec::at(name.to_owned(), format!("robots/{name}.toml").into());
    catalog::load(&spec, &[]).unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn every_shipped_arms_home_is_free_at_the_default_mount() {
    let empty = TreeObstacles::empty();
    for name in SHIPPED {
        let arm = shipped(name).with_base(PAPER_BASE);
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
    assert!((ur5 - UR5_REACH).abs() < 1e-12, "{ur5}");
    let ur10 = shipped("ur10").reach();
    assert!(ur10 > 1.4 * ur5, "the UR10 is the larger arm: {ur10}");
}

/// Where a mobile base stands comes from each arm's kinematics: the URs
/// push from anywhere near and keep the UR5's own six stances (scaled);
/// the iiwa, whose elbow folds against its limit when the wrist comes near
/// the shoulder, stands farther back. Its UR5-scaled stance 0.47 m behind
/// and 0.28 m below the grip carries out none of the test pushes; every
/// stance it keeps carries out most.
#[test]
fn each_arm_stands_where_its_pushes_work() {
    let own = |arm: &Arm| -> Vec<(f64, f64)> {
        let scale = arm.reach() / UR5_REACH;
        [0.3, 0.05, -0.2]
            .iter()
            .flat_map(|h| [0.5, 0.65].map(|d| (d * scale, h * scale)))
            .collect()
    };
    for arm in [Arm::default(), shipped("ur10")] {
        let got: Vec<(f64, f64)> = arm
            .stances()
            .iter()
            .map(|s| (s.stand_off, s.height))
            .collect();
        assert_eq!(got, own(&arm), "{}", arm.name());
    }
    let iiwa = shipped("iiwa");
    let scale = iiwa.reach() / UR5_REACH;
    let close = BaseStance {
        stand_off: 0.5 * scale,
        height: 0.3 * scale,
    };
    assert_eq!(iiwa.push_score(&close), 0);
    assert!(!iiwa.stances().contains(&close));
    let mean_stand_off =
        iiwa.stances().iter().map(|s| s.stand_off).sum::<f64>() / iiwa.stances().len() as f64;
    assert!(mean_stand_off > 0.6 * scale, "{:?}", iiwa.stances());
    for s in iiwa.stances() {
        let score = iiwa.push_score(s);
        assert!(
            score * 3 >= PROBE_PUSHES * 2,
            "{s:?}: {score} of {PROBE_PUSHES}"
        );
    }
}

/// A 7-joint arm swings along its self-motion: every configuration found
/// holds the tool where the first did (to 1e-6 m and rad) yet is another
/// configuration, and the swings reach both sides; a 6-joint arm has none.
#[test]
fn a_redundant_arm_swings_along_its_self_motion() {
    for name in ["panda", "iiwa"] {
        let arm = shipped(name);
        let q = arm.home();
        let tool = arm.tool_pose(&q);
        let swings = arm.self_motions(&q, &[-0.5, 0.5, -1.0, 1.0]);
        assert!(swings.len() >= 3, "{name}: {} swings", swings.len());
        for s in &swings {
            let pose = arm.tool_pose(s);
            let moved = (pose.translation.vector - tool.translation.vector).norm();
            let turned = (pose.rotation.inverse() * tool.rotation).angle();
            assert!(
                moved < 1e-6 && turned < 1e-6,
                "{name}: {moved} m, {turned} rad"
            );
            assert!(s.max_abs_diff(&q) > 0.05, "{name}: the same configuration");
        }
    }
    let ur5 = Arm::default();
    assert!(ur5.self_motions(&ur5.home(), &[0.5]).is_empty());
}

/// An arm to plan with, and where its URDF is for the independent
/// kinematics (`@EXAMPLE_ROBOT_DATA@` and `@PYBULLET_DATA@` filled in by
/// the Python side).
pub(crate) struct Case {
    pub arm: Arm,
    pub urdf: String,
}

/// The shipped arms, and pybullet's Franka Panda URDF (meshes fitted now,
/// self-collision pairs sampled now) when pybullet is installed.
fn cases() -> Vec<Case> {
    let mut out: Vec<Case> = SHIPPED
        .iter()
        .map(|name| {
            let text = std::fs::read_to_string(format!("robots/{name}.toml")).unwrap();
            let d = RobotDescription::from_toml_str(&text, std::path::Path::new(name)).unwrap();
            Case {
                arm: shipped(name),
                urdf: d.source.urdf,
            }
        })
        .collect();
    out.push(paddle_ur10());
    if crate::common::python_has("pybullet_data") {
        let out_dir = crate::common::python_json(
            "import pybullet_data, json; print(json.dumps(pybullet_data.getDataPath()))",
            &serde_json::Value::Null,
        );
        let data: String = serde_json::from_slice(&out_dir).unwrap();
        let urdf = format!("{data}/franka_panda/panda.urdf");
        // The raw URDF and a configuration: the chain's tip, where the ⊔
        // gripper sits (past the closed fingers), and jerk limits tight
        // enough (30 rad/s³, Franka's are 3750 and up) that the timing must
        // spread every change of acceleration over a second or so; all else
        // defaults.
        let config = crate::common::temp_dir("pybullet-panda").join("panda.toml");
        let mount = "[tool]\nmount = { xyz = [0.0, 0.0, 0.11], rpy = [0.0, 0.0, 0.0] }\n";
        std::fs::write(
            &config,
            format!(
                "name = \"panda_pybullet\"\nurdf = \"{urdf}\"\ntip_link = \"panda_hand\"\n\
                 jerk = [30, 30, 30, 30, 30, 30, 30]\n{mount}"
            ),
        )
        .unwrap();
        let spec: RobotSpec = format!("panda_pybullet={}", config.display())
            .parse()
            .unwrap();
        out.push(Case {
            arm: catalog::load(&spec, &[]).expect("pybullet's Panda loads from its URDF"),
            urdf,
        });
    }
    out
}

/// The shipped UR10 with the user's own tool in place of the ⊔ gripper:
/// a flat paddle (a cylinder standoff and a plate) whose face is the tool
/// frame, 9 cm out of the mount.
fn paddle_ur10() -> Case {
    let text = std::fs::read_to_string("robots/ur10.toml").unwrap();
    let tool = "[tool]\ngripper = true\n";
    assert!(text.contains(tool));
    let paddle = "[tool]\ngripper = true\n\
        frame = { xyz = [0.0, 0.0, 0.09], rpy = [0.0, 0.0, 0.0] }\n\
        shapes = [\n\
          { type = \"cylinder\", origin = { xyz = [0.0, 0.0, 0.04], rpy = [0.0, 0.0, 0.0] }, radius = 0.02, length = 0.08 },\n\
          { type = \"box\", origin = { xyz = [0.0, 0.0, 0.085], rpy = [0.0, 0.0, 0.0] }, size = [0.06, 0.06, 0.01] },\n\
        ]\n";
    let text =
        text.replacen(tool, paddle, 1)
            .replacen("name = \"ur10\"", "name = \"ur10_paddle\"", 1);
    let d =
        RobotDescription::from_toml_str(&text, std::path::Path::new("ur10_paddle.toml")).unwrap();
    let arm = Arm::from_description(&d).unwrap();
    // The paddle is the gripper link's geometry, and the tool frame its face.
    let mount = d.tool.mount.isometry();
    let expected = mount * Isometry3::translation(0.0, 0.0, 0.09);
    assert!((arm.tool_in_tip().to_homogeneous() - expected.to_homogeneous()).norm() < 1e-12);
    let gripper = arm
        .link_shapes()
        .find(|(name, _)| *name == "gripper")
        .unwrap();
    assert_eq!(gripper.1.len(), 2, "the paddle's two shapes");
    // Bad tools are named.
    for (from, to, needle) in [
        (
            "size = [0.06, 0.06, 0.01]",
            "size = [0.06, -0.06, 0.01]",
            "tool.shapes[1]",
        ),
        ("gripper = true", "gripper = false", "tool.gripper is false"),
    ] {
        let bad = text.replacen(from, to, 1);
        let d = RobotDescription::from_toml_str(&bad, std::path::Path::new("bad.toml"));
        let e = match d {
            Ok(d) => Arm::from_description(&d).err().unwrap_or_default(),
            Err(e) => e.to_string(),
        };
        assert!(e.contains(needle), "{to}: {e}");
    }
    Case {
        arm,
        urdf: d.source.urdf,
    }
}

/// Every arm plans pushes on random trees (model strategy, base region),
/// and each controller trajectory stays within that arm's position,
/// velocity, acceleration and (where it has them) jerk limits by finite
/// differences of its positions alone, starts and ends at rest at the start, keeps the approach free of
/// the tree, pushes in a straight line at constant tool orientation by
/// Pinocchio's forward kinematics of the original URDF, and converts one to
/// one into a ROS 2 `JointTrajectory` serialised to CDR.
#[test]
fn every_arm_plans_trajectories_its_controller_can_run() {
    plans_trajectories_a_controller_can_run(cases(), Strategy::Model);
}

/// The checks above on each of `cases`, planning with `strategy`.
pub(crate) fn plans_trajectories_a_controller_can_run(cases: Vec<Case>, strategy: Strategy) {
    let set = crate::planner::models();
    let (policy, forward) = crate::planner::policy_and_forward(&set);
    let mut pin_cases = Vec::new();
    for case in cases {
        let name = case.arm.name().to_owned();
        let planner = Planner::new(CollisionModel::new(case.arm.clone().with_base(PAPER_BASE)));
        let mut planned = 0;
        let mut outcomes = Vec::new();
        for seed in 1..=6 {
            let (tree, targets) = crate::common::episode(12, seed);
            let mut q = Query::new(tree, targets);
            q.strategy = strategy;
            q.budget = Duration::from_secs(3);
            q.stance = Stance::Region(treemanip::eval::plan::evaluation_region());
            let plan = planner.plan(&q, policy, Some(forward)).unwrap();
            outcomes.extend(plan.attempts.iter().map(|a| a.outcome));
            let Some(p) = &plan.plan else { continue };
            let e = &p.execution;
            check_limits(&name, planner.robot(), &e.joint_trajectory);
            check_approach(&name, planner.robot(), &plan, &q);
            let json = serde_json::to_value(&e.joint_trajectory).unwrap();
            if crate::common::python_has("rosbags") {
                crate::common::assert_ros2_round_trip(&json);
            }
            let points = &e.joint_trajectory.points[e.push_start_point..=e.push_end_point];
            pin_cases.push((
                name.clone(),
                plan.base.isometry(),
                planner.robot().tool_in_tip(),
                p.push.norm(),
                serde_json::json!({
                    "urdf": case.urdf,
                    "base_link": planner.robot().base_link(),
                    "tip_link": planner.robot().tip_link(),
                    "joint_names": e.joint_trajectory.joint_names,
                    "configurations": points.iter().map(|p| &p.positions).collect::<Vec<_>>(),
                }),
            ));
            planned += 1;
            if planned == 2 {
                break;
            }
        }
        assert!(
            planned >= 1,
            "{name}: nothing planned on 6 trees (home {:?}): {outcomes:?}",
            &planner.robot().home()[..]
        );
    }
    if !crate::common::python_has("pinocchio") {
        return;
    }
    let input: Vec<_> = pin_cases.iter().map(|c| c.4.clone()).collect();
    let out = crate::common::python_json(PIN_TIP_POSES, &serde_json::Value::Array(input));
    let tips: Vec<Vec<[[f64; 4]; 4]>> = serde_json::from_slice(&out).unwrap();
    for ((name, base, tool_in_tip, push, _), tips) in pin_cases.iter().zip(tips) {
        let tool: Vec<Isometry3<f64>> = tips
            .iter()
            .map(|m| {
                let m = Matrix4::from_fn(|r, c| m[r][c]);
                let rotation = Rotation3::from_matrix_unchecked(m.fixed_view::<3, 3>(0, 0).into());
                let t = Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
                base * Isometry3::from_parts(
                    t.into(),
                    UnitQuaternion::from_rotation_matrix(&rotation),
                ) * tool_in_tip
            })
            .collect();
        assert_straight_push(name, &tool, push + APPROACH_OFFSET, 1e-5);
    }
}

/// The tool's poses along a push lie on a straight line of `length` (m)
/// at constant orientation, within `tolerance` (m and rad); returns the
/// travel from the first pose to the last.
pub(crate) fn assert_straight_push(
    name: &str,
    tool: &[Isometry3<f64>],
    length: f64,
    tolerance: f64,
) -> Vector3<f64> {
    let (first, last) = (tool[0], *tool.last().unwrap());
    let travel = last.translation.vector - first.translation.vector;
    assert!(
        (travel.norm() - length).abs() < tolerance,
        "{name}: the push travels {} m",
        travel.norm()
    );
    let direction = travel.normalize();
    for pose in tool {
        assert!(
            pose.rotation.angle_to(&first.rotation) < tolerance,
            "{name}: the tool turns"
        );
        let offset = pose.translation.vector - first.translation.vector;
        let across = offset - direction * offset.dot(&direction);
        assert!(
            across.norm() < tolerance,
            "{name}: the push leaves its line by {}",
            across.norm()
        );
    }
    travel
}

/// Tip poses (base link frame) of each case's configurations by Pinocchio.
const PIN_TIP_POSES: &str = r#"
import json, os, sys, sysconfig
import numpy as np, pinocchio as pin
cases = json.load(sys.stdin)
erd = os.path.join(sysconfig.get_paths()['purelib'], 'cmeel.prefix', 'share', 'example-robot-data', 'robots')
try:
    import pybullet_data
    pbd = pybullet_data.getDataPath()
except ImportError:
    pbd = '@PYBULLET_DATA@'
out = []
for case in cases:
    path = case['urdf'].replace('@EXAMPLE_ROBOT_DATA@', erd).replace('@PYBULLET_DATA@', pbd)
    model = pin.buildModelFromUrdf(path)
    data = model.createData()
    base, tip = model.getFrameId(case['base_link']), model.getFrameId(case['tip_link'])
    poses = []
    for q in case['configurations']:
        x = pin.neutral(model)
        for name, v in zip(case['joint_names'], q):
            joint = model.joints[model.getJointId(name)]
            if joint.nq == 2:
                x[joint.idx_q], x[joint.idx_q + 1] = np.cos(v), np.sin(v)
            else:
                x[joint.idx_q] = v
        pin.framesForwardKinematics(model, data, x)
        poses.append((data.oMf[base].inverse() * data.oMf[tip]).homogeneous.tolist())
    out.append(poses)
print(json.dumps(out))
"#;

/// Positions within limits; velocities and accelerations within limits by
/// finite differences of the positions alone; the reported velocities
/// continuous; at rest at both ends.
pub(crate) fn check_limits(name: &str, arm: &Arm, trajectory: &JointTrajectory) {
    let points = &trajectory.points;
    let t: Vec<f64> = points.iter().map(|p| p.time_from_start.as_secs()).collect();
    assert!(t.windows(2).all(|w| w[1] > w[0]), "{name}: time increases");
    assert_eq!(
        trajectory.joint_names,
        arm.joint_names().collect::<Vec<_>>()
    );
    let (vmax, amax) = (arm.velocity_limits(), arm.acceleration_limits());
    for p in [&points[0], points.last().unwrap()] {
        assert!(
            p.velocities.iter().all(|v| v.abs() < 1e-9),
            "{name}: not at rest"
        );
    }
    for p in points {
        assert!(
            arm.within_limits(&p.positions),
            "{name}: {:?} outside the limits",
            p.positions
        );
    }
    for k in 1..points.len() - 1 {
        let (h1, h2) = (t[k] - t[k - 1], t[k + 1] - t[k]);
        for i in 0..arm.dof() {
            let (a, b, c) = (
                points[k - 1].positions[i],
                points[k].positions[i],
                points[k + 1].positions[i],
            );
            let v = (b - a) / h1;
            assert!(
                v.abs() <= vmax[i] * (1.0 + 1e-6),
                "{name}: joint {i} at {v} rad/s"
            );
            let acc = ((c - b) / h2 - (b - a) / h1) * 2.0 / (h1 + h2);
            assert!(
                acc.abs() <= amax[i] * (1.0 + 1e-3),
                "{name}: joint {i} at {acc} rad/s²"
            );
            // Velocity-continuous: the reported velocities change no
            // faster than the acceleration limit allows.
            let dv = points[k + 1].velocities[i] - points[k].velocities[i];
            assert!(
                dv.abs() <= amax[i] * h2 * 1.05 + 1e-6,
                "{name}: velocity jumps at {k}: joint {i} by {dv} in {h2} s"
            );
        }
    }
    let Some(jmax) = arm.jerk_limits() else {
        return;
    };
    // Jerk: 6·q[t₀, t₁, t₂, t₃] (third divided difference) is a weighted
    // average of the jerk over [t₀, t₃], so it is within the limit wherever
    // the jerk is (and unbounded across a jump of acceleration).
    for w in (0..points.len()).collect::<Vec<_>>().windows(4) {
        for i in 0..arm.dof() {
            let mut d: Vec<f64> = w.iter().map(|&k| points[k].positions[i]).collect();
            for order in 1..4 {
                for k in 0..4 - order {
                    d[k] = (d[k + 1] - d[k]) / (t[w[k + order]] - t[w[k]]);
                }
            }
            let jerk = 6.0 * d[0];
            assert!(
                jerk.abs() <= jmax[i] * (1.0 + 1e-3),
                "{name}: joint {i} at {jerk} rad/s³ around point {}",
                w[0]
            );
        }
    }
}

/// The approach (every point up to the push) is free of the tree.
fn check_approach(name: &str, arm: &Arm, plan: &Plan, query: &Query) {
    let p = plan.plan.as_ref().unwrap();
    let e = &p.execution;
    let model = CollisionModel::new(arm.clone().with_base(plan.base.isometry()));
    let rest = TreeObstacles::new(&query.tree);
    let near = Allowed {
        gripper_branches: std::iter::once(p.node)
            .chain(query.tree.children(p.node).iter().copied())
            .collect(),
    };
    for point in &e.joint_trajectory.points[..=e.push_start_point] {
        assert_eq!(
            model.check(&point.positions, &rest, &near),
            None,
            "{name}: the approach collides"
        );
    }
}
