//! Timed trajectories as ROS 2 `trajectory_msgs/msg/JointTrajectory`: the
//! JSON converts one to one into the message with the `rosbags` package
//! (ROS 2 message types and CDR without ROS), serialises to CDR and reads
//! back equal; times increase, and the velocities are the positions'
//! derivative.

use treemanip_core::robot::motion::ros::{JointTrajectory, RosDuration};
use treemanip_core::robot::motion::topp::{SplinePath, time_optimal};

fn trajectory() -> JointTrajectory {
    let waypoints = vec![
        vec![0.0, -0.5, 0.3, -1.0, 0.2, 0.9, 0.0],
        vec![0.4, -0.2, 0.1, -1.4, 0.5, 1.2, 0.3],
        vec![0.9, 0.1, -0.3, -1.8, 0.3, 1.6, 0.8],
    ];
    let names: Vec<String> = (1..=7).map(|j| format!("panda_joint{j}")).collect();
    let timed = time_optimal(
        SplinePath::new(&waypoints).unwrap(),
        &[2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61],
        &[15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0],
        500,
    )
    .unwrap();
    JointTrajectory::sample(&names, &timed, 0.01)
}

use crate::common::assert_ros2_round_trip;

#[test]
fn durations_round_to_the_nanosecond() {
    assert_eq!(
        RosDuration::from_secs(1.25),
        RosDuration {
            sec: 1,
            nanosec: 250_000_000
        }
    );
    assert_eq!(
        RosDuration::from_secs(-3.0),
        RosDuration { sec: 0, nanosec: 0 }
    );
    assert_eq!(
        RosDuration::from_secs(f64::NAN),
        RosDuration { sec: 0, nanosec: 0 }
    );
    assert!((RosDuration::from_secs(2.000000001).as_secs() - 2.000000001).abs() < 1e-12);
}

#[test]
fn points_are_timed_in_order_with_consistent_velocities() {
    let traj = trajectory();
    assert!(traj.points.len() > 10);
    let first = &traj.points[0];
    let last = traj.points.last().unwrap();
    assert_eq!(first.time_from_start, RosDuration { sec: 0, nanosec: 0 });
    assert!(
        first
            .velocities
            .iter()
            .chain(&last.velocities)
            .all(|v| v.abs() < 1e-9)
    );
    for pair in traj.points.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let dt = b.time_from_start.as_secs() - a.time_from_start.as_secs();
        assert!(dt > 0.0);
        for j in 0..7 {
            // The mean of the two velocities is the positions' slope to
            // second order.
            let slope = (b.positions[j] - a.positions[j]) / dt;
            let mean = (a.velocities[j] + b.velocities[j]) / 2.0;
            assert!((slope - mean).abs() < 0.02, "joint {j}: {slope} vs {mean}");
        }
    }
}

#[test]
fn the_json_is_a_ros2_joint_trajectory() {
    if !crate::common::python_has("rosbags") {
        return;
    }
    let json = serde_json::to_value(trajectory()).unwrap();
    let out = assert_ros2_round_trip(&json);
    let answer = String::from_utf8_lossy(&out);
    let points: usize = answer.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert_eq!(points, trajectory().points.len());
}
