//! What both RRT* variants share: the configuration space and its
//! validator, options, statistics and errors, sampling, steering, the
//! direct link to a goal and the neighbour radius.

use std::time::Duration;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// A joint configuration (one value per joint of the arm planned for).
pub type Config = crate::robot::model::joint_vector::JointVector;

/// Decides which configurations and straight joint-space edges are free.
pub trait MotionValidator {
    fn config_valid(&self, q: &Config) -> bool;
    /// The straight edge from `a` (known valid) to `b` is free.
    fn edge_valid(&self, a: &Config, b: &Config) -> bool;
    /// Each joint's position limits, which bound the sampling.
    fn joint_limits(&self) -> Vec<(f64, f64)>;
}

#[derive(Debug, Clone)]
pub struct RrtStarOptions {
    pub max_iterations: usize,
    pub time_budget: Option<Duration>,
    pub goal_bias: f64,
    /// Largest extension per iteration (rad, Euclidean).
    pub max_step: f64,
    /// γ of the shrinking neighbour radius (rad).
    pub gamma: f64,
    /// Iterations spent improving after the first solution.
    pub refine_iterations: usize,
    /// How far beyond the start and goals each joint is sampled (rad).
    pub sampling_margin: f64,
    /// Lazy edge evaluation (`lazy`): edges join the tree unchecked and
    /// are checked only when a path through them is about to be used.
    pub lazy: bool,
    pub seed: u64,
}

impl Default for RrtStarOptions {
    fn default() -> Self {
        Self {
            max_iterations: 5000,
            time_budget: Some(Duration::from_millis(500)),
            goal_bias: 0.1,
            max_step: 0.6,
            gamma: 6.0,
            // On the robot bench's fence, 20 and 40 give the same median
            // cost; the extra 20 are a quarter of the time.
            refine_iterations: 20,
            sampling_margin: 1.5,
            lazy: true,
            seed: 1,
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct RrtStats {
    pub iterations: usize,
    pub nodes: usize,
    /// Iteration at which the first solution appeared.
    pub first_solution: Option<usize>,
    /// (iteration, best cost) each time the best cost improved.
    pub cost_history: Vec<(usize, f64)>,
    pub elapsed_ms: f64,
}

impl RrtStats {
    /// A search that has not begun: the start node alone.
    pub(super) fn start() -> Self {
        Self {
            iterations: 0,
            nodes: 1,
            first_solution: None,
            cost_history: Vec::new(),
            elapsed_ms: 0.0,
        }
    }
}

#[derive(Debug, Clone)]
pub struct RrtPath {
    /// Start … goal, each edge collision-free.
    pub waypoints: Vec<Config>,
    /// Which of the goals was reached.
    pub goal: usize,
    pub cost: f64,
    pub stats: RrtStats,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RrtError {
    #[error("the start configuration is in collision")]
    StartInvalid,
    #[error("no goal configuration is collision-free")]
    NoValidGoal,
    #[error("no path found within the budget ({iterations} iterations, {elapsed_ms:.1} ms)")]
    NoPath { iterations: usize, elapsed_ms: f64 },
}

pub fn distance(a: &Config, b: &Config) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

pub(super) fn steer(from: &Config, to: &Config, max_step: f64) -> Config {
    let d = distance(from, to);
    if d <= max_step {
        return *to;
    }
    from.lerp(to, max_step / d)
}

/// The valid goals (with their index among those given), the random
/// stream and the sampling box of one query.
pub(super) struct Sampler {
    pub(super) goals: Vec<(usize, Config)>,
    pub(super) rng: ChaCha8Rng,
    pub(super) bounds: Vec<(f64, f64)>,
}

impl Sampler {
    pub(super) fn new(
        start: &Config,
        goals: &[Config],
        validator: &dyn MotionValidator,
        options: &RrtStarOptions,
    ) -> Result<Self, RrtError> {
        if !validator.config_valid(start) {
            return Err(RrtError::StartInvalid);
        }
        let goals: Vec<(usize, Config)> = goals
            .iter()
            .copied()
            .enumerate()
            .filter(|(_, g)| validator.config_valid(g))
            .collect();
        if goals.is_empty() {
            return Err(RrtError::NoValidGoal);
        }
        let limits = validator.joint_limits();
        let bounds: Vec<(f64, f64)> = (0..start.len())
            .map(|i| {
                let values = goals
                    .iter()
                    .map(|g| g.1[i])
                    .chain(std::iter::once(start[i]));
                let lo = values.clone().fold(f64::INFINITY, f64::min) - options.sampling_margin;
                let hi = values.fold(f64::NEG_INFINITY, f64::max) + options.sampling_margin;
                (lo.max(limits[i].0), hi.min(limits[i].1))
            })
            .collect();
        Ok(Self {
            goals,
            rng: ChaCha8Rng::seed_from_u64(options.seed),
            bounds,
        })
    }
}

/// A goal (with probability `goal_bias`) or a uniform sample of the box.
pub(super) fn sample(
    rng: &mut ChaCha8Rng,
    goals: &[(usize, Config)],
    bounds: &[(f64, f64)],
    goal_bias: f64,
) -> Config {
    if rng.random::<f64>() < goal_bias {
        goals[rng.random_range(0..goals.len())].1
    } else {
        Config::from_fn(bounds.len(), |i| {
            rng.random_range(bounds[i].0..=bounds[i].1)
        })
    }
}

/// A direct edge is the shortest path to its goal: the direct edges are
/// checked nearest goal first, and the first free one is returned (a
/// farther goal's direct edge cannot beat it, so it is not checked).
pub(super) fn direct_link(
    start: &Config,
    goals: &[(usize, Config)],
    validator: &dyn MotionValidator,
) -> Option<usize> {
    let mut order: Vec<(usize, f64)> = goals
        .iter()
        .enumerate()
        .map(|(g, (_, goal))| (g, distance(start, goal)))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    order
        .into_iter()
        .map(|(g, _)| g)
        .find(|&g| validator.edge_valid(start, &goals[g].1))
}

/// No path is shorter than the straight line to the nearest goal; a path
/// of that cost ends the search.
pub(super) fn cost_lower_bound(start: &Config, goals: &[(usize, Config)]) -> f64 {
    goals
        .iter()
        .map(|(_, g)| distance(start, g))
        .fold(f64::INFINITY, f64::min)
}

/// The neighbour radius of RRT* with `n` nodes, never above the step.
/// (The exponent is 1/dimension: 1/6 for the UR5, 1/7 for a 7-joint arm.)
pub(super) fn neighbour_radius(options: &RrtStarOptions, n: usize, dof: usize) -> f64 {
    let n = n as f64 + 1.0;
    (options.gamma * (n.ln() / n).powf(1.0 / dof as f64)).min(options.max_step)
}

/// Path length in joint space.
pub fn path_cost(path: &[Config]) -> f64 {
    path.windows(2).map(|w| distance(&w[0], &w[1])).sum()
}
