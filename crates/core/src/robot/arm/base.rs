//! Where an arm stands: the paper's mount, every arm's default base unless
//! set ([`crate::robot::Arm::default_base`]), and a mobile base's stance
//! relative to the grip point ([`crate::robot::Arm::stances`]).

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

/// The paper's mount: `base_link` at (−0.5, 0, 0.1) m from the tree root,
/// identity orientation.
pub const PAPER_BASE: Isometry3<f64> = Isometry3::from_parts(
    Translation3::new(-0.5, 0.0, 0.1),
    UnitQuaternion::new_unchecked(Quaternion::new(1.0, 0.0, 0.0, 0.0)),
);

/// Where a mobile base stands for a push, relative to the grip point:
/// the horizontal distance from the base to the grip point, and the grip
/// point's height above the base (m). Scored per arm by `Arm::stances`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseStance {
    pub stand_off: f64,
    pub height: f64,
}
