//! The ⊔ pusher tool every arm carries (the paper's gripper): a standoff
//! from the flange, a palm and two fingers around a slot that takes the
//! branch. Its boxes are in the flange frame (z out of the flange); the
//! tool frame is the palm's face, [`TOOL_OFFSET`] out along z.

use nalgebra::{Isometry3, Vector3};

use crate::geometry::shape::Shape;

/// The name of the tool frame's link.
pub const TOOL_LINK: &str = "tool";
/// The name of the link carrying the ⊔ gripper's boxes when they are
/// added to a description's tip.
pub const GRIPPER_LINK: &str = "gripper";

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

/// A box of the gripper, in the flange frame: centre and full size (m).
/// A table of numbers because it is a `const`; [`BoxSpec::shape`] is the
/// box as every other part of the planner sees one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxSpec {
    pub link: &'static str,
    pub centre: [f64; 3],
    pub size: [f64; 3],
}

impl BoxSpec {
    /// The box as a [`Shape`] in the flange frame.
    pub fn shape(&self) -> Shape {
        Shape::Box {
            pose: Isometry3::translation(self.centre[0], self.centre[1], self.centre[2]),
            half_extents: Vector3::from(self.size) / 2.0,
        }
    }
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
