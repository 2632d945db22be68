//! A serial kinematic chain read from any URDF: the joints from a base link
//! to a tip link, each with its origin, axis, type and limits, and the
//! forward kinematics and geometric Jacobian of the tip. This is the
//! description a numerical IK ([`crate::robot::kinematics::numeric_ik`]) needs for an arm that
//! is not our UR5 (a 7-joint Panda, an iiwa, a UR of another size).
//!
//! Joint variables: one per revolute, continuous or prismatic joint on the
//! chain, in order from the base; fixed joints carry only their origin; a
//! joint with `<mimic>` follows the joint it names (multiplier × q + offset)
//! and is not a variable. Units: rad for revolute joints, m for prismatic.

use std::collections::HashMap;

use nalgebra::{DMatrix, Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use urdf_rs::JointType;

/// What a joint does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    Revolute,
    /// A revolute joint without position limits.
    Continuous,
    Prismatic,
    Fixed,
}

/// A mimic joint's rule: q = multiplier × q\[variable\] + offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mimic {
    /// Index of the followed joint among the chain's variables.
    pub variable: usize,
    pub multiplier: f64,
    pub offset: f64,
}

/// One joint of the chain.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainJoint {
    pub name: String,
    pub kind: JointKind,
    /// The joint frame in its parent link's frame.
    pub origin: Isometry3<f64>,
    pub axis: Unit<Vector3<f64>>,
    /// Position limits (rad or m); ±∞ for continuous joints.
    pub lower: f64,
    pub upper: f64,
    /// Velocity limit (rad/s or m/s).
    pub velocity: f64,
    /// The link this joint moves.
    pub child_link: String,
    /// For a mimic joint, whom it follows.
    pub mimic: Option<Mimic>,
    /// Index among the chain's variables (`None` for fixed and mimic joints).
    pub variable: Option<usize>,
}

/// A URDF that does not give a usable chain, with what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ChainError {
    #[error("the URDF cannot be read: {0}")]
    Parse(String),
    #[error("link `{0}` is not in the URDF")]
    UnknownLink(String),
    #[error("link `{link}` has two parent joints (`{first}` and `{second}`): a kinematic loop")]
    Loop {
        link: String,
        first: String,
        second: String,
    },
    #[error("no chain of joints leads from `{base}` to `{tip}`")]
    NoChain { base: String, tip: String },
    #[error("the chain from `{base}` branches at link `{at}` (to {children}); name the tip link")]
    AmbiguousTip {
        base: String,
        at: String,
        children: String,
    },
    #[error("joint `{joint}` ({kind}) has no <limit> with a positive velocity")]
    MissingLimits { joint: String, kind: &'static str },
    #[error("joint `{joint}`: {message}")]
    BadJoint { joint: String, message: String },
}

/// A serial chain from a base link to a tip link.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    pub base_link: String,
    pub tip_link: String,
    pub joints: Vec<ChainJoint>,
}

/// A URDF `<origin>` as an isometry (fixed-axis roll, pitch, yaw).
pub(crate) fn isometry(pose: &urdf_rs::Pose) -> Isometry3<f64> {
    let [x, y, z] = pose.xyz.0;
    let [r, p, yaw] = pose.rpy.0;
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(r, p, yaw),
    )
}

/// Parses a URDF document (errors as [`ChainError::Parse`]).
pub fn parse_urdf(urdf: &str) -> Result<urdf_rs::Robot, ChainError> {
    urdf_rs::read_from_string(urdf).map_err(|e| ChainError::Parse(e.to_string()))
}

impl Chain {
    /// The chain of `urdf` from `base` (default: the root link) to `tip`
    /// (default: the end of its only serial chain).
    pub fn from_urdf_str(
        urdf: &str,
        base: Option<&str>,
        tip: Option<&str>,
    ) -> Result<Self, ChainError> {
        Self::from_robot(&parse_urdf(urdf)?, base, tip)
    }

    pub fn from_robot(
        robot: &urdf_rs::Robot,
        base: Option<&str>,
        tip: Option<&str>,
    ) -> Result<Self, ChainError> {
        let links: Vec<&str> = robot.links.iter().map(|l| l.name.as_str()).collect();
        // child link → its joint; parent link → joints below it.
        let mut parent_joint: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
        let mut below: HashMap<&str, Vec<&urdf_rs::Joint>> = HashMap::new();
        for j in &robot.joints {
            for l in [&j.parent.link, &j.child.link] {
                if !links.contains(&l.as_str()) {
                    return Err(ChainError::BadJoint {
                        joint: j.name.clone(),
                        message: format!("names link `{l}`, which the URDF does not define"),
                    });
                }
            }
            if let Some(first) = parent_joint.insert(j.child.link.as_str(), j) {
                return Err(ChainError::Loop {
                    link: j.child.link.clone(),
                    first: first.name.clone(),
                    second: j.name.clone(),
                });
            }
            below.entry(j.parent.link.as_str()).or_default().push(j);
        }
        let base = match base {
            Some(b) if links.contains(&b) => b.to_owned(),
            Some(b) => return Err(ChainError::UnknownLink(b.to_owned())),
            None => links
                .iter()
                .find(|l| !parent_joint.contains_key(*l))
                .map(|l| (*l).to_owned())
                .ok_or_else(|| ChainError::Parse("the URDF has no root link".into()))?,
        };
        let tip = match tip {
            Some(t) if links.contains(&t) => t.to_owned(),
            Some(t) => return Err(ChainError::UnknownLink(t.to_owned())),
            None => {
                // Follow the only child until a leaf.
                let mut at = base.as_str();
                loop {
                    match below.get(at).map(Vec::as_slice) {
                        None | Some([]) => break at.to_owned(),
                        Some([one]) => at = one.child.link.as_str(),
                        Some(many) => {
                            return Err(ChainError::AmbiguousTip {
                                base: base.clone(),
                                at: at.to_owned(),
                                children: many
                                    .iter()
                                    .map(|j| format!("`{}`", j.child.link))
                                    .collect::<Vec<_>>()
                                    .join(", "),
                            });
                        }
                    }
                }
            }
        };
        // Walk up from the tip to the base.
        let mut up: Vec<&urdf_rs::Joint> = Vec::new();
        let mut at = tip.as_str();
        while at != base {
            let Some(j) = parent_joint.get(at) else {
                return Err(ChainError::NoChain { base, tip });
            };
            up.push(j);
            at = j.parent.link.as_str();
        }
        up.reverse();
        let mut joints: Vec<ChainJoint> = Vec::new();
        let mut variables = 0;
        for j in &up {
            let kind = match j.joint_type {
                JointType::Revolute => JointKind::Revolute,
                JointType::Continuous => JointKind::Continuous,
                JointType::Prismatic => JointKind::Prismatic,
                JointType::Fixed => JointKind::Fixed,
                ref other => {
                    return Err(ChainError::BadJoint {
                        joint: j.name.clone(),
                        message: format!(
                            "type {other:?} is not supported on an arm's chain (revolute, continuous, prismatic, fixed)"
                        ),
                    });
                }
            };
            let [ax, ay, az] = j.axis.xyz.0;
            let axis = Vector3::new(ax, ay, az);
            if kind != JointKind::Fixed && !(axis.norm().is_finite() && axis.norm() > 1e-9) {
                return Err(ChainError::BadJoint {
                    joint: j.name.clone(),
                    message: "its axis has no direction".into(),
                });
            }
            let (lower, upper) = match kind {
                JointKind::Revolute | JointKind::Prismatic => {
                    let l = &j.limit;
                    if !(l.velocity > 0.0 && l.lower.is_finite() && l.upper.is_finite())
                        || l.lower > l.upper
                    {
                        return Err(ChainError::MissingLimits {
                            joint: j.name.clone(),
                            kind: if kind == JointKind::Revolute {
                                "revolute"
                            } else {
                                "prismatic"
                            },
                        });
                    }
                    (l.lower, l.upper)
                }
                JointKind::Continuous => (f64::NEG_INFINITY, f64::INFINITY),
                JointKind::Fixed => (0.0, 0.0),
            };
            let mimic = match &j.mimic {
                Some(m) if kind != JointKind::Fixed => {
                    let followed = joints
                        .iter()
                        .find(|c| c.name == m.joint)
                        .and_then(|c| c.variable)
                        .ok_or_else(|| ChainError::BadJoint {
                            joint: j.name.clone(),
                            message: format!(
                                "mimics `{}`, which is not a joint variable earlier on the chain",
                                m.joint
                            ),
                        })?;
                    Some(Mimic {
                        variable: followed,
                        multiplier: m.multiplier.unwrap_or(1.0),
                        offset: m.offset.unwrap_or(0.0),
                    })
                }
                _ => None,
            };
            let variable = (kind != JointKind::Fixed && mimic.is_none()).then(|| {
                variables += 1;
                variables - 1
            });
            joints.push(ChainJoint {
                name: j.name.clone(),
                kind,
                origin: isometry(&j.origin),
                axis: Unit::new_normalize(if kind == JointKind::Fixed {
                    Vector3::z()
                } else {
                    axis
                }),
                lower,
                upper,
                velocity: if kind == JointKind::Fixed {
                    0.0
                } else {
                    j.limit.velocity
                },
                child_link: j.child.link.clone(),
                mimic,
                variable,
            });
        }
        Ok(Self {
            base_link: base,
            tip_link: tip,
            joints,
        })
    }

    /// Joint variables (degrees of freedom).
    pub fn dof(&self) -> usize {
        self.joints.iter().filter(|j| j.variable.is_some()).count()
    }

    /// The variables' joints, in order.
    pub fn variables(&self) -> impl Iterator<Item = &ChainJoint> {
        self.joints.iter().filter(|j| j.variable.is_some())
    }

    /// Each variable's position limits.
    pub fn limits(&self) -> Vec<(f64, f64)> {
        self.variables().map(|j| (j.lower, j.upper)).collect()
    }

    /// Joint `j`'s value for the variables `q`.
    fn value(&self, j: &ChainJoint, q: &[f64]) -> f64 {
        match (j.variable, j.mimic) {
            (Some(v), _) => q[v],
            (None, Some(m)) => m.multiplier * q[m.variable] + m.offset,
            _ => 0.0,
        }
    }

    /// The motion of joint `j` by `value`.
    fn motion(j: &ChainJoint, value: f64) -> Isometry3<f64> {
        match j.kind {
            JointKind::Revolute | JointKind::Continuous => Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&j.axis, value),
            ),
            JointKind::Prismatic => {
                Isometry3::translation(j.axis.x * value, j.axis.y * value, j.axis.z * value)
            }
            JointKind::Fixed => Isometry3::identity(),
        }
    }

    /// The pose of every joint's child link in the base link's frame.
    pub fn link_poses(&self, q: &[f64]) -> Vec<Isometry3<f64>> {
        let mut pose = Isometry3::identity();
        self.joints
            .iter()
            .map(|j| {
                pose = pose * j.origin * Self::motion(j, self.value(j, q));
                pose
            })
            .collect()
    }

    /// The tip link's pose in the base link's frame.
    pub fn tip_pose(&self, q: &[f64]) -> Isometry3<f64> {
        self.link_poses(q)
            .last()
            .copied()
            .unwrap_or_else(Isometry3::identity)
    }

    /// The tip's pose and its geometric Jacobian (6 × dof, rows: linear
    /// velocity of the tip's origin, then angular velocity, both in the
    /// base frame). A mimic joint adds its multiplier times its own column
    /// to the variable it follows.
    pub fn jacobian(&self, q: &[f64]) -> (Isometry3<f64>, DMatrix<f64>) {
        // A revolute joint's column is (a × (tip − o), a) for its axis a
        // through o, = (a × tip + o × a, a): linear in what each joint
        // adds, so one pass accumulates a's (angular rows) and o × a
        // (linear rows) per variable, and the tip, known only at the end,
        // is crossed in once per column. A prismatic joint adds its axis
        // to the linear rows alone.
        let mut jac = DMatrix::zeros(6, self.dof());
        let mut pose = Isometry3::identity();
        for j in &self.joints {
            let frame = pose * j.origin;
            let (gain, variable) = match (j.variable, j.mimic) {
                (Some(v), _) => (1.0, Some(v)),
                (None, Some(m)) => (m.multiplier, Some(m.variable)),
                _ => (0.0, None),
            };
            if let Some(v) = variable {
                let axis = frame.rotation * j.axis.into_inner() * gain;
                let (linear, angular) = match j.kind {
                    JointKind::Prismatic => (axis, Vector3::zeros()),
                    _ => (frame.translation.vector.cross(&axis), axis),
                };
                let mut c = jac.column_mut(v);
                for k in 0..3 {
                    c[k] += linear[k];
                    c[k + 3] += angular[k];
                }
            }
            pose = frame * Self::motion(j, self.value(j, q));
        }
        let tip = pose.translation.vector;
        for v in 0..self.dof() {
            let mut c = jac.column_mut(v);
            let a = Vector3::new(c[3], c[4], c[5]);
            let moved = a.cross(&tip);
            for k in 0..3 {
                c[k] += moved[k];
            }
        }
        (pose, jac)
    }
}

impl JointKind {
    /// The URDF's name of the kind.
    pub fn name(self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Continuous => "continuous",
            JointKind::Prismatic => "prismatic",
            JointKind::Fixed => "fixed",
        }
    }
}

/// Finite bounds for sampling a joint (continuous joints: one turn).
pub(crate) fn sample_range(lower: f64, upper: f64) -> (f64, f64) {
    (
        if lower.is_finite() {
            lower
        } else {
            -std::f64::consts::PI
        },
        if upper.is_finite() {
            upper
        } else {
            std::f64::consts::PI
        },
    )
}

/// A random configuration inside `chain`'s limits.
pub fn random_configuration(chain: &Chain, rng: &mut ChaCha8Rng) -> Vec<f64> {
    chain
        .limits()
        .into_iter()
        .map(|(lo, hi)| {
            let (lo, hi) = sample_range(lo, hi);
            if hi > lo {
                rng.random_range(lo..=hi)
            } else {
                lo
            }
        })
        .collect()
}
