//! A searching stage after [`crate::planner::shorter`]: the best pushes
//! whose simulation put the tree over a load limit, tried again eased back
//! to it.
//!
//! Why: `model` reads a push's loads from the forward model's predicted
//! positions, which err (median 9 % in stress on 200-node trees, p90
//! 32 %), so it screens at twice the limits and leaves the last word to the
//! push's simulation. On 200-node trees with the base free to drive round
//! the tree, the `clear` tasks `model` failed and `physics` solved (seed
//! 7) were ones where every push `model` ranked best was over a limit in
//! its simulation. Stress and force grow with the push's length, so the
//! same push shortened by the simulated overload, a little more, is the
//! nearest thing to it within the limits. Each is predicted again (it must
//! still help and pass the screen) and simulated again before any arm
//! work, as every push is.

use crate::planner::answer::PlanError;
use crate::planner::execute::{Found, Judged, Run};
use crate::planner::predict::Predictor;
use crate::planner::search::{self, MIN_PUSH, Scored};
use crate::planner::shorter::add_shortened;
use crate::sim::Push;
use crate::sim::loads::PushLoads;

/// Overloaded pushes eased, best predicted first.
pub const EASED_SOURCES: usize = 3;
/// The eased length: this share of the length at which the loads, scaled
/// with the push, would reach the tighter limit (they grow faster than the
/// length once thin wood is pulled taut, so a second, shorter try).
pub const EASED_FACTORS: [f64; 2] = [0.95, 0.75];
/// Eased pushes executed at most.
const EASED_EXECUTIONS: usize = 4;

/// Tries the best overloaded pushes of this planning call
/// ([`Run::overloaded`]) eased back to the limits, best predicted first,
/// until one is carried out.
pub(super) fn eased(
    run: &mut Run<'_>,
    predictor: &dyn Predictor,
    judged: &Judged<'_>,
    evaluations: &mut usize,
) -> Result<Option<Found>, PlanError> {
    let Some(limits) = run.query.limits else {
        return Ok(None);
    };
    let overloaded = std::mem::take(&mut run.overloaded);
    let pushes = eased_pushes(overloaded, &run.query.objective, |loads| {
        (limits.max_stress / loads.peak_stress.max(1e-9))
            .min(limits.max_contact_force / loads.contact_force.max(1e-9))
    });
    run.try_again(&pushes, predictor, judged, evaluations, EASED_EXECUTIONS)
}

/// The eased pushes of the [`EASED_SOURCES`] best distinct overloaded
/// ones, with their rank: each at [`EASED_FACTORS`] of `room(loads)` (the
/// factor by which its simulated loads would reach the limits) times its
/// length, at least [`MIN_PUSH`] (a push already that short is left out).
fn eased_pushes(
    mut overloaded: Vec<(usize, Scored, PushLoads)>,
    objective: &crate::planner::objective::Objective,
    room: impl Fn(&PushLoads) -> f64,
) -> Vec<(usize, Push)> {
    overloaded.sort_by(|a, b| search::compare(&a.1, &b.1, objective));
    let mut out: Vec<(usize, Push)> = Vec::new();
    let mut sources: Vec<Push> = Vec::new();
    for (rank, s, loads) in overloaded {
        if sources.len() == EASED_SOURCES {
            break;
        }
        let push = s.push;
        let seen = |p: &Push| p.node == push.node && (p.vector - push.vector).norm() < 1e-3;
        if push.vector.norm() <= MIN_PUSH + 1e-9 || sources.iter().any(seen) {
            continue;
        }
        sources.push(push);
        let share = room(&loads).min(1.0);
        add_shortened(&mut out, rank, &push, EASED_FACTORS.map(|f| share * f));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::objective::Objective;
    use nalgebra::{Point3, Vector3};

    fn overloaded(node: usize, length: f64, error: f64, stress: f64) -> (usize, Scored, PushLoads) {
        let loads = PushLoads {
            peak_stress: stress,
            peak_node: Some(node),
            contact_force: 10.0,
        };
        let s = Scored {
            push: Push {
                node,
                vector: Vector3::x() * length,
            },
            predicted_error: error,
            loads,
            within_limits: true,
            clearance: None,
        };
        (node, s, loads)
    }

    /// Each overloaded push is eased by its own overload, best predicted
    /// first, at most [`EASED_SOURCES`] of them, never below [`MIN_PUSH`].
    #[test]
    fn overloaded_pushes_are_eased_by_their_own_overload() {
        let objective = Objective::shape(vec![Point3::origin(); 12]);
        let room = |l: &PushLoads| 40e6 / l.peak_stress;
        let pushes = eased_pushes(
            vec![
                overloaded(5, 0.10, 0.03, 80e6),
                overloaded(3, 0.12, 0.01, 50e6),
                overloaded(7, 0.08, 0.04, 200e6),
                overloaded(9, 0.06, 0.05, 60e6),
                overloaded(11, 0.06, 0.06, 60e6),
            ],
            &objective,
            room,
        );
        let lengths: Vec<(usize, f64)> =
            pushes.iter().map(|(n, p)| (*n, p.vector.norm())).collect();
        // Node 3 first (best predicted): 12 cm × 40/50 × 0.95 and × 0.75.
        assert_eq!(lengths.len(), 4, "{lengths:?}");
        assert_eq!((lengths[0].0, lengths[1].0), (3, 3));
        assert!((lengths[0].1 - 0.12 * 0.8 * 0.95).abs() < 1e-12);
        assert!((lengths[1].1 - 0.12 * 0.8 * 0.75).abs() < 1e-12);
        // Nodes 5 and 7 would go below the shortest push: at it, once each.
        assert_eq!(lengths[2].0, 5);
        assert_eq!(lengths[3].0, 7);
        assert!(
            lengths[2..]
                .iter()
                .all(|(_, l)| (l - MIN_PUSH).abs() < 1e-12)
        );
        // Three sources only: 9 and 11 are left.
    }
}
