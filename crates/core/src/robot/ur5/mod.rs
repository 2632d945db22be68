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

use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI};

pub use super::dh::{DH_A, DH_ALPHA, DH_D, JOINT_LIMITS};
use nalgebra::{Isometry3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use urdf_rs::{Collision, Geometry, Joint, Link};

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
pub const HOME: [f64; 6] = [
    FRAC_PI_2,
    -2.0 * PI / 3.0,
    4.0 * PI / 5.0,
    -PI / 7.0,
    FRAC_PI_2,
    0.0,
];

/// The paper's mount: `base_link` at (−0.5, 0, 0.1) m from the tree root,
/// identity orientation.
pub fn default_base() -> Isometry3<f64> {
    Isometry3::translation(-0.5, 0.0, 0.1)
}

/// Length of the standoff between flange and palm (m).
pub const MOUNT_LENGTH: f64 = 0.06;
/// Cross-section of the standoff (m).
pub const MOUNT_WIDTH: f64 = 0.04;
/// Palm thickness (m).
pub const PALM_THICKNESS: f64 = 0.01;
/// Distance of the tool frame (palm face) from the flange (m).
pub const TOOL_OFFSET: f64 = MOUNT_LENGTH + PALM_THICKNESS;
/// Finger length beyond the palm (m): the slot depth.
pub const FINGER_LENGTH: f64 = 0.05;
/// Width of the slot between the fingers (m).
pub const SLOT_WIDTH: f64 = 0.02;
/// Finger thickness across the slot (m).
pub const FINGER_THICKNESS: f64 = 0.02;
/// Extent of palm and fingers along the slot (m).
pub const GRIPPER_DEPTH: f64 = 0.04;

/// A capsule around (part of) a link, in the link's frame (m).
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

/// A box of the gripper, in the flange frame: centre and full size (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxSpec {
    pub link: &'static str,
    pub centre: [f64; 3],
    pub size: [f64; 3],
}

pub const GRIPPER_BOXES: [BoxSpec; 4] = [
    BoxSpec {
        link: "gripper_mount",
        centre: [0.0, 0.0, MOUNT_LENGTH / 2.0],
        size: [MOUNT_WIDTH, MOUNT_WIDTH, MOUNT_LENGTH],
    },
    BoxSpec {
        link: "gripper_palm",
        centre: [0.0, 0.0, MOUNT_LENGTH + PALM_THICKNESS / 2.0],
        size: [
            GRIPPER_DEPTH,
            SLOT_WIDTH + 2.0 * FINGER_THICKNESS,
            PALM_THICKNESS,
        ],
    },
    BoxSpec {
        link: "gripper_finger_left",
        centre: [
            0.0,
            (SLOT_WIDTH + FINGER_THICKNESS) / 2.0,
            TOOL_OFFSET + FINGER_LENGTH / 2.0,
        ],
        size: [GRIPPER_DEPTH, FINGER_THICKNESS, FINGER_LENGTH],
    },
    BoxSpec {
        link: "gripper_finger_right",
        centre: [
            0.0,
            -(SLOT_WIDTH + FINGER_THICKNESS) / 2.0,
            TOOL_OFFSET + FINGER_LENGTH / 2.0,
        ],
        size: [GRIPPER_DEPTH, FINGER_THICKNESS, FINGER_LENGTH],
    },
];

mod urdf;
pub use urdf::{URDF, dh_joint_origin, urdf_string};

/// World poses of the links, in the model's link order: on the stack for
/// arms of up to 16 links (the UR5 with its gripper has 13), since the
/// collision checker computes them for every pose it checks.
pub type LinkPoses = smallvec::SmallVec<[Isometry3<f64>; 16]>;

/// A collision shape attached to a link, in the link's frame.
#[derive(Debug, Clone, PartialEq)]
pub enum LinkShape {
    Capsule {
        a: Vector3<f64>,
        b: Vector3<f64>,
        radius: f64,
    },
    Box {
        centre: Isometry3<f64>,
        half_extents: Vector3<f64>,
    },
}

#[derive(Debug, Clone)]
struct ChainLink {
    name: String,
    parent: Option<usize>,
    /// Pose of the joint frame in the parent link.
    origin: Isometry3<f64>,
    /// Index into the configuration and joint axis, for revolute joints.
    joint: Option<(usize, Unit<Vector3<f64>>)>,
    shapes: Vec<LinkShape>,
}

#[derive(Debug, thiserror::Error)]
pub enum RobotModelError {
    #[error("not a valid URDF: {0}")]
    Parse(String),
    #[error("robot URDF: {0}")]
    Layout(String),
}

/// The arm's kinematic tree and collision shapes, as read from a URDF.
#[derive(Debug, Clone)]
pub struct Ur5 {
    links: Vec<ChainLink>,
    index: HashMap<String, usize>,
    /// World pose of `base_link`.
    pub base: Isometry3<f64>,
}

impl Default for Ur5 {
    /// The embedded model at the paper's mount.
    fn default() -> Self {
        Self::from_urdf_str(URDF, default_base()).expect("the embedded URDF is valid")
    }
}

impl Ur5 {
    pub fn from_urdf_str(text: &str, base: Isometry3<f64>) -> Result<Self, RobotModelError> {
        let robot =
            urdf_rs::read_from_string(text).map_err(|e| RobotModelError::Parse(e.to_string()))?;
        let by_child: HashMap<&str, &Joint> = robot
            .joints
            .iter()
            .map(|j| (j.child.link.as_str(), j))
            .collect();
        let mut links: Vec<ChainLink> = Vec::new();
        let mut index = HashMap::new();
        // Parents before children: repeatedly add links whose parent is known.
        let mut pending: Vec<&Link> = robot.links.iter().collect();
        while !pending.is_empty() {
            let before = pending.len();
            pending.retain(|l| {
                let (parent, origin, joint) = match by_child.get(l.name.as_str()) {
                    None => (None, Isometry3::identity(), None),
                    Some(j) => {
                        let Some(&p) = index.get(j.parent.link.as_str()) else {
                            return true;
                        };
                        let o = &j.origin;
                        let origin = Isometry3::from_parts(
                            Translation3::new(o.xyz[0], o.xyz[1], o.xyz[2]),
                            UnitQuaternion::from_euler_angles(o.rpy[0], o.rpy[1], o.rpy[2]),
                        );
                        let joint = JOINT_NAMES.iter().position(|n| *n == j.name).map(|q| {
                            (
                                q,
                                Unit::new_normalize(Vector3::new(
                                    j.axis.xyz[0],
                                    j.axis.xyz[1],
                                    j.axis.xyz[2],
                                )),
                            )
                        });
                        (Some(p), origin, joint)
                    }
                };
                let shapes = l.collision.iter().filter_map(shape_of).collect();
                index.insert(l.name.clone(), links.len());
                links.push(ChainLink {
                    name: l.name.clone(),
                    parent,
                    origin,
                    joint,
                    shapes,
                });
                false
            });
            if pending.len() == before {
                return Err(RobotModelError::Layout(format!(
                    "links {:?} do not connect to the root",
                    pending.iter().map(|l| &l.name).collect::<Vec<_>>()
                )));
            }
        }
        for (q, name) in JOINT_NAMES.iter().enumerate() {
            if !links.iter().any(|l| l.joint.is_some_and(|(i, _)| i == q)) {
                return Err(RobotModelError::Layout(format!(
                    "joint `{name}` is missing"
                )));
            }
        }
        for name in ["base_link", "tool", "base_link_inertia"] {
            if !index.contains_key(name) {
                return Err(RobotModelError::Layout(format!("link `{name}` is missing")));
            }
        }
        Ok(Self { links, index, base })
    }

    pub fn with_base(mut self, base: Isometry3<f64>) -> Self {
        self.base = base;
        self
    }

    /// World pose of every link at configuration `q`, in the model's link
    /// order (see [`Ur5::link_names`]).
    pub fn link_poses(&self, q: &[f64; 6]) -> LinkPoses {
        let mut poses = LinkPoses::new();
        for l in &self.links {
            let parent = l.parent.map_or(self.base, |p| poses[p]);
            let mut pose = parent * l.origin;
            if let Some((i, axis)) = &l.joint {
                pose *= UnitQuaternion::from_axis_angle(axis, q[*i]);
            }
            poses.push(pose);
        }
        poses
    }

    /// Each joint's axis in the world at `poses` (from [`Self::link_poses`]):
    /// a point on it and its unit direction.
    pub fn joint_axes(&self, poses: &[Isometry3<f64>]) -> [(Point3<f64>, Vector3<f64>); 6] {
        let mut axes = [(Point3::origin(), Vector3::z()); 6];
        for (l, link) in self.links.iter().enumerate() {
            if let Some((i, axis)) = &link.joint {
                axes[*i] = (
                    poses[l] * Point3::origin(),
                    poses[l].rotation * axis.into_inner(),
                );
            }
        }
        axes
    }

    /// Whether joint `joint` moves link `link` (the link it drives, or one
    /// further down the chain).
    pub fn moved_by(&self, link: usize, joint: usize) -> bool {
        let mut k = Some(link);
        while let Some(l) = k {
            if self.links[l].joint.is_some_and(|(i, _)| i == joint) {
                return true;
            }
            k = self.links[l].parent;
        }
        false
    }

    pub fn link_names(&self) -> impl Iterator<Item = &str> {
        self.links.iter().map(|l| l.name.as_str())
    }

    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.index.get(name).copied()
    }

    /// Collision shapes of each link, in link order.
    pub fn link_shapes(&self) -> impl Iterator<Item = (&str, &[LinkShape])> {
        self.links
            .iter()
            .map(|l| (l.name.as_str(), l.shapes.as_slice()))
    }

    /// Parent link of each link (`None` for the root), in link order.
    pub fn link_parent(&self, link: usize) -> Option<usize> {
        self.links[link].parent
    }

    pub fn tool_pose(&self, q: &[f64; 6]) -> Isometry3<f64> {
        self.link_poses(q)[self.index["tool"]]
    }

    /// World pose of the DH base frame 0 (`base_link_inertia`).
    pub fn dh_base(&self) -> Isometry3<f64> {
        let i = self.index["base_link_inertia"];
        self.base * self.links[i].origin
    }

    /// Every joint configuration that puts the tool at `tool` (world frame),
    /// within the joint limits, each at the 2π-equivalent nearest to
    /// `reference`, sorted by distance to it (largest joint difference).
    pub fn inverse_kinematics(&self, tool: &Isometry3<f64>, reference: &[f64; 6]) -> Vec<[f64; 6]> {
        let flange = self.dh_base().inverse() * tool * self.tool_in_flange().inverse();
        let mut solutions: Vec<[f64; 6]> = super::ik::solve(&flange.to_homogeneous(), reference)
            .iter()
            .filter_map(|q| super::ik::nearest_within_limits(q, reference))
            .collect();
        let distance = |q: &[f64; 6]| {
            q.iter()
                .zip(reference)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        };
        solutions.sort_by(|a, b| distance(a).total_cmp(&distance(b)));
        solutions
    }

    /// The tool frame in the flange (DH frame 6) frame.
    pub fn tool_in_flange(&self) -> Isometry3<f64> {
        self.links[self.index["tool"]].origin
    }
}

fn shape_of(c: &Collision) -> Option<LinkShape> {
    let o = &c.origin;
    let origin = Isometry3::from_parts(
        Translation3::new(o.xyz[0], o.xyz[1], o.xyz[2]),
        UnitQuaternion::from_euler_angles(o.rpy[0], o.rpy[1], o.rpy[2]),
    );
    match c.geometry {
        Geometry::Capsule { radius, length } => Some(LinkShape::Capsule {
            a: (origin * Point3::new(0.0, 0.0, -length / 2.0)).coords,
            b: (origin * Point3::new(0.0, 0.0, length / 2.0)).coords,
            radius,
        }),
        Geometry::Box { size } => Some(LinkShape::Box {
            centre: origin,
            half_extents: Vector3::new(size[0], size[1], size[2]) / 2.0,
        }),
        _ => None,
    }
}
