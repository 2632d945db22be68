//! The whole held push as one timed trajectory a controller executes:
//! approach (its waypoints blended by a spline when the blended path is
//! collision-free, timed by TOPP-RA, made jerk-limited when the arm has
//! jerk limits), the straight push at a constant tool speed with smooth
//! ramps (inverse kinematics at every sample, so the tool moves exactly
//! along the line at constant orientation), a hold, the release (the push
//! backward) and the retreat (the approach backward). Sampled every
//! `period` into a ROS 2 [`JointTrajectory`]. The acceleration is
//! continuous throughout: the push's ramps are half-cosines.

use nalgebra::{Isometry3, Translation3, Vector3};

use crate::robot::Arm;
use crate::robot::motion::ros::{JointTrajectory, JointTrajectoryPoint, RosDuration};
use crate::robot::motion::rrt::{Config, MotionValidator};
use crate::robot::motion::topp::jerk::JerkLimited;
use crate::robot::motion::topp::{SplinePath, time_optimal};

/// Tool speed during the push (m/s).
pub const PUSH_SPEED: f64 = 0.05;

/// How the trajectory is timed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExecutionOptions {
    /// Tool speed along the push (m/s).
    pub push_speed: f64,
    /// Peak tool acceleration of the push's ramps (m/s²).
    pub push_acceleration: f64,
    /// Time the push is held (s).
    pub hold_s: f64,
    /// Shares (0, 1] of the joints' velocity and acceleration limits, as
    /// MoveIt's scaling factors; jerk limits, where the arm has them, are
    /// scaled with the acceleration.
    pub velocity_scaling: f64,
    pub acceleration_scaling: f64,
    /// Largest spacing of the trajectory's points (s). A joint trajectory
    /// controller interpolates between points with their velocities and
    /// accelerations, so 50 ms keeps a 12 s plan near 250 points (at 10 ms
    /// a response carried 400 kB of them).
    pub period: f64,
}

impl Default for ExecutionOptions {
    fn default() -> Self {
        Self {
            push_speed: PUSH_SPEED,
            push_acceleration: 0.25,
            hold_s: 2.0,
            velocity_scaling: 1.0,
            acceleration_scaling: 1.0,
            period: 0.05,
        }
    }
}

/// The executed trajectory and where its straight push begins and ends.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Execution {
    pub joint_trajectory: JointTrajectory,
    /// Index of the push's first point (the tool at the pre-contact pose).
    pub push_start_point: usize,
    /// Index of the push's last point (the push held from there).
    pub push_end_point: usize,
    /// Whether the approach's waypoints were blended (otherwise the arm
    /// stops at each: the blended path collided).
    pub blended: bool,
}

/// Joint-space chord between collision checks of a blended path (rad).
const BLEND_CHECK_STEP: f64 = 0.02;

fn point(q: &[f64], v: &[f64], a: &[f64], t: f64) -> JointTrajectoryPoint {
    JointTrajectoryPoint {
        positions: q.to_vec(),
        velocities: v.to_vec(),
        accelerations: a.to_vec(),
        time_from_start: RosDuration::from_secs(t),
    }
}

/// Joint limits a trajectory keeps (per joint; jerk only where the arm
/// has jerk limits).
struct Limits {
    velocity: Vec<f64>,
    acceleration: Vec<f64>,
    jerk: Option<Vec<f64>>,
}

impl Limits {
    /// TOPP-RA on `path`, jerk-limited when there are jerk limits.
    fn time(&self, path: SplinePath, grid: usize) -> Option<JerkLimited> {
        let timed = time_optimal(path, &self.velocity, &self.acceleration, grid)?;
        Some(match &self.jerk {
            Some(jerk) => JerkLimited::new(timed, &self.velocity, &self.acceleration, jerk),
            None => JerkLimited::unlimited(timed),
        })
    }
}

/// The approach timed: blended if the blended path is free in `scene`,
/// otherwise a rest-to-rest straight segment per waypoint pair.
fn approach_timing(
    waypoints: &[Config],
    scene: &dyn MotionValidator,
    limits: &Limits,
) -> Option<(Vec<JerkLimited>, bool)> {
    let as_vec: Vec<Vec<f64>> = waypoints.iter().map(|q| q.to_vec()).collect();
    let spline = SplinePath::new(&as_vec)?;
    let steps = (spline.length() / BLEND_CHECK_STEP).ceil().max(1.0) as usize;
    let samples: Vec<Config> = (0..=steps)
        .map(|k| {
            let (q, _, _) = spline.eval(spline.length() * k as f64 / steps as f64);
            Config::from_slice(q.as_slice())
        })
        .collect();
    let free = samples.iter().all(|q| scene.config_valid(q))
        && samples.windows(2).all(|w| scene.edge_valid(&w[0], &w[1]));
    if free {
        return Some((vec![limits.time(spline, 400)?], true));
    }
    let segments = as_vec
        .windows(2)
        .filter_map(SplinePath::new)
        .map(|s| limits.time(s, 100))
        .collect::<Option<Vec<_>>>()?;
    Some((segments, false))
}

/// Distance along the push at time t: from rest up to `speed` over a
/// half-cosine ramp whose peak acceleration is `acceleration` (speed
/// V(1 − cos πt/T)/2, so the acceleration starts and ends at zero and
/// the jerk is bounded), cruise, and the mirror-image ramp down; and the
/// total duration. A push too short to reach `speed` ramps to a lower one.
fn push_profile(length: f64, speed: f64, acceleration: f64) -> (f64, impl Fn(f64) -> f64) {
    use std::f64::consts::PI;
    // A ramp lasts T = πV/(2A) and covers VT/2.
    let speed = speed.min((2.0 * acceleration * length / PI).sqrt());
    let ramp = PI * speed / (2.0 * acceleration);
    let cruise = (length - speed * ramp).max(0.0) / speed;
    let total = 2.0 * ramp + cruise;
    let ramp_distance = move |t: f64| speed / 2.0 * (t - ramp / PI * (PI * t / ramp).sin());
    let at = move |t: f64| {
        let t = t.clamp(0.0, total);
        if t < ramp {
            ramp_distance(t)
        } else if t <= ramp + cruise {
            speed * ramp / 2.0 + speed * (t - ramp)
        } else {
            length - ramp_distance(total - t)
        }
    };
    (total, at)
}

/// The tool's straight push sampled every `period`: positions by inverse
/// kinematics of the tool pose at each sample (nearest the previous
/// sample), velocities and accelerations by central differences of them.
/// `None` when IK leaves the branch it started on.
fn push_samples(
    arm: &Arm,
    start: &Config,
    direction: &Vector3<f64>,
    length: f64,
    speed: f64,
    acceleration: f64,
    period: f64,
) -> Option<Vec<(f64, Config)>> {
    let from = arm.tool_pose(start);
    let (total, at) = push_profile(length, speed, acceleration);
    // Evenly spaced, at most `period` apart (an end sample squeezed in
    // after the last full period would spoil the differences).
    let steps = (total / period).ceil().max(1.0) as usize;
    let mut out = Vec::with_capacity(steps + 1);
    let mut previous = *start;
    for k in 0..=steps {
        let t = total * k as f64 / steps as f64;
        let pose = Isometry3::from_parts(
            Translation3::from(from.translation.vector + direction * at(t)),
            from.rotation,
        );
        let q = if k == 0 {
            *start
        } else {
            arm.inverse_kinematics_near(&pose, &previous)?
        };
        if q.max_abs_diff(&previous) > 0.2 {
            return None;
        }
        previous = q;
        out.push((t, q));
    }
    Some(out)
}

/// Velocities and accelerations of timed samples by central differences;
/// zero at both ends (the push starts and ends at rest).
fn central_differences(samples: &[(f64, Config)]) -> Vec<(Config, Config)> {
    let dof = samples.first().map_or(0, |s| s.1.len());
    (0..samples.len())
        .map(|k| {
            let mut out = (Config::zeros(dof), Config::zeros(dof));
            if k == 0 || k + 1 >= samples.len() {
                return out;
            }
            let (a, b, c) = (&samples[k - 1], &samples[k], &samples[k + 1]);
            let (h1, h2) = (b.0 - a.0, c.0 - b.0);
            if h1 <= 0.0 || h2 <= 0.0 {
                return out;
            }
            for i in 0..dof {
                out.0[i] = (c.1[i] - a.1[i]) / (h1 + h2);
                out.1[i] = ((c.1[i] - b.1[i]) / h2 - (b.1[i] - a.1[i]) / h1) * 2.0 / (h1 + h2);
            }
            out
        })
        .collect()
}

/// How far the push's ends, where it starts and stops at rest, go over the
/// acceleration limits (1: at them). Central differences are zero there
/// and cannot see it: near a stretched elbow the joints' acceleration is
/// largest in the first and last sample interval. Checked one-sided: the
/// acceleration that leaves rest and reaches the next sample,
/// 2 (q₁ − q₀)/h², and the jump to the next sample's velocity, v₁/h (and
/// the same backward at the end).
fn at_rest_ends(samples: &[(f64, Config)], derivatives: &[(Config, Config)], amax: &[f64]) -> f64 {
    let n = samples.len();
    if n < 2 {
        return 0.0;
    }
    let mut worst: f64 = 0.0;
    for (rest, next) in [(0, 1), (n - 1, n - 2)] {
        let h = (samples[next].0 - samples[rest].0).abs();
        if h <= 0.0 {
            continue;
        }
        for (i, limit) in amax.iter().enumerate() {
            let leave = 2.0 * (samples[next].1[i] - samples[rest].1[i]).abs() / (h * h);
            let jump = derivatives[next].0[i].abs() / h;
            worst = worst.max(leave.max(jump) / limit);
        }
    }
    worst
}

/// The largest share of `jmax` that the jerk of timed samples reaches,
/// by third divided differences of their positions (6·q[t₀, t₁, t₂, t₃]
/// is a weighted average of the jerk over [t₀, t₃]), with the samples
/// held at rest one interval before the first and after the last.
fn jerk_ratio(samples: &[(f64, Config)], jmax: &[f64]) -> f64 {
    let (Some(first), Some(last)) = (samples.first(), samples.last()) else {
        return 0.0;
    };
    let h = samples.get(1).map_or(1.0, |s| s.0 - first.0);
    let padded: Vec<(f64, Config)> = std::iter::once((first.0 - h, first.1))
        .chain(samples.iter().copied())
        .chain(std::iter::once((last.0 + h, last.1)))
        .collect();
    let mut worst: f64 = 0.0;
    for w in padded.windows(4) {
        for (i, limit) in jmax.iter().enumerate() {
            let mut d: Vec<f64> = w.iter().map(|(_, q)| q[i]).collect();
            for order in 1..4 {
                for k in 0..4 - order {
                    d[k] = (d[k + 1] - d[k]) / (w[k + order].0 - w[k].0);
                }
            }
            worst = worst.max(6.0 * d[0].abs() / limit);
        }
    }
    worst
}

/// The whole trajectory: approach along `approach` (collision-checked in
/// `scene` when blended), push `length` along `direction` from the
/// approach's end, hold, release, retreat.
pub fn execution(
    arm: &Arm,
    scene: &dyn MotionValidator,
    approach: &[Config],
    direction: &Vector3<f64>,
    length: f64,
    options: &ExecutionOptions,
) -> Option<Execution> {
    let limits = Limits {
        velocity: arm
            .velocity_limits()
            .iter()
            .map(|v| v * options.velocity_scaling)
            .collect(),
        acceleration: arm
            .acceleration_limits()
            .iter()
            .map(|a| a * options.acceleration_scaling)
            .collect(),
        jerk: arm
            .jerk_limits()
            .map(|j| j.iter().map(|j| j * options.acceleration_scaling).collect()),
    };
    let (vmax, amax) = (&limits.velocity, &limits.acceleration);
    let (segments, blended) = approach_timing(approach, scene, &limits)?;
    let period = options.period;
    // Approach, sampled.
    let mut points: Vec<JointTrajectoryPoint> = Vec::new();
    let mut t0 = 0.0;
    // (time, point) of the approach, kept to run it backward at the end.
    let mut approach_samples: Vec<(f64, JointTrajectoryPoint)> = Vec::new();
    for timed in &segments {
        let d = timed.duration();
        let steps = (d / period).ceil().max(1.0) as usize;
        let first = usize::from(!approach_samples.is_empty());
        for k in first..=steps {
            let t = d * k as f64 / steps as f64;
            let (q, v, a) = timed.sample(t);
            let p = point(q.as_slice(), v.as_slice(), a.as_slice(), t0 + t);
            approach_samples.push((t0 + t, p));
        }
        t0 += d;
    }
    points.extend(approach_samples.iter().map(|(_, p)| p.clone()));
    let push_start_point = points.len() - 1;
    let start = approach.last()?;
    // The push, slowed until every joint keeps its limits.
    let mut speed = options.push_speed;
    let mut acceleration = options.push_acceleration;
    let (samples, derivatives) = loop {
        let samples = push_samples(arm, start, direction, length, speed, acceleration, period)?;
        let derivatives = central_differences(&samples);
        let jerk = limits
            .jerk
            .as_ref()
            .map_or(0.0, |jmax| jerk_ratio(&samples, jmax));
        let worst = derivatives
            .iter()
            .flat_map(|(v, a)| {
                (0..v.len()).map(move |i| (v[i].abs() / vmax[i]).max(a[i].abs() / amax[i]))
            })
            .fold(at_rest_ends(&samples, &derivatives, amax), f64::max)
            .max(jerk);
        if worst <= 1.0 {
            break (samples, derivatives);
        }
        if speed < 1e-3 {
            return None;
        }
        speed /= worst.max(1.05);
        acceleration /= worst.max(1.05);
    };
    let push_time = samples.last()?.0;
    for ((t, q), (v, a)) in samples.iter().zip(&derivatives).skip(1) {
        points.push(point(q, v, a, t0 + t));
    }
    let push_end_point = points.len() - 1;
    let held = samples.last()?.1;
    let zero = Config::zeros(arm.dof());
    let mut t = t0 + push_time + options.hold_s.max(0.0);
    if options.hold_s > 0.0 {
        points.push(point(&held, &zero, &zero, t));
    }
    // Release: the push backward in time.
    for ((tk, q), (v, a)) in samples.iter().zip(&derivatives).rev().skip(1) {
        let v: Vec<f64> = v.iter().map(|x| -x).collect();
        points.push(point(q, &v, a, t + (push_time - tk)));
    }
    t += push_time;
    // Retreat: the approach backward in time.
    let total = t0;
    for (ta, p) in approach_samples.iter().rev().skip(1) {
        let v: Vec<f64> = p.velocities.iter().map(|x| -x).collect();
        points.push(point(&p.positions, &v, &p.accelerations, t + (total - ta)));
    }
    Some(Execution {
        joint_trajectory: JointTrajectory {
            joint_names: arm.joint_names().map(str::to_owned).collect(),
            points,
        },
        push_start_point,
        push_end_point,
        blended,
    })
}
