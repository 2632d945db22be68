//! Where the ⊔ tool goes on an arm known only from its URDF.
//!
//! By default ([`flange_axis`]) the push axis is the last revolute joint's
//! axis, pointing away from the arm, and the tool's mount sits on that axis
//! just past every link the joint carries (the flange, a hand, its fingers:
//! their collision geometry's extent along the axis), so the gripper never
//! starts inside the wrist. Which way is "away": away from the joint
//! before it where the wrist offsets the last joint along its own axis
//! (xArm, Z1); where it does not (the URs, the Panda: the offset is across
//! the axis), the side the carried geometry extends further to (the hand
//! hangs off the flange, not back into the forearm). [`frame`] instead puts the mount on a
//! URDF frame the tip carries (`tool=tool0`), its z the push axis. Either
//! can be turned and moved further by `tool_xyz`/`tool_rpy`
//! ([`adjusted`]). Each answer says how it was chosen, which `GET
//! /v1/robots` and `treemanip robot check` report.

use std::collections::HashMap;

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::robot::model::link_geometry::LinkGeometry;
use crate::robot::model::urdf_chain::{Chain, JointKind};

/// The smallest offset of the last joint from the one before it, along
/// its axis, that says which way the wrist points (m).
const WRIST_OFFSET: f64 = 0.01;

/// How a robot configuration places the tool: as its `[tool]` table says
/// (or the tip's origin, without one), on the last joint's axis, or on a
/// named frame; then optionally moved (`tool_xyz`, `tool_rpy`).
#[derive(Debug, Clone, Default, PartialEq)]
pub enum ToolChoice {
    #[default]
    Configured,
    FlangeAxis,
    Frame(String),
}

/// A tool mount in the tip link's frame, and how it was chosen.
#[derive(Debug, Clone, PartialEq)]
pub struct ChosenMount {
    pub mount: Isometry3<f64>,
    pub how: String,
}

/// Every link below `link` in the URDF's tree, `link` included.
fn carried_by<'a>(robot: &'a urdf_rs::Robot, link: &'a str) -> Vec<&'a str> {
    let mut out = vec![link];
    let mut k = 0;
    while k < out.len() {
        let parent = out[k];
        out.extend(
            robot
                .joints
                .iter()
                .filter(|j| j.parent.link == parent)
                .map(|j| j.child.link.as_str()),
        );
        k += 1;
    }
    out
}

/// The mount on the last revolute joint's axis, past what that joint
/// carries (see the module's documentation). `poses` are every link's
/// world pose at one configuration (any: what the joint carries is rigid).
pub fn flange_axis(
    robot: &urdf_rs::Robot,
    chain: &Chain,
    geometry: &[LinkGeometry],
    poses: &HashMap<String, Isometry3<f64>>,
) -> Result<ChosenMount, String> {
    let turning: Vec<_> = chain
        .joints
        .iter()
        .filter(|j| j.variable.is_some() && j.kind != JointKind::Prismatic)
        .collect();
    let last = turning
        .last()
        .ok_or_else(|| "the chain has no revolute joint to push along".to_owned())?;
    let at = poses
        .get(&last.child_link)
        .ok_or_else(|| format!("link `{}` is not placed", last.child_link))?;
    let point = at * Point3::origin();
    let axis = at.rotation * last.axis.into_inner();
    // How far what the joint carries reaches along its axis, each way.
    let carried = carried_by(robot, &last.child_link);
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for g in geometry
        .iter()
        .filter(|g| carried.contains(&g.link.as_str()))
    {
        let Some(pose) = poses.get(&g.link) else {
            continue;
        };
        for shape in &g.shapes {
            let ([a, b], pad) = shape.bounding_points(pose, 0.0);
            for p in [a, b] {
                let t = (p - point).dot(&axis);
                lo = lo.min(t - pad);
                hi = hi.max(t + pad);
            }
        }
    }
    // Away from the joint before it, where the wrist offsets the last
    // joint along its own axis (the flange then sits out along it);
    // else the side the carried geometry reaches further to (a hand hangs
    // off the flange); else along the axis.
    let before = turning
        .len()
        .checked_sub(2)
        .and_then(|k| poses.get(&turning[k].child_link))
        .map(|p| (point - p * Point3::origin()).dot(&axis));
    let sign = match before {
        Some(d) if d.abs() > WRIST_OFFSET => d.signum(),
        _ if -lo > hi + 1e-9 => -1.0,
        _ => 1.0,
    };
    let z = axis * sign;
    let extent = if sign > 0.0 { hi } else { -lo };
    let origin = point + z * extent.max(0.0);
    let tip = poses
        .get(&chain.tip_link)
        .ok_or_else(|| format!("link `{}` is not placed", chain.tip_link))?;
    // The slot's x: the tip's x (else y) made square to the push axis; the
    // last joint turns the tool about z, so any choice serves.
    let x = [tip.rotation * Vector3::x(), tip.rotation * Vector3::y()]
        .into_iter()
        .map(|v| v - z * v.dot(&z))
        .find(|v| v.norm() > 1e-6)
        .map(|v| v.normalize())
        .unwrap_or_else(|| z.cross(&Vector3::z()).normalize());
    let y = z.cross(&x);
    let world = Isometry3::from_parts(
        Translation3::from(origin.coords),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
            Matrix3::from_columns(&[x, y, z]),
        )),
    );
    Ok(ChosenMount {
        mount: tip.inverse() * world,
        how: format!(
            "flange axis: joint `{}`, {:.3} m past it, {} its axis",
            last.name,
            extent.max(0.0),
            if sign > 0.0 { "along" } else { "against" }
        ),
    })
}

/// The mount on URDF frame `name`, which the tip must carry (the tip
/// itself, or a link below it: `tool0`, a flange).
pub fn frame(
    robot: &urdf_rs::Robot,
    chain: &Chain,
    poses: &HashMap<String, Isometry3<f64>>,
    name: &str,
) -> Result<ChosenMount, String> {
    if !carried_by(robot, &chain.tip_link).contains(&name) {
        return Err(format!(
            "tool={name}: `{name}` is not the tip `{}` or a link it carries",
            chain.tip_link
        ));
    }
    let (Some(tip), Some(at)) = (poses.get(&chain.tip_link), poses.get(name)) else {
        return Err(format!("tool={name}: the link is not placed"));
    };
    Ok(ChosenMount {
        mount: tip.inverse() * at,
        how: format!("frame {name}"),
    })
}

/// `chosen` moved by `xyz` and turned by `rpy` (URDF's roll, pitch, yaw)
/// in its own frame.
pub fn adjusted(chosen: ChosenMount, xyz: [f64; 3], rpy: [f64; 3]) -> ChosenMount {
    let by = Isometry3::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    );
    ChosenMount {
        mount: chosen.mount * by,
        how: format!("{}, adjusted by tool_xyz/tool_rpy", chosen.how),
    }
}
