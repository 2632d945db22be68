//! The UR5 + ⊔ gripper URDF, written from Universal Robots' DH parameters
//! and the gripper's boxes (`urdf_string`, committed as
//! `assets/ur5_gripper.urdf` and embedded as [`URDF`]).

use std::f64::consts::PI;

use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion, Vector3};
use urdf_rs::{
    Axis, Collision, Geometry, Inertial, Joint, JointLimit, JointType, Link, LinkName, Pose, Robot,
    Vec3,
};

use crate::robot::model::tool::*;
use crate::robot::ur5::*;

/// The transform of joint i's origin in its parent link:
/// T_x(a_{i−1}) R_x(α_{i−1}) T_z(d_i), with a_{−1} = α_{−1} = 0.
pub fn dh_joint_origin(i: usize) -> Isometry3<f64> {
    let (a, alpha) = if i == 0 {
        (0.0, 0.0)
    } else {
        (DH_A[i - 1], DH_ALPHA[i - 1])
    };
    Isometry3::from_parts(
        Translation3::new(a, 0.0, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), alpha),
    ) * Isometry3::translation(0.0, 0.0, DH_D[i])
}

fn pose_of(iso: &Isometry3<f64>) -> Pose {
    let (r, p, y) = iso.rotation.euler_angles();
    let t = iso.translation.vector;
    Pose {
        xyz: Vec3([t.x, t.y, t.z]),
        rpy: Vec3([r, p, y]),
    }
}

fn link(name: &str, collision: Vec<Collision>) -> Link {
    Link {
        name: name.to_owned(),
        inertial: Inertial::default(),
        visual: Vec::new(),
        collision,
    }
}

fn joint(
    name: &str,
    kind: JointType,
    parent: &str,
    child: &str,
    origin: Isometry3<f64>,
    limit: JointLimit,
) -> Joint {
    Joint {
        name: name.to_owned(),
        joint_type: kind,
        origin: pose_of(&origin),
        parent: LinkName {
            link: parent.to_owned(),
        },
        child: LinkName {
            link: child.to_owned(),
        },
        axis: Axis {
            xyz: Vec3([0.0, 0.0, 1.0]),
        },
        limit,
        calibration: None,
        dynamics: None,
        mimic: None,
        safety_controller: None,
    }
}

fn capsule_collision(spec: &CapsuleSpec) -> Collision {
    let a = Vector3::from(spec.a);
    let b = Vector3::from(spec.b);
    let axis = b - a;
    let rotation = Rotation3::rotation_between(&Vector3::z(), &axis.normalize())
        .unwrap_or_else(Rotation3::identity);
    let origin = Isometry3::from_parts(
        Translation3::from((a + b) / 2.0),
        UnitQuaternion::from(rotation),
    );
    Collision {
        name: None,
        origin: pose_of(&origin),
        geometry: Geometry::Capsule {
            radius: spec.radius,
            length: axis.norm(),
        },
    }
}

/// Our UR5 + ⊔ gripper URDF (what `assets/ur5_gripper.urdf` holds).
pub fn urdf_string() -> String {
    let mut links = vec![link("base_link", Vec::new())];
    let capsules = |name: &str| {
        ARM_CAPSULES
            .iter()
            .filter(|c| c.link == name)
            .map(capsule_collision)
            .collect::<Vec<_>>()
    };
    links.push(link("base_link_inertia", capsules("base_link_inertia")));
    let mut joints = vec![joint(
        "base_link-base_link_inertia",
        JointType::Fixed,
        "base_link",
        "base_link_inertia",
        Isometry3::rotation(Vector3::z() * PI),
        JointLimit::default(),
    )];
    let mut parent = "base_link_inertia";
    for i in 0..6 {
        links.push(link(LINK_NAMES[i], capsules(LINK_NAMES[i])));
        let (lower, upper) = JOINT_LIMITS[i];
        let limit = JointLimit {
            lower,
            upper,
            effort: if i < 3 { 150.0 } else { 28.0 },
            velocity: MAX_VELOCITY[i],
            ..JointLimit::default()
        };
        joints.push(joint(
            JOINT_NAMES[i],
            JointType::Revolute,
            parent,
            LINK_NAMES[i],
            dh_joint_origin(i),
            limit,
        ));
        parent = LINK_NAMES[i];
    }
    for spec in &GRIPPER_BOXES {
        let collision = Collision {
            name: None,
            origin: Pose::default(),
            geometry: Geometry::Box {
                size: Vec3(spec.size),
            },
        };
        links.push(link(spec.link, vec![collision]));
        joints.push(joint(
            &format!("wrist_3-{}", spec.link),
            JointType::Fixed,
            "wrist_3_link",
            spec.link,
            Isometry3::translation(spec.centre[0], spec.centre[1], spec.centre[2]),
            JointLimit::default(),
        ));
    }
    links.push(link("tool", Vec::new()));
    joints.push(joint(
        "wrist_3-tool",
        JointType::Fixed,
        "wrist_3_link",
        "tool",
        Isometry3::translation(0.0, 0.0, TOOL_OFFSET),
        JointLimit::default(),
    ));
    let robot = Robot {
        name: "ur5_u_gripper".to_owned(),
        version: None,
        links,
        joints,
        materials: Vec::new(),
    };
    let body = urdf_rs::write_to_string(&robot).expect("serialising plain structs cannot fail");
    format!(
        "<?xml version=\"1.0\"?>\n<!-- treemanip UR5 with the U-shaped pushing gripper, from Universal Robots' DH parameters. Generated by treemanip::robot::ur5::urdf_string(); collision capsules enclose the ROS-Industrial UR5 meshes. Units: m, rad. -->\n{body}\n"
    )
}

/// The committed URDF, embedded so the binary needs no files.
pub const URDF: &str = include_str!("../../../../../assets/ur5_gripper.urdf");
