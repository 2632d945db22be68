//! Time-optimal timing for any number of joints (`robot::motion::topp`): the
//! spline passes its waypoints at rest only at the ends, every limit holds
//! when checked by finite differences of the positions alone, and the
//! duration matches TOPP-RA's own implementation (the `toppra` package) on
//! the same path and limits.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use treemanip_core::robot::motion::topp::jerk::JerkLimited;
use treemanip_core::robot::motion::topp::{SplinePath, TimedPath, time_optimal};

/// `count` random waypoints of `dof` joints, each a step of up to 1 rad.
fn waypoints(dof: usize, count: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut q = vec![0.0; dof];
    let mut out = vec![q.clone()];
    for _ in 1..count {
        for v in q.iter_mut() {
            *v += rng.random_range(-1.0..1.0);
        }
        out.push(q.clone());
    }
    out
}

fn limits(dof: usize) -> (Vec<f64>, Vec<f64>) {
    let v: Vec<f64> = (0..dof).map(|j| 1.0 + 0.3 * j as f64).collect();
    let a: Vec<f64> = (0..dof).map(|j| 3.0 - 0.2 * j as f64).collect();
    (v, a)
}

/// Largest velocity and acceleration over the trajectory, per joint, as
/// finite differences of positions sampled every `dt`.
fn finite_difference_peaks(timed: &TimedPath, dof: usize, dt: f64) -> (Vec<f64>, Vec<f64>) {
    let steps = (timed.duration() / dt).ceil() as usize;
    let q: Vec<_> = (0..=steps).map(|k| timed.sample(k as f64 * dt).0).collect();
    let (mut v, mut a) = (vec![0.0f64; dof], vec![0.0f64; dof]);
    for k in 1..steps {
        for j in 0..dof {
            v[j] = v[j].max(((q[k + 1][j] - q[k - 1][j]) / (2.0 * dt)).abs());
            a[j] = a[j].max(((q[k + 1][j] - 2.0 * q[k][j] + q[k - 1][j]) / (dt * dt)).abs());
        }
    }
    (v, a)
}

#[test]
fn the_spline_passes_its_waypoints_and_starts_and_ends_at_rest() {
    let w = waypoints(7, 6, 1);
    let path = SplinePath::new(&w).unwrap();
    for (k, s) in path.knots.iter().enumerate() {
        let (q, _, _) = path.eval(*s);
        for j in 0..7 {
            assert!((q[j] - w[k][j]).abs() < 1e-12);
        }
    }
    assert!(path.eval(0.0).1.norm() < 1e-12);
    assert!(path.eval(path.length()).1.norm() < 1e-12);
    // C²: the second derivative is continuous across an inner knot.
    let s = path.knots[2];
    let (a, b) = (path.eval(s - 1e-9).2, path.eval(s + 1e-9).2);
    assert!((a - b).norm() < 1e-6);
    assert!(SplinePath::new(&[vec![0.0; 3], vec![0.0; 3]]).is_none());
}

/// On random 6- and 7-joint paths, velocities and accelerations measured
/// from positions alone (1 ms finite differences) stay within the limits,
/// and the motion does not stop at inner waypoints.
#[test]
fn timed_paths_keep_every_limit() {
    for (dof, seed) in [(6, 2u64), (7, 3), (7, 4), (6, 5)] {
        let (vmax, amax) = limits(dof);
        let path = SplinePath::new(&waypoints(dof, 5, seed)).unwrap();
        let knot = path.knots[2];
        let timed = time_optimal(path, &vmax, &amax, 1000).unwrap();
        let (v, a) = finite_difference_peaks(&timed, dof, 1e-3);
        let worst = (0..dof)
            .map(|j| (v[j] / vmax[j]).max(a[j] / amax[j]))
            .fold(0.0, f64::max);
        eprintln!("{dof} joints: peak {worst:.4} of a limit");
        for j in 0..dof {
            assert!(
                v[j] <= vmax[j],
                "joint {j}: velocity {} > {}",
                v[j],
                vmax[j]
            );
            assert!(
                a[j] <= amax[j],
                "joint {j}: acceleration {} > {}",
                a[j],
                amax[j]
            );
        }
        let k = timed.s.iter().position(|s| *s >= knot).unwrap();
        assert!(timed.speed[k] > 0.05, "stops at a waypoint");
        assert_eq!(timed.speed[0], 0.0);
        assert_eq!(*timed.speed.last().unwrap(), 0.0);
    }
}

/// The same path (a clamped cubic spline through the same waypoints at the
/// same knots) and limits, timed by the `toppra` package: durations within
/// 1.1× (both are TOPP-RA; the grid differs).
#[test]
fn durations_match_the_toppra_package() {
    if !crate::common::python_has("toppra") {
        return;
    }
    let mut cases = Vec::new();
    for (dof, seed) in [(6, 12u64), (7, 13), (7, 14)] {
        let (vmax, amax) = limits(dof);
        let w = waypoints(dof, 6, seed);
        let path = SplinePath::new(&w).unwrap();
        let knots = path.knots.clone();
        let ours = time_optimal(path, &vmax, &amax, 1000).unwrap().duration();
        cases.push((knots, w, vmax, amax, ours));
    }
    let input: Vec<_> = cases
        .iter()
        .map(|(k, w, v, a, _)| serde_json::json!({ "ss": k, "qs": w, "v": v, "a": a }))
        .collect();
    let script = r#"
import json, sys, numpy as np, toppra as ta, toppra.constraint as constraint, toppra.algorithm as algo
ta.setup_logging("WARNING")
out = []
for c in json.load(sys.stdin):
    path = ta.SplineInterpolator(c["ss"], np.array(c["qs"]), bc_type="clamped")
    v, a = np.array(c["v"]), np.array(c["a"])
    pc_v = constraint.JointVelocityConstraint(np.stack([-v, v], axis=1))
    pc_a = constraint.JointAccelerationConstraint(np.stack([-a, a], axis=1))
    grid = np.linspace(0, path.duration, 1001)
    inst = algo.TOPPRA([pc_v, pc_a], path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
    traj = inst.compute_trajectory(0, 0)
    out.append(traj.duration)
print(json.dumps(out))
"#;
    let out = crate::common::python_json(script, &serde_json::Value::from(input));
    let theirs: Vec<f64> = serde_json::from_slice(&out).unwrap();
    for ((.., ours), theirs) in cases.iter().zip(theirs) {
        let ratio = ours / theirs;
        eprintln!("ours {ours:.4} s, toppra {theirs:.4} s, ratio {ratio:.4}");
        assert!(
            (0.95..=1.1).contains(&ratio),
            "ours {ours} s vs toppra {theirs} s"
        );
    }
}

/// Per joint, the largest |jerk| over positions sampled every `dt`, by
/// third differences (Δ³q/dt³ is the jerk somewhere in its span).
fn jerk_peaks(sample: impl Fn(f64) -> Vec<f64>, duration: f64, dof: usize, dt: f64) -> Vec<f64> {
    let steps = (duration / dt).ceil() as usize;
    let q: Vec<Vec<f64>> = (0..=steps).map(|k| sample(k as f64 * dt)).collect();
    let mut peak = vec![0.0f64; dof];
    for w in q.windows(4) {
        for j in 0..dof {
            let third = w[3][j] - 3.0 * w[2][j] + 3.0 * w[1][j] - w[0][j];
            peak[j] = peak[j].max((third / dt.powi(3)).abs());
        }
    }
    peak
}

/// Jerk limits: TOPP-RA alone jerks far past them (its acceleration
/// jumps); the jerk-limited timing of the same path keeps them and the
/// velocity and acceleration limits, measured from positions alone,
/// begins and ends exactly at the path's ends at rest, and costs little
/// time when the limits are loose.
#[test]
fn jerk_limited_timing_keeps_jerk_limits() {
    for (dof, seed, jerk) in [(7, 21u64, 20.0), (6, 22, 50.0), (7, 23, 1000.0)] {
        let (vmax, amax) = limits(dof);
        let jmax = vec![jerk; dof];
        let w = waypoints(dof, 5, seed);
        let timed = time_optimal(SplinePath::new(&w).unwrap(), &vmax, &amax, 400).unwrap();
        let dt = 2e-3;
        let raw = jerk_peaks(
            |t| timed.sample(t).0.as_slice().to_vec(),
            timed.duration(),
            dof,
            dt,
        );
        let raw_worst = raw.iter().fold(0.0f64, |m, v| m.max(*v)) / jerk;
        let smooth = JerkLimited::new(timed.clone(), &vmax, &amax, &jmax);
        let peaks = jerk_peaks(
            |t| smooth.sample(t).0.as_slice().to_vec(),
            smooth.duration(),
            dof,
            dt,
        );
        let ratio = smooth.duration() / timed.duration();
        eprintln!(
            "{dof} joints, jerk {jerk}: TOPP-RA {raw_worst:.1}× the jerk limit; jerk-limited \
             {:.3} of it, {ratio:.3}× as long",
            peaks.iter().fold(0.0f64, |m, v| m.max(*v)) / jerk
        );
        if jerk < 1000.0 {
            assert!(raw_worst > 1.5, "the test path must need the jerk limit");
        }
        for j in 0..dof {
            assert!(peaks[j] <= jmax[j] * 1.001, "joint {j}: jerk {}", peaks[j]);
        }
        // Velocity and acceleration by finite differences of positions.
        let steps = (smooth.duration() / 1e-3).ceil() as usize;
        let q: Vec<_> = (0..=steps)
            .map(|k| smooth.sample(k as f64 * 1e-3).0)
            .collect();
        for k in 1..steps {
            for j in 0..dof {
                let v = (q[k + 1][j] - q[k - 1][j]) / 2e-3;
                let a = (q[k + 1][j] - 2.0 * q[k][j] + q[k - 1][j]) / 1e-6;
                assert!(v.abs() <= vmax[j], "joint {j}: velocity {v}");
                assert!(a.abs() <= amax[j] * 1.001, "joint {j}: acceleration {a}");
            }
        }
        let (start, v0, a0) = smooth.sample(0.0);
        let (end, v1, a1) = smooth.sample(smooth.duration());
        assert_eq!(start.as_slice(), w[0].as_slice());
        assert_eq!(end.as_slice(), w.last().unwrap().as_slice());
        assert!(v0.norm() + a0.norm() + v1.norm() + a1.norm() < 1e-9);
        if jerk >= 1000.0 {
            assert!(ratio < 1.05, "a loose jerk limit costs {ratio}×");
        }
    }
}
