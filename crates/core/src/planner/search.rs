//! Choosing the push vector for each candidate node: a few rounds of the
//! cross-entropy method around the contact policy's push T_j, every round of
//! every node predicted in one batch, each push scored by the objective's
//! predicted residual (for a full shape, the paper's largest node distance
//! to the target). With limits, a push predicted to overload the tree ranks
//! after every push that does not; among pushes that satisfy a `clear` or
//! `reach` objective the least stressing, then the shortest, ranks first.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::objective::{Limits, Objective, SATISFIED};
use super::predict::{PredictError, Predictor};
use crate::model::domain::Margin;
use crate::seed::standard_normal;
use crate::sim::Push;
use crate::sim::loads::PushLoads;
use crate::tree::Tree;

/// The paper's pushes are 5-15 cm; the forward model was trained on them.
pub const MIN_PUSH: f64 = 0.05;
pub const MAX_PUSH: f64 = 0.15;

/// How much wider than the first round's spread a seed whose pushes the
/// arm can make none of is looked around, once.
const WIDER_SIGMA_FACTOR: f64 = 3.0;
/// Mixed into the search's seed for the wider look's own random stream.
const WIDER_STREAM: u64 = 0x5749_4445_5221;

/// Pushes per node and round when the budget is small: the policy's push
/// (or the mean) and two around it.
const MIN_SAMPLES: usize = 3;

#[derive(Debug, Clone)]
pub struct SearchOptions {
    pub rounds: usize,
    /// Pushes sampled per node and round, at most (fewer when
    /// `max_evaluations` spread over the rounds and nodes allows fewer).
    pub samples: usize,
    /// The best this many of a node's round set its next mean and spread.
    pub elite: usize,
    /// Spread of the first round around T_j (m).
    pub initial_sigma: f64,
    /// Predictions allowed in all (rounds stop early when reached).
    pub max_evaluations: usize,
    /// A node whose best push so far is predicted this much worse than the
    /// best of all (m) gets no further rounds: the search would not pick it.
    pub drop_margin: f64,
    pub seed: u64,
}

impl Default for SearchOptions {
    fn default() -> Self {
        Self {
            rounds: 3,
            samples: 8,
            elite: 3,
            initial_sigma: 0.03,
            max_evaluations: 96,
            drop_margin: 0.05,
            seed: 1,
        }
    }
}

/// A push and what it is predicted to leave.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Scored {
    pub push: Push,
    /// The objective's predicted residual after the push (m).
    pub predicted_error: f64,
    /// Predicted loads of the held push.
    pub loads: PushLoads,
    /// Whether the loads stay within the limits (always, without limits).
    pub within_limits: bool,
    /// For `clear`: the predicted clearance between branches and regions
    /// (m; negative: overlapping).
    pub clearance: Option<f64>,
}

impl Scored {
    /// The search's order: within the limits first, then the residual; for
    /// objectives met exactly (`clear`, `reach`) ties at zero go to the
    /// smaller peak stress, then the shorter push.
    fn order(&self, other: &Self, regional: bool) -> std::cmp::Ordering {
        let key = |s: &Self| {
            let met = regional && s.predicted_error <= SATISFIED;
            let residual = if met { 0.0 } else { s.predicted_error };
            let (stress, length) = if met {
                (s.loads.peak_stress, s.push.vector.norm())
            } else {
                (0.0, 0.0)
            };
            (!s.within_limits, residual, stress, length)
        };
        let (a, b) = (key(self), key(other));
        a.0.cmp(&b.0)
            .then(a.1.total_cmp(&b.1))
            .then(a.2.total_cmp(&b.2))
            .then(a.3.total_cmp(&b.3))
    }
}

/// Sorts `scored` best first (see [`Scored`]'s order).
pub fn sort_scored(scored: &mut [Scored], objective: &Objective) {
    scored.sort_by(|a, b| compare(a, b, objective));
}

/// The search's order of two scored pushes for `objective` (best first).
pub fn compare(a: &Scored, b: &Scored, objective: &Objective) -> std::cmp::Ordering {
    a.order(b, objective.has_goal_region())
}

/// `v` with its length clamped into the trained range.
fn clamp_length(v: Vector3<f64>) -> Option<Vector3<f64>> {
    let length = v.norm();
    (length.is_finite() && length > 1e-9).then(|| v * (length.clamp(MIN_PUSH, MAX_PUSH) / length))
}

/// A push drawn around `mean` with isotropic spread `sigma` (m), its
/// length clamped into the trained range; `None` for a zero push.
fn sample_around(mean: &Vector3<f64>, sigma: f64, rng: &mut ChaCha8Rng) -> Option<Vector3<f64>> {
    let noise = Vector3::new(
        standard_normal(rng),
        standard_normal(rng),
        standard_normal(rng),
    );
    clamp_length(mean + noise * sigma)
}

/// Whether the policy's own push T_j is scored as it is: while the forward
/// model answers for its length (`model::domain` reaches a factor
/// [`Margin::push_factor`] below the shortest trained push). Outside that,
/// it is clamped into the trained range like every sampled push. Scoring a
/// short push the policy asks for as it is means the search never does
/// worse than executing the policy's pick.
fn scored_as_is(v: &Vector3<f64>) -> bool {
    (MIN_PUSH / Margin::STANDARD.push_factor..=MAX_PUSH).contains(&v.norm())
}

/// Scores each prediction: the objective's residual and the limits' verdict.
pub fn score(
    tree: &Tree,
    objective: &Objective,
    limits: Option<&Limits>,
    pushes: &[Push],
    predicted: Vec<Option<super::predict::Predicted>>,
) -> Vec<Option<Scored>> {
    let scorer = objective.scorer();
    pushes
        .iter()
        .zip(predicted)
        .map(|(push, p)| {
            p.map(|p| Scored {
                push: *push,
                predicted_error: scorer.residual(tree, &p.positions),
                clearance: scorer.clearance(tree, &p.positions),
                within_limits: limits.is_none_or(|l| l.allow(&p.loads)),
                loads: p.loads,
            })
        })
        .collect()
}

/// Searches a push for each seed (node, initial push). `feasible` prunes
/// pushes the arm cannot carry out before they are predicted. Returns every
/// scored push, best first, and the number of predictions made.
pub fn search_pushes(
    tree: &Tree,
    objective: &Objective,
    limits: Option<&Limits>,
    seeds: &[Push],
    predictor: &dyn Predictor,
    feasible: &(dyn Fn(&Push) -> bool + Sync),
    options: &SearchOptions,
) -> Result<(Vec<Scored>, usize), PredictError> {
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    // Per seed: mean push and isotropic spread.
    let mut state: Vec<(Vector3<f64>, f64)> = seeds
        .iter()
        .filter_map(|s| clamp_length(s.vector).map(|v| (v, options.initial_sigma)))
        .collect();
    let seeds: Vec<&Push> = seeds
        .iter()
        .filter(|s| clamp_length(s.vector).is_some())
        .collect();
    let mut scored = Vec::new();
    let mut evaluations = 0;
    // Per seed: the best error predicted so far, and whether it still
    // gets rounds.
    let mut best = vec![f64::INFINITY; seeds.len()];
    let mut active = vec![true; seeds.len()];
    for round in 0..options.rounds {
        let mut round_pushes: Vec<(usize, Push)> = Vec::new();
        // A small budget is spread over every round and active seed rather
        // than spent on the first seeds' first round.
        let active_seeds = active.iter().filter(|a| **a).count().max(1);
        let rounds_left = options.rounds - round;
        let budget_left = options.max_evaluations.saturating_sub(evaluations);
        let samples = budget_left
            .div_ceil(rounds_left * active_seeds)
            .clamp(MIN_SAMPLES, options.samples.max(MIN_SAMPLES));
        for (k, (seed, (mean, sigma))) in seeds.iter().zip(&state).enumerate() {
            if !active[k] {
                continue;
            }
            for i in 0..samples {
                let vector = if round == 0 && i == 0 {
                    // The policy's own push is always a candidate (`mean`
                    // is still its clamped form in the first round).
                    if scored_as_is(&seed.vector) {
                        seed.vector
                    } else {
                        *mean
                    }
                } else {
                    match sample_around(mean, *sigma, &mut rng) {
                        Some(v) => v,
                        None => continue,
                    }
                };
                round_pushes.push((
                    k,
                    Push {
                        node: seed.node,
                        vector,
                    },
                ));
            }
        }
        let budget = options.max_evaluations.saturating_sub(evaluations);
        let keep_feasible = |pushes: Vec<(usize, Push)>| -> Vec<(usize, Push)> {
            use rayon::prelude::*;
            pushes
                .into_par_iter()
                .filter(|(_, p)| feasible(p))
                .collect()
        };
        let mut candidates = keep_feasible(round_pushes);
        if round == 0 {
            // A seed none of whose pushes the arm can make (the arm cannot
            // push its node that way from where it may stand) gets one
            // wider look around before it is given up: a push that does
            // part of the work (its node's move across, not toward the
            // arm) may still be the best there is. The look draws from its
            // own random stream, so every other seed's pushes are those the
            // search would draw without it.
            let mut wider = Vec::new();
            let mut wider_rng = ChaCha8Rng::seed_from_u64(options.seed ^ WIDER_STREAM);
            let sigma = WIDER_SIGMA_FACTOR * options.initial_sigma;
            let unreached: Vec<usize> = (0..seeds.len())
                .filter(|&k| active[k] && !candidates.iter().any(|c| c.0 == k))
                .collect();
            for _ in 0..samples {
                for &k in &unreached {
                    if let Some(vector) = sample_around(&state[k].0, sigma, &mut wider_rng) {
                        wider.push((
                            k,
                            Push {
                                node: seeds[k].node,
                                vector,
                            },
                        ));
                    }
                }
            }
            candidates.extend(keep_feasible(wider));
        }
        candidates.truncate(budget);
        if candidates.is_empty() {
            break;
        }
        let pushes: Vec<Push> = candidates.iter().map(|c| c.1).collect();
        let predicted = predictor.predict(tree, &pushes)?;
        evaluations += pushes.len();
        let mut by_seed: Vec<Vec<Scored>> = vec![Vec::new(); seeds.len()];
        for ((k, _), s) in candidates
            .iter()
            .zip(score(tree, objective, limits, &pushes, predicted))
        {
            if let Some(s) = s {
                by_seed[*k].push(s);
                scored.push(s);
            }
        }
        for (k, mut round_scores) in by_seed.into_iter().enumerate() {
            if round_scores.is_empty() {
                continue;
            }
            sort_scored(&mut round_scores, objective);
            if round_scores[0].within_limits {
                best[k] = best[k].min(round_scores[0].predicted_error);
            }
            let elite = &round_scores[..options.elite.min(round_scores.len())];
            let mean =
                elite.iter().map(|s| s.push.vector).sum::<Vector3<f64>>() / elite.len() as f64;
            let spread = (elite
                .iter()
                .map(|s| (s.push.vector - mean).norm_squared())
                .sum::<f64>()
                / (3.0 * elite.len() as f64))
                .sqrt();
            state[k] = (mean, spread.max(0.005));
        }
        let overall = best.iter().copied().fold(f64::INFINITY, f64::min);
        for (k, b) in best.iter().enumerate() {
            if *b > overall + options.drop_margin {
                active[k] = false;
            }
        }
        if evaluations >= options.max_evaluations {
            break;
        }
    }
    sort_scored(&mut scored, objective);
    Ok((scored, evaluations))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::predict::PhysicsPredictor;
    use crate::sim::sampling::PushDistribution;
    use crate::sim::{SimConfig, simulate};
    use crate::tree::{ScaParams, generate};

    /// A push the policy asks for is scored as it is while the forward
    /// model's domain covers its length; shorter ones are lengthened into
    /// the trained range, as every sampled push is.
    #[test]
    fn the_policys_own_push_is_scored_unchanged_inside_the_domain() {
        let tree = generate(8, 4, &ScaParams::default()).unwrap();
        let targets = tree.positions();
        let options = SearchOptions {
            max_evaluations: 16,
            ..SearchOptions::default()
        };
        let all = |_: &Push| true;
        // A direction the simulator accepts at both kept lengths.
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let (node, direction) = std::iter::repeat_with(|| {
            let p = PushDistribution::default().sample(&tree, &mut rng);
            (p.node, p.vector.normalize())
        })
        .find(|(node, d)| {
            [0.03, 0.1].iter().all(|l| {
                let push = Push {
                    node: *node,
                    vector: d * *l,
                };
                simulate(&tree, &push, &SimConfig::default()).is_ok()
            })
        })
        .unwrap();
        for (length, kept) in [(0.03, true), (0.1, true), (0.01, false)] {
            let seed = Push {
                node,
                vector: direction * length,
            };
            let objective = Objective::shape(targets.to_vec());
            let (scored, _) = search_pushes(
                &tree,
                &objective,
                None,
                &[seed],
                &PhysicsPredictor,
                &all,
                &options,
            )
            .unwrap();
            let has_own = scored.iter().any(|s| s.push.vector == seed.vector);
            assert_eq!(has_own, kept, "a {length} m push");
            for s in &scored {
                let l = s.push.vector.norm();
                assert!(
                    s.push.vector == seed.vector
                        || (MIN_PUSH - 1e-12..=MAX_PUSH + 1e-12).contains(&l),
                    "a sampled push of {l} m"
                );
            }
        }
    }

    /// A seed the arm can push its node nowhere near (every push within
    /// 40° of it refused) is looked around wider once: the search still
    /// scores feasible pushes of that node (around the seed alone, at the
    /// first round's spread, it finds none).
    #[test]
    fn a_seed_the_arm_cannot_push_is_looked_around_wider() {
        let tree = generate(15, 3, &ScaParams::default()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (made, targets) = std::iter::repeat_with(|| {
            let p = PushDistribution::default().sample(&tree, &mut rng);
            (p, simulate(&tree, &p, &SimConfig::default()))
        })
        .find_map(|(p, out)| match out {
            Ok(o) if p.vector.norm() > 0.1 => Some((p, o.final_positions)),
            _ => None,
        })
        .unwrap();
        let away = made.vector.normalize();
        let feasible = |p: &Push| p.vector.normalize().dot(&away) < 0.77;
        let objective = Objective::shape(targets.clone());
        let (scored, _) = search_pushes(
            &tree,
            &objective,
            None,
            &[made],
            &PhysicsPredictor,
            &feasible,
            &SearchOptions::default(),
        )
        .unwrap();
        assert!(!scored.is_empty());
        assert!(scored.iter().all(|s| feasible(&s.push)));
    }

    /// The wider look draws from its own stream: another node's pushes,
    /// every round, are the ones the search draws when the look finds
    /// nothing, so what the look adds is compared with the same draws.
    #[test]
    fn the_wider_look_leaves_other_nodes_pushes_as_drawn() {
        let tree = generate(15, 3, &ScaParams::default()).unwrap();
        let objective = Objective::shape(tree.positions().to_vec());
        let (a, b) = (tree.len() - 1, tree.len() - 2);
        let seeds = [
            Push {
                node: a,
                vector: Vector3::new(0.08, 0.0, 0.0),
            },
            Push {
                node: b,
                vector: Vector3::new(0.0, 0.08, 0.0),
            },
        ];
        // Enough budget for full rounds and no node dropped, so the two
        // runs differ in node `b`'s pushes only.
        let options = SearchOptions {
            max_evaluations: 1000,
            drop_margin: f64::INFINITY,
            ..SearchOptions::default()
        };
        let pushes_of_a = |feasible: &(dyn Fn(&Push) -> bool + Sync)| {
            let (scored, _) = search_pushes(
                &tree,
                &objective,
                None,
                &seeds,
                &PhysicsPredictor,
                feasible,
                &options,
            )
            .unwrap();
            let mut v: Vec<[f64; 3]> = scored
                .iter()
                .filter(|s| s.push.node == a)
                .map(|s| s.push.vector.into())
                .collect();
            v.sort_by(|x, y| x.partial_cmp(y).unwrap());
            (v, scored.iter().filter(|s| s.push.node == b).count())
        };
        // Node b: nothing near its seed (the look finds pushes), or nothing.
        let near = |p: &Push| p.node != b || p.vector.normalize().y < 0.77;
        let none = |p: &Push| p.node != b;
        let (with_look, b_pushes) = pushes_of_a(&near);
        let (without, b_none) = pushes_of_a(&none);
        assert!(b_pushes > 0 && b_none == 0);
        assert!(!with_look.is_empty());
        assert_eq!(with_look, without);
    }
}
