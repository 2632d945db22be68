//! The UR5 arm with the ⊔ gripper: our own URDF, written from Universal
//! Robots' published DH parameters, and the kinematic chain read back from
//! it with urdf-rs (so the URDF file is what forward kinematics runs on).
//!
//! Frames follow the ROS-Industrial description: `base_link` is the mount;
//! `base_link_inertia` (the DH base frame 0) is it turned by π about z; each
//! joint's origin is T_x(a_{i−1}) R_x(α_{i−1}) T_z(d_i), so `wrist_3_link`
//! is the DH frame 6, the tool flange, with z pointing out of the flange.
//!
//! Gripper (on the flange, all in the flange frame, metres): a 6 cm standoff
//! (0.04 × 0.04 box) that keeps the held branch clear of the wrist housings,
//! a palm box 0.04 (x) × 0.06 (y) × 0.01 (z) on it, and two fingers
//! 0.04 × 0.02 × 0.05 at y = ±0.02 in front of the palm, leaving a slot 2 cm
//! wide and 5 cm deep along x. The **tool frame** is at the centre of the
//! palm's front face, 7 cm out of the flange: tool z is the push direction,
//! tool x runs along the slot (the held branch lies along it), tool y across
//! the slot.

use std::f64::consts::{FRAC_PI_2, PI};

use crate::robot::arm::Arm;
pub use crate::robot::kinematics::dh::{DH_A, DH_ALPHA, DH_D, JOINT_LIMITS};
use crate::robot::model::description::{
    PerJoint, PoseSpec, RobotConfig, RobotDescription, ToolSpec,
};
use crate::robot::model::import::describe;
use crate::robot::model::joint_vector::JointVector;
use nalgebra::Isometry3;

pub const JOINT_NAMES: [&str; 6] = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
];

/// Link carried by each joint.
pub const LINK_NAMES: [&str; 6] = [
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
];

/// Joint speed limits (rad/s): the UR5's 180°/s.
pub const MAX_VELOCITY: [f64; 6] = [PI; 6];

/// Joint acceleration limits used for trajectories (rad/s²); a conservative
/// value for moving near a tree.
pub const MAX_ACCELERATION: [f64; 6] = [3.0; 6];

/// The paper's home configuration (rad).
pub const HOME: JointVector = JointVector::new([
    FRAC_PI_2,
    -2.0 * PI / 3.0,
    4.0 * PI / 5.0,
    -PI / 7.0,
    FRAC_PI_2,
    0.0,
]);

/// A capsule around (part of) a link, in the link's frame (m): data for
/// the UR5's URDF writer (`urdf.rs`), which the planner reads back as
/// [`crate::geometry::shape::Shape`]s like any other arm's URDF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CapsuleSpec {
    pub link: &'static str,
    pub a: [f64; 3],
    pub b: [f64; 3],
    pub radius: f64,
}

/// Capsules around the arm links (one to three per link: the joint housings
/// and the tube between them), enclosing the ROS-Industrial UR5 collision
/// meshes. Fitted by `scripts/measure-ur5-meshes.py` (triangles sliced along
/// the link axis, tightest capsule per slice, least total volume), radii
/// rounded up by 1 mm; `tests/robot_model.rs` checks that every mesh
/// triangle lies inside one of its link's capsules.
pub const ARM_CAPSULES: [CapsuleSpec; 12] = [
    CapsuleSpec {
        link: "base_link_inertia",
        a: [-0.0013, 0.0000, 0.0085],
        b: [0.0021, 0.0000, 0.0085],
        radius: 0.0750,
    },
    CapsuleSpec {
        link: "base_link_inertia",
        a: [0.0001, 0.1100, 0.0085],
        b: [-0.0001, 0.0726, 0.0084],
        radius: 0.0064,
    },
    CapsuleSpec {
        link: "shoulder_link",
        a: [-0.0003, -0.0189, 0.0261],
        b: [0.0008, -0.0168, -0.0449],
        radius: 0.0791,
    },
    CapsuleSpec {
        link: "upper_arm_link",
        a: [-0.4166, -0.0017, 0.1152],
        b: [-0.4058, 0.0017, 0.1530],
        radius: 0.0815,
    },
    CapsuleSpec {
        link: "upper_arm_link",
        a: [-0.3546, 0.0003, 0.1359],
        b: [-0.1111, -0.0003, 0.1354],
        radius: 0.0597,
    },
    CapsuleSpec {
        link: "upper_arm_link",
        a: [-0.0192, 0.0002, 0.1230],
        b: [0.0013, 0.0007, 0.1394],
        radius: 0.0907,
    },
    CapsuleSpec {
        link: "forearm_link",
        a: [-0.3873, 0.0005, 0.0023],
        b: [-0.3781, -0.0012, 0.0546],
        radius: 0.0543,
    },
    CapsuleSpec {
        link: "forearm_link",
        a: [-0.3467, -0.0006, 0.0175],
        b: [-0.0743, 0.0008, 0.0161],
        radius: 0.0398,
    },
    CapsuleSpec {
        link: "forearm_link",
        a: [-0.0569, -0.0018, 0.0379],
        b: [0.0026, -0.0004, 0.0479],
        radius: 0.0638,
    },
    CapsuleSpec {
        link: "wrist_1_link",
        a: [0.0003, -0.0436, -0.0138],
        b: [-0.0003, 0.0225, -0.0087],
        radius: 0.0524,
    },
    CapsuleSpec {
        link: "wrist_2_link",
        a: [0.0008, 0.0418, -0.0145],
        b: [-0.0005, -0.0184, -0.0077],
        radius: 0.0531,
    },
    CapsuleSpec {
        link: "wrist_3_link",
        a: [0.0000, 0.0014, -0.0204],
        b: [0.0000, -0.0034, -0.0209],
        radius: 0.0409,
    },
];

mod urdf;
pub use urdf::{URDF, dh_joint_origin, urdf_string};

/// Link pairs not checked for self-collision besides parent/child pairs.
/// Each is two links apart across a short link and a joint housing, so the
/// real arm cannot bring them into contact, while our (conservative)
/// capsules already overlap in the valid zero configuration:
/// base–upper arm (around the shoulder housing), forearm–wrist 2 and
/// wrist 1–wrist 3 (around the wrist housings). The gripper sits in front of
/// the flange face and wrist 2 behind it, but the hemispherical cap of
/// wrist 2's capsule reaches past the face into the standoff and palm. Sampling showed
/// these overlaps at the valid zero and home configurations.
pub const DISABLED_PAIRS: [(&str, &str); 7] = [
    ("base_link_inertia", "upper_arm_link"),
    ("forearm_link", "wrist_2_link"),
    ("wrist_1_link", "wrist_3_link"),
    ("wrist_2_link", "gripper_mount"),
    ("wrist_2_link", "gripper_palm"),
    ("wrist_2_link", "gripper_finger_left"),
    ("wrist_2_link", "gripper_finger_right"),
];

/// The built-in UR5's description: the embedded URDF (arm capsules and the
/// gripper's boxes), chain `base_link` → `wrist_3_link`, the tool frame at
/// the palm's face, [`MAX_ACCELERATION`], [`HOME`] and [`DISABLED_PAIRS`].
pub fn description() -> RobotDescription {
    let robot = urdf_rs::read_from_string(URDF).expect("the embedded URDF parses");
    let config = RobotConfig {
        name: "ur5".to_owned(),
        urdf: "assets/ur5_gripper.urdf".into(),
        base_link: Some("base_link".to_owned()),
        tip_link: Some("wrist_3_link".to_owned()),
        acceleration: Some(PerJoint::Each(MAX_ACCELERATION.to_vec())),
        jerk: None,
        home: Some(HOME.to_vec()),
        disabled_pairs: DISABLED_PAIRS
            .iter()
            .map(|(a, b)| [(*a).to_owned(), (*b).to_owned()])
            .collect(),
        srdf: None,
        licence: "treemanip's own (written from Universal Robots' DH parameters)".to_owned(),
        tool: ToolSpec {
            mount: PoseSpec::identity(),
            gripper: false,
            shapes: None,
            frame: None,
            chosen: Some("built in: the ⊔ gripper on the UR5's flange".to_owned()),
        },
        tool_choice: Default::default(),
        tool_adjust: None,
    };
    describe(config, &robot, None, &[], "built in", 0).expect("the embedded UR5 is valid")
}

impl Arm {
    /// The built-in UR5 with the ⊔ gripper, at `base`.
    pub fn ur5(base: Isometry3<f64>) -> Self {
        static ARM: std::sync::OnceLock<Arm> = std::sync::OnceLock::new();
        ARM.get_or_init(|| {
            Arm::from_description(&description()).expect("the embedded UR5 is valid")
        })
        .clone()
        .with_base(base)
    }
}

impl Default for Arm {
    /// The built-in UR5 at the paper's mount.
    fn default() -> Self {
        Self::ur5(crate::robot::arm::PAPER_BASE)
    }
}
