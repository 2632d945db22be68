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
use treemanip_core::robot::motion::trajectory::TimedPoint;

use crate::api::types::objective::LoadsJson;

/// How the push is chosen: `model` (search with the forward GNN, the
/// default), `physics` (search with the simulator), `paper` (Algorithm 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BasePoseJson {
    pub position: [f64; 3],
    pub yaw: f64,
    pub roll: f64,
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

/// One waypoint of the planned path: time (s) and joint positions.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TimedPointJson {
    pub t: f64,
    pub q: Vec<f64>,
}

impl From<&TimedPoint> for TimedPointJson {
    fn from(p: &TimedPoint) -> Self {
        Self {
            t: p.t,
            q: p.q.to_vec(),
        }
    }
}

/// `builtin_interfaces/Duration`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct RosDurationJson {
    pub sec: i32,
    pub nanosec: u32,
}

/// `trajectory_msgs/JointTrajectoryPoint`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointTrajectoryPointJson {
    pub positions: Vec<f64>,
    pub velocities: Vec<f64>,
    pub accelerations: Vec<f64>,
    pub time_from_start: RosDurationJson,
}

/// `trajectory_msgs/JointTrajectory` (without its header).
#[derive(Debug, Clone, PartialEq, Serialize)]
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OutcomeJson {
    Planned,
    InvalidCandidate,
    Unreachable,
    GoalInCollision,
    PushInfeasible,
    NoPath,
    Skipped,
    NotHelpful,
    StartInCollision,
    OverLimit,
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
            OutcomeJson::Skipped => "skipped",
            OutcomeJson::NotHelpful => "not_helpful",
            OutcomeJson::StartInCollision => "start_in_collision",
            OutcomeJson::OverLimit => "over_limit",
            OutcomeJson::Missed => "missed",
        }
    }
}

/// One push the planner looked at, and what became of it.
#[derive(Debug, Clone, Serialize)]
pub struct AttemptJson {
    pub node: usize,
    pub rank: usize,
    pub push: [f64; 3],
    pub outcome: OutcomeJson,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_error: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_loads: Option<LoadsJson>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub simulated_loads: Option<LoadsJson>,
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LimitsAnswer {
    pub max_stress: f64,
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ClearanceJson {
    pub predicted: Option<f64>,
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
