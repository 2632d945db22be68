//! Planning on a tree whose stiffness is known, stage by stage: propose
//! pushes (the policy's ranking or the tree's geometry), search them with
//! a predictor, execute the best on the arm, fall back to Algorithm 1's
//! ranked walk, and answer.

use std::time::Instant;

use crate::planner::answer::{Clearance, Plan, PlanError};
use crate::planner::base::{self, BasePose};
use crate::planner::execute::{Found, Judged, Run};
use crate::planner::objective::{Limits, Objective};
use crate::planner::placed::{Placed, Planner};
use crate::planner::predict::{ContactPolicy, PhysicsPredictor, Predictor};
use crate::planner::query::{Query, Stance, Strategy};
use crate::planner::refine;
use crate::planner::search::{self, SearchOptions, score, search_pushes};
use crate::planner::seeds::{self, interleave, ranked};
use crate::planner::{eased, shorter};
use crate::robot::collision::{Allowed, TreeObstacles};
use crate::robot::motion::push_motion::Outcome;
use crate::robot::motion::rrt::{Config, MotionValidator};
use crate::robot::motion::scene::PlanningScene;
use crate::sim::Push;
use crate::tree::Tree;

/// Predictions the fallback to the policy's own pushes may make even when
/// the search spent the budget (the reachable ones, best ranked first).
pub const FALLBACK_PREDICTIONS: usize = 8;

/// Nodes searched by default when the geometry proposes them (`clear`,
/// `reach`, a weighted shape): its proposals are cruder than the policy's,
/// so more are tried (an intruding branch and its ancestors).
pub const DEFAULT_GEOMETRIC_CANDIDATES: usize = 6;
/// Over-limit pushes better than the one executed that are reported.
const MAX_OVER_LIMIT_NOTED: usize = 4;
/// How far over a limit a `model` prediction may read and still be
/// checked by simulation: loads read from the forward model's positions err
/// by a median 12 % and a p90 of 68 % in stress (`docs/results/tasks_eval.md`),
/// so a strict screen drops pushes that are in fact within the limits (on
/// 105 `clear` tasks with a base region, a screen at 1.0× met 74.6 % of the
/// tasks the oracle meets, 1.5× 86.4 %, 2.0× 91.5 %, with no executed push
/// over a limit in any).
const MODEL_LOAD_SLACK: f64 = 2.0;
/// Pushes whose simulation is checked (loads, and for `model` a `clear` or
/// `reach` objective) at most: one simulation each, no arm work.
const MAX_SIMULATED_CHECKS: usize = 24;
/// Pushes executed (push check and RRT*) at most, best predicted first.
const MAX_EXECUTIONS: usize = 6;
impl Planner {
    /// The cheap reach test the push search prunes with, for pushes on
    /// `tree` by the arm at `stance` (a base region: any of its proposed
    /// placements) from `start` (default: home): IK of the pre-contact
    /// pose, joint limits, a collision-free pre-contact configuration and a
    /// straight push. For proposing only pushes the arm can make (probes).
    pub fn reach_test<'a>(
        &'a self,
        tree: &'a Tree,
        obstacles: &[crate::geometry::shape::Shape],
        stance: &'a Stance,
        start: Option<Config>,
    ) -> impl Fn(&Push) -> bool + Sync + 'a {
        let rest = TreeObstacles::new(tree).with_obstacles(obstacles);
        let fixed = match stance {
            Stance::Fixed(base) => Some(self.placed_at(base)),
            Stance::Region(_) => None,
        };
        let start = start.unwrap_or_else(|| self.robot().home());
        move |push: &Push| {
            let placed = fixed.as_ref().map(|arm| (arm, &start));
            crate::planner::execute::reach_at(self, placed, stance, tree, &rest, push).is_ok()
        }
    }

    /// Plans `query` on its tree's stiffness as given (no observations),
    /// the searching strategies also starting from the pushes in `again`:
    /// [`propose`], [`Planner::place_fixed`], then for `model` and
    /// `physics` [`search_and_execute`], else (or when nothing searched
    /// could be carried out) [`walk_ranked`], then [`closest_miss`], and
    /// [`Planner::answer`].
    pub(crate) fn plan_known(
        &self,
        query: &Query,
        policy: &dyn ContactPolicy,
        forward: Option<&dyn Predictor>,
        again: &[Push],
    ) -> Result<Plan, PlanError> {
        let clock = Instant::now();
        let tree = &query.tree;
        let objective = &query.objective;
        let rest = TreeObstacles::new(tree).with_obstacles(&query.obstacles);
        let proposals = propose(query, policy)?;
        let fixed = self.place_fixed(query, &rest)?;
        let enforce_limits = query.strategy != Strategy::Paper;
        let limits = query.limits.filter(|_| enforce_limits);
        let screen = screen(query, limits);
        let mut run = Run {
            planner: self,
            query,
            rest: &rest,
            fixed: &fixed,
            clock,
            attempts: Vec::new(),
            no_path: Vec::new(),
            enforce_limits,
            verify: query.strategy == Strategy::Model && objective.has_goal_region(),
            missed: Vec::new(),
            blocked: Vec::new(),
            overloaded: Vec::new(),
        };
        let no_action_error = objective.residual(tree, tree.positions());
        let physics = PhysicsPredictor;
        let predictor: Option<&dyn Predictor> = match query.strategy {
            Strategy::Paper => None,
            Strategy::Physics => Some(&physics),
            Strategy::Model => Some(forward.ok_or(PlanError::NoForwardModel)?),
        };
        let judged = Judged {
            screen: screen.as_ref(),
            no_action_error,
        };
        let mut evaluations = 0;
        let mut found = None;
        if let Some(predictor) = predictor {
            found = search_and_execute(
                &mut run,
                &proposals,
                again,
                predictor,
                &judged,
                &mut evaluations,
            )?;
        }
        if found.is_none() {
            found = walk_ranked(&mut run, proposals, predictor, &judged, &mut evaluations)?;
        }
        if found.is_none()
            && let Some(predictor) = predictor
        {
            found = shorter::shorter(&mut run, predictor, &judged, &mut evaluations)?;
        }
        if found.is_none()
            && let Some(predictor) = predictor
        {
            found = eased::eased(&mut run, predictor, &judged, &mut evaluations)?;
        }
        if found.is_none() {
            found = closest_miss(&mut run, no_action_error);
        }
        let attempts = std::mem::take(&mut run.attempts);
        Ok(self.answer(
            query,
            found,
            fixed.as_ref(),
            Answered {
                limits,
                no_action_error,
                evaluations,
                attempts,
                clock,
            },
        ))
    }

    /// With a fixed base: the arm placed there and its start (the one
    /// given, else home or the first free tucked pose), or
    /// [`PlanError::StartInCollision`]. `None` with a base region (each
    /// push places the arm itself).
    fn place_fixed(
        &self,
        query: &Query,
        rest: &TreeObstacles,
    ) -> Result<Option<Placed>, PlanError> {
        let Stance::Fixed(base) = &query.stance else {
            return Ok(None);
        };
        let arm = self.placed_at(base);
        let free = PlanningScene::new(&arm, rest, Allowed::default());
        let start = match query.start {
            Some(q) => Some(q).filter(|q| free.config_valid(q)),
            None => base::tucked_starts(&arm.robot)
                .into_iter()
                .find(|q| free.config_valid(q)),
        };
        let Some(start) = start else {
            return Err(PlanError::StartInCollision);
        };
        Ok(Some(Placed {
            pose: BasePose::of(base),
            arm,
            start,
        }))
    }

    /// The planner's answer from what was found (or not).
    fn answer(
        &self,
        query: &Query,
        found: Option<Found>,
        fixed: Option<&Placed>,
        answered: Answered,
    ) -> Plan {
        let objective = &query.objective;
        let home = self.robot().home();
        let (base, start, start_chosen) = match (&found, fixed) {
            (Some(f), _) => (
                f.placed.pose,
                f.placed.start,
                query.start.is_none() && (fixed.is_none() || f.placed.start != home),
            ),
            (None, Some(f)) => (f.pose, f.start, query.start.is_none() && f.start != home),
            (None, None) => (
                BasePose::of(&self.robot().default_base()),
                query.start.unwrap_or(home),
                false,
            ),
        };
        Plan {
            strategy: query.strategy,
            objective: objective.kind(),
            base,
            start,
            start_chosen,
            predicted_error: found
                .as_ref()
                .and_then(|f| f.predicted.map(|s| s.predicted_error)),
            no_action_error: answered.no_action_error,
            predicted_loads: found.as_ref().and_then(|f| f.predicted.map(|s| s.loads)),
            simulated_loads: found.as_ref().and_then(|f| f.simulated.map(|s| s.loads)),
            clearance: found.as_ref().and_then(|f| {
                matches!(objective, Objective::Clear { .. }).then_some(Clearance {
                    predicted: f.predicted.and_then(|s| s.clearance),
                    simulated: f.simulated.and_then(|s| s.clearance),
                })
            }),
            guard_contact_force: answered.limits.zip(found.as_ref()).and_then(|(l, f)| {
                l.guard_force(
                    &query.tree,
                    &Push {
                        node: f.plan.node,
                        vector: f.plan.push,
                    },
                )
            }),
            limits: answered.limits,
            plan: found.map(|f| f.plan),
            evaluations: answered.evaluations,
            attempts: answered.attempts,
            total_ms: answered.clock.elapsed().as_secs_f64() * 1e3,
            identification: None,
        }
    }
}

/// What the answer reports besides the push found.
struct Answered {
    limits: Option<Limits>,
    no_action_error: f64,
    evaluations: usize,
    attempts: Vec<crate::planner::answer::Attempt>,
    clock: Instant,
}

/// Stage 1, propose: the pushes to start from, with their rank: the
/// policy's for a full shape (and any shape for `paper`), the tree's
/// geometry's otherwise (a weighted shape interleaves the policy's).
fn propose(query: &Query, policy: &dyn ContactPolicy) -> Result<Vec<(usize, Push)>, PlanError> {
    let tree = &query.tree;
    let objective = &query.objective;
    Ok(match (objective, query.strategy) {
        (Objective::Shape { targets, .. }, Strategy::Paper) => ranked(policy, tree, targets)?,
        (_, Strategy::Paper) => return Err(PlanError::PaperNeedsShape(objective.kind())),
        (Objective::Shape { targets, .. }, _) if objective.full_shape().is_some() => {
            ranked(policy, tree, targets)?
        }
        _ => {
            let geometric = seeds::geometric_seeds(
                tree,
                objective,
                query.max_candidates.max(DEFAULT_GEOMETRIC_CANDIDATES),
            );
            // A weighted shape still has targets for every node: the
            // policy's ranking for them is a second opinion, taken in
            // turns with the geometry's.
            let policy_pushes = match objective {
                Objective::Shape { targets, .. } => ranked(policy, tree, targets)?
                    .into_iter()
                    .map(|(_, p)| p)
                    .collect(),
                _ => Vec::new(),
            };
            interleave(&geometric, &policy_pushes)
                .into_iter()
                .enumerate()
                .map(|(k, p)| (k + 1, p))
                .collect()
        }
    })
}

/// The limits the search screens predictions with: for `model`, loosened
/// by its load error (the simulation of each push about to be executed is
/// held to the limits themselves).
fn screen(query: &Query, limits: Option<Limits>) -> Option<Limits> {
    limits.map(|l| match query.strategy {
        Strategy::Model => Limits {
            max_stress: l.max_stress * MODEL_LOAD_SLACK,
            max_contact_force: l.max_contact_force * MODEL_LOAD_SLACK,
        },
        _ => l,
    })
}

/// A proposed node's rank (0: not proposed).
fn rank_of(proposals: &[(usize, Push)], node: usize) -> usize {
    proposals
        .iter()
        .find(|(_, p)| p.node == node)
        .map_or(0, |(r, _)| *r)
}

/// Stages 2 and 3 for `model` and `physics`, search then execute: the
/// push search from the top proposals (and `again`), physics pushes
/// polished ([`refine`]), then the best predicted pushes carried out on
/// the arm in turn until one works.
fn search_and_execute(
    run: &mut Run<'_>,
    proposals: &[(usize, Push)],
    again: &[Push],
    predictor: &dyn Predictor,
    judged: &Judged<'_>,
    evaluations: &mut usize,
) -> Result<Option<Found>, PlanError> {
    let query = run.query;
    let tree = &query.tree;
    let objective = &query.objective;
    // How many proposals the search starts from.
    let searched = if objective.full_shape().is_some() {
        query.max_candidates.max(1)
    } else {
        query.max_candidates.max(DEFAULT_GEOMETRIC_CANDIDATES)
    };
    let seeds: Vec<Push> = proposals
        .iter()
        .take(searched)
        .map(|(_, p)| *p)
        .chain(again.iter().copied())
        .collect();
    let options = SearchOptions {
        max_evaluations: query.evaluations(),
        seed: query.seed,
        ..SearchOptions::default()
    };
    let scored = {
        let feasible = |p: &Push| run.reachable(p);
        let (scored, count) = search_pushes(
            tree,
            objective,
            judged.screen,
            &seeds,
            predictor,
            &feasible,
            &options,
        )?;
        *evaluations = count;
        // Physics pushes are polished (see `refine`).
        if query.strategy == Strategy::Physics {
            let (mut polished, count) = refine::refine(
                tree,
                objective,
                judged.screen,
                &scored,
                predictor,
                &feasible,
                refine::PHYSICS_REFINE_EVALUATIONS,
            )?;
            *evaluations += count;
            polished.extend(scored);
            search::sort_scored(&mut polished, objective);
            polished
        } else {
            scored
        }
    };
    let mut executed = 0;
    let mut checked = 0;
    let mut over_limit = 0;
    for s in &scored {
        let rank = rank_of(proposals, s.push.node);
        if !s.within_limits {
            // Sorted after every push within the limits: only the ones
            // reached here, none of those left, are noted.
            if over_limit < MAX_OVER_LIMIT_NOTED {
                run.note(rank, &s.push, Outcome::OverLimit, Some(s), 0.0);
            }
            over_limit += 1;
            continue;
        }
        if executed >= MAX_EXECUTIONS || checked >= MAX_SIMULATED_CHECKS {
            break;
        }
        if s.predicted_error >= judged.no_action_error {
            run.note(rank, &s.push, Outcome::NotHelpful, Some(s), 0.0);
            break;
        }
        let tried = run.try_push(rank, &s.push, Some(s));
        // A push passed over on its simulation alone cost no arm work: it
        // counts against the simulated checks only.
        checked += 1;
        if !matches!(
            run.attempts.last().map(|a| a.outcome),
            Some(Outcome::OverLimit | Outcome::Missed)
        ) {
            executed += 1;
        }
        if let Some((plan, placed, simulated)) = tried {
            return Ok(Some(Found {
                plan,
                placed,
                predicted: Some(*s),
                simulated,
            }));
        }
    }
    Ok(None)
}

/// Algorithm 1 as published (the proposals in rank order); for the
/// searching strategies the fallback when no searched push could be
/// carried out: the proposed pushes the arm can reach (the reach test
/// costs far less than a prediction, and most low-ranked pushes fail it
/// from a fixed base), the best ranked predicted in one batch (what is
/// left of the evaluation budget, at least [`FALLBACK_PREDICTIONS`]) and
/// the unhelpful and overloading ones dropped.
fn walk_ranked(
    run: &mut Run<'_>,
    proposals: Vec<(usize, Push)>,
    predictor: Option<&dyn Predictor>,
    judged: &Judged<'_>,
    evaluations: &mut usize,
) -> Result<Option<Found>, PlanError> {
    let query = run.query;
    let (tree, objective) = (&query.tree, &query.objective);
    let proposals: Vec<(usize, Push)> = match predictor {
        None => proposals,
        Some(_) => proposals
            .into_iter()
            .filter(|(rank, push)| match run.reach_check(push) {
                Ok(()) => true,
                Err(outcome) => {
                    run.note(*rank, push, outcome, None, 0.0);
                    false
                }
            })
            .collect(),
    };
    let predicted: Vec<Option<search::Scored>> = match predictor {
        None => vec![None; proposals.len()],
        Some(p) => {
            let left = query
                .evaluations()
                .saturating_sub(*evaluations)
                .max(FALLBACK_PREDICTIONS);
            let pushes: Vec<Push> = proposals.iter().take(left).map(|(_, p)| *p).collect();
            *evaluations += pushes.len();
            let predictions = p.predict(tree, &pushes)?;
            let mut scored = score(tree, objective, judged.screen, &pushes, predictions);
            scored.resize(proposals.len(), None);
            scored
        }
    };
    // Predicted ones in the search's order, the rest as ranked (a stable
    // sort).
    let mut order: Vec<usize> = (0..proposals.len()).collect();
    order.sort_by(|&a, &b| match (&predicted[a], &predicted[b]) {
        (Some(x), Some(y)) => search::compare(x, y, objective),
        (Some(_), None) => std::cmp::Ordering::Less,
        (None, Some(_)) => std::cmp::Ordering::Greater,
        (None, None) => std::cmp::Ordering::Equal,
    });
    for k in order {
        let (rank, push) = &proposals[k];
        let scored = predicted[k];
        if predictor.is_some() {
            let Some(s) = scored else {
                // Beyond the predictions allowed (or rejected by the
                // simulator): a searching strategy never executes a push
                // it has not predicted.
                run.note(*rank, push, Outcome::Skipped, None, 0.0);
                continue;
            };
            let outcome = if !s.within_limits {
                Some(Outcome::OverLimit)
            } else if s.predicted_error >= judged.no_action_error {
                Some(Outcome::NotHelpful)
            } else {
                None
            };
            if let Some(outcome) = outcome {
                run.note(*rank, push, outcome, Some(&s), 0.0);
                continue;
            }
        }
        if let Some((plan, placed, simulated)) = run.try_push(*rank, push, scored.as_ref()) {
            return Ok(Some(Found {
                plan,
                placed,
                predicted: scored,
                simulated,
            }));
        }
    }
    Ok(None)
}

/// When nothing met the objective: the missed push that came closest in
/// its simulation, if it helps at all, carried out for what its
/// simulation gave (reported as predicted too).
fn closest_miss(run: &mut Run<'_>, no_action_error: f64) -> Option<Found> {
    let mut missed = std::mem::take(&mut run.missed);
    missed.sort_by(|a, b| a.1.predicted_error.total_cmp(&b.1.predicted_error));
    run.verify = false;
    for (rank, seen) in missed.into_iter().take(2) {
        if seen.predicted_error >= no_action_error {
            break;
        }
        if let Some((plan, placed, simulated)) = run.try_push(rank, &seen.push, Some(&seen)) {
            return Some(Found {
                plan,
                placed,
                predicted: Some(seen),
                simulated,
            });
        }
    }
    None
}
