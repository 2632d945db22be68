//! Timing a joint-space path: each segment is a synchronised trapezoidal
//! velocity profile that starts and ends at rest, as fast as the joint
//! velocity and acceleration limits allow.
//!
//! For a segment with per-joint distances D_i, all joints follow
//! q_i(t) = q_i0 + Δ_i s(t) with one normalised trapezoid s: cruise speed
//! 1/u and acceleration 1/(τu). The limits require u ≥ V = max D_i / v_i and
//! τ u ≥ A = max D_i / a_i; the shortest duration T = u + A/u is reached at
//! u = max(V, √A), τ = A/u.

use serde::{Deserialize, Serialize};

use crate::robot::motion::rrt::Config;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimedPoint {
    /// Time from the start of the trajectory (s).
    pub t: f64,
    /// Joint positions (rad).
    pub q: Config,
}

/// Duration and shape (u, τ) of one segment.
fn segment_profile(a: &Config, b: &Config, vmax: &[f64], amax: &[f64]) -> (f64, f64, f64) {
    let v = (0..a.len())
        .map(|i| (b[i] - a[i]).abs() / vmax[i])
        .fold(0.0, f64::max);
    let acc = (0..a.len())
        .map(|i| (b[i] - a[i]).abs() / amax[i])
        .fold(0.0, f64::max);
    if v == 0.0 && acc == 0.0 {
        return (0.0, 1.0, 0.0);
    }
    let u = v.max(acc.sqrt());
    let tau = acc / u;
    (u + tau, u, tau)
}

/// s(t) of the normalised trapezoid.
fn progress(t: f64, total: f64, u: f64, tau: f64) -> f64 {
    if total == 0.0 {
        return 1.0;
    }
    let accel = 1.0 / (tau * u);
    if t < tau {
        0.5 * accel * t * t
    } else if t <= total - tau {
        0.5 * tau / u + (t - tau) / u
    } else {
        let r = total - t;
        1.0 - 0.5 * accel * r * r
    }
}

/// Samples the timed path every `dt` seconds (and at every waypoint).
pub fn time_parameterize(path: &[Config], vmax: &[f64], amax: &[f64], dt: f64) -> Vec<TimedPoint> {
    let mut out = Vec::new();
    let Some(first) = path.first() else {
        return out;
    };
    out.push(TimedPoint { t: 0.0, q: *first });
    let mut start = 0.0;
    for w in path.windows(2) {
        let (total, u, tau) = segment_profile(&w[0], &w[1], vmax, amax);
        let samples = (total / dt).ceil().max(1.0) as usize;
        for k in 1..=samples {
            let t = total * k as f64 / samples as f64;
            let s = progress(t, total, u, tau);
            let q = w[0].lerp(&w[1], s);
            out.push(TimedPoint { t: start + t, q });
        }
        start += total;
    }
    out
}
