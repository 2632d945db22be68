//! The paper's Algorithm 1: try the policy's push candidates in order of
//! affordance and return the first one the arm can execute.
//!
//! For a candidate (node j, push T):
//! 1. **Pre-contact pose.** The gripper point g = p_j − 0.01·b̂ (on the
//!    branch axis, 1 cm back from the node, b̂ the branch direction); the
//!    tool starts 5 cm behind it along T: tool origin g − 0.05·T̂, tool z
//!    along T̂, tool x along the branch (b̂ with its T̂ component removed), so
//!    the slot lies across the branch. The slot is symmetric, so the pose
//!    turned by π about z is tried too.
//! 2. **IK**: all solutions of both poses within limits (closed form for
//!    UR kinematics, numerical from several starts for any other arm).
//! 3. **Goal check**: solutions in collision are dropped (a 7-joint arm's
//!    first swing along their self-motion, and free swings take their
//!    place). The gripper may
//!    touch the contacted branch and the branches leaving node j; the arm's
//!    links may touch nothing.
//! 4. **Push check**: the tool moves in a straight line by |T| + 5 cm along
//!    T̂; every 5 mm of it must have an IK solution continuous with the last
//!    (no joint moves more than 0.15 rad per step) that is collision-free.
//!    The first 5 cm are checked against the tree at rest; once the slot
//!    holds the branch, against the tree as the simulator deforms it
//!    (quasi-static snapshots every 1 cm of push, each step checked against
//!    the snapshot at or beyond it). The gripper may touch the pushed
//!    subtree; a push the simulator rejects (the branch would slip out) is
//!    infeasible.
//! 5. **RRT\*** from the start to all remaining goal configurations at once,
//!    and to entries outside the canopy: the tool backs away from each
//!    pre-contact pose along −T̂ at constant orientation, as far as that is
//!    free (up to 12 cm); an approach to an entry ends with the straight
//!    line back in.
//! 6. The first success is shortcut, timed (trapezoidal joint profiles for
//!    the approach, constant tool speed for the push) and returned with the
//!    index where the push begins. Every attempt is reported with its
//!    outcome and time.

use std::time::Duration;

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use crate::robot::arm::tool_line::{
    APPROACH_OFFSET, PUSH_MAX_JOINT_STEP, PUSH_STEP, either_way_round, push_line, tool_line,
};
use crate::robot::collision::{Allowed, CollisionModel, TreeObstacles};
use crate::robot::motion::execution::{Execution, ExecutionOptions, PUSH_SPEED, execution};
use crate::robot::motion::rrt::{
    Config, MotionValidator, RrtError, RrtStarOptions, distance, rrt_star, shortcut,
};
use crate::robot::motion::scene::PlanningScene;
use crate::robot::motion::trajectory::{TimedPoint, time_parameterize};
use crate::sim::loads::PushLoads;
use crate::sim::{GRIP_OFFSET, Push, SimConfig, simulate_from};
use crate::tree::Tree;

/// Spacing of the deformed-tree snapshots used while pushing (m).
pub const PUSH_SNAPSHOT: f64 = 0.01;
/// Swings along a redundant arm's self-motion tried for a pre-contact
/// configuration in collision (rad along the unit null-space direction,
/// [`crate::robot::Arm::self_motions`]).
pub const SELF_MOTION_SWINGS: [f64; 4] = [-0.5, 0.5, -1.0, 1.0];
/// Pre-contact configurations (nearest the start first) whose push is
/// checked and handed to RRT* as goals, at most.
pub const PUSH_GOALS: usize = 4;

#[derive(Debug, Clone)]
pub struct PlanOptions {
    pub rrt: RrtStarOptions,
    /// Shortcutting attempts on the approach path.
    pub shortcut_attempts: usize,
    /// Stop trying candidates after this long.
    pub budget: Option<Duration>,
    /// Sampling interval of the timed approach (s).
    pub dt: f64,
    /// How the controller's trajectory (approach, push, hold, release,
    /// retreat) is timed.
    pub execution: ExecutionOptions,
}

impl Default for PlanOptions {
    fn default() -> Self {
        Self {
            rrt: RrtStarOptions {
                time_budget: Some(Duration::from_millis(150)),
                // Successful approaches need far fewer (first solutions of
                // 115 traced plans: p90 773, p95 1,258 iterations); a
                // failing one would otherwise spend most of a plan's time.
                max_iterations: 1000,
                ..RrtStarOptions::default()
            },
            shortcut_attempts: 100,
            budget: Some(Duration::from_secs(2)),
            dt: 0.05,
            execution: ExecutionOptions::default(),
        }
    }
}

/// Why a candidate was or was not planned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    Planned,
    /// Not a usable push (root node, zero push, push along the branch).
    InvalidCandidate,
    /// No IK solution for the pre-contact pose.
    Unreachable,
    /// Every IK solution of the pre-contact pose collides.
    GoalInCollision,
    /// No pre-contact solution can carry out the straight push.
    PushInfeasible,
    /// RRT* found no path within its budget.
    NoPath,
    /// A path was found, but no controller trajectory could be made of it
    /// (the timed push would leave a joint's limits, or the approach could
    /// not be timed): a plan is never answered without its trajectory.
    NoTrajectory,
    /// A budget (time, or the predictions of a searching strategy) ran
    /// out before this candidate.
    Skipped,
    /// The planner predicted this push leaves the tree no closer to its
    /// target than doing nothing, so it was not executed.
    NotHelpful,
    /// The start configuration collides at this base (mobile bases only).
    StartInCollision,
    /// The push is predicted (or, when executed, simulated) to exceed a
    /// load limit: the branch's bending stress or the gripper's force.
    OverLimit,
    /// Predicted to meet a `clear` or `reach` objective, but the simulation
    /// of its push (run for the push line's collision check) misses it;
    /// carried out only if no push meets the objective.
    Missed,
}

#[derive(Debug, Clone, Serialize)]
pub struct PushPlan {
    pub node: usize,
    pub rank: usize,
    pub push: Vector3<f64>,
    /// The path: approach then push, each waypoint at the earliest time
    /// the joints' limits allow (what the planner's own checks walk; the
    /// controller's timing is `execution`).
    pub trajectory: Vec<TimedPoint>,
    /// Index of the trajectory point where the push begins (the tool at the
    /// pre-contact pose).
    pub push_start_index: usize,
    /// The whole held push timed for a controller (ROS 2 JointTrajectory):
    /// every plan has one ([`Outcome::NoTrajectory`] otherwise).
    pub execution: Execution,
}

/// Tool poses for the pre-contact of a push (both slot orientations), or
/// `None` when the push is unusable.
pub fn pre_contact_poses(tree: &Tree, candidate: &Push) -> Option<[Isometry3<f64>; 2]> {
    let branch = tree.branch_direction(candidate.node)?;
    let length = candidate.vector.norm();
    if !(length.is_finite() && length > 1e-6) {
        return None;
    }
    let z = candidate.vector / length;
    let along = branch - z * branch.dot(&z);
    if along.norm() < 1e-3 {
        return None; // pushing along the branch: no slot orientation
    }
    let x = along.normalize();
    let y = z.cross(&x);
    let grip = tree.position(candidate.node) - branch * GRIP_OFFSET;
    let origin = grip - z * APPROACH_OFFSET;
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
        Matrix3::from_columns(&[x, y, z]),
    ));
    Some(either_way_round(Isometry3::from_parts(
        Translation3::from(origin.coords),
        rotation,
    )))
}

/// What the gripper may touch at the pre-contact pose: the contacted branch
/// and the branches leaving its node.
fn near_contact(tree: &Tree, node: usize) -> Allowed {
    Allowed {
        gripper_branches: std::iter::once(node)
            .chain(tree.children(node).iter().copied())
            .collect(),
    }
}

/// The cheap test of whether the arm can carry out `push` at all, before
/// any simulation or RRT*: the pre-contact pose has IK solutions within
/// the joint limits, some are collision-free, and from some of those the
/// straight push at constant tool orientation stays on one IK branch.
/// Returns every such pre-contact configuration, or why none.
pub fn reach(
    model: &CollisionModel,
    tree: &Tree,
    obstacles: &TreeObstacles,
    push: &Push,
    start: &Config,
) -> Result<Vec<Config>, Outcome> {
    reach_up_to(model, tree, obstacles, push, start, usize::MAX)
}

/// [`reach`] stopped at the first pre-contact configuration that serves:
/// whether a push is reachable, asked of every candidate and placement a
/// search looks at, without solving IK from every start of a numerical
/// chain (most of a plan's time on such arms).
pub fn reachable(
    model: &CollisionModel,
    tree: &Tree,
    obstacles: &TreeObstacles,
    push: &Push,
    start: &Config,
) -> Result<(), Outcome> {
    reach_up_to(model, tree, obstacles, push, start, 1).map(|_| ())
}

/// Up to `wanted` usable pre-contact configurations, or the furthest any
/// got (`unreachable`, `goal_in_collision`, `push_infeasible`).
fn reach_up_to(
    model: &CollisionModel,
    tree: &Tree,
    obstacles: &TreeObstacles,
    push: &Push,
    start: &Config,
    wanted: usize,
) -> Result<Vec<Config>, Outcome> {
    if push.node == 0 || push.node >= tree.len() {
        return Err(Outcome::InvalidCandidate);
    }
    let poses = pre_contact_poses(tree, push).ok_or(Outcome::InvalidCandidate)?;
    let scene = PlanningScene::new(model, obstacles, near_contact(tree, push.node));
    let direction = push.vector.normalize();
    let travel = push.vector.norm() + APPROACH_OFFSET;
    let anywhere = |_: &Config, _: &Config, _: f64| true;
    let mut outcome = Outcome::Unreachable;
    let mut feasible: Vec<Config> = Vec::new();
    for goal in poses
        .iter()
        .flat_map(|p| model.robot.ik_solutions(p, start))
    {
        // A redundant arm's colliding solutions swing along their
        // self-motion to free ones where they can.
        let free: Vec<Config> = if scene.config_valid(&goal) {
            vec![goal]
        } else {
            model
                .robot
                .self_motions(&goal, &SELF_MOTION_SWINGS)
                .into_iter()
                .filter(|q| scene.config_valid(q))
                .collect()
        };
        if free.is_empty() {
            if outcome == Outcome::Unreachable {
                outcome = Outcome::GoalInCollision;
            }
            continue;
        }
        outcome = Outcome::PushInfeasible;
        for g in free {
            if push_line(&model.robot, &anywhere, &g, &direction, travel).is_some() {
                feasible.push(g);
                if feasible.len() >= wanted {
                    return Ok(feasible);
                }
            }
        }
    }
    if feasible.is_empty() {
        Err(outcome)
    } else {
        Ok(feasible)
    }
}

/// Carries out a reachable push: checks the straight push from each of
/// `goals` (from [`reach`]) against the tree as it deforms (`snapshots`),
/// plans the approach from `start` with RRT*,
/// shortcuts and times it. The plan's `rank` is left 0 for the caller.
#[allow(clippy::too_many_arguments)]
pub fn execute(
    model: &CollisionModel,
    tree: &Tree,
    obstacles: &TreeObstacles,
    snapshots: &PushSnapshots<'_>,
    push: &Push,
    goals: &[Config],
    start: &Config,
    options: &PlanOptions,
) -> Result<PushPlan, Outcome> {
    let node = push.node;
    let approach_scene = PlanningScene::new(model, obstacles, near_contact(tree, node));
    let pushed = Allowed {
        gripper_branches: tree.subtree(node),
    };
    let direction = push.vector.normalize();
    let travel = push.vector.norm() + APPROACH_OFFSET;
    // Obstacles along the push: the tree at rest until contact, then the
    // simulated tree every PUSH_SNAPSHOT of push.
    let edge_free = |a: &Config, b: &Config, distance: f64| -> bool {
        let contact = (distance - APPROACH_OFFSET).max(0.0);
        let at = if distance <= APPROACH_OFFSET {
            Some(obstacles)
        } else {
            snapshots.at((contact / PUSH_SNAPSHOT).ceil() as usize)
        };
        // A push the simulator rejects part of is infeasible.
        at.is_some_and(|at| PlanningScene::new(model, at, pushed.clone()).edge_valid(a, b))
    };
    // The pre-contact configurations nearest the start (in joint space)
    // first; once PUSH_GOALS of them can carry out the push, the others
    // are not checked (each push line is 30 IK steps and edge checks
    // against the deforming tree, and a reach can have 16 solutions).
    let mut by_distance: Vec<&Config> = goals.iter().collect();
    by_distance.sort_by(|a, b| distance(start, a).total_cmp(&distance(start, b)));
    let pushes: Vec<(Config, Vec<Config>)> = by_distance
        .into_iter()
        .filter_map(|g| push_line(&model.robot, &edge_free, g, &direction, travel).map(|l| (*g, l)))
        .take(PUSH_GOALS)
        .collect();
    if pushes.is_empty() {
        return Err(Outcome::PushInfeasible);
    }
    // RRT* aims at the pre-contact configurations and at entries outside
    // the canopy: from each pre-contact configuration the tool backs out
    // along −T̂ at constant orientation as far as that is free (at most
    // RETREAT). Reaching an entry, the approach ends with the straight
    // line back in. An entry is often the easier goal, but not always (on
    // 40 test episodes, entries alone planned 2 fewer), so both are goals.
    let mut lines: Vec<(usize, Vec<Config>)> = pushes
        .iter()
        .enumerate()
        .map(|(k, (goal, _))| (k, retreat_line(model, &approach_scene, goal, &-direction)))
        .filter(|(_, r)| r.len() > 1)
        .collect();
    lines.extend(
        pushes
            .iter()
            .enumerate()
            .map(|(k, (goal, _))| (k, vec![*goal])),
    );
    let targets: Vec<Config> = lines
        .iter()
        .map(|(_, r)| *r.last().expect("a retreat starts at its goal"))
        .collect();
    let path = match rrt_star(start, &targets, &approach_scene, &options.rrt) {
        Ok(path) => path,
        Err(RrtError::StartInvalid) => return Err(Outcome::StartInCollision),
        Err(RrtError::NoPath { .. } | RrtError::NoValidGoal) => return Err(Outcome::NoPath),
    };
    let (push_index, retreat) = &lines[path.goal];
    let mut approach = path.waypoints.clone();
    approach.extend(retreat.iter().rev().skip(1));
    let smooth = shortcut(
        &approach,
        &approach_scene,
        options.shortcut_attempts,
        options.rrt.seed,
    );
    let vmax = model.robot.velocity_limits();
    let mut trajectory = time_parameterize(
        &smooth,
        &vmax,
        &model.robot.acceleration_limits(),
        options.dt,
    );
    let push_start_index = trajectory.len() - 1;
    let t0 = trajectory.last().map_or(0.0, |p| p.t);
    let line = &pushes[*push_index].1;
    let step_time = PUSH_STEP / PUSH_SPEED;
    let mut t = t0;
    for w in line.windows(2) {
        // Slow down where a joint would exceed its speed limit.
        let joint_time = (0..vmax.len())
            .map(|i| (w[1][i] - w[0][i]).abs() / vmax[i])
            .fold(0.0, f64::max);
        t += step_time.max(joint_time);
        trajectory.push(TimedPoint { t, q: w[1] });
    }
    let execution = execution(
        &model.robot,
        &approach_scene,
        &smooth,
        &direction,
        travel,
        &options.execution,
    )
    .ok_or(Outcome::NoTrajectory)?;
    Ok(PushPlan {
        node,
        rank: 0,
        push: push.vector,
        trajectory,
        push_start_index,
        execution,
    })
}

/// The tree during a push: snapshot k is the steady state after k·1 cm of
/// push (k = 0 is the tree at rest, the last the full push), each with the
/// fixed obstacles of `rest`. Each is simulated when first asked for, so a
/// push line that collides early costs only the snapshots it reached; one
/// set serves every base a planner tries.
pub struct PushSnapshots<'a> {
    tree: &'a Tree,
    push: Push,
    rest: &'a TreeObstacles,
    /// Snapshots 1..=count with the joint rotations they were solved at;
    /// `None` inside: the simulator rejects that part.
    cache: Vec<std::cell::OnceCell<Option<Snapshot>>>,
}

struct Snapshot {
    obstacles: TreeObstacles,
    positions: Vec<nalgebra::Point3<f64>>,
    joint_rotations: Vec<Vector3<f64>>,
    contact_force: [f64; 3],
}

impl<'a> PushSnapshots<'a> {
    pub fn new(tree: &'a Tree, push: &Push, rest: &'a TreeObstacles) -> Self {
        let count = (push.vector.norm() / PUSH_SNAPSHOT).ceil().max(1.0) as usize;
        Self {
            tree,
            push: *push,
            rest,
            cache: (0..count).map(|_| std::cell::OnceCell::new()).collect(),
        }
    }

    /// Number of snapshots after the rest state.
    pub fn count(&self) -> usize {
        self.cache.len()
    }

    /// Snapshot `k` (clamped to the last), or `None` when the simulator
    /// rejects the push that far.
    pub fn at(&self, k: usize) -> Option<&TreeObstacles> {
        if k == 0 {
            return Some(self.rest);
        }
        let k = k.min(self.count());
        self.cache[k - 1]
            .get_or_init(|| {
                let partial = Push {
                    node: self.push.node,
                    vector: self.push.vector * (k as f64 / self.count() as f64),
                };
                // Warm-started from the nearest earlier snapshot solved, or
                // else from the whole push's rotations scaled down (the
                // planner solves the whole push first to check it).
                let earlier = self.cache[..k - 1]
                    .iter()
                    .rev()
                    .find_map(|c| c.get().and_then(|s| s.as_ref()))
                    .map(|s| s.joint_rotations.clone());
                let scaled = || {
                    self.cache[self.count() - 1]
                        .get()
                        .and_then(|s| s.as_ref())
                        .map(|s| {
                            let f = k as f64 / self.count() as f64;
                            s.joint_rotations.iter().map(|r| r * f).collect::<Vec<_>>()
                        })
                };
                let warm = earlier.or_else(scaled);
                simulate_from(self.tree, &partial, &SimConfig::default(), warm.as_deref())
                    .ok()
                    .map(|o| Snapshot {
                        obstacles: self.rest.with_tree_at(self.tree, &o.final_positions),
                        contact_force: o.report.contact_force,
                        positions: o.final_positions,
                        joint_rotations: o.joint_rotations,
                    })
            })
            .as_ref()
            .map(|s| &s.obstacles)
    }

    /// The whole push, held, as the simulator gives it: node positions and
    /// loads (`None` when the simulator rejects it).
    pub fn final_state(&self) -> Option<(&[nalgebra::Point3<f64>], PushLoads)> {
        self.at(self.count())?;
        self.cache[self.count() - 1]
            .get()
            .and_then(|s| s.as_ref())
            .map(|s| {
                let loads = PushLoads::of_state(self.tree, &s.joint_rotations, s.contact_force);
                (s.positions.as_slice(), loads)
            })
    }
}

/// Longest tool retreat from the pre-contact pose before the approach (m).
pub const RETREAT: f64 = 0.12;
/// Spacing of the retreat's IK steps (m); the edges between them are
/// checked continuously.
const RETREAT_STEP: f64 = 0.02;

/// The tool's straight retreat from `goal` along `direction` at constant
/// orientation, every [`RETREAT_STEP`] up to [`RETREAT`], as far as it
/// stays on one IK branch and free in `scene`: `goal` first, at least.
fn retreat_line(
    model: &CollisionModel,
    scene: &PlanningScene<'_>,
    goal: &Config,
    direction: &Vector3<f64>,
) -> Vec<Config> {
    let steps = (RETREAT / RETREAT_STEP).round() as usize;
    tool_line(
        &model.robot,
        goal,
        direction,
        steps,
        &|k| RETREAT_STEP * k as f64,
        PUSH_MAX_JOINT_STEP * (RETREAT_STEP / PUSH_STEP),
        &|previous, next, _| scene.config_valid(next) && scene.edge_valid(previous, next),
    )
}
