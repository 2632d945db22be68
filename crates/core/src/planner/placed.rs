//! The planner and the arm it places: [`Planner`] holds the arm's
//! collision geometry, built once; `Placed` is that arm moved to one
//! base, with its start configuration.

use nalgebra::Isometry3;

use crate::planner::base::BasePose;
use crate::robot::Arm;
use crate::robot::collision::CollisionModel;
use crate::robot::motion::rrt::Config;

/// The arm's collision geometry, built once, moved to each request's base.
pub struct Planner {
    arm: CollisionModel,
}

impl Default for Planner {
    fn default() -> Self {
        Self::new(CollisionModel::new(Arm::default()))
    }
}

/// An arm placed at one base with its start configuration.
pub(crate) struct Placed {
    pub(crate) pose: BasePose,
    pub(crate) arm: CollisionModel,
    pub(crate) start: Config,
}

impl Planner {
    pub fn new(arm: CollisionModel) -> Self {
        Self { arm }
    }

    /// The arm's kinematics and shapes (at its default base).
    pub fn robot(&self) -> &Arm {
        &self.arm.robot
    }

    pub(crate) fn placed_at(&self, base: &Isometry3<f64>) -> CollisionModel {
        let mut arm = self.arm.clone();
        arm.robot = arm.robot.clone().with_base(*base);
        arm
    }
}
