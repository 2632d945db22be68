//! `robot::check` and what it stands for: arms from a bare URDF whose
//! fitted shapes overlap in nearly every pose get those pairs disabled (the
//! ROS-Industrial UR10 with `tip=tool0` could not plan at all before), a
//! tool turned into the arm is reported as unable to push, and an arm of
//! fewer than six joints is refused at load with why.

use std::path::PathBuf;

use treemanip_core::robot::arm::{PROBE_PUSHES, STANCES};
use treemanip_core::robot::catalog::{load, load_description};
use treemanip_core::robot::check::check;
use treemanip_core::robot::model::self_pairs::DisableReason;
use treemanip_core::robot::{Arm, catalog::RobotSpec};

fn spec(text: &str) -> RobotSpec {
    text.parse().unwrap()
}

#[test]
fn a_bare_ur10_urdf_with_its_tool0_can_push() {
    let Some(erd) = crate::common::robot_data() else {
        return;
    };
    let s = spec(&format!(
        "ur10ri={}/ur_description/urdf/ur10_robot.urdf,tip=tool0",
        erd.display()
    ));
    let description = load_description(&s, std::slice::from_ref(&erd)).unwrap();
    // The base housing and the upper arm's fitted capsules overlap in
    // nearly every pose (about 99 %): disabled as MoveIt would.
    let often = description
        .disabled_pairs
        .iter()
        .find(|p| {
            [p.a.as_str(), p.b.as_str()] == ["base_link", "upper_arm_link"]
                || [p.b.as_str(), p.a.as_str()] == ["base_link", "upper_arm_link"]
        })
        .expect("base_link–upper_arm_link is disabled");
    assert_eq!(often.reason, DisableReason::Often);
    let arm = load(&s, &[erd]).unwrap();
    let report = check(&arm, 500, 1);
    assert!(report.fatal().is_none(), "{report}");
    assert!(report.self_free > 0.3, "{report}");
    assert!(report.pushes_free >= 12, "{report}");
    assert_eq!(report.ik.0, report.ik.1, "{report}");
}

/// The shipped UR10 with its tool turned to point back into the wrist (a
/// half turn about x) is named as unable to push, and why.
#[test]
fn a_tool_pointing_into_the_arm_cannot_push() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let text = std::fs::read_to_string(dir.join("ur10.toml")).unwrap();
    let mut description =
        treemanip_core::robot::model::description::RobotDescription::from_toml_str(
            &text,
            &dir.join("ur10.toml"),
        )
        .unwrap();
    let good = check(&Arm::from_description(&description).unwrap(), 300, 1);
    assert!(good.fatal().is_none(), "{good}");
    description.tool.mount.rpy[0] += std::f64::consts::PI;
    let flipped = check(&Arm::from_description(&description).unwrap(), 300, 1);
    let why = flipped.fatal().expect("a flipped tool cannot push");
    assert!(why.contains("points back into the arm"), "{why}");
    assert!(good.tool_outward.unwrap() > 0.9, "{good}");
}

/// A four-joint arm is refused at load, naming its joints and why.
#[test]
fn an_arm_of_four_joints_is_refused_with_why() {
    let mut urdf = String::from("<robot name=\"four\"><link name=\"l0\"/>");
    for k in 1..=4 {
        urdf.push_str(&format!(
            "<link name=\"l{k}\"><collision><geometry><cylinder radius=\"0.03\" length=\"0.2\"/></geometry></collision></link>\
             <joint name=\"j{k}\" type=\"revolute\"><parent link=\"l{}\"/><child link=\"l{k}\"/>\
             <origin xyz=\"0 0 0.2\"/><axis xyz=\"0 {} 1\"/><limit lower=\"-2\" upper=\"2\" velocity=\"1\" effort=\"1\"/></joint>",
            k - 1,
            k % 2
        ));
    }
    urdf.push_str("</robot>");
    let dir = crate::common::temp_dir("four");
    let path = dir.join("four.urdf");
    std::fs::write(&path, urdf).unwrap();
    let err = load(&spec(&format!("four={}", path.display())), &[]).unwrap_err();
    let message = err.to_string();
    assert!(message.contains("4 joints"), "{message}");
    assert!(message.contains("6 or more"), "{message}");
}

/// With only a URDF and its last arm link, the tool goes on the last
/// joint's axis, out of the wrist and past the hand: the Jaco2's link 6
/// has its z back into the wrist (the mount is turned round, 0.17 m out,
/// past the fingers), the Z1's last joint turns about x (the mount is
/// turned onto x). Both then push in front of themselves.
#[test]
fn the_tool_frame_comes_from_the_chain() {
    let Some(erd) = crate::common::robot_data() else {
        return;
    };
    let jaco = load(
        &spec(&format!(
            "jaco={}/kinova_description/robots/kinova.urdf,tip=j2s6s200_link_6",
            erd.display()
        )),
        std::slice::from_ref(&erd),
    )
    .unwrap();
    assert!(
        jaco.tool_chosen()
            .starts_with("flange axis: joint `j2s6s200_joint_6`")
    );
    assert!(
        jaco.tool_chosen().contains("against its axis"),
        "{}",
        jaco.tool_chosen()
    );
    let z = jaco.tool_in_tip().rotation * nalgebra::Vector3::z();
    assert!(z.z < -0.99, "{z}");
    let report = check(&jaco, 300, 1);
    assert!(report.tool_outward.unwrap() > 0.9, "{report}");
    assert!(report.pushes_free >= 15, "{report}");

    let z1 = load(
        &spec(&format!(
            "z1={}/z1_description/urdf/z1.urdf,tip=link06",
            erd.display()
        )),
        std::slice::from_ref(&erd),
    )
    .unwrap();
    let z = z1.tool_in_tip().rotation * nalgebra::Vector3::z();
    assert!(z.x > 0.99, "the Z1's last joint turns about x: {z}");

    // tool=FRAME names the frame; one the tip does not carry is refused.
    let ur10 = |extra: &str| {
        load(
            &spec(&format!(
                "ur10ri={}/ur_description/urdf/ur10_robot.urdf,tip=tool0{extra}",
                erd.display()
            )),
            std::slice::from_ref(&erd),
        )
    };
    let framed = ur10(",tool=tool0").unwrap();
    assert_eq!(framed.tool_chosen(), "frame tool0");
    let err = ur10(",tool=forearm_link").unwrap_err().to_string();
    assert!(err.contains("not the tip"), "{err}");
    // tool_xyz moves the chosen mount along its own axes.
    let moved = ur10(",tool=tool0,tool_xyz=[0,0,0.05]").unwrap();
    let dz = moved.tool_in_tip().translation.z - framed.tool_in_tip().translation.z;
    assert!((dz - 0.05).abs() < 1e-9, "{dz}");
    assert!(
        moved
            .tool_chosen()
            .ends_with("adjusted by tool_xyz/tool_rpy")
    );
}

#[test]
fn tool_options_parse_or_say_what_is_wrong() {
    let s = spec("a=x.urdf,tip=t,tool=tool0,tool_xyz=[0,0,0.1],tool_rpy=[1.5,0,0]");
    assert_eq!(s.tool.as_deref(), Some("tool0"));
    assert_eq!(s.tool_xyz, Some([0.0, 0.0, 0.1]));
    assert_eq!(s.tool_rpy, Some([1.5, 0.0, 0.0]));
    let err = "a=x.urdf,tool_xyz=[0,0]".parse::<RobotSpec>().unwrap_err();
    assert!(err.contains("three"), "{err}");
    let err = "a=x.urdf,tool_xyz=[0,nan,0]"
        .parse::<RobotSpec>()
        .unwrap_err();
    assert!(err.contains("finite"), "{err}");
}

/// The ROS-Industrial UR3's fitted base housing and upper arm touch where
/// the URDF draws the arm (and in half of all poses): disabled as MoveIt
/// disables pairs in collision at the default pose, so its rest pose is
/// free and it pushes.
#[test]
fn pairs_touching_at_rest_are_disabled() {
    let Some(erd) = crate::common::robot_data() else {
        return;
    };
    let s = spec(&format!(
        "ur3ri={}/ur_description/urdf/ur3_robot.urdf,tip=tool0",
        erd.display()
    ));
    let description = load_description(&s, std::slice::from_ref(&erd)).unwrap();
    let pair = description
        .disabled_pairs
        .iter()
        .find(|p| {
            let mut names = [p.a.as_str(), p.b.as_str()];
            names.sort();
            names == ["base_link", "upper_arm_link"]
        })
        .expect("base_link–upper_arm_link is disabled");
    assert_eq!(pair.reason, DisableReason::Default);
    let report = check(&load(&s, &[erd]).unwrap(), 500, 2);
    assert!(report.home_contacts.is_empty(), "{report}");
    assert!(report.fatal().is_none(), "{report}");
}

/// The SO-100 names a link `gripper`, as the ⊔ tool's link is named: the
/// tool's link takes another name instead of refusing the arm.
#[test]
fn a_robot_link_named_like_the_tool_keeps_its_name() {
    let Some(erd) = crate::common::robot_data() else {
        return;
    };
    let s = spec(&format!(
        "so100={}/so_arm_description/urdf/so100.urdf",
        erd.display()
    ));
    let (arm, _) =
        treemanip_core::robot::catalog::load_as_described(&s, std::slice::from_ref(&erd)).unwrap();
    let names: Vec<&str> = arm.link_names().collect();
    assert!(names.contains(&"gripper"), "{names:?}");
    assert!(names.contains(&"treemanip_gripper"), "{names:?}");
    let ours = arm.gripper_link().unwrap();
    assert_eq!(names[ours], "treemanip_gripper");
}

/// An arm with a narrow workspace keeps a stance for each direction it can
/// push somewhere: the Unitree Z1 (bare URDF) pushes level from one height
/// and up or down from others, so the six best stances by count leave test
/// pushes that another stance carries out; the UR10, which pushes every
/// way from its best stance, keeps six.
#[test]
fn a_narrow_arm_keeps_a_stance_for_each_direction_it_can_push() {
    let Some(erd) = crate::common::robot_data() else {
        return;
    };
    let z1 = spec(&format!(
        "z1={}/z1_description/urdf/z1.urdf,tip=link06",
        erd.display()
    ));
    let arm = load(&z1, &[erd.clone(), erd.join("../..")]).unwrap();
    let report = check(&arm, 100, 1);
    assert!(report.stances > STANCES, "{report}");
    assert!(
        report.pushes_any_stance > report.pushes_kinematic,
        "{report}"
    );
    // Every kept stance carries out a test push no better one does.
    let stances = arm.stances();
    let mut covered = stances[..STANCES]
        .iter()
        .fold(0, |m, s| m | arm.push_mask(s));
    for s in &stances[STANCES..] {
        let mask = arm.push_mask(s);
        assert!(mask & !covered != 0, "{s:?} adds nothing");
        covered |= mask;
    }
    let ur10 = spec(&format!(
        "ur10ri={}/ur_description/urdf/ur10_robot.urdf,tip=tool0",
        erd.display()
    ));
    let arm = load(&ur10, &[erd]).unwrap();
    assert_eq!(arm.stances().len(), STANCES);
    assert_eq!(arm.push_score(&arm.stances()[0]), PROBE_PUSHES);
}
