//! Trajectories in the shape of ROS 2's `trajectory_msgs/msg/JointTrajectory`
//! (what a `FollowJointTrajectory` controller executes): joint names, and
//! points with positions, velocities, accelerations and `time_from_start`
//! as `builtin_interfaces/Duration` (`sec`, `nanosec`). Serialised to JSON
//! with the field names of the message, so a client converts it one to one.

use serde::{Deserialize, Serialize};

use crate::robot::motion::topp::TimedPath;

/// `builtin_interfaces/msg/Duration`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RosDuration {
    pub sec: i32,
    pub nanosec: u32,
}

impl RosDuration {
    /// Seconds, rounded to the nanosecond (negative or NaN: zero).
    pub fn from_secs(t: f64) -> Self {
        let total = if t.is_finite() && t > 0.0 {
            (t * 1e9).round() as i64
        } else {
            0
        };
        Self {
            sec: (total / 1_000_000_000).min(i32::MAX as i64) as i32,
            nanosec: (total % 1_000_000_000) as u32,
        }
    }

    pub fn as_secs(&self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }
}

/// `trajectory_msgs/msg/JointTrajectoryPoint` (without `effort`, which a
/// position-controlled arm leaves empty).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointTrajectoryPoint {
    pub positions: Vec<f64>,
    pub velocities: Vec<f64>,
    pub accelerations: Vec<f64>,
    pub time_from_start: RosDuration,
}

/// `trajectory_msgs/msg/JointTrajectory` (the header is the client's: a
/// controller stamps it when it starts).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointTrajectory {
    pub joint_names: Vec<String>,
    pub points: Vec<JointTrajectoryPoint>,
}

impl JointTrajectory {
    /// `timed` sampled evenly, at most `period` seconds apart, its last
    /// point included (exactly at rest at the end).
    pub fn sample(joint_names: &[String], timed: &TimedPath, period: f64) -> Self {
        let duration = timed.duration();
        let period = if period.is_finite() && period > 0.0 {
            period
        } else {
            0.01
        };
        let steps = (duration / period).ceil().max(1.0) as usize;
        let points = (0..=steps)
            .map(|k| {
                let t = duration * k as f64 / steps as f64;
                let (q, v, a) = timed.sample(t);
                JointTrajectoryPoint {
                    positions: q.as_slice().to_vec(),
                    velocities: v.as_slice().to_vec(),
                    accelerations: a.as_slice().to_vec(),
                    time_from_start: RosDuration::from_secs(t),
                }
            })
            .collect();
        Self {
            joint_names: joint_names.to_vec(),
            points,
        }
    }
}
