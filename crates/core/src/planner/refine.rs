//! Polishing the search's best pushes: a compass (pattern) search on the
//! push vector of the best few nodes.
//!
//! The cross-entropy rounds end with a spread of about a centimetre; a push
//! that is 1 cm off leaves roughly that much at the branch tip, which is
//! the size of the effect a stiffness estimate corrects. Around each of
//! the best pushes the compass search predicts the six pushes a step away
//! along ±x, ±y, ±z (every node's six in one batch), moves to the best one
//! when it ranks better in the search's order (limits, then residual), and
//! halves the step when none does, from [`INITIAL_STEP`] down to
//! [`FINAL_STEP`]. It needs nothing but the scorer, so it works for every
//! objective, including the non-smooth largest node distance.
//!
//! It pays where predictions are exact and cheap: the planner polishes
//! `physics` pushes by default (a simulation is about a millisecond) and
//! not `model` ones, whose prediction errors (about 2 cm) are larger than
//! what polishing against them could gain.

use super::objective::{Limits, Objective};
use super::predict::{PredictError, Predictor};
use super::search::{MAX_PUSH, MIN_PUSH, Scored, compare, score};
use crate::sim::Push;
use crate::tree::Tree;

/// First step of the compass search (m).
pub const INITIAL_STEP: f64 = 0.008;
/// Steps shorter than this end it (m).
pub const FINAL_STEP: f64 = 0.0005;
/// Distinct nodes polished, best first.
pub const REFINED_NODES: usize = 2;
/// Predictions the planner spends polishing `physics` pushes: about five
/// rounds of both nodes' six neighbours, enough to halve the step from
/// [`INITIAL_STEP`] to [`FINAL_STEP`] with a few moves between.
pub const PHYSICS_REFINE_EVALUATIONS: usize = 72;

/// Polishes the best push of each of the best [`REFINED_NODES`] nodes in
/// `scored` (sorted best first) with at most `max_evaluations`
/// predictions. Returns the polished pushes that improved on where they
/// started (only those: the neighbours scored on the way are near copies,
/// and a list full of them would spend the planner's arm attempts on one
/// spot) and the number of predictions made.
pub fn refine(
    tree: &Tree,
    objective: &Objective,
    limits: Option<&Limits>,
    scored: &[Scored],
    predictor: &dyn Predictor,
    feasible: &(dyn Fn(&Push) -> bool + Sync),
    max_evaluations: usize,
) -> Result<(Vec<Scored>, usize), PredictError> {
    let mut current: Vec<Scored> = Vec::new();
    for s in scored {
        if current.len() == REFINED_NODES {
            break;
        }
        if !current.iter().any(|c| c.push.node == s.push.node) {
            current.push(*s);
        }
    }
    let started = current.clone();
    let mut step = vec![INITIAL_STEP; current.len()];
    let mut evaluations = 0;
    while evaluations < max_evaluations {
        let mut owners = Vec::new();
        let mut pushes = Vec::new();
        for (k, c) in current.iter().enumerate() {
            if step[k] < FINAL_STEP {
                continue;
            }
            for axis in 0..3 {
                for sign in [1.0, -1.0] {
                    let mut v = c.push.vector;
                    v[axis] += sign * step[k];
                    let length = v.norm();
                    if !(MIN_PUSH..=MAX_PUSH).contains(&length) {
                        continue;
                    }
                    let push = Push {
                        node: c.push.node,
                        vector: v,
                    };
                    if feasible(&push) {
                        owners.push(k);
                        pushes.push(push);
                    }
                }
            }
        }
        if pushes.is_empty() {
            break;
        }
        pushes.truncate(max_evaluations - evaluations);
        owners.truncate(pushes.len());
        let predicted = predictor.predict(tree, &pushes)?;
        evaluations += pushes.len();
        let mut best: Vec<Option<Scored>> = vec![None; current.len()];
        for (k, s) in owners
            .iter()
            .zip(score(tree, objective, limits, &pushes, predicted))
        {
            let Some(s) = s else { continue };
            if best[*k].is_none_or(|b| compare(&s, &b, objective).is_lt()) {
                best[*k] = Some(s);
            }
        }
        for (k, b) in best.into_iter().enumerate() {
            if step[k] < FINAL_STEP {
                continue;
            }
            match b {
                Some(b) if compare(&b, &current[k], objective).is_lt() => current[k] = b,
                _ => step[k] *= 0.5,
            }
        }
    }
    let polished = current
        .into_iter()
        .zip(started)
        .filter(|(now, then)| now.push != then.push)
        .map(|(now, _)| now)
        .collect();
    Ok((polished, evaluations))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::predict::PhysicsPredictor;
    use crate::sim::sampling::PushDistribution;
    use crate::sim::{SimConfig, simulate};
    use crate::tree::{ScaParams, generate};
    use nalgebra::Vector3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// A target some push makes exactly: started 1.5 cm off that push, the
    /// compass search ends within a few millimetres of the target, never
    /// worse than where it started, and inside its budget.
    #[test]
    fn polishing_a_push_near_the_one_that_made_the_target_recovers_it() {
        let tree = generate(10, 3, &ScaParams::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (truth, targets) =
            std::iter::repeat_with(|| PushDistribution::default().sample(&tree, &mut rng))
                .find_map(|p| {
                    (p.vector.norm() > MIN_PUSH + 0.02 && p.vector.norm() < MAX_PUSH - 0.02)
                        .then(|| simulate(&tree, &p, &SimConfig::default()).ok())
                        .flatten()
                        .map(|o| (p, o.final_positions))
                })
                .unwrap();
        let objective = Objective::shape(targets);
        let start = Push {
            node: truth.node,
            vector: truth.vector + Vector3::new(0.015, -0.01, 0.005),
        };
        let scored_start = score(
            &tree,
            &objective,
            None,
            &[start],
            PhysicsPredictor.predict(&tree, &[start]).unwrap(),
        )[0]
        .unwrap();
        let all = |_: &Push| true;
        let (found, evaluations) = refine(
            &tree,
            &objective,
            None,
            &[scored_start],
            &PhysicsPredictor,
            &all,
            PHYSICS_REFINE_EVALUATIONS,
        )
        .unwrap();
        assert!(evaluations <= PHYSICS_REFINE_EVALUATIONS && evaluations > 0);
        assert_eq!(found.len(), 1, "one node, polished");
        let best = found[0].predicted_error;
        assert!(
            best < scored_start.predicted_error * 0.5 && best < 0.004,
            "from {:.4} m to {best:.4} m",
            scored_start.predicted_error
        );
    }

    /// Pushes the arm cannot make are never predicted.
    #[test]
    fn infeasible_neighbours_are_not_predicted() {
        let tree = generate(8, 4, &ScaParams::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let objective = Objective::shape(tree.positions().to_vec());
        let s = std::iter::repeat_with(|| PushDistribution::default().sample(&tree, &mut rng))
            .find_map(|push| {
                score(
                    &tree,
                    &objective,
                    None,
                    &[push],
                    PhysicsPredictor.predict(&tree, &[push]).unwrap(),
                )[0]
            })
            .unwrap();
        let none = |_: &Push| false;
        let (found, evaluations) =
            refine(&tree, &objective, None, &[s], &PhysicsPredictor, &none, 72).unwrap();
        assert_eq!((found.len(), evaluations), (0, 0));
    }
}
