//! What a plan answers about the arm's motion and the pushes it weighed:
//! the strategy, the base pose, the timed path, the ROS 2 controller
//! trajectory, every attempt and its outcome, the limits and the
//! clearance. Wire mirrors of core types, converted with `From`, so that a
//! change in the library never changes the answer by itself.

use serde::{Deserialize, Serialize};
use treemanip_core::planner::base::BasePose;
use treemanip_core::planner::{Attempt, Clearance, Limits, Strategy};
use treemanip_core::robot::motion::push_motion::Outcome;
use treemanip_core::robot::motion::ros::{JointTrajectory, JointTrajectoryPoint, RosDuration};
use utoipa::ToSchema;

use crate::api::types::objective::LoadsJson;
use crate::api::types::schema::{Joints, Vec3};

/// How the push is chosen: `model` (search with the forward GNN, the
/// default), `physics` (search with the simulator), `paper` (Algorithm 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = Strategy)]
pub enum StrategyJson {
    #[default]
    Model,
    Physics,
    Paper,
}

impl From<StrategyJson> for Strategy {
    fn from(s: StrategyJson) -> Self {
        match s {
            StrategyJson::Model => Strategy::Model,
            StrategyJson::Physics => Strategy::Physics,
            StrategyJson::Paper => Strategy::Paper,
        }
    }
}

impl From<Strategy> for StrategyJson {
    fn from(s: Strategy) -> Self {
        match s {
            Strategy::Model => StrategyJson::Model,
            Strategy::Physics => StrategyJson::Physics,
            Strategy::Paper => StrategyJson::Paper,
        }
    }
}

/// Where the arm's `base_link` stands (m) and how it is turned (rad).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, ToSchema)]
#[schema(as = BasePose)]
pub struct BasePoseJson {
    #[schema(value_type = Vec3)]
    pub position: [f64; 3],
    /// rad about the vertical axis.
    pub yaw: f64,
    /// rad about the base's x axis (0 upright, π hanging);
    /// R = Rz(yaw) Ry(pitch) Rx(roll).
    pub roll: f64,
    /// rad about the base's y axis.
    pub pitch: f64,
}

impl From<BasePose> for BasePoseJson {
    fn from(b: BasePose) -> Self {
        Self {
            position: b.position,
            yaw: b.yaw,
            roll: b.roll,
            pitch: b.pitch,
        }
    }
}

/// One point of the planned motion: time (s) and joint positions, as the
/// controller trajectory has them (`joint_trajectory.points`).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
#[schema(as = TimedPoint)]
pub struct TimedPointJson {
    /// s.
    pub t: f64,
    #[schema(value_type = Joints)]
    pub q: Vec<f64>,
}

impl From<&JointTrajectoryPoint> for TimedPointJson {
    fn from(p: &JointTrajectoryPoint) -> Self {
        Self {
            t: p.time_from_start.as_secs(),
            q: p.positions.clone(),
        }
    }
}

/// `builtin_interfaces/Duration`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[schema(as = RosDuration)]
pub struct RosDurationJson {
    pub sec: i32,
    #[schema(minimum = 0, maximum = 999999999)]
    pub nanosec: u32,
}

/// `trajectory_msgs/JointTrajectoryPoint`.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
#[schema(as = JointTrajectoryPoint)]
pub struct JointTrajectoryPointJson {
    /// rad (m for a prismatic joint).
    pub positions: Vec<f64>,
    /// rad/s.
    pub velocities: Vec<f64>,
    /// rad/s².
    pub accelerations: Vec<f64>,
    pub time_from_start: RosDurationJson,
}

/// ROS 2 `trajectory_msgs/msg/JointTrajectory` without its header: the
/// whole held push (approach, straight push, hold, release, retreat),
/// velocity-continuous, within every joint's velocity and acceleration
/// limit; the approach's waypoints blended when the blended path is
/// collision-free.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
#[schema(as = JointTrajectory)]
pub struct JointTrajectoryJson {
    pub joint_names: Vec<String>,
    pub points: Vec<JointTrajectoryPointJson>,
}

impl From<RosDuration> for RosDurationJson {
    fn from(d: RosDuration) -> Self {
        Self {
            sec: d.sec,
            nanosec: d.nanosec,
        }
    }
}

impl From<&JointTrajectoryPoint> for JointTrajectoryPointJson {
    fn from(p: &JointTrajectoryPoint) -> Self {
        Self {
            positions: p.positions.clone(),
            velocities: p.velocities.clone(),
            accelerations: p.accelerations.clone(),
            time_from_start: p.time_from_start.into(),
        }
    }
}

impl From<&JointTrajectory> for JointTrajectoryJson {
    fn from(t: &JointTrajectory) -> Self {
        Self {
            joint_names: t.joint_names.clone(),
            points: t.points.iter().map(Into::into).collect(),
        }
    }
}

/// Why a push was or was not planned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = Outcome)]
pub enum OutcomeJson {
    /// Carried out: this is the plan.
    Planned,
    /// Not a push that can be made (the root, a zero push, along the branch).
    InvalidCandidate,
    /// No IK solution for the pre-contact pose.
    Unreachable,
    /// Every IK solution of the pre-contact pose collides.
    GoalInCollision,
    /// No pre-contact solution carries out the straight push.
    PushInfeasible,
    /// RRT* found no approach within its budget.
    NoPath,
    /// A path, but no controller trajectory within the joints' limits.
    NoTrajectory,
    /// A budget ran out before it.
    Skipped,
    /// Predicted no better than doing nothing.
    NotHelpful,
    /// The start collides at this base.
    StartInCollision,
    /// Predicted or simulated over a load limit.
    OverLimit,
    /// Simulated to miss the `clear` or `reach` it was predicted to meet.
    Missed,
}

impl From<Outcome> for OutcomeJson {
    fn from(o: Outcome) -> Self {
        match o {
            Outcome::Planned => OutcomeJson::Planned,
            Outcome::InvalidCandidate => OutcomeJson::InvalidCandidate,
            Outcome::Unreachable => OutcomeJson::Unreachable,
            Outcome::GoalInCollision => OutcomeJson::GoalInCollision,
            Outcome::PushInfeasible => OutcomeJson::PushInfeasible,
            Outcome::NoPath => OutcomeJson::NoPath,
            Outcome::NoTrajectory => OutcomeJson::NoTrajectory,
            Outcome::Skipped => OutcomeJson::Skipped,
            Outcome::NotHelpful => OutcomeJson::NotHelpful,
            Outcome::StartInCollision => OutcomeJson::StartInCollision,
            Outcome::OverLimit => OutcomeJson::OverLimit,
            Outcome::Missed => OutcomeJson::Missed,
        }
    }
}

impl OutcomeJson {
    /// The outcome's name on the wire (`no_path`, ...).
    pub fn name(self) -> &'static str {
        match self {
            OutcomeJson::Planned => "planned",
            OutcomeJson::InvalidCandidate => "invalid_candidate",
            OutcomeJson::Unreachable => "unreachable",
            OutcomeJson::GoalInCollision => "goal_in_collision",
            OutcomeJson::PushInfeasible => "push_infeasible",
            OutcomeJson::NoPath => "no_path",
            OutcomeJson::NoTrajectory => "no_trajectory",
            OutcomeJson::Skipped => "skipped",
            OutcomeJson::NotHelpful => "not_helpful",
            OutcomeJson::StartInCollision => "start_in_collision",
            OutcomeJson::OverLimit => "over_limit",
            OutcomeJson::Missed => "missed",
        }
    }
}

/// One push the planner looked at, and what became of it.
#[derive(Debug, Clone, Serialize, ToSchema)]
#[schema(as = Attempt)]
pub struct AttemptJson {
    pub node: usize,
    /// The node's rank among the proposed pushes (the policy's, or the
    /// geometry's for other objectives than a full shape).
    pub rank: usize,
    #[schema(value_type = Vec3)]
    pub push: [f64; 3],
    pub outcome: OutcomeJson,
    /// The objective's predicted residual after this push (m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_error: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_loads: Option<LoadsJson>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub simulated_loads: Option<LoadsJson>,
    /// Time spent on it (ms).
    pub ms: f64,
}

impl From<&Attempt> for AttemptJson {
    fn from(a: &Attempt) -> Self {
        Self {
            node: a.node,
            rank: a.rank,
            push: a.push,
            outcome: a.outcome.into(),
            predicted_error: a.predicted_error,
            predicted_loads: a.predicted_loads.map(|l| LoadsJson::new(&l, None)),
            simulated_loads: a.simulated_loads.map(|l| LoadsJson::new(&l, None)),
            ms: a.ms,
        }
    }
}

/// The load limits enforced (Pa, N).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, ToSchema)]
#[schema(as = LimitsEnforced)]
pub struct LimitsAnswer {
    /// Pa.
    pub max_stress: f64,
    /// N.
    pub max_contact_force: f64,
}

impl From<Limits> for LimitsAnswer {
    fn from(l: Limits) -> Self {
        Self {
            max_stress: l.max_stress,
            max_contact_force: l.max_contact_force,
        }
    }
}

/// The clearance a `clear` plan reaches (m; negative: overlapping).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, ToSchema)]
#[schema(as = Clearance)]
pub struct ClearanceJson {
    #[schema(required = true)]
    pub predicted: Option<f64>,
    #[schema(required = true)]
    pub simulated: Option<f64>,
}

impl From<Clearance> for ClearanceJson {
    fn from(c: Clearance) -> Self {
        Self {
            predicted: c.predicted,
            simulated: c.simulated,
        }
    }
}
