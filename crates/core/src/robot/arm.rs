//! [`Arm`]: any serial arm the planner drives, built from a
//! [`RobotDescription`] (an imported robot, a bare URDF described on the
//! fly, or the built-in UR5 of [`crate::robot::ur5`]).
//!
//! The arm is a tree of links in parent-before-child order: the chain's
//! links, each moved by its joint (revolute or prismatic, or following
//! another as a mimic joint), and every other link with collision shapes
//! fixed on the chain link it rides on (hands, fingers and joints off the
//! chain stay where they are at zero). The pusher tool sits on the tip:
//! the link `gripper` with the ⊔ gripper's boxes or the user's own tool
//! shapes (none when the URDF carries them), and the tool frame `tool`,
//! at the palm's face or where the user's tool says.
//!
//! Inverse kinematics takes the closed form when the chain has UR
//! kinematics ([`UrKinematics::detect`]: 2.5 µs a pose) and damped least
//! squares with restarts otherwise ([`crate::robot::kinematics::numeric_ik`]).

use std::collections::HashMap;

use nalgebra::{Isometry3, Point3, Unit, UnitQuaternion, Vector3};

use crate::geometry::shape::Shape;
use crate::robot::kinematics::ur_kinematics::UrKinematics;
use crate::robot::model::description::RobotDescription;
use crate::robot::model::joint_vector::{JointVector, MAX_DOF};
use crate::robot::model::tool::{GRIPPER_BOXES, GRIPPER_LINK, TOOL_LINK, TOOL_OFFSET};
use crate::robot::model::urdf_chain::{Chain, JointKind};

pub mod base;
mod inverse;
mod reach;
mod self_motion;
mod stance;
pub mod tool_line;
pub use base::{BaseStance, PAPER_BASE};
pub use stance::{PROBE_PUSHES, STANCES, UR5_REACH};

/// World poses of the links, in the arm's link order: on the stack for
/// arms of up to 24 links, since the collision checker computes them for
/// every pose it checks.
pub type LinkPoses = smallvec::SmallVec<[Isometry3<f64>; 24]>;

/// Starts tried for the pre-contact poses of a numerical chain, besides
/// the reference: each converged one that differs from the others is a
/// solution (a closed form gives up to 8).
const IK_STARTS: usize = 10;
/// Two solutions closer than this in every joint are one (rad or m).
const SAME_SOLUTION: f64 = 0.05;

/// A joint variable: its limits (rad or m; per second, per second²).
#[derive(Debug, Clone, PartialEq)]
pub struct ArmJoint {
    pub name: String,
    pub kind: JointKind,
    pub lower: f64,
    pub upper: f64,
    pub velocity: f64,
    pub acceleration: f64,
    pub jerk: Option<f64>,
}

/// How a link moves relative to its parent.
#[derive(Debug, Clone, Copy)]
struct Motion {
    variable: usize,
    multiplier: f64,
    offset: f64,
    axis: Unit<Vector3<f64>>,
    prismatic: bool,
}

#[derive(Debug, Clone)]
struct ArmLink {
    name: String,
    parent: Option<usize>,
    /// Pose of the joint frame in the parent link.
    origin: Isometry3<f64>,
    motion: Option<Motion>,
    shapes: Vec<Shape>,
}

#[derive(Debug, Clone)]
enum Solver {
    Ur(Box<UrKinematics>),
    Numeric,
}

/// An arm: its links, joints, collision shapes, tool and solver.
#[derive(Debug, Clone)]
pub struct Arm {
    name: String,
    links: Vec<ArmLink>,
    index: HashMap<String, usize>,
    joints: Vec<ArmJoint>,
    chain: Chain,
    solver: Solver,
    tip: usize,
    tool: usize,
    home: JointVector,
    disabled_pairs: Vec<(String, String)>,
    /// How the tool's mount was chosen (`flange axis: joint ...`, `frame
    /// tool0`, `configured`).
    tool_chosen: String,
    /// The added ⊔ gripper's link (none when the description's URDF
    /// carries the tool itself).
    gripper: Option<usize>,
    /// World pose of the chain's base link.
    pub base: Isometry3<f64>,
    /// Where a mobile base stands for a push ([`Arm::stances`]), and the
    /// test pushes one of them carries out (a mask of [`PROBE_PUSHES`]).
    stances: std::sync::OnceLock<(Vec<BaseStance>, u32)>,
}

impl Arm {
    /// The arm `description` describes, its base at the world origin.
    pub fn from_description(d: &RobotDescription) -> Result<Self, String> {
        let chain = d.chain()?;
        let dof = chain.dof();
        if dof == 0 || dof > MAX_DOF {
            return Err(format!("{dof} joints: an arm has 1 to {MAX_DOF}"));
        }
        let mut links = vec![ArmLink {
            name: d.base_link.clone(),
            parent: None,
            origin: Isometry3::identity(),
            motion: None,
            shapes: Vec::new(),
        }];
        for j in &chain.joints {
            let source = match (j.variable, j.mimic) {
                (Some(v), _) => Some((v, 1.0, 0.0)),
                (None, Some(m)) => Some((m.variable, m.multiplier, m.offset)),
                _ => None,
            };
            let motion = source.filter(|_| j.kind != JointKind::Fixed).map(
                |(variable, multiplier, offset)| Motion {
                    variable,
                    multiplier,
                    offset,
                    axis: j.axis,
                    prismatic: j.kind == JointKind::Prismatic,
                },
            );
            links.push(ArmLink {
                name: j.child_link.clone(),
                parent: Some(links.len() - 1),
                origin: j.origin,
                motion,
                shapes: Vec::new(),
            });
        }
        let tip = links.len() - 1;
        let mut index: HashMap<String, usize> = links
            .iter()
            .enumerate()
            .map(|(k, l)| (l.name.clone(), k))
            .collect();
        for (k, l) in d.links.iter().enumerate() {
            let shapes = l
                .shapes
                .iter()
                .enumerate()
                .map(|(m, s)| {
                    s.shape()
                        .map_err(|e| format!("links[{k}] ({}).shapes[{m}]: {e}", l.name))
                })
                .collect::<Result<Vec<_>, _>>()?;
            let frame = *index.get(&l.frame).ok_or_else(|| {
                format!(
                    "links[{k}] ({}): frame `{}` is not a link of the chain",
                    l.name, l.frame
                )
            })?;
            let pose = l.pose.isometry();
            if l.name == l.frame {
                // A chain link's own shapes (its pose the identity, up to
                // rounding).
                links[frame]
                    .shapes
                    .extend(shapes.iter().map(|s| s.placed(&pose)));
            } else if index.contains_key(&l.name) {
                return Err(format!("links[{k}] ({}): listed twice", l.name));
            } else {
                index.insert(l.name.clone(), links.len());
                links.push(ArmLink {
                    name: l.name.clone(),
                    parent: Some(frame),
                    origin: pose,
                    motion: None,
                    shapes,
                });
            }
        }
        let mount = d.tool.mount.isometry();
        let tool_shapes: Vec<Shape> = match &d.tool.shapes {
            Some(_) if !d.tool.gripper => {
                return Err("tool.shapes is given but tool.gripper is false".to_owned());
            }
            Some(shapes) if shapes.is_empty() => {
                return Err("tool.shapes is empty (leave it out for the ⊔ gripper)".to_owned());
            }
            Some(shapes) => shapes
                .iter()
                .enumerate()
                .map(|(k, s)| s.shape().map_err(|e| format!("tool.shapes[{k}]: {e}")))
                .collect::<Result<_, _>>()?,
            None => GRIPPER_BOXES.iter().map(|b| b.shape()).collect(),
        };
        let tool_frame = match &d.tool.frame {
            Some(f) if !(f.xyz.iter().chain(&f.rpy).all(|v| v.is_finite())) => {
                return Err("tool.frame must be finite".to_owned());
            }
            Some(f) => f.isometry(),
            None => Isometry3::translation(0.0, 0.0, TOOL_OFFSET),
        };
        // The tool's links keep their names unless the robot has links of
        // those names (the SO-100's `gripper`): then they are prefixed.
        let unused = |name: &str| {
            let mut n = name.to_owned();
            while index.contains_key(&n) {
                n = format!("treemanip_{n}");
            }
            n
        };
        let gripper_name = unused(GRIPPER_LINK);
        let tool_name = unused(TOOL_LINK);
        let gripper = d.tool.gripper.then(|| {
            index.insert(gripper_name.clone(), links.len());
            links.push(ArmLink {
                name: gripper_name,
                parent: Some(tip),
                origin: mount,
                motion: None,
                shapes: tool_shapes,
            });
            links.len() - 1
        });
        let tool = links.len();
        index.insert(tool_name.clone(), tool);
        links.push(ArmLink {
            name: tool_name,
            parent: Some(tip),
            origin: mount * tool_frame,
            motion: None,
            shapes: Vec::new(),
        });
        let accelerations = d.acceleration_limits();
        let jerks: Vec<Option<f64>> = d
            .joints
            .iter()
            .filter(|j| j.acceleration.is_some())
            .map(|j| j.jerk)
            .collect();
        let joints: Vec<ArmJoint> = chain
            .variables()
            .zip(accelerations.iter().zip(&jerks))
            .map(|(j, (a, jerk))| ArmJoint {
                name: j.name.clone(),
                kind: j.kind,
                lower: j.lower,
                upper: j.upper,
                velocity: j.velocity,
                acceleration: *a,
                jerk: *jerk,
            })
            .collect();
        if joints.len() != dof {
            return Err(format!(
                "{} acceleration limits for {dof} joints",
                joints.len()
            ));
        }
        let home = JointVector::from_slice(&d.home);
        for (k, (q, j)) in home.iter().zip(&joints).enumerate() {
            if !(q.is_finite() && j.lower <= *q && *q <= j.upper) {
                return Err(format!("home[{k}] = {q} is outside the joint's limits"));
            }
        }
        for p in &d.disabled_pairs {
            for l in [&p.a, &p.b] {
                if !index.contains_key(l) {
                    return Err(format!("disabled_pairs: `{l}` is not a link of the robot"));
                }
            }
        }
        let solver = match UrKinematics::detect(&chain) {
            Some(ur) => Solver::Ur(Box::new(ur)),
            None => Solver::Numeric,
        };
        Ok(Self {
            name: d.name.clone(),
            links,
            index,
            joints,
            chain,
            solver,
            tip,
            tool,
            gripper,
            home,
            tool_chosen: d.tool.how_chosen(),
            disabled_pairs: d
                .disabled_pairs
                .iter()
                .map(|p| (p.a.clone(), p.b.clone()))
                .collect(),
            base: Isometry3::identity(),
            stances: std::sync::OnceLock::new(),
        })
    }

    /// Where this arm stands when a request names no base: the paper's
    /// mount, `base_link` at (−0.5, 0, 0.1) m from the tree root facing +x.
    /// Every caller asks the arm, so a description that names its own
    /// mount changes this one method.
    pub fn default_base(&self) -> Isometry3<f64> {
        PAPER_BASE
    }

    pub fn with_base(mut self, base: Isometry3<f64>) -> Self {
        self.base = base;
        self
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Number of joint variables.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    pub fn joints(&self) -> &[ArmJoint] {
        &self.joints
    }

    pub fn joint_names(&self) -> impl Iterator<Item = &str> {
        self.joints.iter().map(|j| j.name.as_str())
    }

    /// Each joint's position limits.
    pub fn limits(&self) -> Vec<(f64, f64)> {
        self.joints.iter().map(|j| (j.lower, j.upper)).collect()
    }

    pub fn velocity_limits(&self) -> JointVector {
        JointVector::from_fn(self.dof(), |i| self.joints[i].velocity)
    }

    pub fn acceleration_limits(&self) -> JointVector {
        JointVector::from_fn(self.dof(), |i| self.joints[i].acceleration)
    }

    /// Jerk limits, when the description gives one for every joint.
    pub fn jerk_limits(&self) -> Option<JointVector> {
        let jerks: Option<Vec<f64>> = self.joints.iter().map(|j| j.jerk).collect();
        jerks.map(|j| JointVector::from_slice(&j))
    }

    /// The home configuration.
    pub fn home(&self) -> JointVector {
        self.home
    }

    /// This arm with home `home` (within the joints' limits).
    pub fn with_home(mut self, home: JointVector) -> Result<Self, String> {
        if !self.within_limits(&home) {
            return Err(format!(
                "home {:?} is not within the joints' limits",
                &home[..]
            ));
        }
        self.home = home;
        Ok(self)
    }

    /// Whether `q` has one finite value per joint, each within its limits.
    pub fn within_limits(&self, q: &[f64]) -> bool {
        q.len() == self.dof()
            && q.iter()
                .zip(&self.joints)
                .all(|(v, j)| v.is_finite() && j.lower <= *v && *v <= j.upper)
    }

    /// The planning chain (base link to tip link).
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Link pairs the description leaves unchecked (besides parent/child).
    pub fn disabled_pairs(&self) -> &[(String, String)] {
        &self.disabled_pairs
    }

    /// Whether the closed-form UR solver serves this arm.
    pub fn has_closed_form_ik(&self) -> bool {
        matches!(self.solver, Solver::Ur(_))
    }

    /// World pose of every link at configuration `q`, in the arm's link
    /// order (see [`Arm::link_names`]).
    pub fn link_poses(&self, q: &[f64]) -> LinkPoses {
        let mut poses = LinkPoses::new();
        for l in &self.links {
            let parent = l.parent.map_or(self.base, |p| poses[p]);
            let mut pose = parent * l.origin;
            if let Some(m) = &l.motion {
                let value = m.multiplier * q[m.variable] + m.offset;
                if m.prismatic {
                    pose.translation.vector += pose.rotation * (m.axis.into_inner() * value);
                } else {
                    pose *= UnitQuaternion::from_axis_angle(&m.axis, value);
                }
            }
            poses.push(pose);
        }
        poses
    }

    /// Each joint's axis in the world at `poses` (from
    /// [`Self::link_poses`]): a point on it, its unit direction, and
    /// whether the joint slides along it rather than turning about it.
    pub fn joint_axes(&self, poses: &[Isometry3<f64>]) -> JointAxes {
        let mut axes: JointAxes = (0..self.dof())
            .map(|_| (Point3::origin(), Vector3::z(), false))
            .collect();
        for (l, link) in self.links.iter().enumerate() {
            if let Some(m) = &link.motion {
                axes[m.variable] = (
                    poses[l] * Point3::origin(),
                    poses[l].rotation * m.axis.into_inner(),
                    m.prismatic,
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
            if self.links[l].motion.is_some_and(|m| m.variable == joint) {
                return true;
            }
            k = self.links[l].parent;
        }
        false
    }

    /// Whether `link` moves rigidly with the tip (the tip, links welded to
    /// it, the tool): these may touch the branch the tool holds.
    pub fn carried_by_tip(&self, link: usize) -> bool {
        self.driving_link(link) == self.driving_link(self.tip)
    }

    /// Whether `link` never moves (the base and what is bolted to it).
    pub fn fixed_to_base(&self, link: usize) -> bool {
        self.driving_link(link).is_none()
    }

    /// The nearest link at or above `link` that a joint moves: links with
    /// the same one move rigidly together. (Comparing the sets of
    /// variables that move them would not do: a mimic joint moves the
    /// links below it with a variable that already moves those above.)
    fn driving_link(&self, link: usize) -> Option<usize> {
        let mut k = Some(link);
        while let Some(l) = k {
            if self.links[l].motion.is_some() {
                return Some(l);
            }
            k = self.links[l].parent;
        }
        None
    }

    /// Whether `variable` drives more than one joint (a mimic joint on the
    /// chain follows it). The edge checks then bound its motion by its
    /// lever arm, which sums every joint it drives, instead of by one
    /// joint's axis.
    pub fn drives_several_joints(&self, variable: usize) -> bool {
        self.links
            .iter()
            .filter(|l| l.motion.is_some_and(|m| m.variable == variable))
            .count()
            > 1
    }

    pub fn link_names(&self) -> impl Iterator<Item = &str> {
        self.links.iter().map(|l| l.name.as_str())
    }

    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.index.get(name).copied()
    }

    /// Collision shapes of each link, in link order.
    pub fn link_shapes(&self) -> impl Iterator<Item = (&str, &[Shape])> {
        self.links
            .iter()
            .map(|l| (l.name.as_str(), l.shapes.as_slice()))
    }

    /// Parent link of each link (`None` for the root), in link order.
    pub fn link_parent(&self, link: usize) -> Option<usize> {
        self.links[link].parent
    }

    /// The tip link's name.
    pub fn tip_link(&self) -> &str {
        &self.links[self.tip].name
    }

    /// The chain's base link's name.
    pub fn base_link(&self) -> &str {
        &self.links[0].name
    }

    pub fn tool_pose(&self, q: &[f64]) -> Isometry3<f64> {
        self.link_poses(q)[self.tool]
    }

    /// The added ⊔ gripper's link, if the arm carries one.
    pub fn gripper_link(&self) -> Option<usize> {
        self.gripper
    }

    /// How the tool's mount was chosen: `flange axis: joint ...` (a bare
    /// URDF's default), `frame NAME` (`tool=NAME`), `configured` (a
    /// robot configuration's `[tool]`), each possibly `adjusted by
    /// tool_xyz/tool_rpy`.
    pub fn tool_chosen(&self) -> &str {
        &self.tool_chosen
    }

    /// The tool frame in the tip link's frame.
    pub fn tool_in_tip(&self) -> Isometry3<f64> {
        self.links[self.tool].origin
    }
}

/// Per joint: a point on its axis, the axis, whether it is prismatic.
pub type JointAxes = smallvec::SmallVec<[(Point3<f64>, Vector3<f64>, bool); MAX_DOF]>;
