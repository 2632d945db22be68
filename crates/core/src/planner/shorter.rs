//! The last searching stage before the closest miss: the best pushes the
//! arm could not carry out, tried again shorter.
//!
//! Why: a push that helps most can move the tree more than the arm's room
//! allows. A 15 cm push down on a trunk node 19 cm above the ground swings
//! a 17-node crown by 97 cm; the bare UR10 from `example-robot-data`
//! (reach 1.3 m) had every stance's push line refused against the tree as
//! it deformed (the crown landing on its forearm and wrist), so the plan
//! did nothing while a push two thirds as long, in the same direction on
//! the same node, still helped. The search samples push lengths around its
//! seeds, but ranks them by the objective alone: when every helpful one it
//! executed was blocked by the arm, the same pushes shortened are the
//! nearest thing to them the arm may still make. Each is predicted again
//! (it must still help and keep within the limits) before any arm work.

use crate::planner::answer::PlanError;
use crate::planner::execute::{Found, Judged, Run};
use crate::planner::predict::Predictor;
use crate::planner::search::{self, MIN_PUSH, Scored};
use crate::sim::Push;

/// Blocked pushes shortened, best predicted first.
pub const SHORTER_SOURCES: usize = 3;
/// The lengths tried, as shares of the blocked push's (never below
/// [`MIN_PUSH`]).
pub const SHORTER_FACTORS: [f64; 2] = [2.0 / 3.0, 0.45];
/// Shortened pushes executed at most.
const SHORTER_EXECUTIONS: usize = 4;

/// Tries the best blocked pushes of this planning call ([`Run::blocked`])
/// shortened, best predicted first, until one is carried out.
pub(super) fn shorter(
    run: &mut Run<'_>,
    predictor: &dyn Predictor,
    judged: &Judged<'_>,
    evaluations: &mut usize,
) -> Result<Option<Found>, PlanError> {
    let pushes = shortened(std::mem::take(&mut run.blocked), &run.query.objective);
    run.try_again(&pushes, predictor, judged, evaluations, SHORTER_EXECUTIONS)
}

/// The shortened pushes of the [`SHORTER_SOURCES`] best distinct blocked
/// ones, with their rank: each at [`SHORTER_FACTORS`] of its length, at
/// least [`MIN_PUSH`] (a push already that short is left out).
fn shortened(
    mut blocked: Vec<(usize, Scored)>,
    objective: &crate::planner::objective::Objective,
) -> Vec<(usize, Push)> {
    blocked.sort_by(|a, b| search::compare(&a.1, &b.1, objective));
    let mut sources: Vec<(usize, Push)> = Vec::new();
    for (rank, s) in blocked {
        let same = |p: &Push| p.node == s.push.node && (p.vector - s.push.vector).norm() < 1e-3;
        if !sources.iter().any(|(_, p)| same(p)) {
            sources.push((rank, s.push));
        }
        if sources.len() == SHORTER_SOURCES {
            break;
        }
    }
    let mut out: Vec<(usize, Push)> = Vec::new();
    for (rank, push) in sources {
        let length = push.vector.norm();
        if length <= MIN_PUSH + 1e-9 {
            continue;
        }
        add_shortened(&mut out, rank, &push, SHORTER_FACTORS);
    }
    out
}

/// Adds `push` at each of `shares` of its length (never below
/// [`MIN_PUSH`]) to `out` with `rank`, leaving out pushes already there.
pub(super) fn add_shortened(
    out: &mut Vec<(usize, Push)>,
    rank: usize,
    push: &Push,
    shares: impl IntoIterator<Item = f64>,
) {
    let length = push.vector.norm();
    for f in shares {
        let to = (length * f).max(MIN_PUSH);
        let short = Push {
            node: push.node,
            vector: push.vector * (to / length),
        };
        let repeated = out
            .iter()
            .any(|(_, p)| p.node == short.node && (p.vector - short.vector).norm() < 1e-3);
        if !repeated {
            out.push((rank, short));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::objective::Objective;
    use crate::sim::loads::PushLoads;
    use nalgebra::{Point3, Vector3};

    fn scored(node: usize, vector: Vector3<f64>, predicted_error: f64) -> Scored {
        Scored {
            push: Push { node, vector },
            predicted_error,
            loads: PushLoads {
                peak_stress: 0.0,
                peak_node: None,
                contact_force: 0.0,
            },
            within_limits: true,
            clearance: None,
        }
    }

    #[test]
    fn the_best_distinct_blocked_pushes_are_shortened_not_below_the_shortest_push() {
        let objective = Objective::shape(vec![Point3::origin(); 4]);
        let blocked = vec![
            (2, scored(1, Vector3::new(0.0, 0.0, -0.15), 0.10)),
            // The same push again (blocked from another stage): once.
            (2, scored(1, Vector3::new(0.0, 0.0, -0.15), 0.10)),
            (5, scored(3, Vector3::new(0.09, 0.0, 0.0), 0.05)),
            // Already as short as a push may be: nothing shorter.
            (7, scored(2, Vector3::new(0.0, MIN_PUSH, 0.0), 0.01)),
            // The fourth best: not a source.
            (9, scored(2, Vector3::new(0.0, 0.2, 0.0), 0.20)),
        ];
        let out = shortened(blocked, &objective);
        let lengths: Vec<(usize, usize, f64)> = out
            .iter()
            .map(|(r, p)| (*r, p.node, (p.vector.norm() * 1e4).round() / 1e4))
            .collect();
        // Best predicted first; 0.09 × 0.45 is below MIN_PUSH, so MIN_PUSH.
        assert_eq!(
            lengths,
            vec![(5, 3, 0.06), (5, 3, MIN_PUSH), (2, 1, 0.1), (2, 1, 0.0675)]
        );
        // Directions are kept.
        assert!((out[2].1.vector.normalize() - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
    }
}
