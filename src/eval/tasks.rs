//! Evaluating orchard objectives (`treemanip eval tasks`): on test-split
//! trees, tasks a user would pose, planned per strategy and stance, the
//! chosen push then executed in the simulator, where success, the residual
//! and the loads are measured (never the planner's own prediction).
//!
//! - `clear`: a fruit-sized sphere (radius 4 cm) placed across a random
//!   branch (centre within 3 cm of the branch's axis, so it intersects it),
//!   cleared with the default margin;
//! - `reach`: a node that moved at least 3 cm in the episode, into a 3 cm
//!   sphere around where the episode's push took it (solvable by
//!   construction, ignoring the arm);
//! - `shape_masked`: the episode's final shape, a random third of the
//!   non-root nodes weighted 1 and the rest 0.
//!
//! The ceiling is an oracle that ignores the arm: the simulator searching
//! pushes freely from the same geometric seeds with a larger budget.

use std::time::Duration;

use nalgebra::{Point3, Unit, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::plan::{BaseArea, percentile};
use crate::dataset::Episode;
use crate::geometry::shape::Shape;
use crate::infer::models::ServedModel;
use crate::planner::objective::{DEFAULT_CLEAR_MARGIN, SATISFIED};
use crate::planner::predict::PhysicsPredictor;
use crate::planner::search::{Scored, SearchOptions, search_pushes};
use crate::planner::seeds::geometric_seeds;
use crate::planner::{Limits, Objective, Planner, Query, Stance, Strategy};
use crate::sim::loads::PushLoads;
use crate::sim::{Push, SimConfig, simulate};
use crate::tree::Tree;

/// Radius of the fruit of `clear` tasks (m).
pub const FRUIT_RADIUS: f64 = 0.04;
/// Radius of the region of `reach` tasks (m).
pub const REACH_RADIUS: f64 = 0.03;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TaskKind {
    Clear,
    Reach,
    ShapeMasked,
}

impl TaskKind {
    pub const ALL: [TaskKind; 3] = [TaskKind::Clear, TaskKind::Reach, TaskKind::ShapeMasked];

    pub fn name(&self) -> &'static str {
        match self {
            TaskKind::Clear => "clear",
            TaskKind::Reach => "reach",
            TaskKind::ShapeMasked => "shape_masked",
        }
    }
}

/// A unit vector perpendicular to `axis`, uniformly random about it.
fn perpendicular(axis: &Vector3<f64>, rng: &mut ChaCha8Rng) -> Vector3<f64> {
    let helper = if axis.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = axis.cross(&helper).normalize();
    let angle = rng.random_range(0.0..std::f64::consts::TAU);
    UnitQuaternion::from_axis_angle(&Unit::new_normalize(*axis), angle) * u
}

/// A `clear` task: a fruit-sized sphere across a random branch (centre
/// within 3 cm of its axis).
pub fn clear_task(tree: &Tree, rng: &mut ChaCha8Rng) -> Option<Objective> {
    let node = rng.random_range(1..tree.len());
    let parent = tree.parent(node)?;
    let (a, b) = (tree.position(parent), tree.position(node));
    let on_axis = a + (b - a) * rng.random_range(0.3..0.9);
    let axis = (b - a).normalize();
    let centre = on_axis + perpendicular(&axis, rng) * rng.random_range(0.0..0.03);
    Some(Objective::Clear {
        regions: vec![Shape::Sphere {
            centre,
            radius: FRUIT_RADIUS,
        }],
        margin: DEFAULT_CLEAR_MARGIN,
    })
}

/// The task of `kind` on an episode's tree, or `None` when the episode
/// offers none (no node moved enough for `reach`).
pub fn make_task(
    kind: TaskKind,
    tree: &Tree,
    episode: &Episode,
    rng: &mut ChaCha8Rng,
) -> Option<Objective> {
    let n = tree.len();
    match kind {
        TaskKind::Clear => clear_task(tree, rng),
        TaskKind::Reach => {
            let moved: Vec<usize> = (1..n)
                .filter(|&j| (episode.final_positions[j] - tree.position(j)).norm() >= 0.03)
                .collect();
            if moved.is_empty() {
                return None;
            }
            let node = moved[rng.random_range(0..moved.len())];
            Some(Objective::Reach {
                node,
                region: Shape::Sphere {
                    centre: episode.final_positions[node],
                    radius: REACH_RADIUS,
                },
            })
        }
        TaskKind::ShapeMasked => {
            let mut weights = vec![0.0; n];
            let listed = ((n - 1) as f64 / 3.0).round().max(1.0) as usize;
            let mut nodes: Vec<usize> = (1..n).collect();
            for k in 0..listed {
                let pick = rng.random_range(k..nodes.len());
                nodes.swap(k, pick);
                weights[nodes[k]] = 1.0;
            }
            Some(Objective::Shape {
                targets: episode.final_positions.clone(),
                weights: Some(weights),
            })
        }
    }
}

/// The held state of `push` in the simulator: the objective's residual and
/// the loads, or `None` when the simulator rejects the push.
pub fn execute(
    tree: &Tree,
    objective: &Objective,
    push: &Push,
) -> Option<(f64, Option<f64>, PushLoads)> {
    let out = simulate(tree, push, &SimConfig::default()).ok()?;
    let scorer = objective.scorer();
    Some((
        scorer.residual(tree, &out.final_positions),
        scorer.clearance(tree, &out.final_positions),
        PushLoads::of_outcome(tree, &out),
    ))
}

/// What the arm-free oracle reaches: the simulator searching pushes from
/// the geometric seeds (12 nodes, 256 predictions) within `limits`.
pub fn oracle(
    tree: &Tree,
    objective: &Objective,
    limits: Option<&Limits>,
    seed: u64,
) -> Option<f64> {
    best_push(tree, objective, limits, seed).map(|s| s.predicted_error)
}

/// The oracle's push: the best within `limits` the simulator finds from
/// the geometric seeds (12 nodes, 256 predictions), arm ignored.
pub fn best_push(
    tree: &Tree,
    objective: &Objective,
    limits: Option<&Limits>,
    seed: u64,
) -> Option<Scored> {
    let seeds = geometric_seeds(tree, objective, 12);
    let options = SearchOptions {
        max_evaluations: 256,
        samples: 12,
        rounds: 4,
        seed,
        ..SearchOptions::default()
    };
    let all = |_: &Push| true;
    let (scored, _) = search_pushes(
        tree,
        objective,
        limits,
        &seeds,
        &PhysicsPredictor,
        &all,
        &options,
    )
    .ok()?;
    scored.into_iter().find(|s| s.within_limits)
}

/// One planned task.
#[derive(Debug, Clone, Serialize)]
pub struct TaskResult {
    pub kind: TaskKind,
    pub n: usize,
    pub planned: bool,
    /// Residual after executing the plan in the simulator (no plan: doing
    /// nothing), m.
    pub executed_residual: f64,
    pub no_action_residual: f64,
    /// The oracle's residual (arm ignored), m.
    pub oracle_residual: Option<f64>,
    /// For `clear`: the executed clearance between branches and regions
    /// (no plan: doing nothing's), m.
    pub executed_clearance: Option<f64>,
    /// Executed loads (zero without a plan).
    pub executed_stress: f64,
    pub executed_force: f64,
    /// Executed loads over a limit.
    pub over_limit: bool,
    /// The planner's predicted peak stress of its push (Pa).
    pub predicted_stress: Option<f64>,
    pub ms: f64,
    pub outcomes: Vec<String>,
}

impl TaskResult {
    /// Whether the executed push satisfies the objective (for `clear` and
    /// `reach`), within the limits.
    pub fn success(&self) -> bool {
        self.executed_residual <= SATISFIED && !self.over_limit
    }

    /// Whether the arm-free oracle satisfies the objective.
    pub fn oracle_solvable(&self) -> bool {
        self.oracle_residual.is_some_and(|r| r <= SATISFIED)
    }
}

/// Plans and executes one task with `strategy`, fixed base or region.
#[allow(clippy::too_many_arguments)]
pub fn run_task(
    planner: &Planner,
    policy: &ServedModel,
    // The forward model for this tree's size (`ModelSet::forward_for`).
    forward: &ServedModel,
    kind: TaskKind,
    tree: &Tree,
    objective: &Objective,
    limits: Option<&Limits>,
    strategy: Strategy,
    // The base's region, or the fixed default base.
    region: Option<BaseArea>,
    oracle_residual: Option<f64>,
) -> TaskResult {
    let mut query = Query::with_objective(tree.clone(), objective.clone());
    query.strategy = strategy;
    query.limits = limits.copied();
    query.budget = Duration::from_secs(2);
    if let Some(area) = region {
        query.stance = Stance::Region(area.region());
    }
    let no_action = objective.residual(tree, tree.positions());
    let (plan, ms, outcomes, predicted_stress) =
        match super::plan::plan_as_served(planner, &query, policy, forward) {
            Ok(p) => (
                p.plan,
                p.total_ms,
                p.attempts
                    .iter()
                    .map(|a| super::plan::outcome_name(&a.outcome))
                    .collect(),
                p.predicted_loads.map(|l| l.peak_stress),
            ),
            Err(e) => (None, 0.0, vec![format!("error: {e}")], None),
        };
    let executed = plan.as_ref().and_then(|p| {
        execute(
            tree,
            objective,
            &Push {
                node: p.node,
                vector: p.push,
            },
        )
    });
    let (executed_residual, executed_clearance, loads) = executed.unwrap_or((
        no_action,
        objective.scorer().clearance(tree, tree.positions()),
        PushLoads {
            peak_stress: 0.0,
            peak_node: None,
            contact_force: 0.0,
        },
    ));
    TaskResult {
        kind,
        n: tree.len(),
        planned: plan.is_some(),
        executed_residual,
        executed_clearance,
        no_action_residual: no_action,
        oracle_residual,
        executed_stress: loads.peak_stress,
        executed_force: loads.contact_force,
        over_limit: limits.is_some_and(|l| !l.allow(&loads)),
        predicted_stress,
        ms,
        outcomes,
    }
}

/// One row of the tasks table.
#[derive(Debug, Clone, Serialize)]
pub struct TaskSummary {
    pub task: String,
    pub setting: String,
    pub tasks: usize,
    pub planned: f64,
    /// Share of tasks satisfied within the limits (`clear`, `reach`).
    pub success: f64,
    /// The same over the tasks the oracle satisfies.
    pub success_of_solvable: f64,
    pub oracle_solvable: usize,
    /// Executed pushes over a limit.
    pub violations: usize,
    /// Mean executed residual (m).
    pub residual: f64,
    /// For `clear`: median executed clearance (m).
    pub clearance: f64,
    pub ms_p50: f64,
    pub ms_p95: f64,
}

pub fn summarise(task: &str, setting: &str, results: &[TaskResult]) -> TaskSummary {
    let count = results.len().max(1) as f64;
    let solvable: Vec<&TaskResult> = results.iter().filter(|r| r.oracle_solvable()).collect();
    // A shape has no success threshold: its rows report the residual.
    let graded = results.iter().all(|r| r.kind != TaskKind::ShapeMasked);
    let graded_share = |v: f64| if graded { v } else { f64::NAN };
    let mut times: Vec<f64> = results.iter().map(|r| r.ms).collect();
    times.sort_by(f64::total_cmp);
    TaskSummary {
        task: task.to_owned(),
        setting: setting.to_owned(),
        tasks: results.len(),
        planned: results.iter().filter(|r| r.planned).count() as f64 / count,
        success: graded_share(results.iter().filter(|r| r.success()).count() as f64 / count),
        success_of_solvable: graded_share(
            solvable.iter().filter(|r| r.success()).count() as f64 / solvable.len().max(1) as f64,
        ),
        oracle_solvable: solvable.len(),
        violations: results.iter().filter(|r| r.over_limit).count(),
        residual: results.iter().map(|r| r.executed_residual).sum::<f64>() / count,
        clearance: {
            let mut c: Vec<f64> = results
                .iter()
                .filter_map(|r| r.executed_clearance)
                .collect();
            c.sort_by(f64::total_cmp);
            percentile(&c, 0.5)
        },
        ms_p50: percentile(&times, 0.5),
        ms_p95: percentile(&times, 0.95),
    }
}

/// The tasks table as Markdown (residuals in cm, times in ms).
pub fn to_markdown(rows: &[TaskSummary]) -> String {
    let mut out = String::from(
        "| task | setting | tasks | planned % | success % | success % of oracle-solvable (solvable) | executed over a limit | mean residual (cm) | median clearance (cm) | plan ms p50 | p95 |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let (pct, ms) = (super::plan::percent_cell, super::plan::ms_cell);
    for r in rows {
        let solvable = if r.success_of_solvable.is_nan() {
            "–".to_owned()
        } else {
            format!("{} ({})", pct(r.success_of_solvable), r.oracle_solvable)
        };
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {solvable} | {} | {:.2} | {} | {} | {} |\n",
            r.task,
            r.setting,
            r.tasks,
            pct(r.planned),
            pct(r.success),
            r.violations,
            100.0 * r.residual,
            if r.clearance.is_nan() {
                "–".to_owned()
            } else {
                format!("{:.2}", 100.0 * r.clearance)
            },
            ms(r.ms_p50),
            ms(r.ms_p95),
        ));
    }
    out
}

/// How well loads read from predicted positions match the simulator's.
#[derive(Debug, Clone, Serialize)]
pub struct LoadAccuracy {
    pub pushes: usize,
    /// Median |predicted − simulated| / simulated peak stress.
    pub stress_relative_error_median: f64,
    pub stress_relative_error_p90: f64,
    /// Median relative error of the contact force.
    pub force_relative_error_median: f64,
    /// Pushes predicted within `limit` whose simulated stress exceeds it by
    /// more than 10 % (what the check would let through without the
    /// simulation of the executed push).
    pub let_through_over_10_percent: usize,
    /// Pushes the simulator puts over `limit`.
    pub simulated_over_limit: usize,
    pub limit: f64,
    /// The simulator's peak stress over the pushes (Pa): median and p90.
    pub simulated_stress_p50: f64,
    pub simulated_stress_p90: f64,
    /// The simulator's contact force (N): median and p90.
    pub simulated_force_p50: f64,
    pub simulated_force_p90: f64,
}

/// Compares loads from `predicted` positions with the simulator's on the
/// same pushes.
pub fn load_accuracy(
    cases: &[(&Tree, Push, Vec<Point3<f64>>)],
    limit: f64,
) -> Option<LoadAccuracy> {
    use rayon::prelude::*;
    let contact = SimConfig::default().contact;
    let pairs: Vec<(PushLoads, PushLoads)> = cases
        .par_iter()
        .filter_map(|(tree, push, predicted)| {
            let sim = simulate(tree, push, &SimConfig::default()).ok()?;
            Some((
                PushLoads::from_positions(tree, push, predicted, contact),
                PushLoads::of_outcome(tree, &sim),
            ))
        })
        .filter(|(_, s)| s.peak_stress > 0.0 && s.contact_force > 0.0)
        .collect();
    if pairs.is_empty() {
        return None;
    }
    let mut stress: Vec<f64> = pairs
        .iter()
        .map(|(p, s)| (p.peak_stress - s.peak_stress).abs() / s.peak_stress)
        .collect();
    stress.sort_by(f64::total_cmp);
    let mut force: Vec<f64> = pairs
        .iter()
        .map(|(p, s)| (p.contact_force - s.contact_force).abs() / s.contact_force)
        .collect();
    force.sort_by(f64::total_cmp);
    let mut sim_stress: Vec<f64> = pairs.iter().map(|(_, s)| s.peak_stress).collect();
    sim_stress.sort_by(f64::total_cmp);
    let mut sim_force: Vec<f64> = pairs.iter().map(|(_, s)| s.contact_force).collect();
    sim_force.sort_by(f64::total_cmp);
    Some(LoadAccuracy {
        simulated_stress_p50: percentile(&sim_stress, 0.5),
        simulated_stress_p90: percentile(&sim_stress, 0.9),
        simulated_force_p50: percentile(&sim_force, 0.5),
        simulated_force_p90: percentile(&sim_force, 0.9),
        pushes: pairs.len(),
        stress_relative_error_median: percentile(&stress, 0.5),
        stress_relative_error_p90: percentile(&stress, 0.9),
        force_relative_error_median: percentile(&force, 0.5),
        let_through_over_10_percent: pairs
            .iter()
            .filter(|(p, s)| p.peak_stress <= limit && s.peak_stress > 1.1 * limit)
            .count(),
        simulated_over_limit: pairs.iter().filter(|(_, s)| s.peak_stress > limit).count(),
        limit,
    })
}

/// A seeded generator for task `index` (tasks are reproducible one by one).
pub fn task_rng(seed: u64, index: usize) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed ^ (index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}
