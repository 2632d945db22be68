//! Where a mobile arm should stand for a push: a few base poses behind the
//! grip point along the push, within the allowed region, each turned to
//! face the grip point (the way the paper's fixed mount faces the tree).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use crate::robot::motion::rrt::Config;
use crate::robot::{Arm, UR5_REACH};
use crate::sim::{GRIP_OFFSET, Push};
use crate::tree::Tree;

/// The box of allowed base positions (m, tree frame) and, optionally, of
/// base headings about the vertical axis (rad).
#[derive(Debug, Clone, PartialEq)]
pub struct BaseRegion {
    pub min: Vector3<f64>,
    pub max: Vector3<f64>,
    pub yaw: Option<(f64, f64)>,
}

/// Where the arm's `base_link` stands and how it is turned: `yaw` about
/// the vertical axis, and for a tilted or hanging mount `roll` and `pitch`
/// (rad; the URDF's fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch)
/// Rx(roll)).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BasePose {
    /// m, tree frame.
    pub position: [f64; 3],
    /// Rotation about the vertical axis (rad).
    pub yaw: f64,
    /// Tilt about the base's x axis (rad; 0 upright, π hanging).
    pub roll: f64,
    /// Tilt about the base's y axis (rad).
    pub pitch: f64,
}

impl BasePose {
    /// An upright base at `position` turned by `yaw`.
    pub fn upright(position: [f64; 3], yaw: f64) -> Self {
        Self {
            position,
            yaw,
            roll: 0.0,
            pitch: 0.0,
        }
    }

    pub fn isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(Vector3::from(self.position)),
            UnitQuaternion::from_euler_angles(self.roll, self.pitch, self.yaw),
        )
    }

    /// The pose of a base given as an isometry.
    pub fn of(iso: &Isometry3<f64>) -> Self {
        let t = iso.translation.vector;
        let (roll, pitch, yaw) = iso.rotation.euler_angles();
        // An upright base reads exactly 0 (not −0.0 or 1e-17).
        let tidy = |a: f64| if a.abs() < 1e-12 { 0.0 } else { a };
        Self {
            position: [t.x, t.y, t.z],
            yaw,
            roll: tidy(roll),
            pitch: tidy(pitch),
        }
    }
}

/// Sideways offsets (m, UR5 scale) across the push.
const SIDEWAYS: [f64; 3] = [0.0, 0.2, -0.2];

/// Candidate base poses for `push` by `arm`: its [`Arm::stances`] behind
/// the grip point along the push, each straight behind it and to either
/// side, most promising first, all inside `region` (duplicates after
/// clamping removed).
pub fn proposals(region: &BaseRegion, tree: &Tree, push: &Push, arm: &Arm) -> Vec<BasePose> {
    let scale = arm.reach() / UR5_REACH;
    let Some(branch) = tree.branch_direction(push.node) else {
        return Vec::new();
    };
    let grip = tree.position(push.node) - branch * GRIP_OFFSET;
    let mut ahead = Vector3::new(push.vector.x, push.vector.y, 0.0);
    if ahead.norm() < 1e-6 {
        // A vertical push: stand on the grip point's side of the trunk.
        ahead = -Vector3::new(grip.x, grip.y, 0.0);
        if ahead.norm() < 1e-6 {
            ahead = Vector3::x();
        }
    }
    let ahead = ahead.normalize();
    let across = Vector3::z().cross(&ahead);
    let mut out: Vec<BasePose> = Vec::new();
    for stance in arm.stances() {
        for &side in &SIDEWAYS {
            let wanted = grip.coords - ahead * stance.stand_off + across * (side * scale)
                - Vector3::z() * stance.height;
            let position = wanted.sup(&region.min).inf(&region.max);
            let facing = grip.coords - position;
            let mut yaw = facing.y.atan2(facing.x);
            if let Some((lo, hi)) = region.yaw {
                yaw = yaw.clamp(lo, hi);
            }
            let pose = BasePose::upright([position.x, position.y, position.z], yaw);
            let duplicate = out.iter().any(|b| {
                (Vector3::from(b.position) - position).norm() < 0.02 && (b.yaw - yaw).abs() < 0.05
            });
            if !duplicate {
                out.push(pose);
            }
        }
    }
    out
}

/// Start configurations tried when the request gives none: the arm's home,
/// then (for UR kinematics) the arm folded up and back from the tree, then
/// (any arm) home turned about the first joint away from the tree (a half
/// turn, or as far as the joint allows) or a quarter turn either way.
pub fn tucked_starts(arm: &crate::robot::Arm) -> Vec<Config> {
    use std::f64::consts::{FRAC_PI_2, PI};
    let home = arm.home();
    let mut out = vec![home];
    if arm.has_closed_form_ik() {
        out.push(Config::from([
            0.0,
            -FRAC_PI_2,
            2.6,
            -PI / 2.0 - 0.5,
            -FRAC_PI_2,
            0.0,
        ]));
        out.push(Config::from([
            PI,
            -FRAC_PI_2,
            2.6,
            -PI / 2.0 - 0.5,
            -FRAC_PI_2,
            0.0,
        ]));
    }
    // Every arm: home turned about its first joint (a small arm's base
    // stands close enough that its home and folds can all touch the tree).
    let (lo, hi) = arm.limits()[0];
    for turn in [PI, -PI, FRAC_PI_2, -FRAC_PI_2] {
        let mut q = home;
        q[0] = (q[0] + turn).clamp(lo, hi);
        if out.iter().all(|o| o.max_abs_diff(&q) > 0.1) {
            out.push(q);
        }
    }
    out.retain(|q| arm.within_limits(q));
    out
}
