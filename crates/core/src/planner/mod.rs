//! Planning a push that moves the tree toward its target: the one entry
//! point used by `/v1/plan`, `treemanip plan` and `treemanip eval plan`.
//!
//! It composes the contact policy ([`crate::infer`]), a predictor of what a
//! push does (the forward model or the simulator, [`predict`]), and the arm
//! ([`crate::robot`]):
//! 1. the policy ranks the nodes and proposes a push T_j for each;
//! 2. `paper` (Algorithm 1 as published) walks that ranking; `model` and
//!    `physics` search the push of the top nodes ([`search`]), pruned by the
//!    cheap reachability test ([`crate::robot::plan::reach`]) and scored by
//!    the predicted largest node distance to the target;
//! 3. the best push is executed: its straight push against the deforming
//!    tree, then RRT* for the approach, falling back to the next best;
//! 4. with a base region the arm may stand anywhere in it ([`base`]).

pub mod base;
pub mod predict;
pub mod search;

use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Point3, Vector3};
use serde::Serialize;

use crate::robot::collision::{Allowed, CollisionModel, Obstacle, TreeObstacles};
use crate::robot::plan::{Outcome, PlanOptions, PushPlan, PushSnapshots, execute, reach};
use crate::robot::rrt::{Config, MotionValidator};
use crate::robot::scene::PlanningScene;
use crate::robot::{Ur5, ur5};
use crate::sim::Push;
use crate::tree::Tree;
use base::{BasePose, BaseRegion};
pub use predict::{Candidate, ContactPolicy, PredictError, Predictor};
use predict::{PhysicsPredictor, max_node_error};
use search::{SearchOptions, search_pushes};

/// How the push is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Strategy {
    /// Search pushes, predicting each with the forward GNN (the default).
    #[default]
    Model,
    /// Search pushes, predicting each with the simulator.
    Physics,
    /// The paper's Algorithm 1: the policy's ranking and pushes as they are.
    Paper,
}

/// Where the arm stands.
#[derive(Debug, Clone, PartialEq)]
pub enum Stance {
    Fixed(Isometry3<f64>),
    /// The planner chooses a base pose in this region.
    Region(BaseRegion),
}

/// One planning problem.
#[derive(Debug, Clone)]
pub struct Query {
    pub tree: Tree,
    pub targets: Vec<Point3<f64>>,
    pub stance: Stance,
    /// Start configuration; `None` is the home pose (or, with a base region,
    /// the first collision-free tucked pose at the chosen base).
    pub start: Option<Config>,
    pub obstacles: Vec<Obstacle>,
    pub strategy: Strategy,
    pub budget: Duration,
    /// Policy-ranked nodes searched (`model`, `physics`).
    pub max_candidates: usize,
    /// Push predictions allowed (`model`, `physics`); `None`: the
    /// default for the tree's size and the stance ([`default_evaluations`]).
    pub max_evaluations: Option<usize>,
    pub seed: u64,
}

impl Query {
    /// A query with the default stance, strategy and budgets.
    pub fn new(tree: Tree, targets: Vec<Point3<f64>>) -> Self {
        Self {
            stance: Stance::Fixed(ur5::default_base()),
            start: None,
            obstacles: Vec::new(),
            strategy: Strategy::Model,
            budget: Duration::from_secs(2),
            max_candidates: DEFAULT_CANDIDATES,
            max_evaluations: None,
            seed: 1,
            tree,
            targets,
        }
    }
}

/// Push predictions by default for a tree of `n` nodes. A forward pass
/// costs in proportion to the graph's n(n−1) directed edges (fully
/// connected), so the default is a budget of edge evaluations (pushes ×
/// edges), never more than 96 pushes or fewer than 16:
/// - fixed base, [`FIXED_EVALUATION_EDGES`]: 60 pushes at N = 15, 33 at
///   N = 20, 21 at N = 25, 16 at N = 30, keeping a plan near 100-150 ms
///   (10 ms a push at N = 30 on 2 cores). Fewer cost accuracy: on 50 test
///   episodes `physics` left 7.06 cm with 40 at N = 15 and 6.62 cm with 96;
/// - base region, [`REGION_EVALUATION_EDGES`]: 96 pushes up to N = 22, 48
///   at N = 30. With the base free the push chosen is the result (on 30
///   test episodes, 96 pushes left 2.47 cm and 48 left 2.89 cm), within
///   the region's latency goal of 1 s.
pub fn default_evaluations(n: usize, region: bool) -> usize {
    let edges = (n * n.saturating_sub(1)).max(1);
    let budget = if region {
        REGION_EVALUATION_EDGES
    } else {
        FIXED_EVALUATION_EDGES
    };
    (budget / edges).clamp(16, SearchOptions::default().max_evaluations)
}

/// Edge evaluations of the default search from a fixed base.
pub const FIXED_EVALUATION_EDGES: usize = 60 * 15 * 14;
/// Edge evaluations of the default search with a base region.
pub const REGION_EVALUATION_EDGES: usize = 48 * 30 * 29;

impl Query {
    /// The push predictions this query allows.
    pub fn evaluations(&self) -> usize {
        self.max_evaluations.unwrap_or_else(|| {
            default_evaluations(self.tree.len(), matches!(self.stance, Stance::Region(_)))
        })
    }
}

/// Predictions the fallback to the policy's own pushes may make even when
/// the search spent the budget (the reachable ones, best ranked first).
pub const FALLBACK_PREDICTIONS: usize = 8;

/// Nodes searched by default.
pub const DEFAULT_CANDIDATES: usize = 4;
/// Pushes executed (push check and RRT*) at most, best predicted first.
const MAX_EXECUTIONS: usize = 6;
/// RRT* iterations for a node's approach from a base where an approach to
/// the same node already found no path: the pre-contact poses of a node's
/// pushes lie close together, so a second full search rarely succeeds.
const RETRY_ITERATIONS: usize = 800;

/// One push the planner looked at, and what became of it.
#[derive(Debug, Clone, Serialize)]
pub struct Attempt {
    pub node: usize,
    /// The node's rank in the policy's ranking (1 = best).
    pub rank: usize,
    pub push: [f64; 3],
    pub outcome: Outcome,
    /// Predicted max node distance to the target after it (m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_error: Option<f64>,
    pub ms: f64,
}

/// The planner's answer.
#[derive(Debug, Clone, Serialize)]
pub struct Plan {
    pub strategy: Strategy,
    /// The chosen push, its approach and push trajectory.
    pub plan: Option<PushPlan>,
    /// Where the arm stands (the given base, or the one chosen).
    pub base: BasePose,
    /// The start configuration the trajectory begins at.
    pub start: Config,
    /// Whether the planner chose `start` (no start given, base region).
    pub start_chosen: bool,
    /// Predicted max node error after the chosen push (m); `None` for
    /// `paper`, which does not predict.
    pub predicted_error: Option<f64>,
    /// Max node error if nothing is done (m).
    pub no_action_error: f64,
    /// Pushes predicted by the search.
    pub evaluations: usize,
    pub attempts: Vec<Attempt>,
    pub total_ms: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    #[error("the start configuration collides with the tree, an obstacle, the ground or itself")]
    StartInCollision,
    #[error("the forward model is needed for the `model` strategy and is not loaded")]
    NoForwardModel,
    #[error("inference failed: {0}")]
    Predict(#[from] PredictError),
}

/// The arm's collision geometry, built once, moved to each request's base.
pub struct Planner {
    arm: CollisionModel,
}

impl Default for Planner {
    fn default() -> Self {
        Self::new(CollisionModel::new(Ur5::default()))
    }
}

/// An arm placed at one base with its start configuration.
struct Placed {
    pose: BasePose,
    arm: CollisionModel,
    start: Config,
}

impl Planner {
    pub fn new(arm: CollisionModel) -> Self {
        Self { arm }
    }

    /// The arm's kinematics and shapes (at its default base).
    pub fn robot(&self) -> &Ur5 {
        &self.arm.robot
    }

    fn placed_at(&self, base: &Isometry3<f64>) -> CollisionModel {
        let mut arm = self.arm.clone();
        arm.robot = arm.robot.clone().with_base(*base);
        arm
    }

    /// Plans `query` with the contact `policy` and, for `model`, the
    /// `forward` model.
    pub fn plan(
        &self,
        query: &Query,
        policy: &dyn ContactPolicy,
        forward: Option<&dyn Predictor>,
    ) -> Result<Plan, PlanError> {
        let clock = Instant::now();
        let tree = &query.tree;
        let rest = TreeObstacles::new(tree).with_obstacles(&query.obstacles);
        let ranked = policy.rank(tree, &query.targets)?;
        let policy_pushes: Vec<(usize, Push)> = ranked
            .iter()
            .map(|c| {
                let push = Push {
                    node: c.node,
                    vector: Vector3::from(c.push),
                };
                (c.rank, push)
            })
            .collect();
        let rank_of = |node: usize| ranked.iter().find(|c| c.node == node).map_or(0, |c| c.rank);
        let fixed = match &query.stance {
            Stance::Fixed(base) => {
                let arm = self.placed_at(base);
                let start = query.start.unwrap_or(ur5::HOME);
                let free = PlanningScene::new(&arm, &rest, Allowed::default());
                if !free.config_valid(&start) {
                    return Err(PlanError::StartInCollision);
                }
                Some(Placed {
                    pose: BasePose::of(base),
                    arm,
                    start,
                })
            }
            Stance::Region(_) => None,
        };
        let mut run = Run {
            planner: self,
            query,
            rest: &rest,
            fixed: &fixed,
            clock,
            attempts: Vec::new(),
            no_path: Vec::new(),
        };
        let no_action_error = max_node_error(tree.positions(), &query.targets);
        let mut evaluations = 0;
        let mut found: Option<(PushPlan, Placed, Option<f64>)> = None;
        let physics = PhysicsPredictor;
        let predictor: Option<&dyn Predictor> = match query.strategy {
            Strategy::Paper => None,
            Strategy::Physics => Some(&physics),
            Strategy::Model => Some(forward.ok_or(PlanError::NoForwardModel)?),
        };
        if let Some(predictor) = predictor {
            let seeds: Vec<Push> = policy_pushes
                .iter()
                .take(query.max_candidates.max(1))
                .map(|(_, p)| *p)
                .collect();
            let options = SearchOptions {
                max_evaluations: query.evaluations(),
                seed: query.seed,
                ..SearchOptions::default()
            };
            let feasible = |p: &Push| run.reachable(p);
            let (scored, count) =
                search_pushes(tree, &query.targets, &seeds, predictor, &feasible, &options)?;
            evaluations = count;
            for s in scored.iter().take(MAX_EXECUTIONS) {
                let rank = rank_of(s.push.node);
                if s.predicted_error >= no_action_error {
                    run.note(
                        rank,
                        &s.push,
                        Outcome::NotHelpful,
                        Some(s.predicted_error),
                        0.0,
                    );
                    break;
                }
                if let Some((plan, placed)) = run.try_push(rank, &s.push, Some(s.predicted_error)) {
                    found = Some((plan, placed, Some(s.predicted_error)));
                    break;
                }
            }
        }
        if found.is_none() {
            // Algorithm 1 as published; for the searching strategies the
            // fallback when no searched push could be carried out: the
            // policy's pushes the arm can reach (the reach test costs far
            // less than a prediction, and most low-ranked pushes fail it
            // from a fixed base), the best ranked predicted in one batch
            // (what is left of the evaluation budget, at least
            // FALLBACK_PREDICTIONS) and the unhelpful ones dropped.
            let policy_pushes: Vec<(usize, Push)> = match predictor {
                None => policy_pushes,
                Some(_) => policy_pushes
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
            let predicted: Vec<Option<f64>> = match predictor {
                None => vec![None; policy_pushes.len()],
                Some(p) => {
                    let left = query
                        .evaluations()
                        .saturating_sub(evaluations)
                        .max(FALLBACK_PREDICTIONS);
                    let pushes: Vec<Push> =
                        policy_pushes.iter().take(left).map(|(_, p)| *p).collect();
                    evaluations += pushes.len();
                    let mut predicted: Vec<Option<f64>> = p
                        .final_positions(tree, &pushes)?
                        .into_iter()
                        .map(|f| {
                            Some(f.map_or(f64::INFINITY, |f| max_node_error(&f, &query.targets)))
                        })
                        .collect();
                    predicted.resize(policy_pushes.len(), None);
                    predicted
                }
            };
            for ((rank, push), predicted) in policy_pushes.iter().zip(predicted) {
                if let Some(e) = predicted
                    && e >= no_action_error
                {
                    run.note(*rank, push, Outcome::NotHelpful, Some(e), 0.0);
                    continue;
                }
                if predictor.is_some() && predicted.is_none() {
                    // Beyond the predictions allowed: a searching strategy
                    // never executes a push it has not predicted.
                    run.note(*rank, push, Outcome::Skipped, None, 0.0);
                    continue;
                }
                if let Some((plan, placed)) = run.try_push(*rank, push, predicted) {
                    found = Some((plan, placed, predicted));
                    break;
                }
            }
        }
        let attempts = run.attempts;
        let (plan, placed, predicted_error) = match found {
            Some((plan, placed, predicted)) => (Some(plan), Some(placed), predicted),
            None => (None, None, None),
        };
        let (base, start, start_chosen) = match (placed, &fixed, &query.stance) {
            (Some(p), _, _) => (p.pose, p.start, query.start.is_none() && fixed.is_none()),
            (None, Some(f), _) => (f.pose, f.start, false),
            (None, None, _) => (
                BasePose::of(&ur5::default_base()),
                query.start.unwrap_or(ur5::HOME),
                false,
            ),
        };
        Ok(Plan {
            strategy: query.strategy,
            plan,
            base,
            start,
            start_chosen,
            predicted_error,
            no_action_error,
            evaluations,
            attempts,
            total_ms: clock.elapsed().as_secs_f64() * 1e3,
        })
    }
}

/// The state of one planning call.
struct Run<'a> {
    planner: &'a Planner,
    query: &'a Query,
    rest: &'a TreeObstacles,
    fixed: &'a Option<Placed>,
    clock: Instant,
    attempts: Vec<Attempt>,
    /// (node, base) pairs whose approach RRT* found no path.
    no_path: Vec<(usize, BasePose)>,
}

impl Run<'_> {
    fn remaining(&self) -> Duration {
        self.query.budget.saturating_sub(self.clock.elapsed())
    }

    fn note(
        &mut self,
        rank: usize,
        push: &Push,
        outcome: Outcome,
        predicted: Option<f64>,
        ms: f64,
    ) {
        self.attempts.push(Attempt {
            node: push.node,
            rank,
            push: push.vector.into(),
            outcome,
            predicted_error: predicted,
            ms,
        });
    }

    /// The arm placements to try for `push`: the fixed base, or the region's
    /// proposals, each with a collision-free start.
    fn placements(&self, push: &Push) -> Vec<Placed> {
        match (self.fixed, &self.query.stance) {
            (Some(f), _) => vec![Placed {
                pose: f.pose,
                arm: f.arm.clone(),
                start: f.start,
            }],
            (None, Stance::Region(region)) => base::proposals(region, &self.query.tree, push)
                .into_iter()
                .filter_map(|pose| {
                    let arm = self.planner.placed_at(&pose.isometry());
                    let free = PlanningScene::new(&arm, self.rest, Allowed::default());
                    let start = match self.query.start {
                        Some(q) => free.config_valid(&q).then_some(q),
                        None => base::tucked_starts()
                            .into_iter()
                            .find(|q| free.config_valid(q)),
                    }?;
                    Some(Placed { pose, arm, start })
                })
                .collect(),
            (None, Stance::Fixed(_)) => Vec::new(),
        }
    }

    /// Whether the arm can reach `push` from some placement (the cheap test).
    fn reachable(&self, push: &Push) -> bool {
        self.reach_check(push).is_ok()
    }

    /// [`Self::reachable`], or the furthest any placement got.
    fn reach_check(&self, push: &Push) -> Result<(), Outcome> {
        let tree = &self.query.tree;
        match (self.fixed, &self.query.stance) {
            (Some(f), _) => reach(&f.arm, tree, self.rest, push, &f.start).map(|_| ()),
            (None, Stance::Region(region)) => {
                let mut outcome = Outcome::Unreachable;
                for pose in base::proposals(region, tree, push) {
                    let arm = self.planner.placed_at(&pose.isometry());
                    match reach(&arm, tree, self.rest, push, &ur5::HOME) {
                        Ok(_) => return Ok(()),
                        Err(o) => outcome = worst_to_best(outcome, o),
                    }
                }
                Err(outcome)
            }
            (None, Stance::Fixed(_)) => Err(Outcome::Unreachable),
        }
    }

    /// Tries to carry out `push` from each placement; records the attempt.
    fn try_push(
        &mut self,
        rank: usize,
        push: &Push,
        predicted: Option<f64>,
    ) -> Option<(PushPlan, Placed)> {
        let remaining = self.remaining();
        if remaining.is_zero() {
            self.note(rank, push, Outcome::Skipped, predicted, 0.0);
            return None;
        }
        let started = Instant::now();
        let tree = &self.query.tree;
        let mut options = PlanOptions::default();
        options.rrt.seed = self.query.seed;
        let full_iterations = options.rrt.max_iterations;
        let placements = self.placements(push);
        let mut outcome = if placements.is_empty() {
            Outcome::StartInCollision
        } else {
            Outcome::Unreachable
        };
        // The deformed tree does not depend on the base: simulated once, as
        // far as the push lines get.
        let snapshots = PushSnapshots::new(tree, push, self.rest);
        let mut result = None;
        for placed in placements {
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
                    result = Some((PushPlan { rank, ..plan }, placed));
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
        result
    }
}

/// Over several bases, report the outcome that got furthest.
fn worst_to_best(a: Outcome, b: Outcome) -> Outcome {
    let depth = |o: Outcome| match o {
        Outcome::StartInCollision | Outcome::InvalidCandidate => 0,
        Outcome::Unreachable => 1,
        Outcome::GoalInCollision => 2,
        Outcome::PushInfeasible => 3,
        Outcome::NoPath => 4,
        _ => 5,
    };
    if depth(b) > depth(a) { b } else { a }
}
