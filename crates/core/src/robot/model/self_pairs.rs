//! Which pairs of an arm's links never need a self-collision check, found
//! the way MoveIt's setup assistant finds them.
//!
//! - **adjacent**: links joined by a joint (and links welded together by
//!   fixed joints count as one link, so their neighbours are adjacent to
//!   every one of them): their shapes overlap at the joint by design;
//! - **never**: no collision at any of `samples` random configurations
//!   inside the joint limits (the pair cannot reach each other);
//! - **always**: a collision at every sample (the shapes overlap whatever
//!   the joints do: a checker would refuse every configuration);
//! - **default**: a collision at the chain's default configuration (zero,
//!   clamped into the limits), as MoveIt's setup assistant disables them:
//!   fitted capsules that touch where the arm was drawn (the UR3's base
//!   housing and upper arm, whose meshes nearly touch there) would refuse
//!   the arm's own rest pose;
//! - **often**: a collision in at least [`OFTEN`] of the samples, MoveIt's
//!   default "often in collision" (95 %): fitted shapes that overlap in
//!   nearly every pose (a base housing and the upper arm two joints on)
//!   would otherwise refuse nearly every configuration.
//!
//! Every other pair collides at some configurations and not at others and
//! stays checked. Joints off the chain (fingers, a gripper) stay at zero,
//! as the planner holds them; a `mimic` joint follows its leader.

use std::collections::HashMap;

use nalgebra::{Isometry3, Vector3};
use parry3d_f64::math::Pose;
use parry3d_f64::shape::Shape as ParryShape;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::geometry::convert::pose;
use crate::geometry::shape::Shape;
use crate::robot::model::urdf_chain::{Chain, isometry, random_configuration};

use crate::robot::model::link_geometry::LinkGeometry;

/// Why a pair is not checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DisableReason {
    Adjacent,
    Never,
    Always,
    /// In collision in at least [`OFTEN`] of the samples.
    Often,
    /// In collision at the chain's default configuration.
    Default,
    /// Named in the robot's configuration.
    Configured,
    /// Named in the robot's SRDF.
    Srdf,
}

/// The share of samples in collision above which a pair is disabled as
/// [`DisableReason::Often`] (MoveIt setup assistant's default).
pub const OFTEN: f64 = 0.95;

/// How close two links may be at the default configuration before the
/// pair counts as touching there (m): the clearance the planner keeps
/// between an arm's own links (`robot::collision`'s `SELF_CLEARANCE`).
pub const REST_CLEARANCE: f64 = 0.001;

/// A pair of links left out of self-collision checks.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DisabledPair {
    pub a: String,
    pub b: String,
    pub reason: DisableReason,
}

/// A test of two placed parry shapes (touching, or within a distance).
type ShapeTest = dyn Fn(&Pose, &dyn ParryShape, &Pose, &dyn ParryShape) -> bool;

/// Parry shapes, each with its pose in its link's frame.
type PlacedShapes = Vec<(Isometry3<f64>, Box<dyn ParryShape>)>;

/// A link's shapes as parry shapes, each with its pose in the link frame.
fn parry_shapes(shapes: &[Shape]) -> PlacedShapes {
    shapes.iter().map(Shape::parry_in_frame).collect()
}

/// A URDF joint ready to be placed: its origin, its motion per unit of
/// value, and where its value comes from.
struct PlacedJoint<'a> {
    child: &'a str,
    origin: Isometry3<f64>,
    kind: urdf_rs::JointType,
    axis: Vector3<f64>,
    /// Its value: multiplier × the chain variable it follows (itself, or
    /// its mimic leader; none off the chain, which holds it at zero) +
    /// offset.
    source: (Option<usize>, f64, f64),
}

/// The URDF's link tree, read once, placing every link for any
/// configuration of the chain (joints off the chain at zero, mimic joints
/// following their leader).
pub struct LinkTree<'a> {
    roots: Vec<&'a str>,
    children: HashMap<&'a str, Vec<PlacedJoint<'a>>>,
}

impl<'a> LinkTree<'a> {
    pub fn new(robot: &'a urdf_rs::Robot, chain: &Chain) -> Self {
        let variable = |name: &str| {
            chain
                .joints
                .iter()
                .find(|j| j.name == name)
                .and_then(|j| j.variable)
        };
        let is_child: std::collections::HashSet<&str> =
            robot.joints.iter().map(|j| j.child.link.as_str()).collect();
        let mut children: HashMap<&str, Vec<PlacedJoint>> = HashMap::new();
        for j in &robot.joints {
            let axis = Vector3::from(j.axis.xyz.0);
            let source = match &j.mimic {
                Some(m) => (
                    variable(&m.joint),
                    m.multiplier.unwrap_or(1.0),
                    m.offset.unwrap_or(0.0),
                ),
                None => (variable(&j.name), 1.0, 0.0),
            };
            children
                .entry(j.parent.link.as_str())
                .or_default()
                .push(PlacedJoint {
                    child: j.child.link.as_str(),
                    origin: isometry(&j.origin),
                    kind: j.joint_type.clone(),
                    axis: if axis.norm() > 0.0 {
                        axis.normalize()
                    } else {
                        Vector3::x()
                    },
                    source,
                });
        }
        Self {
            roots: robot
                .links
                .iter()
                .map(|l| l.name.as_str())
                .filter(|l| !is_child.contains(l))
                .collect(),
            children,
        }
    }

    /// Every link's pose (relative to the URDF's root) at the chain's
    /// configuration `q`; links not reached from the root are left out.
    pub fn poses(&self, q: &[f64]) -> HashMap<String, Isometry3<f64>> {
        let mut poses = HashMap::new();
        let mut stack: Vec<(&str, Isometry3<f64>)> = self
            .roots
            .iter()
            .map(|l| (*l, Isometry3::identity()))
            .collect();
        while let Some((link, pose)) = stack.pop() {
            if poses.insert(link.to_owned(), pose).is_some() {
                continue;
            }
            for j in self.children.get(link).into_iter().flatten() {
                let (variable, multiplier, offset) = j.source;
                let value =
                    variable.and_then(|v| q.get(v)).copied().unwrap_or(0.0) * multiplier + offset;
                let motion = match j.kind {
                    urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                        Isometry3::rotation(j.axis * value)
                    }
                    urdf_rs::JointType::Prismatic => {
                        Isometry3::translation(j.axis.x * value, j.axis.y * value, j.axis.z * value)
                    }
                    _ => Isometry3::identity(),
                };
                stack.push((j.child, pose * j.origin * motion));
            }
        }
        poses
    }
}

/// Every link's pose at the chain's configuration `q` (see
/// [`LinkTree::poses`]; build a [`LinkTree`] once to place many).
pub fn all_link_poses(
    robot: &urdf_rs::Robot,
    chain: &Chain,
    q: &[f64],
) -> HashMap<String, Isometry3<f64>> {
    LinkTree::new(robot, chain).poses(q)
}

/// Groups of links welded by fixed joints: each link's group index.
fn welded_groups(robot: &urdf_rs::Robot) -> HashMap<String, usize> {
    let mut group: HashMap<String, usize> = robot
        .links
        .iter()
        .enumerate()
        .map(|(k, l)| (l.name.clone(), k))
        .collect();
    // Merge until stable (a handful of passes for any real arm).
    loop {
        let mut changed = false;
        for j in &robot.joints {
            if j.joint_type == urdf_rs::JointType::Fixed {
                let (a, b) = (group[&j.parent.link], group[&j.child.link]);
                if a != b {
                    let (keep, drop) = (a.min(b), a.max(b));
                    for g in group.values_mut() {
                        if *g == drop {
                            *g = keep;
                        }
                    }
                    changed = true;
                }
            }
        }
        if !changed {
            return group;
        }
    }
}

/// The pairs of links with collision geometry that need no check (see the
/// module's documentation), over `samples` random configurations of
/// `chain` drawn with `seed`.
pub fn disabled_pairs(
    robot: &urdf_rs::Robot,
    chain: &Chain,
    geometry: &[LinkGeometry],
    samples: usize,
    seed: u64,
) -> Vec<DisabledPair> {
    let group = welded_groups(robot);
    let adjacent = |a: &str, b: &str| {
        let (ga, gb) = (group.get(a), group.get(b));
        ga == gb
            || robot.joints.iter().any(|j| {
                let (p, c) = (group.get(&j.parent.link), group.get(&j.child.link));
                (p == ga && c == gb) || (p == gb && c == ga)
            })
    };
    let shapes: Vec<(&str, PlacedShapes)> = geometry
        .iter()
        .filter(|l| !l.shapes.is_empty())
        .map(|l| (l.link.as_str(), parry_shapes(&l.shapes)))
        .collect();
    let mut out = Vec::new();
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    for i in 0..shapes.len() {
        for k in i + 1..shapes.len() {
            if adjacent(shapes[i].0, shapes[k].0) {
                out.push(DisabledPair {
                    a: shapes[i].0.to_owned(),
                    b: shapes[k].0.to_owned(),
                    reason: DisableReason::Adjacent,
                });
            } else {
                pairs.push((i, k));
            }
        }
    }
    let mut hits = vec![0usize; pairs.len()];
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let links = LinkTree::new(robot, chain);
    // Whether any shape of link i and any of link k pass `test`, placed
    // at `poses`.
    let any_shapes =
        |poses: &HashMap<String, Isometry3<f64>>, i: usize, k: usize, test: &ShapeTest| {
            let (Some(pi), Some(pk)) = (poses.get(shapes[i].0), poses.get(shapes[k].0)) else {
                return false;
            };
            shapes[i].1.iter().any(|(oi, si)| {
                shapes[k].1.iter().any(|(ok, sk)| {
                    test(
                        &pose(&(pi * oi)),
                        si.as_ref(),
                        &pose(&(pk * ok)),
                        sk.as_ref(),
                    )
                })
            })
        };
    let touching = |poses: &HashMap<String, Isometry3<f64>>, i: usize, k: usize| {
        any_shapes(poses, i, k, &|a, sa, b, sb| {
            parry3d_f64::query::intersection_test(a, sa, b, sb)
                // An unsupported pair counts as touching: the pair then
                // stays checked unless it always touches.
                .map_or(true, |hit| hit.intersecting)
        })
    };
    for _ in 0..samples {
        let q = random_configuration(chain, &mut rng);
        let poses = links.poses(&q);
        for (n, &(i, k)) in pairs.iter().enumerate() {
            hits[n] += usize::from(touching(&poses, i, k));
        }
    }
    // At rest, a pair counts as touching within the clearance the planner
    // keeps between an arm's own links.
    let near_at_rest = |poses: &HashMap<String, Isometry3<f64>>, i: usize, k: usize| {
        any_shapes(poses, i, k, &|a, sa, b, sb| {
            parry3d_f64::query::distance(a, sa, b, sb)
                .map_or(true, |d| d.distance <= REST_CLEARANCE)
        })
    };
    let rest: Vec<f64> = chain
        .limits()
        .iter()
        .map(|(lo, hi)| 0f64.clamp(*lo, *hi))
        .collect();
    let at_rest = links.poses(&rest);
    // With no samples, nothing is known of the other pairs: all stay checked.
    for (&(i, k), &h) in pairs.iter().zip(&hits).filter(|_| samples > 0) {
        let reason = match h {
            0 => DisableReason::Never,
            h if h == samples => DisableReason::Always,
            h if h as f64 >= OFTEN * samples as f64 => DisableReason::Often,
            _ if near_at_rest(&at_rest, i, k) => DisableReason::Default,
            _ => continue,
        };
        out.push(DisabledPair {
            a: shapes[i].0.to_owned(),
            b: shapes[k].0.to_owned(),
            reason,
        });
    }
    out
}
