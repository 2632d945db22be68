//! A robot description: the arm's URDF plus the few lines URDF has no
//! place for, and the self-contained file `treemanip robot import` makes
//! of them.
//!
//! The **configuration** (`RobotConfig`, TOML next to the URDF, in the
//! spirit of an SRDF and MoveIt's `joint_limits.yaml`):
//!
//! ```toml
//! name = "panda"
//! urdf = "panda.urdf"              # relative to this file
//! base_link = "panda_link0"        # default: the URDF's root
//! tip_link = "panda_hand"          # default: the end of its only serial chain
//! acceleration = [15, 7.5, 10, 12.5, 15, 20, 20]   # rad/s² (or m/s²); one number for all
//! jerk = 5000                      # optional
//! home = [0, -0.785, 0, -2.356, 0, 1.571, 0.785]    # default: 0 clamped into the limits
//! disabled_pairs = [["panda_link0", "panda_link2"]] # added to the sampled ones
//! srdf = "panda.srdf"              # optional: its <disable_collisions> added too
//! licence = "Apache-2.0 (example-robot-data)"
//! ```
//!
//! The **description** (`RobotDescription`, what `import` writes and the
//! planner loads without the URDF or its meshes): the chain's joints with
//! their origins, axes and limits, every link's collision shapes (meshes
//! already fitted with capsules) placed on the chain link it rides on, the
//! self-collision pairs left unchecked and why, the home configuration,
//! and where it all came from.

use crate::robot::model::tool_mount::{ChosenMount, ToolChoice, adjusted};
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::geometry::shape::Shape;
pub use crate::robot::model::import::import;
use crate::robot::model::self_pairs::DisabledPair;
use crate::robot::model::urdf_chain::{Chain, ChainJoint, JointKind, Mimic};

/// Acceleration limit when the configuration gives none: rad/s² for
/// revolute joints (the UR5's, a conservative value for most arms).
pub const DEFAULT_ACCELERATION: f64 = 3.0;
/// The same for prismatic joints (m/s²).
pub const DEFAULT_LINEAR_ACCELERATION: f64 = 1.0;
/// Random configurations sampled for the self-collision pairs.
pub const SELF_COLLISION_SAMPLES: usize = 2000;

/// One number for every joint, or one per joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PerJoint {
    All(f64),
    Each(Vec<f64>),
}

impl PerJoint {
    pub(crate) fn values(&self, dof: usize, what: &str) -> Result<Vec<f64>, String> {
        let v = match self {
            PerJoint::All(x) => vec![*x; dof],
            PerJoint::Each(v) if v.len() == dof => v.clone(),
            PerJoint::Each(v) => {
                return Err(format!(
                    "{what}: {} values for a {dof}-joint chain",
                    v.len()
                ));
            }
        };
        match v.iter().position(|x| !(x.is_finite() && *x > 0.0)) {
            Some(k) => Err(format!("{what}[{k}] must be positive and finite")),
            None => Ok(v),
        }
    }
}

/// The lines a URDF needs to become a robot description.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    pub name: String,
    /// The URDF, relative to the configuration file.
    pub urdf: PathBuf,
    pub base_link: Option<String>,
    pub tip_link: Option<String>,
    pub acceleration: Option<PerJoint>,
    pub jerk: Option<PerJoint>,
    pub home: Option<Vec<f64>>,
    #[serde(default)]
    pub disabled_pairs: Vec<[String; 2]>,
    /// A MoveIt SRDF, relative to the configuration file, whose
    /// `<disable_collisions>` pairs are added to the sampled ones.
    #[serde(default)]
    pub srdf: Option<PathBuf>,
    /// Where the URDF comes from and under which licence.
    #[serde(default)]
    pub licence: String,
    /// Where the pusher tool sits on the tip (default: the ⊔ gripper on
    /// the tip's origin, pushing along its z).
    #[serde(default)]
    pub tool: ToolSpec,
    /// How the tool is placed (a bare URDF's: on the last joint's axis, or
    /// `tool=FRAME`); a configuration file's `[tool]` is taken as it is.
    #[serde(skip)]
    pub tool_choice: ToolChoice,
    /// `tool_xyz`/`tool_rpy` of a `--robot` specification: the chosen
    /// mount moved and turned by them.
    #[serde(skip)]
    pub tool_adjust: Option<([f64; 3], [f64; 3])>,
}

/// Where the pusher tool sits on the tip link, and optionally the user's
/// own tool in place of the ⊔ gripper:
///
/// ```toml
/// [tool]
/// mount = { xyz = [0, 0, 0.11], rpy = [0, 0, 0] }   # on the tip link
/// frame = { xyz = [0, 0, 0.06], rpy = [0, 0, 0] }   # on the mount
/// shapes = [{ type = "box", origin = { xyz = [0, 0, 0.03], rpy = [0, 0, 0] }, size = [0.08, 0.08, 0.06] }]
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolSpec {
    /// Where the ⊔ gripper's standoff is bolted, in the tip link's frame;
    /// the gripper pushes along this frame's z, and the tool frame (the
    /// palm's face, see [`crate::robot::ur5`]) is `TOOL_OFFSET` further
    /// along it. Put it past whatever the tip already carries (a hand's
    /// fingers) and turn it so that z leaves the flange.
    #[serde(default = "PoseSpec::identity")]
    pub mount: PoseSpec,
    /// Whether the tool's shapes (the ⊔ gripper's boxes, or `shapes`) are
    /// added to the tip; false when the URDF carries the tool's geometry
    /// itself (the built-in UR5's does).
    #[serde(default = "yes")]
    pub gripper: bool,
    /// The user's own tool in place of the ⊔ gripper: its collision shapes
    /// (boxes, capsules, cylinders, spheres) in the mount's frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shapes: Option<Vec<ShapeSpec>>,
    /// The tool frame in the mount's frame: the point the planner puts on
    /// the branch, z along the push and x along the branch (default: the
    /// ⊔ gripper's palm face, `TOOL_OFFSET` out along z, its slot along
    /// x).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<PoseSpec>,
    /// How `mount` was chosen (`flange axis: joint ...`, `frame tool0`);
    /// absent: configured by hand.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chosen: Option<String>,
}

fn yes() -> bool {
    true
}

impl ToolSpec {
    /// How the mount was chosen (`configured` when nothing says).
    pub fn how_chosen(&self) -> String {
        self.chosen
            .clone()
            .unwrap_or_else(|| "configured".to_owned())
    }

    /// The mount `chosen` chose, and how.
    pub fn place(&mut self, chosen: ChosenMount) {
        self.mount = (&chosen.mount).into();
        self.chosen = Some(chosen.how);
    }

    /// The mount moved by `xyz` and turned by `rpy` in its own frame
    /// (`tool_xyz`, `tool_rpy`).
    pub fn adjust(&mut self, xyz: [f64; 3], rpy: [f64; 3]) {
        let current = ChosenMount {
            mount: self.mount.isometry(),
            how: self.how_chosen(),
        };
        self.place(adjusted(current, xyz, rpy));
    }
}

impl Default for ToolSpec {
    fn default() -> Self {
        Self {
            mount: PoseSpec::identity(),
            gripper: true,
            shapes: None,
            frame: None,
            chosen: None,
        }
    }
}

/// A pose as URDF writes it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseSpec {
    pub xyz: [f64; 3],
    pub rpy: [f64; 3],
}

impl From<&Isometry3<f64>> for PoseSpec {
    fn from(iso: &Isometry3<f64>) -> Self {
        let t = iso.translation.vector;
        let (r, p, y) = iso.rotation.euler_angles();
        Self {
            xyz: [t.x, t.y, t.z],
            rpy: [r, p, y],
        }
    }
}

impl PoseSpec {
    pub fn identity() -> Self {
        Self {
            xyz: [0.0; 3],
            rpy: [0.0; 3],
        }
    }

    pub fn isometry(&self) -> Isometry3<f64> {
        let [x, y, z] = self.xyz;
        let [r, p, w] = self.rpy;
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(r, p, w),
        )
    }
}

/// A joint of the description's chain.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    pub name: String,
    /// `revolute`, `continuous`, `prismatic` or `fixed`.
    pub kind: String,
    pub child: String,
    pub origin: PoseSpec,
    pub axis: [f64; 3],
    /// Position limits (rad or m); absent for continuous and fixed joints.
    pub lower: Option<f64>,
    pub upper: Option<f64>,
    /// Velocity, acceleration and jerk limits (absent for fixed joints).
    pub velocity: Option<f64>,
    pub acceleration: Option<f64>,
    pub jerk: Option<f64>,
    /// A mimic joint follows `mimic_joint` × `mimic_multiplier` + offset.
    pub mimic_joint: Option<String>,
    pub mimic_multiplier: Option<f64>,
    pub mimic_offset: Option<f64>,
}

/// A collision shape in its link's frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    Capsule {
        a: [f64; 3],
        b: [f64; 3],
        radius: f64,
    },
    Box {
        origin: PoseSpec,
        size: [f64; 3],
    },
    /// Along the origin's z axis.
    Cylinder {
        origin: PoseSpec,
        radius: f64,
        length: f64,
    },
    Sphere {
        center: [f64; 3],
        radius: f64,
    },
}

/// A link's collision shapes, and where the link sits: on the chain link
/// `frame`, at `pose` (joints off the chain held at zero).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkSpec {
    pub name: String,
    pub frame: String,
    pub pose: PoseSpec,
    pub shapes: Vec<ShapeSpec>,
}

/// Where a description came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    pub urdf: String,
    pub licence: String,
    pub command: String,
    pub self_collision_samples: usize,
}

/// A self-contained robot description (see the module's documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotDescription {
    pub name: String,
    pub base_link: String,
    pub tip_link: String,
    pub dof: usize,
    pub home: Vec<f64>,
    pub joints: Vec<JointSpec>,
    pub links: Vec<LinkSpec>,
    pub disabled_pairs: Vec<DisabledPair>,
    #[serde(default)]
    pub tool: ToolSpec,
    pub source: Provenance,
}

/// A description or configuration that cannot be used: the file and what
/// is wrong with which element.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {message}")]
pub struct DescriptionError {
    pub file: PathBuf,
    pub message: String,
}

pub(crate) fn arr(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

pub(crate) fn shape_spec(s: &Shape) -> ShapeSpec {
    match s {
        Shape::Capsule { a, b, radius } => ShapeSpec::Capsule {
            a: arr(&a.coords),
            b: arr(&b.coords),
            radius: *radius,
        },
        Shape::Box { pose, half_extents } => ShapeSpec::Box {
            origin: pose.into(),
            size: arr(&(half_extents * 2.0)),
        },
        Shape::Cylinder {
            pose,
            radius,
            half_length,
        } => ShapeSpec::Cylinder {
            origin: pose.into(),
            radius: *radius,
            length: 2.0 * half_length,
        },
        Shape::Sphere {
            centre: center,
            radius,
        } => ShapeSpec::Sphere {
            center: arr(&center.coords),
            radius: *radius,
        },
    }
}

impl ShapeSpec {
    /// The shape, checked.
    pub fn shape(&self) -> Result<Shape, String> {
        let positive = |what: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(format!("{what} must be positive and finite, it is {v}"))
            }
        };
        Ok(match self {
            ShapeSpec::Capsule { a, b, radius } => Shape::Capsule {
                a: Point3::from(*a),
                b: Point3::from(*b),
                radius: positive("radius", *radius)?,
            },
            ShapeSpec::Box { origin, size } => Shape::Box {
                pose: origin.isometry(),
                half_extents: Vector3::new(
                    positive("size", size[0])? / 2.0,
                    positive("size", size[1])? / 2.0,
                    positive("size", size[2])? / 2.0,
                ),
            },
            ShapeSpec::Cylinder {
                origin,
                radius,
                length,
            } => Shape::Cylinder {
                pose: origin.isometry(),
                radius: positive("radius", *radius)?,
                half_length: positive("length", *length)? / 2.0,
            },
            ShapeSpec::Sphere { center, radius } => Shape::Sphere {
                centre: Point3::from(*center),
                radius: positive("radius", *radius)?,
            },
        })
    }
}

impl RobotDescription {
    /// The description as TOML.
    pub fn to_toml(&self) -> Result<String, String> {
        toml::to_string(self).map_err(|e| e.to_string())
    }

    /// Reads and checks a description (`file` names it in errors).
    pub fn from_toml_str(text: &str, file: &Path) -> Result<Self, DescriptionError> {
        let fail = |message: String| DescriptionError {
            file: file.to_path_buf(),
            message,
        };
        let d: Self = toml::from_str(text).map_err(|e| fail(e.to_string()))?;
        d.chain().map_err(fail)?;
        for (k, l) in d.links.iter().enumerate() {
            for (m, s) in l.shapes.iter().enumerate() {
                s.shape()
                    .map_err(|e| fail(format!("links[{k}] ({}).shapes[{m}]: {e}", l.name)))?;
            }
        }
        if d.home.len() != d.dof {
            return Err(fail(format!(
                "home: {} values for {} joints",
                d.home.len(),
                d.dof
            )));
        }
        Ok(d)
    }

    /// The planning chain.
    pub fn chain(&self) -> Result<Chain, String> {
        let mut joints = Vec::with_capacity(self.joints.len());
        let mut variables: Vec<&str> = Vec::new();
        for (k, j) in self.joints.iter().enumerate() {
            let at = |m: &str| format!("joints[{k}] ({}): {m}", j.name);
            let kind = match j.kind.as_str() {
                "revolute" => JointKind::Revolute,
                "continuous" => JointKind::Continuous,
                "prismatic" => JointKind::Prismatic,
                "fixed" => JointKind::Fixed,
                other => return Err(at(&format!("unknown kind `{other}`"))),
            };
            let axis = Vector3::from(j.axis);
            if !(axis.iter().all(|x| x.is_finite()) && axis.norm() > 1e-9) {
                return Err(at("the axis must be a non-zero vector"));
            }
            let mimic = match &j.mimic_joint {
                Some(name) => Some(Mimic {
                    variable: variables
                        .iter()
                        .position(|v| v == name)
                        .ok_or_else(|| at(&format!("follows `{name}`, not a joint before it")))?,
                    multiplier: j.mimic_multiplier.unwrap_or(1.0),
                    offset: j.mimic_offset.unwrap_or(0.0),
                }),
                None => None,
            };
            let moves = kind != JointKind::Fixed && mimic.is_none();
            let (lower, upper) = match kind {
                JointKind::Revolute | JointKind::Prismatic if moves => match (j.lower, j.upper) {
                    (Some(lo), Some(hi)) if lo.is_finite() && hi.is_finite() && lo <= hi => {
                        (lo, hi)
                    }
                    _ => return Err(at("needs finite lower ≤ upper limits")),
                },
                _ => (f64::NEG_INFINITY, f64::INFINITY),
            };
            let velocity = if moves {
                match j.velocity {
                    Some(v) if v.is_finite() && v > 0.0 => v,
                    _ => return Err(at("needs a positive velocity limit")),
                }
            } else {
                0.0
            };
            if moves && !j.acceleration.is_some_and(|a| a.is_finite() && a > 0.0) {
                return Err(at("needs a positive acceleration limit"));
            }
            let variable = moves.then(|| {
                variables.push(j.name.as_str());
                variables.len() - 1
            });
            joints.push(ChainJoint {
                name: j.name.clone(),
                kind,
                origin: j.origin.isometry(),
                axis: Unit::new_normalize(axis),
                lower,
                upper,
                velocity,
                child_link: j.child.clone(),
                mimic,
                variable,
            });
        }
        if variables.len() != self.dof {
            return Err(format!(
                "dof is {} but the joints have {} variables",
                self.dof,
                variables.len()
            ));
        }
        Ok(Chain {
            base_link: self.base_link.clone(),
            tip_link: self.tip_link.clone(),
            joints,
        })
    }

    /// Each variable's acceleration limit.
    pub fn acceleration_limits(&self) -> Vec<f64> {
        self.joints.iter().filter_map(|j| j.acceleration).collect()
    }
}
