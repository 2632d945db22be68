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
//! licence = "Apache-2.0 (example-robot-data)"
//! ```
//!
//! The **description** (`RobotDescription`, what `import` writes and the
//! planner loads without the URDF or its meshes): the chain's joints with
//! their origins, axes and limits, every link's collision shapes (meshes
//! already fitted with capsules) placed on the chain link it rides on, the
//! self-collision pairs left unchecked and why, the home configuration,
//! and where it all came from.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::chain::{Chain, ChainJoint, JointKind, Mimic, parse_urdf};
use super::link_geometry::{LinkShape, link_geometry};
use super::mesh_fit::Capsule;
use super::self_collision::{DisableReason, DisabledPair, all_link_poses, disabled_pairs};

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
    fn values(&self, dof: usize, what: &str) -> Result<Vec<f64>, String> {
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
    /// Where the URDF comes from and under which licence.
    #[serde(default)]
    pub licence: String,
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

fn arr(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn shape_spec(s: &LinkShape) -> ShapeSpec {
    match s {
        LinkShape::Capsule(c) => ShapeSpec::Capsule {
            a: arr(&c.a.coords),
            b: arr(&c.b.coords),
            radius: c.radius,
        },
        LinkShape::Box { pose, half_extents } => ShapeSpec::Box {
            origin: pose.into(),
            size: arr(&(half_extents * 2.0)),
        },
        LinkShape::Cylinder {
            pose,
            radius,
            half_length,
        } => ShapeSpec::Cylinder {
            origin: pose.into(),
            radius: *radius,
            length: 2.0 * half_length,
        },
        LinkShape::Sphere { center, radius } => ShapeSpec::Sphere {
            center: arr(&center.coords),
            radius: *radius,
        },
    }
}

impl ShapeSpec {
    /// The shape, checked.
    pub fn shape(&self) -> Result<LinkShape, String> {
        let positive = |what: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(format!("{what} must be positive and finite, it is {v}"))
            }
        };
        Ok(match self {
            ShapeSpec::Capsule { a, b, radius } => LinkShape::Capsule(Capsule {
                a: Point3::from(*a),
                b: Point3::from(*b),
                radius: positive("radius", *radius)?,
            }),
            ShapeSpec::Box { origin, size } => LinkShape::Box {
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
            } => LinkShape::Cylinder {
                pose: origin.isometry(),
                radius: positive("radius", *radius)?,
                half_length: positive("length", *length)? / 2.0,
            },
            ShapeSpec::Sphere { center, radius } => LinkShape::Sphere {
                center: Point3::from(*center),
                radius: positive("radius", *radius)?,
            },
        })
    }
}

fn kind_name(kind: JointKind) -> &'static str {
    match kind {
        JointKind::Revolute => "revolute",
        JointKind::Continuous => "continuous",
        JointKind::Prismatic => "prismatic",
        JointKind::Fixed => "fixed",
    }
}

/// Imports the robot that the configuration at `config_path` describes:
/// reads its URDF and meshes (through `packages` and the URDF's
/// ancestors), fits the meshes, samples the self-collision pairs.
pub fn import(
    config_path: &Path,
    packages: &[PathBuf],
    command: &str,
) -> Result<RobotDescription, DescriptionError> {
    let fail = |file: &Path, message: String| DescriptionError {
        file: file.to_path_buf(),
        message,
    };
    let text = std::fs::read_to_string(config_path)
        .map_err(|e| fail(config_path, format!("cannot be read: {e}")))?;
    let config: RobotConfig =
        toml::from_str(&text).map_err(|e| fail(config_path, e.to_string()))?;
    let urdf_path = config_path
        .parent()
        .unwrap_or(Path::new("."))
        .join(&config.urdf);
    let urdf_text = std::fs::read_to_string(&urdf_path)
        .map_err(|e| fail(&urdf_path, format!("cannot be read: {e}")))?;
    let robot = parse_urdf(&urdf_text).map_err(|e| fail(&urdf_path, e.to_string()))?;
    let chain = Chain::from_robot(
        &robot,
        config.base_link.as_deref(),
        config.tip_link.as_deref(),
    )
    .map_err(|e| fail(&urdf_path, e.to_string()))?;
    let dof = chain.dof();
    let acceleration = config
        .acceleration
        .as_ref()
        .map(|a| a.values(dof, "acceleration"))
        .transpose()
        .map_err(|m| fail(config_path, m))?;
    let jerk = config
        .jerk
        .as_ref()
        .map(|a| a.values(dof, "jerk"))
        .transpose()
        .map_err(|m| fail(config_path, m))?;
    let limits = chain.limits();
    let home = match &config.home {
        Some(h) if h.len() != dof => {
            return Err(fail(
                config_path,
                format!("home: {} values for a {dof}-joint chain", h.len()),
            ));
        }
        Some(h) => {
            if let Some(k) = h
                .iter()
                .zip(&limits)
                .position(|(q, (lo, hi))| !(q.is_finite() && *lo <= *q && q <= hi))
            {
                return Err(fail(
                    config_path,
                    format!("home[{k}] = {} is outside the joint's limits", h[k]),
                ));
            }
            h.clone()
        }
        // Continuous joints' ±∞ limits leave 0 as it is.
        None => limits.iter().map(|(lo, hi)| 0f64.clamp(*lo, *hi)).collect(),
    };
    let geometry = link_geometry(&robot, urdf_path.parent(), packages)
        .map_err(|e| fail(&urdf_path, e.to_string()))?;
    let mut pairs = disabled_pairs(&robot, &chain, &geometry, SELF_COLLISION_SAMPLES, 0);
    for [a, b] in &config.disabled_pairs {
        for l in [a, b] {
            if !robot.links.iter().any(|x| &x.name == l) {
                return Err(fail(
                    config_path,
                    format!("disabled_pairs: link `{l}` is not in the URDF"),
                ));
            }
        }
        if !pairs
            .iter()
            .any(|p| (&p.a == a && &p.b == b) || (&p.a == b && &p.b == a))
        {
            pairs.push(DisabledPair {
                a: a.clone(),
                b: b.clone(),
                reason: DisableReason::Configured,
            });
        }
    }
    // Each link with shapes, on the chain link it rides on.
    let zero = vec![0.0; dof];
    let poses = all_link_poses(&robot, &chain, &zero);
    let chain_links: Vec<&str> = std::iter::once(chain.base_link.as_str())
        .chain(chain.joints.iter().map(|j| j.child_link.as_str()))
        .collect();
    let parent_of = |link: &str| {
        robot
            .joints
            .iter()
            .find(|j| j.child.link == link)
            .map(|j| j.parent.link.as_str())
    };
    let mut links = Vec::new();
    for g in &geometry {
        let mut frame = g.link.as_str();
        while !chain_links.contains(&frame) {
            match parent_of(frame) {
                Some(p) => frame = p,
                None => break,
            }
        }
        if !chain_links.contains(&frame) {
            // Above the chain's base: fixed relative to it.
            frame = chain.base_link.as_str();
        }
        let (Some(at), Some(of)) = (poses.get(&g.link), poses.get(frame)) else {
            continue;
        };
        links.push(LinkSpec {
            name: g.link.clone(),
            frame: frame.to_owned(),
            pose: (&(of.inverse() * at)).into(),
            shapes: g.shapes.iter().map(shape_spec).collect(),
        });
    }
    let joints = chain
        .joints
        .iter()
        .map(|j| {
            let v = j.variable;
            let is_linear = j.kind == JointKind::Prismatic;
            let default_acc = if is_linear {
                DEFAULT_LINEAR_ACCELERATION
            } else {
                DEFAULT_ACCELERATION
            };
            JointSpec {
                name: j.name.clone(),
                kind: kind_name(j.kind).to_owned(),
                child: j.child_link.clone(),
                origin: (&j.origin).into(),
                axis: arr(&j.axis),
                lower: j.lower.is_finite().then_some(j.lower),
                upper: j.upper.is_finite().then_some(j.upper),
                velocity: v.map(|_| j.velocity),
                acceleration: v.map(|k| acceleration.as_ref().map_or(default_acc, |a| a[k])),
                jerk: v.and_then(|k| jerk.as_ref().map(|a| a[k])),
                mimic_joint: j
                    .mimic
                    .and_then(|m| chain.variables().nth(m.variable).map(|x| x.name.clone())),
                mimic_multiplier: j.mimic.map(|m| m.multiplier),
                mimic_offset: j.mimic.map(|m| m.offset),
            }
        })
        .collect();
    Ok(RobotDescription {
        name: config.name,
        base_link: chain.base_link.clone(),
        tip_link: chain.tip_link.clone(),
        dof,
        home,
        joints,
        links,
        disabled_pairs: pairs,
        source: Provenance {
            urdf: config.urdf.display().to_string(),
            licence: config.licence,
            command: command.to_owned(),
            self_collision_samples: SELF_COLLISION_SAMPLES,
        },
    })
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
