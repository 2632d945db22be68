//! Arms no one here configured: every 6-7 joint arm that
//! `example-robot-data` and `pybullet_data` ship, each loaded from its bare
//! URDF with only a tip (`NAME=URDF,tip=LINK`, as `scripts/eval-arms`
//! loads them: the tool frame from the chain, self-collision pairs sampled
//! at load), plans pushes whose controller trajectories pass the shipped
//! arms' checks: limits by finite differences, the approach free of the
//! tree, the push straight at constant orientation by Pinocchio, a ROS 2
//! CDR round trip.

use std::path::PathBuf;

use treemanip::planner::Strategy;
use treemanip::robot::catalog::{self, RobotSpec};

use crate::robot_arms::{Case, plans_trajectories_a_controller_can_run};

/// The arms of `scripts/eval-arms`, by their packages' folders.
fn bare_cases() -> Vec<Case> {
    let Some(erd) = crate::common::robot_data() else {
        return Vec::new();
    };
    let mut specs = vec![
        "ur3=@ERD@/ur_description/urdf/ur3_robot.urdf,tip=tool0".to_owned(),
        "ur10=@ERD@/ur_description/urdf/ur10_robot.urdf,tip=tool0".to_owned(),
        "panda=@ERD@/panda_description/urdf/panda.urdf,tip=panda_link8".to_owned(),
        "jaco2=@ERD@/kinova_description/robots/kinova.urdf,tip=j2s6s200_link_6".to_owned(),
        "xarm7=@ERD@/xarm_description/urdf/xarm7.urdf,tip=link7".to_owned(),
        "z1=@ERD@/z1_description/urdf/z1.urdf,tip=link06".to_owned(),
    ];
    let mut packages: Vec<PathBuf> = vec![erd.clone(), erd.join("../..")];
    if crate::common::python_has("pybullet_data") {
        let out = crate::common::python_json(
            "import pybullet_data, json; print(json.dumps(pybullet_data.getDataPath()))",
            &serde_json::Value::Null,
        );
        let pbd: String = serde_json::from_slice(&out).unwrap();
        specs.push(format!(
            "iiwa_pybullet={pbd}/kuka_iiwa/model.urdf,tip=lbr_iiwa_link_7"
        ));
        packages.push(pbd.into());
    }
    specs
        .iter()
        .map(|s| {
            // Names unique beside the shipped descriptions'.
            let text = format!("bare_{}", s.replace("@ERD@", &erd.display().to_string()));
            let spec: RobotSpec = text.parse().unwrap();
            let arm = catalog::load(&spec, &packages).unwrap_or_else(|e| panic!("{text}: {e}"));
            Case {
                arm,
                urdf: spec.path.display().to_string(),
            }
        })
        .collect()
}

#[test]
fn every_bare_urdf_arm_plans_trajectories_its_controller_can_run() {
    let cases = bare_cases();
    if cases.is_empty() {
        return;
    }
    plans_trajectories_a_controller_can_run(cases, Strategy::Physics);
}
