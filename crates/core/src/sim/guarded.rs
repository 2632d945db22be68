//! A push carried out as a guarded move: the arm follows the push and
//! stops where the force at its wrist first reaches a set value.
//!
//! Why: a plan keeps the tree it was planned on within the load limits,
//! but the tree the arm meets may be stiffer. A tree extracted from one
//! leafy view, for one, can join a twig to the wrong parent, and pushing
//! it then takes 3-5 times the planned force on the real tree
//! (docs/scans.md, end to end). A force-torque sensor at the wrist reads
//! the contact force whatever the model got wrong, so a controller that
//! stops there keeps that limit on the real tree. No sensor reads the
//! wood's stress, so the force is the only load a guard can hold.
//!
//! The simulator is quasi-static and the joints elastic, so the tree's
//! state a fraction s along the push is the push of s × T, solved from the
//! state one step before (warm start). The guard trips at the *first*
//! crossing, as a controller would, even where the force would fall again
//! further on.

use super::{Push, PushOutcome, SimConfig, SimError, simulate, simulate_from};
use crate::tree::Tree;
use nalgebra::Vector3;

/// Steps (m) at which the force is read along the push before the
/// crossing is bisected: short enough that a push cannot pass over a
/// force peak unseen (a branch's force peaks about a branch length along).
pub const GUARD_STEP: f64 = 0.005;

/// Most readings before the crossing is bisected: a push longer than
/// `MAX_GUARD_STEPS` × [`GUARD_STEP`] (20 cm) is read at its length over
/// this. Each reading is a simulation, warm-started from the one before,
/// so the work of a guarded push is bounded (at most this plus a dozen
/// bisections) whatever its length.
pub const MAX_GUARD_STEPS: usize = 40;

/// How closely (m along the push) the stop is located: a wrist sensor
/// read at 500 Hz during a 2 cm/s push sees every 0.04 mm.
pub const GUARD_TOLERANCE: f64 = 1e-4;

/// How many readings a guarded move takes along `push` before any
/// bisection: one every [`GUARD_STEP`], at most [`MAX_GUARD_STEPS`]. The
/// planner's guard ([`crate::planner::objective::Limits::guard_force`])
/// reads a push at the same points.
pub fn guard_readings(push: &Push) -> usize {
    ((push.vector.norm() / GUARD_STEP).ceil() as usize).clamp(1, MAX_GUARD_STEPS)
}

/// `push` carried a `fraction` (0-1) of its length.
pub fn partway(push: &Push, fraction: f64) -> Push {
    Push {
        node: push.node,
        vector: push.vector * fraction,
    }
}

/// What a guarded push did.
#[derive(Debug, Clone)]
pub struct GuardedPush {
    /// Where the tree settled when the arm stopped (or at the push's end).
    pub outcome: PushOutcome,
    /// Share of the push carried out: 1 when the guard never tripped.
    pub fraction: f64,
    /// Whether the guard stopped the arm before the push's end.
    pub stopped: bool,
}

/// `push` carried out on `tree` as a move that stops where the contact
/// force first reaches `stop_at` (N). The returned state's force is at
/// most `stop_at`. Errors are the simulator's, at the first step it
/// rejects before the guard trips; with `config.solver.deadline`, that
/// is [`SimError::OutOfTime`] once it passes (a deep path's simulation can
/// take seconds, and a guarded push is dozens of them).
pub fn guarded_push(
    tree: &Tree,
    push: &Push,
    config: &SimConfig,
    stop_at: f64,
) -> Result<GuardedPush, SimError> {
    let length = push.vector.norm();
    let force = |o: &PushOutcome| Vector3::from(o.report.contact_force).norm();
    let steps = guard_readings(push);
    let part = |s: f64| partway(push, s);
    let mut below: Option<(f64, PushOutcome)> = None;
    let mut k = 0;
    loop {
        k += 1;
        let s = k as f64 / steps as f64;
        let warm = below.as_ref().map(|(_, o)| o.joint_rotations.as_slice());
        let out = simulate_from(tree, &part(s), config, warm)?;
        if force(&out) <= stop_at {
            if k == steps {
                return Ok(GuardedPush {
                    outcome: out,
                    fraction: 1.0,
                    stopped: false,
                });
            }
            below = Some((s, out));
            continue;
        }
        // Crossed between the last step below and s: bisect.
        let (mut lo, mut hi) = (below.as_ref().map_or(0.0, |(s, _)| *s), s);
        while (hi - lo) * length > GUARD_TOLERANCE {
            let mid = 0.5 * (lo + hi);
            let warm = below.as_ref().map(|(_, o)| o.joint_rotations.as_slice());
            let o = simulate_from(tree, &part(mid), config, warm)?;
            if force(&o) <= stop_at {
                lo = mid;
                below = Some((mid, o));
            } else {
                hi = mid;
            }
        }
        let (fraction, outcome) = match below {
            Some(b) => b,
            // Tripped within the tolerance of the start: the tree as it
            // stands, the gripper closed on it (no force).
            None => (0.0, simulate(tree, &part(0.0), config)?),
        };
        return Ok(GuardedPush {
            outcome,
            fraction,
            stopped: true,
        });
    }
}
