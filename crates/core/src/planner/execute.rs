//! One planning call's state: the attempts so far, the placements of the
//! arm, and carrying out a push (reach test, push line, RRT*).

use std::time::{Duration, Instant};

use crate::planner::answer::Attempt;
use crate::planner::answer::PlanError;
use crate::planner::base::{self, BasePose};
use crate::planner::objective::{Limits, SATISFIED};
use crate::planner::placed::{Placed, Planner};
use crate::planner::predict::Predictor;
use crate::planner::query::{Query, Stance};
use crate::planner::search::{self, Scored, score};
use crate::robot::collision::{Allowed, CollisionModel, TreeObstacles};
use crate::robot::motion::push_motion::{
    Outcome, PlanOptions, PushPlan, PushSnapshots, execute, reach, reachable,
};
use crate::robot::motion::rrt::{Config, MotionValidator};
use crate::robot::motion::scene::PlanningScene;
use crate::sim::Push;
use crate::sim::loads::PushLoads;

/// RRT* iterations for a node's approach from a base where an approach to
/// the same node already found no path: the pre-contact poses of a node's
/// pushes lie close together, so a second full search rarely succeeds.
pub(crate) const RETRY_ITERATIONS: usize = 800;

/// The state of one planning call.
pub(super) struct Run<'a> {
    pub planner: &'a Planner,
    pub query: &'a Query,
    pub rest: &'a TreeObstacles,
    pub fixed: &'a Option<Placed>,
    pub clock: Instant,
    pub attempts: Vec<Attempt>,
    /// (node, base) pairs whose approach RRT* found no path.
    pub no_path: Vec<(usize, BasePose)>,
    /// Whether a push the simulation finds over a limit is refused
    /// (`model`, `physics`) or only reported (`paper`).
    pub enforce_limits: bool,
    /// Whether a push predicted to meet a `clear` or `reach` objective
    /// must meet it in its simulation too (`model`; `physics` predicted
    /// with that very simulation).
    pub verify: bool,
    /// Pushes passed over as [`Outcome::Missed`], with their rank and what
    /// their simulation gave (residual, loads, clearance).
    pub missed: Vec<(usize, Scored)>,
    /// Pushes predicted to help that the arm could not carry out (no
    /// stance reached, the tool collided, the straight push or the approach
    /// blocked), with their rank and prediction: [`crate::planner::shorter`]
    /// tries them shorter.
    pub blocked: Vec<(usize, Scored)>,
    /// Pushes predicted within the limits that their simulation put over
    /// one, with their rank, prediction and simulated loads:
    /// [`crate::planner::eased`] tries them eased back to the limits.
    pub overloaded: Vec<(usize, Scored, PushLoads)>,
}

impl Run<'_> {
    fn remaining(&self) -> Duration {
        self.query.budget.saturating_sub(self.clock.elapsed())
    }

    /// Records an attempt at `push` with what was predicted of it.
    pub fn note(
        &mut self,
        rank: usize,
        push: &Push,
        outcome: Outcome,
        predicted: Option<&Scored>,
        ms: f64,
    ) {
        self.attempts.push(Attempt {
            node: push.node,
            rank,
            push: push.vector.into(),
            outcome,
            predicted_error: predicted.map(|s| s.predicted_error),
            predicted_loads: predicted.map(|s| s.loads),
            simulated_loads: None,
            ms,
        });
    }

    /// The base poses to try for `push`: the fixed base, or the region's
    /// proposals behind the push, then pulling from ahead of it (never in
    /// the cheap reach test: only pushes worth executing pay for the
    /// second side).
    fn poses(&self, push: &Push) -> Vec<BasePose> {
        match (self.fixed, &self.query.stance) {
            (Some(f), _) => vec![f.pose],
            (None, Stance::Region(region)) => {
                let (tree, arm) = (&self.query.tree, self.planner.robot());
                let mut poses = base::proposals(region, tree, push, arm);
                for pose in base::pulling_proposals(region, tree, push, arm) {
                    if !poses.iter().any(|b| b.same_as(&pose)) {
                        poses.push(pose);
                    }
                }
                poses
            }
            (None, Stance::Fixed(_)) => Vec::new(),
        }
    }

    /// The arm at `pose` (one of [`Self::poses`]) with a collision-free
    /// start, or `None` where it has none; the fixed base as placed.
    fn place(&self, pose: BasePose) -> Option<Placed> {
        if let Some(f) = self.fixed {
            return Some(Placed {
                pose: f.pose,
                arm: f.arm.clone(),
                start: f.start,
            });
        }
        let arm = self.planner.placed_at(&pose.isometry());
        let free = PlanningScene::new(&arm, self.rest, Allowed::default());
        let start = match self.query.start {
            Some(q) => free.config_valid(&q).then_some(q),
            None => base::tucked_starts(&arm.robot)
                .into_iter()
                .find(|q| free.config_valid(q)),
        }?;
        Some(Placed { pose, arm, start })
    }

    /// Whether the arm can reach `push` from some placement (the cheap test).
    pub fn reachable(&self, push: &Push) -> bool {
        self.reach_check(push).is_ok()
    }

    /// [`Self::reachable`], or the furthest any placement got.
    pub fn reach_check(&self, push: &Push) -> Result<(), Outcome> {
        let fixed = self.fixed.as_ref().map(|f| (&f.arm, &f.start));
        reach_at(
            self.planner,
            fixed,
            &self.query.stance,
            &self.query.tree,
            self.rest,
            push,
        )
    }

    /// Predicts `pushes` (each with its rank) again, keeps those that help
    /// and pass the screen, and tries the best of them, at most
    /// `executions`, best predicted first, until one is carried out: the
    /// retry of [`crate::planner::shorter`] and [`crate::planner::eased`].
    pub fn try_again(
        &mut self,
        pushes: &[(usize, Push)],
        predictor: &dyn Predictor,
        judged: &Judged<'_>,
        evaluations: &mut usize,
        executions: usize,
    ) -> Result<Option<Found>, PlanError> {
        if pushes.is_empty() {
            return Ok(None);
        }
        let query = self.query;
        let (tree, objective) = (&query.tree, &query.objective);
        *evaluations += pushes.len();
        let only: Vec<Push> = pushes.iter().map(|(_, p)| *p).collect();
        let predictions = predictor.predict(tree, &only)?;
        let scored = score(tree, objective, judged.screen, &only, predictions);
        let mut helpful: Vec<(usize, Scored)> = pushes
            .iter()
            .zip(scored)
            .filter_map(|((rank, _), s)| Some((*rank, s?)))
            .filter(|(_, s)| s.within_limits && s.predicted_error < judged.no_action_error)
            .collect();
        helpful.sort_by(|a, b| search::compare(&a.1, &b.1, objective));
        for (rank, s) in helpful.into_iter().take(executions) {
            if let Some((plan, placed, simulated)) = self.try_push(rank, &s.push, Some(&s)) {
                return Ok(Some(Found {
                    plan,
                    placed,
                    predicted: Some(s),
                    simulated,
                }));
            }
        }
        Ok(None)
    }

    /// Tries to carry out `push` from each placement; records the attempt.
    /// A push carried out is also checked against the limits with the
    /// simulation its push line was checked with: the returned loads are
    /// the simulator's.
    pub fn try_push(
        &mut self,
        rank: usize,
        push: &Push,
        predicted: Option<&Scored>,
    ) -> Option<(PushPlan, Placed, Option<SimulatedHold>)> {
        let remaining = self.remaining();
        if remaining.is_zero() {
            self.note(rank, push, Outcome::Skipped, predicted, 0.0);
            return None;
        }
        let started = Instant::now();
        let tree = &self.query.tree;
        let mut options = PlanOptions::default();
        options.rrt.seed = self.query.seed;
        options.execution = self.query.execution;
        let full_iterations = options.rrt.max_iterations;
        let poses = self.poses(push);
        // Until some pose has a collision-free start.
        let mut outcome = Outcome::StartInCollision;
        // The deformed tree does not depend on the base: simulated once, as
        // far as the push lines get. The whole push first: its loads and
        // what it does for the objective are checked before any arm work.
        let snapshots = PushSnapshots::new(tree, push, self.rest);
        let simulated = snapshots.final_state().map(|(positions, loads)| {
            let scorer = self.query.objective.scorer();
            (
                scorer.residual(tree, positions),
                SimulatedHold {
                    loads,
                    clearance: scorer.clearance(tree, positions),
                },
            )
        });
        let verdict = match simulated {
            Some((_, hold))
                if self.enforce_limits
                    && self.query.limits.is_some_and(|l| !l.allow(&hold.loads)) =>
            {
                Some(Outcome::OverLimit)
            }
            Some((residual, hold))
                if self.verify
                    && predicted.is_some_and(|p| p.predicted_error <= SATISFIED)
                    && residual > SATISFIED =>
            {
                let seen = Scored {
                    push: *push,
                    predicted_error: residual,
                    loads: hold.loads,
                    within_limits: true,
                    clearance: hold.clearance,
                };
                self.missed.push((rank, seen));
                Some(Outcome::Missed)
            }
            _ => None,
        };
        if let (Some(Outcome::OverLimit), Some((_, hold)), Some(p)) =
            (verdict, simulated, predicted)
        {
            self.overloaded.push((rank, *p, hold.loads));
        }
        if let Some(outcome) = verdict {
            let ms = started.elapsed().as_secs_f64() * 1e3;
            self.note(rank, push, outcome, predicted, ms);
            if let Some(a) = self.attempts.last_mut() {
                a.simulated_loads = simulated.map(|s| s.1.loads);
            }
            return None;
        }
        let simulated = simulated.map(|s| s.1);
        let mut result = None;
        for pose in poses {
            // A base's start is looked for only when the base is tried:
            // a push carried out from its first base, or refused on its
            // simulation, costs no other base's collision checks.
            let Some(placed) = self.place(pose) else {
                continue;
            };
            if outcome == Outcome::StartInCollision {
                outcome = Outcome::Unreachable;
            }
            let remaining = self.remaining();
            if remaining.is_zero() {
                break;
            }
            options.rrt.time_budget = options.rrt.time_budget.map(|b| b.min(remaining));
            let failed_before = self.no_path.contains(&(push.node, placed.pose));
            options.rrt.max_iterations = if failed_before {
                RETRY_ITERATIONS.min(full_iterations)
            } else {
                full_iterations
            };
            let goals = match reach(&placed.arm, tree, self.rest, push, &placed.start) {
                Ok(goals) => goals,
                Err(o) => {
                    outcome = worst_to_best(outcome, o);
                    continue;
                }
            };
            match execute(
                &placed.arm,
                tree,
                self.rest,
                &snapshots,
                push,
                &goals,
                &placed.start,
                &options,
            ) {
                Ok(plan) => {
                    result = Some((PushPlan { rank, ..plan }, placed, simulated));
                    outcome = Outcome::Planned;
                    break;
                }
                Err(o) => {
                    if o == Outcome::NoPath && !failed_before {
                        self.no_path.push((push.node, placed.pose));
                    }
                    outcome = worst_to_best(outcome, o);
                }
            }
        }
        let ms = started.elapsed().as_secs_f64() * 1e3;
        self.note(rank, push, outcome, predicted, ms);
        if let Some(a) = self.attempts.last_mut() {
            a.simulated_loads = simulated.map(|s| s.loads);
        }
        if result.is_none() && outcome != Outcome::StartInCollision {
            if let Some(p) = predicted {
                self.blocked.push((rank, *p));
            }
        }
        result
    }
}

/// A push's held state as the simulator gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulatedHold {
    pub loads: PushLoads,
    /// For `clear`: the clearance reached (m).
    pub clearance: Option<f64>,
}

/// Whether the arm can reach `push`: placed at `fixed` (from its start
/// configuration), else from some placement a base-region `stance`
/// proposes; or the furthest any placement got. The one reach test of a
/// planning call ([`Run::reach_check`]) and of the pushes proposed before
/// one ([`Planner::reach_test`]).
pub(super) fn reach_at(
    planner: &Planner,
    fixed: Option<(&CollisionModel, &Config)>,
    stance: &Stance,
    tree: &crate::tree::Tree,
    rest: &TreeObstacles,
    push: &Push,
) -> Result<(), Outcome> {
    match (fixed, stance) {
        (Some((arm, start)), _) => reachable(arm, tree, rest, push, start),
        (None, Stance::Region(region)) => reach_in_region(planner, region, tree, rest, push),
        (None, Stance::Fixed(_)) => Err(Outcome::Unreachable),
    }
}

/// Whether the arm can reach `push` from some placement the base `region`
/// proposes for it (from home), or the furthest any placement got.
fn reach_in_region(
    planner: &Planner,
    region: &super::base::BaseRegion,
    tree: &crate::tree::Tree,
    rest: &TreeObstacles,
    push: &Push,
) -> Result<(), Outcome> {
    let mut outcome = Outcome::Unreachable;
    for pose in base::proposals(region, tree, push, planner.robot()) {
        let arm = planner.placed_at(&pose.isometry());
        match reachable(&arm, tree, rest, push, &arm.robot.home()) {
            Ok(_) => return Ok(()),
            Err(o) => outcome = worst_to_best(outcome, o),
        }
    }
    Err(outcome)
}

/// Over several bases, report the outcome that got furthest.
pub(super) fn worst_to_best(a: Outcome, b: Outcome) -> Outcome {
    let depth = |o: Outcome| match o {
        Outcome::StartInCollision | Outcome::InvalidCandidate => 0,
        Outcome::Unreachable => 1,
        Outcome::GoalInCollision => 2,
        Outcome::PushInfeasible => 3,
        Outcome::NoPath => 4,
        Outcome::NoTrajectory => 5,
        _ => 6,
    };
    if depth(b) > depth(a) { b } else { a }
}

/// How predicted pushes are judged: the limits their loads are screened
/// with, and the residual of doing nothing, which a push must beat.
pub(super) struct Judged<'a> {
    pub screen: Option<&'a Limits>,
    pub no_action_error: f64,
}

/// A push carried out, with what was predicted and simulated of it.
pub(super) struct Found {
    pub plan: PushPlan,
    pub placed: Placed,
    /// What was predicted of it (`None` for `paper`).
    pub predicted: Option<Scored>,
    pub simulated: Option<SimulatedHold>,
}
