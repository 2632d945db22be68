//! The tool's straight lines, by IK steps: the push itself, the retreat
//! after it, and the test pushes that score a base stance. Kinematics
//! only: whether a step is free is the caller's question (a closure), so
//! the same walk serves the planner (against the tree and obstacles) and
//! [`crate::robot::arm::BaseStance`] scoring (against nothing).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::robot::Arm;
use crate::robot::model::joint_vector::JointVector;

/// The tool starts this far behind the gripper point along the push (m).
pub const APPROACH_OFFSET: f64 = 0.05;
/// Spacing of the IK/collision checks along the push (m).
pub const PUSH_STEP: f64 = 0.005;
/// Largest joint change between two push steps (rad); more means the arm
/// would have to jump to another IK branch.
pub const PUSH_MAX_JOINT_STEP: f64 = 0.15;

/// A tool pose and the same pose turned half a turn about the push axis
/// (its z): the ⊔ slot holds a branch either way round, and a last joint
/// of less than a full turn reaches only one of them, so every push (the
/// planner's pre-contact poses, a stance's test pushes) is tried both ways.
pub fn either_way_round(pose: Isometry3<f64>) -> [Isometry3<f64>; 2] {
    let flipped = pose * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI);
    [pose, flipped]
}

/// The tool's straight line from `goal` along `direction` at constant
/// orientation: IK at `distance(k)` for k = 1..=steps, each solution
/// continuous with the last (no joint moves more than `max_jump`) and
/// accepted by `step_free(previous, next, distance)`; `goal` first, up to
/// the first step that fails.
pub fn tool_line(
    arm: &Arm,
    goal: &JointVector,
    direction: &Vector3<f64>,
    steps: usize,
    distance: &dyn Fn(usize) -> f64,
    max_jump: f64,
    step_free: &dyn Fn(&JointVector, &JointVector, f64) -> bool,
) -> Vec<JointVector> {
    let start_pose = arm.tool_pose(goal);
    let mut line = vec![*goal];
    for k in 1..=steps {
        let distance = distance(k);
        let pose = Isometry3::from_parts(
            Translation3::from(start_pose.translation.vector + direction * distance),
            start_pose.rotation,
        );
        let previous = *line.last().expect("non-empty");
        let Some(next) = arm.inverse_kinematics_near(&pose, &previous) else {
            break;
        };
        let jump = next.max_abs_diff(&previous);
        if jump > max_jump || !step_free(&previous, &next, distance) {
            break;
        }
        line.push(next);
    }
    line
}

/// Joint configurations along the straight push from `goal`, every
/// [`PUSH_STEP`], or `None` when IK breaks (no solution, or a jump to
/// another IK branch) or `edge_free(from, to, distance travelled)` refuses
/// a step.
pub fn push_line(
    arm: &Arm,
    edge_free: &dyn Fn(&JointVector, &JointVector, f64) -> bool,
    goal: &JointVector,
    direction: &Vector3<f64>,
    travel: f64,
) -> Option<Vec<JointVector>> {
    let steps = (travel / PUSH_STEP).ceil() as usize;
    let line = tool_line(
        arm,
        goal,
        direction,
        steps,
        &|k| travel * k as f64 / steps as f64,
        PUSH_MAX_JOINT_STEP,
        edge_free,
    );
    (line.len() == steps + 1).then_some(line)
}
